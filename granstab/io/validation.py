"""The validation report of an import (build.py writes the dict, which is JSON-able): its warnings, and the whole
report as readable lines."""
from __future__ import annotations

import re

NAMES_SHOWN = 8
LAW_DEFAULT = "built-in default (not in the file)"    # the source of a law parameter neither file nor user gave


def percent(fraction: float) -> str:
    """A fraction as a percentage with the digits it needs: two significant figures below 10 % (0.05 %, 1.2 %), one
    decimal above; never a non-zero share shown as 0 % or a partial one as 100 %. The report's one way of writing
    a share."""
    value = 100 * fraction
    if value == 0 or value == 100:
        return f"{value:.0f} %"
    digits = 2
    while True:                       # more digits until the rounding neither hides it nor makes it whole
        text = f"{value:.{digits}g}" if value < 10 else f"{value:.{max(digits - 1, 1)}f}"
        if 0 < float(text) < 100 or digits > 16:
            return f"{text} %"
        digits += 1


def _names(names: list) -> str:
    if not names:
        return ""
    more = f", … {len(names) - NAMES_SHOWN} more" if len(names) > NAMES_SHOWN else ""
    return " (" + ", ".join(names[:NAMES_SHOWN]) + more + ")"


def _stats(s: dict, fmt: str = ".3g") -> str:
    if s.get("median") is None:
        return "n/a"
    return f"median {s['median']:{fmt}}, p95 {s['p95']:{fmt}}, max {s['max']:{fmt}}"


def import_warnings(report: dict) -> list[str]:
    """What the import changed in the file's data or assumed beyond it, one line each: forces moved onto the
    friction cone, tension kept elastic, rattlers dropped, contacts cut around a periodic cell, gaps under the
    centres rule, a law the file does not give, listings that disagree, pairs and columns left out."""
    r, out = report, []
    cone, co, pa, fo = r["cone"], r["contacts"], r["particles"], r["forces"]["fn_nonpositive"]
    outside, ratio = cone["outside"], cone["largest_ratio_ft_over_mu_fn"]
    if outside["count"]:
        out.append(f"{outside['count']} contact(s) outside the friction cone ({percent(outside['fraction'])}"
                   + ("" if ratio is None else f", |f_t|/(μ f_n) up to {ratio:.4g}") + f"): {outside['action']}; "
                   f"forces changed by up to {cone['largest_change_over_force']:.3g} of their size"
                   f"{_names(outside['names'])}")
    if cone["at_yield_by_file_flag"]:
        out.append(f"{cone['at_yield_by_file_flag']} contact(s) inside the cone flagged fully mobilised by the file: "
                   "projected onto the cone, marked sliding")
    if fo["with_force"]:
        out.append(f"{fo['with_force']} contact(s) with f_n <= 0 carrying a force (tension): treated as elastic"
                   f"{_names(fo['names'])}")
    if pa["without_contacts_dropped"]:
        out.append(f"{pa['without_contacts_dropped']} particle(s) without contacts (rattlers) dropped"
                   f"{_names(pa['dropped'])}")
    if co["cut_around_periodic_cell"]:
        out.append(f"{co['cut_around_periodic_cell']} contact(s) closing a loop around the periodic cell cut: their "
                   f"forces act as loads on both particles{_names(r['periodic']['cut_names'])}")
    extreme, geo = r["geometry"].get("extreme_overlaps"), r["geometry"]
    if extreme and extreme["count"]:
        out.append(f"{extreme['count']} contact(s) overlap by more than {extreme['threshold']:g} of the pair's mean "
                   f"radius (2δ/(R_p+R_q) up to {geo['overlap_over_mean_radius']['max']:.3g}; d/(R_p+R_q) down to "
                   f"{geo['distance_over_sum_of_radii']['min']:.3g}): a DEM keeps overlaps at a few per cent of a "
                   "radius; check the radii (diameters?), the units and the frame, since the contact points and "
                   f"curvatures follow from them{_names(extreme['names'])}")
    agree = r["geometry"].get("normals_disagree_deg")
    if agree and agree["count"]:
        out.append(f"{agree['count']} contact(s) where the two grains' surface normals at the contact point's foot "
                   f"points disagree by more than {agree['threshold']:g}° (up to {agree['max']:.3g}°): the normal "
                   "is their bisector")
    if r["geometry"]["rule"] == "centres" and r["geometry"]["gaps"]:
        out.append(f"{r['geometry']['gaps']} contact(s) with a gap (centre distance > R_p + R_q): the centres rule "
                   "puts their contact point in the gap (data whose radii do not match: --geometry touching)")
    defaults = [f"{k} = {v['value']:g}" for k, v in r["law"].items() if v["source"] == LAW_DEFAULT]
    if defaults:
        out.append(f"law: {', '.join(defaults)}: not in the file, built-in default (give --k, --alpha, --mu)")
    if isinstance(r["duplicates"], dict) and r["duplicates"].get("disagreeing_listings"):
        out.append(f"{r['duplicates']['disagreeing_listings']} pair(s) listed twice with different forces: kept "
                   f"{r['duplicates']['kept']}")
    apart = r.get("non_touching_pairs", {})
    if apart.get("with_force"):
        out.append(f"{apart['with_force']} pair(s) with a force but no overlap dropped ({apart['rule']})")
    left = r.get("left_out")
    if left and left["largest_over_force"]:
        out.append(f"left out: column {left['column']}, up to {left['largest_over_force']:.3g} of a contact force "
                   f"({left['why']})")
    return out


def run_warnings(frames: list[tuple[object, list[str]]]) -> list[str]:
    """The import warnings of a run over frames [(frame, its warnings)], once each: a warning of one kind (its text
    without numbers and parenthesised lists) is written as the first frame gave it, with the frames it came from
    where not every frame gave the same line. What every command prints once per run, not once per frame."""
    kinds: dict[str, list] = {}
    for frame, lines in frames:
        for line in lines:
            kinds.setdefault(re.sub(r"\([^()]*\)|[-+]?\d[\d.e+-]*", "#", line), []).append((frame, line))
    out = []
    for seen in kinds.values():
        (first, line), texts = seen[0], {text for _, text in seen}
        if len(seen) == len(frames) and len(texts) == 1:
            out.append(line)
        else:
            out.append(f"{line} [frame {first}" + (f"; one like it in {len(seen)} of {len(frames)} frames]"
                                                   if len(frames) > 1 else "]"))
    return out


def _bodies_line(b: dict, offset) -> str:
    """Rigid bodies (io/bodies.py): how many, their arms, the engine's contact points against the parts' geometry,
    flat sides and conforming (flat on flat) contacts."""
    engine = "" if offset is None else (f"; the engine's contact points differ by {_stats(offset)} of the smaller "
                                        "part radius")
    return (f"bodies: {b['bodies']} rigid {b['kind']}s, {b['parts_touching']} part(s) in contact; arms {b['arms']}"
            f"{engine}; flat sides in contact {b['flat_sides_in_contact']}, conforming (flat on flat) "
            f"{b['conforming_contacts']}")


def _periodic_line(pe: dict) -> str:
    """The periodic cell and which treatment was used: seam contacts kept with their images, or cut."""
    cell = "[" + ", ".join("[" + ", ".join(f"{v:.6g}" for v in row) + "]" for row in pe["lattice"]) + "]"
    if pe["periodic"]:
        return (f"periodic: {pe.get('kind', 'cell')} {cell}: periodic scene, {pe['seam_contacts']} seam contact(s) "
                f"kept with their images{_names(pe['seam_names'])}; {pe['treatment']}")
    return (f"periodic: {pe.get('kind', 'cell')} {cell}: {pe['contacts_cut']} contact(s) cut"
            f"{_names(pe['cut_names'])}; {pe['treatment']}")


def _yield_rule(cone: dict) -> str:
    """Which rule decided the contacts at yield: the file's flags, or the tolerance (files without flags)."""
    if cone.get("rule", "").startswith("the file's flag"):
        return (f"by the file's fully-mobilised flag, {cone['at_yield_by_file_flag']} of them beyond "
                f"{cone['yield_rtol']:g} of |f_t| = μ f_n; {cone['within_tolerance_not_flagged']} within it not "
                "flagged, kept sticking")
    return f"within {cone['yield_rtol']:g} of |f_t| = μ f_n; the file flags none"


def _states(co: dict) -> str:
    """What the scene's contact states mean, in words: at the friction limit (state "sliding"), forced elastic by
    the input (tension, or a force outside the cone kept with --outside-cone project/elastic), the rest inside."""
    inside = co["in_scene"] - co["sliding"] - co["elastic"]
    return (f"{co['sliding']} at the friction limit (sliding: both of their branches are examined), "
            f"{co['elastic']} forced elastic by the input (tension, or outside the cone with --outside-cone "
            f"project/elastic), {inside} inside the cone (sticking)")


def _columns(r: dict) -> list[str]:
    """Lines for how the contact table's columns were read and the pairs the file lists that do not touch."""
    out = []
    if r.get("columns"):
        c = r["columns"]
        out.append(f"columns of {c['file']} (from {c['from']}): "
                   + ", ".join(f"{h} → {'ignored' if n == '-' else n}" for h, n in c["map"])
                   + "".join(f"; {key.split('_')[0]} from {r[key]}" for key in ("forces_from", "moments_from")
                             if r.get(key) not in (None, "none")))
    apart = r.get("non_touching_pairs")
    if apart:
        out.append(f"non-touching pairs: {apart['count']} listed by the file and dropped, {apart['with_force']} of "
                   f"them with a force; {apart['rule']}")
    return out


def format_report(report: dict) -> str:
    """The report as lines: a scene file's one line, a snapshot's every section, then its warnings."""
    r = report
    if r["read_as"] == "scene file":
        return f"{r['source']} ({r['format']}): read as a scene file, as written"
    frame = "" if r["frame"] is None else f", frame {r['frame']}"
    frames = "" if r["frames_available"] is None else f"; {r['frames_available']} frame(s) in the input"
    pa, co, cone, fo = r["particles"], r["contacts"], r["cone"], r["forces"]
    geo, law, imb = r["geometry"], r["law"], r["imbalance"]
    out = cone["outside"]
    lines = [
        f"{r['source']} ({r['format']}{frame}{frames})",
        f"particles: {pa['in_scene']} in the scene of {pa['in_file']} (outside region {pa['outside_region']}, "
        f"without contacts dropped {pa['without_contacts_dropped']})",
        f"contacts: {co['in_scene']} in the scene of {co['in_file']} (cut by region {co['cut_by_region']}, cut around "
        f"the periodic cell {co['cut_around_periodic_cell']}); {_states(co)}",
        *_columns(r),
        f"units: length {r['units']['length']}, force {r['units']['force']}",
        _geometry_line(geo),
        "law: " + "; ".join(f"{k} = {v['value'] if isinstance(v['value'], str) else format(v['value'], '.6g')} "
                            f"({v['source']})" for k, v in law.items()),
        f"cone (all {co['in_file']} contacts of the frame): {cone['at_yield']} at yield ({_yield_rule(cone)}); "
        f"{out['count']} outside "
        f"({percent(out['fraction'])}): {out['action']}{_names(out['names'])}",
        f"forces: {fo['convention']}; f_n <= 0: {fo['fn_nonpositive']['count']} "
        f"(treated as {fo['fn_nonpositive']['treated_as']}){_names(fo['fn_nonpositive']['names'])}",
        f"duplicates: {r['duplicates']}",
        f"walls: {r['walls']}",
        f"masses: {r.get('masses') or 'none (for the inertia metric: a mass column or --density)'}",
        f"imbalance over {imb['particles']} particles: force {_stats(imb['force'])}; moment {_stats(imb['moment'])}"
        f" ({imb['scale']})",
    ]
    if r.get("bodies"):
        lines.append(_bodies_line(r["bodies"], geo.get("engine_point_offset_over_radius")))
    if r.get("periodic"):
        lines.append(_periodic_line(r["periodic"]))
    for key in ("left_out",):
        if key in r:
            lines.append(f"left out: {r[key]}")
    lines += [f"warning: {w}" for w in r["warnings"]]
    return "\n".join(lines)


def _geometry_line(geo: dict) -> str:
    """The report's geometry line: spheres (the centres/touching rules) or shaped grains (a reader's contact points
    and foot-point normals, e.g. superquadrics)."""
    if "normals_disagree_deg" in geo:
        agree, depth = geo["normals_disagree_deg"], geo["depth_over_size"]
        return (f"geometry: {geo['rule']}; foot-point normals disagree up to {agree['max']:.3g}° (median "
                f"{agree['median']:.3g}°); contact point depth / grain size up to {depth['max']:.3g}")
    return (f"geometry: {geo['rule']}; d/(R_p+R_q) {geo['distance_over_sum_of_radii']['min']:.4g} … "
            f"{geo['distance_over_sum_of_radii']['max']:.4g}; gaps {geo['gaps']}; "
            f"normal vs centre line up to {geo['normal_to_centre_line_deg_max']:.3g}°")
