"""The explorer's page text: HTML and Markdown strings as pure functions of what they show (no viser).

app/panel/*.py write them into their handles; tests/app/test_app_text.py reads them without a browser or a server.
"""
from __future__ import annotations

import html

from .params import PARAMS

VERDICT_COLOR = {"stable": "#1e8449", "neutral": "#b7950b", "unstable": "#c0392b", None: "#555555"}
TWO_LINES = "line-height:1.3em;height:2.6em;overflow:hidden;display:-webkit-box;-webkit-line-clamp:2;" \
            "-webkit-box-orient:vertical"                   # a headline line's box: two lines, whatever its text
NO_REASON = (None, "no contact", "not analysed", "scan map", "rigidity map", "track")   # badges without a reason line
PRESETS = {      # each preset's title and what it shows, in one line (the Scene tab, under the menu)
    "two_particle": ("Two grains, one contact", "Sharp tips roll apart, flat sides rock back: move ρ/r across 1."),
    "two_particle_flat": ("Two grains with flat sides", "The same pair at ρ/r = 2: stable while pressed together."),
    "two_disks": ("Two equal disks", "Exactly round (ρ = r): they roll freely — neutral."),
    "ellipses_sharp": ("Two ellipses, tip to tip", "Drag them: the contact follows the shapes (sharp: unstable)."),
    "ellipses_flat": ("Two ellipses, side to side", "The same ellipses turned by 90°: flat sides, stable."),
    "ellipsoid_trio": ("Three ellipsoids (3D)", "Shapes in 3D, half the friction mobilised."),
    "four_disk": ("Four disks (the paper's Sec. 4.2)", "All four contacts sliding: 16 cases, unstable — try μ."),
    "gear_packing": ("Gears: a square packing", "Disks that turn like gears cost no energy: neutral."),
    "gear_packing_rolling": ("Gears with rolling resistance", "Rolling stiffness stops the gears."),
    "hand_in_glove": ("Hand in glove", "A convex grain in a concave socket: nearly the same curvature."),
    "spheres_tetrahedron": ("Four spheres (3D)", "A tetrahedron with sliding apex contacts and contact moments."),
    "annulus_frame": ("A real packing: 143 photoelastic disks", "Measured forces from an experiment: where does "
                      "it give way?"),
    "superquadric_cluster": ("Five blocky grains (3D, LIGGGHTS)", "Corners pressed on faces: their tight curvature "
                             "rolls the grains off — unstable by shape."),
}


def preset_label(name: str) -> str:
    """The Preset menu's entry for a preset: its title (PRESETS) with its file stem, the name docs, links
    (`?preset=NAME`) and `granstab-app --preset NAME` use; else the stem. The session keeps the stem."""
    return f"{PRESETS[name][0]} ({name})" if name in PRESETS else name


MAP_DETAILS = ("**Scan map.** {report}.\n\nColour: the fraction of the clusters containing a particle that are "
               "unstable (white 0 → dark red 1; grey: in no scanned cluster). Click a particle, or type its name "
               "under *Scene*, to open its cluster here; *Back to the map* returns.")
MAP_LEGEND = ("**Legend** — particle colour: the share of the scanned clusters containing it that are unstable by the "
              "packing (mechanism frictional, geometric or mixed; white 0 → dark red 1). Light grey: unstable only "
              "through `boundary` clusters (the dead loads at the cut, docs/attribution.md); dark grey: in no "
              "cluster.")


def loading_html(name: str) -> str:
    """The line shown while a scene opens."""
    return (f'<div class="granstab-loading" style="color:#555;font-style:italic;padding:2px 8px">'
            f"Opening {html.escape(name)} …</div>")


def error_html(text: str | None) -> str:
    """A failure in one red line ("" none)."""
    return (f'<div class="granstab-error" style="color:#b03a2e;font-weight:600;padding:2px 8px">'
            f"{html.escape(text)}</div>") if text else ""


def wrapped(text: str) -> str:
    """Preformatted lines that wrap at the panel's edge (a Markdown code block cuts them off), as Markdown's raw
    HTML."""
    return (f'<div class="granstab-report" style="white-space:pre-wrap;overflow-wrap:anywhere;font-family:monospace;'
            f'font-size:0.85em">{html.escape(text)}</div>')


def badge(s) -> tuple[str | None, str, str]:
    """(verdict word or badge, title, reason) of the headline of session `s`: the verdict, or what the page shows
    instead (a map, a large packing not analysed yet, particles apart)."""
    r = s.report()
    verdict = r["verdict"]
    title = s.scene.title if s.scene is not None else str(s.preset)
    if s.deferred:
        title = f"{title} — {s.scene.n_particles} particles: drawn, not analysed (Analyse the whole packing)"
        verdict = "not analysed"
    if s.on_map:      # a scan's map, a track's frame (its own headline) or a rigidity map
        title, verdict = s.model.headline or (
            f"{s.scene.n_particles} particles: click one (or type its name) for its cluster", "scan map")
    elif s.scene is not None and s.scene.n_contacts == 0:  # pulled apart: the file's title no longer holds
        title, verdict = "no contact: the particles are apart (every motion is free)", "no contact"
    return verdict, title, "" if verdict in NO_REASON else plain_sentence(s, verdict)


def lowest_mode(modes):
    """The mode a page shows first: the lowest consistent negative one, else the lowest consistent non-rigid one,
    else the lowest non-rigid one (None: none)."""
    moving = sorted((m for m in modes if m.label != "rigid"), key=lambda m: (m.eigenvalue, m.branch, m.index))
    return next((m for m in moving if m.consistent), moving[0] if moving else None)


def plain_sentence(s, verdict: str | None) -> str:
    """One sentence a student reads under the badge: what the grains can do, and for the pair why (its curvature
    against a circle's: λ⁽⁶⁾ = f(ρ − r), Sec. 4.1). The technical reason and bounds are on the Verdict tab."""
    if verdict not in ("stable", "neutral", "unstable"):
        return s.headline()[1] if verdict else ""
    m = lowest_mode(s.modes())
    what = m.label if m is not None else "small"
    if s.kind == "two_particle":
        rho, pull = s.params["rho_r"], s.params["f_kr"] < 0
        shape = (f"sharper than a circle (ρ/r = {rho:g} < 1)" if rho < 1 else "exactly as curved as a circle (ρ/r = 1)"
                 if rho == 1 else f"flatter than a circle (ρ/r = {rho:g} > 1)")
        force = " and the force pulls (cohesive)" if pull else " and pressed together" if s.params["f_kr"] > 0 else ""
        doing = {"unstable": "The grains can roll apart", "neutral": "The grains roll over each other freely",
                 "stable": "The grains rock back when rolled"}[verdict]
        if verdict == "unstable" and what != "rolling":
            return (f"The grains can move on their own by {what.split(' at ')[0]}: friction is at its limit "
                    f"(μ = {s.params['mu']:g}), whatever the curvature.")
        return f"{doing}: the contact is {shape}{force}."
    return {"unstable": f"The grains can move on their own: a small {what} motion releases energy.",
            "neutral": f"A small {what} motion costs no energy: the grains can drift that way.",
            "stable": "Every small motion the contacts allow costs energy: the grains spring back."}[verdict]


def notation_html(markdown: str) -> str:
    """The "?" beside the verdict: the notation (docs/equations.md#notation) folded until asked for."""
    # the text waits in an attribute until the fold opens: folded, none of its words is on the page
    return ('<details class="granstab-notation" style="margin:0 2px 4px 2px;font-size:0.85em" '
            f'data-notation="{html.escape(markdown, quote=True)}" ontoggle="if(this.open){{'
            "this.querySelector('div').textContent=this.dataset.notation}\">"
            '<summary style="cursor:pointer;color:#1c5d99" title="the symbols, in words">? What the words and '
            'symbols mean (docs/equations.md#notation)</summary>'
            '<div style="white-space:pre-wrap;max-height:40vh;overflow:auto"></div></details>')


def headline_html(verdict: str | None, title: str, reason: str, revision: int) -> str:
    """The coloured badge, the scene's title and the reason under it: two lines each at most, always two lines
    tall (the full text on hover), so that the controls below never jump when one of them wraps."""
    return (
        f'<div class="granstab-verdict" data-verdict="{(verdict or "none").replace(" ", "-")}" '
        f'data-revision="{revision}" style="background:'
        f'{VERDICT_COLOR.get(verdict, "#555")};color:white;font-weight:700;font-size:1.35em;padding:4px 10px;'
        f'border-radius:6px;letter-spacing:0.05em">{(verdict or "no verdict").upper()}</div>'
        f'<div title="{html.escape(title)}" style="font-style:italic;margin:4px 2px 0 2px;{TWO_LINES}">'
        f'{html.escape(title)}</div>'
        f'<div title="{html.escape(reason)}" style="margin:2px 2px 4px 2px;font-size:0.92em;{TWO_LINES}">'
        f'{html.escape(reason)}</div>')


def info_markdown(s, verdict: str | None) -> str:
    """The Scene tab's text: a notice, the scene's kind and parameters, how to drag it, its import report."""
    note = "\n\n".join(x for x in (s.report().get("notice"), s.adjusted, s.caveat) if x)
    params = ", ".join(f"{PARAMS[k].label} = {s.params[k]:g} ({PARAMS[k].hint})" for k in s.used_params)
    report = s.model.report
    grains = getattr(s.model, "grains", None)
    drag = ("" if s.on_map else " Drag a particle by its arrows (the arc turns it): contacts and forces follow the "
            "geometry." if s.draggable else " Its contacts are given in the file (points, normals, curvatures, "
            "forces), not shapes: the particles cannot be dragged." if grains is None else
            f" Drawn as they are ({grains.kind.replace('_', ' ')}s, from the file); the contacts are the file's "
            "(points, normals, curvatures, forces): the particles cannot be dragged.")
    kind = verdict if s.on_map else s.kind.replace("_", " ")      # a map says which map
    title, line = PRESETS.get(str(s.preset), (None, None))
    return (f"**{title}** — {line}\n\n" if title else "") + (f"{note}\n\n" if note else "") + (f"{kind} scene" + (f" · {params}." if params else ".")) + drag + (
        f"\n\n**Import report**\n\n{wrapped(report)}" if report else "")


def details_markdown(s, metric_row: str) -> str:
    """The Verdict tab's text: the table of the verdict and its bounds, or what stands instead of one."""
    r = s.report()
    if s.on_map:
        return s.model.details or MAP_DETAILS.format(report=s.model.report)
    if s.deferred:
        return "Not analysed yet: a large packing is analysed only on request."
    if r["verdict"] is None:
        return f"**Analysis failed:** {s.error}\n\n(last attempt {r['elapsed'] * 1e3:.1f} ms)"
    name, worst = r["worst_error"]
    rows = [
        "| | |", "|---|---|",
        f"| verdict | **{r['verdict']}** ({'sufficient condition met' if r['sufficient'] else 'not proven'}) |",
        f"| consistent modes | {mode_counts(s.distinct_modes(), r['counts'])} |",
        f"| Type-1 non-uniqueness | {r['type1']} |",
        f"| Type-2 non-uniqueness | {'yes' if r['type2'] else 'no'} |",
        f"| metric | {metric_row} |",
        f"| verdict hinges on S tolerance | {'yes' if r['hinges'] else 'no'} |",
        f"| particles · contacts · at yield | {r['n_particles']} · {r['n_contacts']} · {r['n_sliding']} |",
        f"| branches (2^Ms) | {r['n_branches']} |",
        f"| largest error estimate | {worst:.1e} ({name}) |",
        f"| analysis time | {r['analysis_time'] * 1e3:.1f} ms (with scene: {r['elapsed'] * 1e3:.1f} ms) |",
    ]
    if r.get("attribution"):
        rows.insert(2, f"| why (docs/attribution.md) | {r['attribution']} |")
    if r["dynamics"] is not None:
        d = r["dynamics"]
        rows.insert(7, "| lowest frequencies ω = √λ | " + (", ".join(f"{w:.4g}" for w in d["frequencies"])
                                                            or "none") + " (1/time: √(k/m)) |")
        rows.insert(8, "| growth rates √(−λ) | " + (", ".join(f"{g:.4g}" for g in d["growth_rates"])
                                                     or "none: no resolved negative λ") + " |")
    warn = "".join(f"\n\n**Warning:** {w}" for w in r["warnings"])
    return f"**Why:** {r['reason']}\n\n" + "\n".join(rows) + warn


def mode_counts(distinct: dict, counts: tuple) -> str:
    """Consistent modes by sign, each mode once (Session.distinct_modes), and the core's per-branch count
    `counts` = (positive, zero, negative) where a mode recurs in several branches."""
    pos, zero, neg = counts
    text = f"{distinct['negative']} negative · {distinct['zero']} zero · {distinct['positive']} positive"
    if (neg, zero, pos) != (distinct["negative"], distinct["zero"], distinct["positive"]):
        text += f" (over the branches: {neg} · {zero} · {pos}, a mode counted in each branch it appears in)"
    return text


def metric_row(metric: str, metrics: dict | None, revision: int, checking: bool, masses: bool,
               estimate: float) -> str:
    """The metric-robustness flag of the core (summary["metric_robust"]) once checked, the check running, else how
    to check."""
    if checking:
        return (f"checking L/10, L and 10L{' and inertia' if masses else ''} … "
                f"(about {max(estimate, 0.1):.1g} s; a slider move supersedes it)")
    if metrics is None or metrics["revision"] != revision:
        return f"{metric} only: *Check other metrics* below runs L/10, L, 10L (and inertia with masses)"
    if metrics["robust"]:
        return ("this verdict is proven for every rotation length (and the inertia metric where masses are known), "
                f"not only those tried ({', '.join(x['metric'] for x in metrics['metrics'])})")
    return " · ".join(f"{x['metric']}: {x['verdict']} ({x['consistent_negative']} negative)"
                      for x in metrics["metrics"])


PARTICLE_LEGEND = {        # what app/views.py drew the particles as (SceneView.drawn) → the legend's words
    "stripe": "Dark stripe: a body axis (turns with the particle).",
    "dot": "Dark dot: the end of a body axis (turns with the particle).",
    "rounded_polygon": "Grains: each rounded polygon as the file gives it (its vertices swept by the rounding "
                       "radius); dark stripe: a body axis (turns with it).",
    "superquadric": "Grains: each superquadric as the file gives it (semi-axes, blockiness, orientation), "
                    "translucent; its shape shows how it turns.",
    "clump": "Grains: each clump as its member spheres (one colour a clump; they move as one body), translucent.",
    "cloud": "Dots: the particles' centres (a packing this large is drawn as points).",
}


def legend_markdown(scene, options: dict, legend: dict, lines_off: bool, lines_max: int, mesh_max: int) -> str:
    """What the drawing shows now, and only that (`options`: the Display tab's ticks; `legend`: SceneView's
    numbers; `lines_off`: force lines and normals are off by default for this size)."""
    contacts = scene is not None and scene.n_contacts > 0
    parts = []
    if contacts and legend["max_force"] == 0:
        parts.append("no contact force.")
    elif contacts and options["forces"]:
        parts.append(f"{'lines' if legend.get('lines') else 'arrows'}: the contact force on each particle "
                     "(pointing into it when compressive; red compressive, blue tensile, orange at the Coulomb "
                     f"limit); length {legend['arrow']:.2g}·size = largest |f| = {legend['max_force']:.3g}.")
    if contacts and options["normals"]:
        parts.append("Blue lines: normals n^pq.")
    if contacts and options["osculating"] and scene.n_contacts <= mesh_max:
        parts.append("Purple arcs: osculating circles (radius ρ at each contact).")
    if scene is not None and legend.get("drawn") in PARTICLE_LEGEND:
        parts.append(PARTICLE_LEGEND[legend["drawn"]])
    if getattr(scene, "cell", None) is not None:
        parts.append("Pale copies beyond the cell's outline: periodic images of the particles near its faces "
                     "(each at its particle's orientation; they move with it).")
    if lines_off and not (options["forces"] or options["normals"]):
        parts.append(f"Force lines and normals are off above {lines_max:,} contacts (seconds per frame in a "
                     "browser without a GPU): tick them under *Display*.")
    return "**Legend** — " + " ".join(parts) if parts else ""


def field_note(alpha: float, lam: float | None, tol: float | None, other: str | None = None) -> str:
    """The line above the λ⁽⁶⁾ contour: that it shows the rolling mode only, where the ★ stands, and `other`: the
    mode that makes the verdict unstable when it is not the rolling one (the ★ is red then, not read as stable)."""
    now = ("" if lam is None else f" (λ⁽⁶⁾/k = 0 within the zero tolerance {tol:.0e})" if lam == 0
           else f" (λ⁽⁶⁾/k = {lam:.4g})")
    text = (f"The **rolling** mode only: its eigenvalue λ⁽⁶⁾/k over (ρ/r, f/(kr)) at α = {alpha:g} "
            f"(red < 0 unstable, blue > 0 stable); ★ = now{now}.")
    if other:
        text += (f" **The pair is unstable through another mode ({other})**: the ★ is red, whatever the colour "
                 "under it.")
    return text


def no_mode_text(s) -> str:
    """Why the Eigenmodes panel is empty, and how to fill it."""
    return ("No mode to show." if s.analysis is not None else
            "A map has no modes: open a particle's cluster (click it, or type its name under *Scene*) for its "
            "eigenmodes." if s.on_map else
            "Not analysed yet: *Analyse the whole packing* (under *Scene*) computes the modes." if s.deferred else
            f"No analysis: {s.error}")


def mode_text(m, mask, coloured: bool) -> str:
    """The selected mode `m` (state.Mode) of a branch whose contacts at yield are `mask` (1 sliding, -1
    unloading), said in words; `coloured`: the particles are coloured by its share."""
    shares = ", ".join(f"{k} {v:.0%}" for k, v in m.shares.items() if v >= 0.005)
    way = {1: "consistent in +v only", -1: "consistent in -v only", 0: "consistent both ways",
           2: "not consistent with its branch", 3: "rigid"}[m.code]
    sliding, unloading = int((mask == 1).sum()), int((mask == -1).sum())
    where = f"{sliding} sliding, {unloading} unloading contact(s)" if sliding + unloading else "no contact at yield"
    return (f"**{m.label}** mode, λ = {m.eigenvalue:.5g} (branch {m.branch}: {where}), "
            f"{way}{' (hinges on the S tolerance)' if m.hinges else ''}. "
            f"Contact deformation: {shares or '—'}. Tick *Play* to animate it."
            + (f" Particle colour: its share of this mode's motion, white 0 → dark {'red' if m.consistent and m.eigenvalue < 0 else 'blue'} "
               "100 % of the largest." if coloured else ""))
