"""The validation report of an import as readable lines (the dict itself is JSON-able)."""
from __future__ import annotations

NAMES_SHOWN = 8


def _names(names: list) -> str:
    if not names:
        return ""
    more = f", … {len(names) - NAMES_SHOWN} more" if len(names) > NAMES_SHOWN else ""
    return " (" + ", ".join(names[:NAMES_SHOWN]) + more + ")"


def _stats(s: dict, fmt: str = ".3g") -> str:
    if s.get("median") is None:
        return "n/a"
    return f"median {s['median']:{fmt}}, p95 {s['p95']:{fmt}}, max {s['max']:{fmt}}"


def format_report(report: dict) -> str:
    r = report
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
        f"the periodic cell {co['cut_around_periodic_cell']}); {co['sliding']} sliding, {co['elastic']} elastic",
        f"units: length {r['units']['length']}, force {r['units']['force']}",
        f"geometry: {geo['rule']}; d/(R_p+R_q) {geo['distance_over_sum_of_radii']['min']:.4g} … "
        f"{geo['distance_over_sum_of_radii']['max']:.4g}; gaps {geo['gaps']}; "
        f"normal vs centre line up to {geo['normal_to_centre_line_deg_max']:.3g}°",
        "law: " + "; ".join(f"{k} = {v['value'] if isinstance(v['value'], str) else format(v['value'], '.6g')} "
                            f"({v['source']})" for k, v in law.items()),
        f"cone (all {co['in_file']} contacts of the frame): {cone['at_yield']} at yield (within {cone['yield_rtol']:g} of |f_t| = μ f_n, "
        f"{cone['at_yield_by_file_flag']} by the file's flag); {out['count']} outside "
        f"({100 * out['fraction']:.1f} %): {out['action']}{_names(out['names'])}",
        f"forces: {fo['convention']}; f_n <= 0: {fo['fn_nonpositive']['count']} "
        f"(treated as {fo['fn_nonpositive']['treated_as']}){_names(fo['fn_nonpositive']['names'])}",
        f"duplicates: {r['duplicates']}",
        f"walls: {r['walls']}",
        f"masses: {r.get('masses') or 'none (for the inertia metric: a mass column or --density)'}",
        f"imbalance over {imb['particles']} particles: force {_stats(imb['force'])}; moment {_stats(imb['moment'])}"
        f" ({imb['scale']})",
    ]
    if r.get("periodic"):
        pe = r["periodic"]
        lines.append(f"periodic: {pe.get('kind', 'cell')}, {pe['contacts_cut']} contacts cut{_names(pe['cut_names'])}"
                     f"; {pe['treatment']}")
    for key in ("left_out",):
        if key in r:
            lines.append(f"left out: {r[key]}")
    return "\n".join(lines)
