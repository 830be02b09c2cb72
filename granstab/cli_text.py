"""The command line's readable output: a result as a table or summary lines (analyze, moduli, rigidity, scan, track),
printed by `cli.py` where `--json` is not asked for."""
from __future__ import annotations

import numpy as np

from .mechanics.branches import BOTH, MINUS, PLUS, RIGID


def import_lines(loaded) -> list[str]:
    """The import's warnings (projected forces, dropped rattlers, cut contacts, ...; none for a scene file) as
    lines of a command's output."""
    return [f"warning: import: {w}" for w in loaded.warnings]


MARK = {PLUS: "+v", MINUS: "-v", BOTH: "±v", RIGID: "rigid"}


TABLE_LOWEST = 8   # eigenvalues per branch in the readable table (all of them with --all)


def format_table(result, show_all: bool = False) -> str:
    """A readable report of an Analysis: per branch the lowest TABLE_LOWEST eigenvalues with consistency marks and
    the counts (every eigenvalue with show_all), then the verdict."""
    s = result.scene
    d = result.to_dict()
    lines = [f"{s.title or s.source}: {s.dim}D, {s.n_particles} particles, {s.n_contacts} contacts, "
             f"{d['n_sliding']} potentially sliding, {len(result.branches)} branch(es), metric {result.metric.name}"
             + ("" if result.length is None else f", L = {result.length:.4g}") + f" (eigenvalues in {result.metric.units})"]
    for b in result.branches:
        mask = " ".join(f"{int(v):+d}" for v in b.mask[result.problem.sliding]) or "(all elastic)"
        lines.append(f"branch [{mask}]  zeros: {b.n_zero} (tol {b.zero_tol:.1e})  ℍ nullity: {b.uniqueness_n_zero}")
        lam, codes = np.asarray(b.stability_eigenvalues), np.asarray(b.codes)
        shown = np.argsort(lam, kind="stable") if show_all else np.argsort(lam, kind="stable")[:TABLE_LOWEST]
        cells = [f"{lam[i]: .6g}{'(' + MARK[codes[i]] + ')' if codes[i] in MARK else ''}" for i in shown]
        rest = len(lam) - len(shown)
        lines.append(f"  sym(𝓗) eigenvalues ({'all ' if not rest else f'lowest {len(shown)} of '}{len(lam)}: "
                     f"{int(np.sum(lam < -b.zero_tol))} negative, {b.n_zero} zero, {int(np.sum(lam > b.zero_tol))} "
                     f"positive): " + ", ".join(cells) + (f", … ({rest} more: --all)" if rest else ""))
    sm = d["summary"]
    lines.append(f"verdict: {sm['verdict'].upper()} — {sm['reason']}")
    low = [k.split("_")[1] for k, v in sm["counts_are"].items() if v != "totals"]
    lines.append(f"consistent eigenvalues: {sm['consistent_positive']} positive, {sm['consistent_negative']} "
                 f"negative, {sm['consistent_zero']} zero"
                 + (f" ({', '.join(low)}: lower bounds; suggested k: {sm.get('suggest_k')})" if low else "")
                 + "; Type-2 non-uniqueness: "
                 f"{'yes' if sm['type2_nonuniqueness'] else 'no'}"
                 + ("; verdict hinges on an S within tolerance" if sm["hinges_on_tolerance"] else ""))
    if sm.get("metrics"):
        robust = {True: "verdict proven metric-robust", False: "verdict proven to depend on the metric"}.get(
            sm["metric_robust"], "verdict's metric-robustness not proven")
        counts = "counts equal" if sm.get("counts_robust") else "counts differ"
        lines.append(f"metric family ({robust}; {counts}): " + "; ".join(
            f"{e['metric']}: {e['verdict']} {e['consistent_positive']}+/{e['consistent_negative']}-"
            for e in sm["metrics"]))
    if result.attribution is not None:
        lines.append(result.attribution.line())
    if not sm["sufficient"]:
        lines.append("not sufficient because: " + ", ".join(sm["insufficient_because"]))
    lines.append("errors (relative): " + ", ".join(f"{k} {v:.1e}" for k, v in d["errors"].items()))
    lines.append("timings: " + ", ".join(f"{k} {1e3 * v:.2f} ms" for k, v in d["timings"].items()))
    lines += [f"warning: {w}" for w in d["warnings"]]
    return "\n".join(lines)


def format_moduli(result, scene) -> str:
    """A readable report of a Moduli result: stress, C in Voigt-like index pairs, isotropic summaries, the branches'
    eigenvalues (fixed cell and fixed stress), the direction's consistent branches, zero modes, errors, time."""
    d = result.dim
    pairs = [(i, i) for i in range(d)] + ([(0, 1)] if d == 2 else [(1, 2), (0, 2), (0, 1)])
    axes = "xyz"
    label = [axes[i] + axes[j] for i, j in pairs]
    C = result.C
    lines = [f"{scene.title or scene.source}: {d}D periodic, {scene.n_particles} particles, {scene.n_contacts} "
             f"contacts, volume {result.volume:.6g}",
             "stress σ (tension positive): " + "; ".join(" ".join(f"{v: .6g}" for v in row) for row in result.stress)
             + f"   (pressure {result.pressure:.6g})",
             "C_ijkl (elastic branch)  " + "  ".join(f"{lab:>11}" for lab in label)]
    for (i, j), lab in zip(pairs, label):
        lines.append(f"  {lab:>22}  " + "  ".join(f"{C[i, j, k, m]:11.5g}" for k, m in pairs))
    lines.append(f"bulk {result.bulk:.6g}, shear {result.shear:.6g} (isotropic averages)")
    for b in result.branches:
        lines.append(f"branch {b.name}: eigenvalues of sym(C) " + ", ".join(f"{v:.5g}" for v in b.eigenvalues)
                     + "; at fixed stress sym(C - Q) " + ", ".join(f"{v:.5g}" for v in b.fixed_stress_eigenvalues))
    if result.direction is not None:
        found = result.direction["consistent"]
        lines.append(f"strain direction: {len(found)} consistent branch(es) of {result.direction['n_branches']}"
                     + "".join(f"; modulus {c['modulus']:.6g}" for c in found))
        if "note" in result.direction:
            lines.append(f"  {result.direction['note']}")
    fs = result.verdicts["fixed_stress"]
    lines.append(f"fixed stress: {fs['verdict'].upper()} ({'proven' if fs['sufficient'] else 'not proven'}; "
                 f"min eigenvalue {fs['min_eigenvalue']:.4g}, tolerance {fs['tolerance']:.1e}, "
                 f"{fs['n_branches']} branch(es)); fixed cell: {result.verdicts['fixed_cell']['verdict'].upper()} "
                 "(sym(H), elastic branch; granstab analyze for every branch)")
    z = result.zero_modes
    lines.append(f"zero modes: {z['translations']} translations, {z['free_spins']} free spins, {z['rattlers']} "
                 f"rattlers, {z['mechanisms']} mechanisms")
    lines.append("errors (relative): " + ", ".join(f"{k} {v:.1e}" for k, v in result.errors.items() if v is not None)
                 + f"; time {1e3 * result.seconds:.1f} ms")
    lines += [f"note: {n}" for n in result.notes]
    return "\n".join(lines)


def uncertainty_lines(robust, balance: dict) -> list[str]:
    out = [f"balance: {balance['method']}" + ("" if balance.get("inside_band") is None else
           f"; corrections {'inside' if balance['inside_band'] else 'OUTSIDE'} the band (largest "
           f"{balance['largest_correction_over_band']:.3g}× a contact's band)")]
    if robust is not None:
        out.append(f"data uncertainty ({robust.band}): the verdict {robust.verdict} {robust.robust.upper()} — "
                   f"{robust.reason}")
    return out


def format_rigidity(result: dict) -> str:
    """A readable summary of a rigidity result: per model the clusters, modes, counts and cost."""
    lines = [f"{result['source']}: {result['dim']}D, walls {result['walls']}"
             + (", periodic cell (fixed)" if result["periodic"] else "")]
    for name in ("physical", "generic"):
        if name not in result:
            continue
        r, c = result[name], result[name]["counts"]
        sizes = ", ".join(str(len(cl["particles"])) for cl in r["clusters"][:5])
        lines.append(f"{name} ({r['method']}): {len(r['clusters'])} rigid clusters (largest: {sizes or 'none'} "
                     f"particles); {r['floppy_modes']['count']} internal floppy modes + {r['trivial_modes']['count']} "
                     f"trivial; {r['self_stresses']} self-stresses; {len(r['rattlers'])} rattlers; "
                     f"z = {c['z']:.3f} (without rattlers {c['z_without_rattlers']:.3f}), z_iso = "
                     f"{c['z_iso']:.3f}; Maxwell: {c['maxwell']['dofs']} dofs - {c['maxwell']['constraints']} "
                     f"constraints + {c['maxwell']['self_stresses']} self-stresses = {c['maxwell']['floppy']} floppy; "
                     f"{r['seconds']:.2f} s")
        if name == "physical":
            t = r["rank_tolerance"]
            gap = "none dropped (full rank)" if t["gap"] is None else f"{t['gap']:.3g}"
            lines.append(f"  rank tolerance {t['largest']:.2e}, singular-value gap {gap}")
            ps = r["prestress"]
            for branch in ("all_loading", "all_unloading"):
                if ps.get("evaluated"):
                    b = ps[branch]
                    lines.append(f"  prestress, {branch.replace('_', '-')}: {b['stabilised']} floppy directions "
                                 f"stabilised, {b['destabilised']} destabilised, {b['neutral']} neutral")
    if "differ" in result:
        d = result["differ"]
        lines.append("models agree on every contact" if d["same_partition"] else
                     f"models differ on {d['count']} contacts (--json: differ.contacts)")
    if "figure" in result:
        lines.append(f"wrote {result['figure']}")
    if "out" in result:
        lines.append(f"wrote {result['out']} (rigidity.json, packing.npz): granstab-app --preset {result['out']}")
    return "\n".join(lines)


def scan_lines(summary: dict, out) -> list[str]:
    """A scan's readable output: clusters, time and verdicts (and, resumed, how many an interrupted run had kept),
    then where it ran and why (the default's rule: granstab/scan/workers.py)."""
    kept = summary.get("resumed", 0)
    resumed = (f" (resumed: {kept} already in the folder, {summary['clusters_this_run']} analysed now)"
               if kept else "")
    mechanisms = summary.get("mechanisms", {})
    return [f"{summary['clusters']} clusters{resumed} in {summary['seconds']:.1f} s: "
            + ", ".join(f"{v} {c}" for v, c in summary["verdicts"].items())
            + ("; unstable by mechanism: " + ", ".join(f"{m} {c}" for m, c in mechanisms.items() if c)
               if any(mechanisms.values()) else "") + f"; wrote {out}",
            *(["verdicts under the data's uncertainty (docs/uncertainty.md): "
               + ", ".join(f"{v} {c}" for v, c in summary["data_robust"].items())] if "data_robust" in summary else []),
            f"ran {summary['workers']['where']} ({summary['workers']['why']})"]


def track_lines(summary: dict, out) -> list[str]:
    """A track's readable output: frames, time, events, where it ran, what ran after, the import's warnings."""
    resumed = summary["cost"]["resumed"]
    return [f"{summary['frames']} frames ({resumed} already in the folder) in {summary['cost']['seconds']:.1f} s; "
            f"{summary['events']} events ({summary['thresholds']['event_quantity']} drops over "
            f"{summary['thresholds']['event_threshold']:g} × its mean); wrote {out}",
            f"ran {summary['cost']['workers']['where']} ({summary['cost']['workers']['why']})",
            *[f"{name}: {what}" for name, what in summary.get("after", {}).items()],
            *[f"warning: import: {w}" for w in summary["import_warnings"]]]
