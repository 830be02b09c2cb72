"""The scan's `data_robust` and `robust_margin` columns (issue 42): each cluster's verdict under the data's stated
uncertainty, as the factor of the band that the bound proves (docs/uncertainty.md).

Batched first (batch.py calls `batch_margins` with each stack's eigenvalues, bounds and lowest consistent negative
mode): stability by Weyl over every branch, min(λ − δ) / e with e = Σ_c δ_c β_c the band's bound of ‖Δ sym(𝓗)‖ in
the cluster's metric (mechanics/uncertainty.py); instability by the fixed lowest consistent negative mode, whose
work moves by at most F = Σ_c δ_c ‖w_c‖ (exact: H is affine in the forces) and by the sliding work of its loading
contacts, which may unload. A cluster with a contact of uncertain mobilisation (whose sliding branches would count
too) or whose bound does not prove its verdict is undecided, or, with the search (options["uncertainty"]["search"],
`scan --search-counterexamples`), goes to `granstab.uncertainty.data_robustness` on its own scene (tighter: first
order plus a rigorous remainder, the uncertain contacts' branches; the counter-example search: depends)."""
from __future__ import annotations

import numpy as np

from ..mechanics.uncertainty import band_from, contact_norms, mobilisation, radius, unit_blocks, work_gradient
from ..model.scene import SceneError
from ..uncertainty import data_robustness, flat_counterexample
from .clusters import boundary_rings, cluster


def band_parts(scene, band: dict) -> dict:
    """What the batch needs of the band for the chunk's scene: the unit blocks G (M, J, n, n), the radii δ (M,) and
    `open` (M,): contacts of uncertain mobilisation or a sliding term not affine in the band (3D: h turns), which the
    batch does not bound (mechanics.uncertainty.mobilisation): their clusters go to data_robustness."""
    band = band_from(band, scene)
    mob = mobilisation(scene, band)
    return {"G": unit_blocks(scene), "delta": radius(scene, band), "open": mob["uncertain"] | mob["unbounded"] | mob["turning"]}


def batch_margins(parts: dict, blocks, st: dict, modes: dict, lam, bounds, owner, G: int) -> dict:
    """Per cluster of a stack: robust_stable = min over every eigenvalue of every branch of (λ − δ)/e (Weyl),
    robust_unstable = (−λ − δ − sliding work of the loading contacts)/F of the lowest consistent negative mode
    (module docstring), robust_open = whether a contact of the cluster has an open mobilisation."""
    g, m = st["g"], st["m"]
    delta = parts["delta"][m]
    e = np.bincount(g, weights=delta * contact_norms(parts["G"][m], st["Dp"]), minlength=G)
    lower = np.full(G, np.inf)
    np.minimum.at(lower, owner, (lam - bounds).min(axis=1))
    take = modes["take"]
    w = work_gradient(parts["G"][m[take]], modes["U"])
    F = np.bincount(g[take], weights=delta[take] * np.linalg.norm(w, axis=1), minlength=G) * (1 + 1e-10)
    loading = np.zeros(len(g), dtype=bool)
    loading[np.flatnonzero(st["slide"])] = modes["signs"][g[st["slide"]], st["col"]] == 1
    a, s = (np.einsum("pn,pn->p", f[m[take]], modes["U"]) for f in (blocks.slide_left, blocks.slide_right))
    work = np.bincount(g[take], weights=np.abs(a * s) * (loading[take] & (delta[take] > 0)), minlength=G)
    with np.errstate(divide="ignore", invalid="ignore"):
        stable = np.where(e > 0, lower / e, np.where(lower > 0, np.inf, -np.inf))
        slack = -modes["value"] - modes["bound"] - work
        unstable = np.where(modes["mode"], np.where(F > 0, slack / F, np.where(slack > 0, np.inf, -np.inf)), -np.inf)
    return {"robust_stable": stable, "robust_unstable": unstable,
            "robust_open": np.bincount(g, weights=parts["open"][m], minlength=G) > 0}


def robust_columns(scene, centers, member_lists, rows: dict, options: dict, graph, sub_index, share: float) -> dict:
    """data_robust (holds / depends / undecided; "" where the row is an error), robust_margin (the factor of the
    band the bound proves) and counterexample (depends: the forces, flat, and the positions where it moved them:
    granstab.uncertainty.flat_counterexample) of each centre, in the order of `centers`.
    rows: the rows' "verdict", "sufficient" and the batch's margins (NaN where the cluster was not batched). The
    rest (and all with a position band): data_robustness on the cluster's scene (a cluster whose verdict there
    differs from its row's is undecided); `share`: the embedded boundary's EMBEDDED_INSIDE."""
    verdicts = rows["verdict"]
    margin = np.where(verdicts == "stable", rows["robust_stable"],
                      np.where(verdicts == "unstable", rows["robust_unstable"], np.nan))
    fast = rows["sufficient"] & ~rows["robust_open"] & (margin > 1)
    band = band_from(options["uncertainty"], scene)
    robust = np.where(fast, "holds", "").astype(object)
    example = np.full(len(centers), None, dtype=object)
    search = options["uncertainty"].get("search", False)
    boundary = options.get("boundary", "loads")
    embedded = boundary_rings(boundary)[0] == "embedded"
    metric = "L" if options["metric"] == "family" else options["metric"]
    batched = np.isfinite(rows["robust_stable"]) | np.isfinite(rows["robust_unstable"])
    if band.position > 0:          # the batch bounds forces only: a position band is added cluster by cluster
        fast[:] = False
        robust[:] = ""
        batched[:] = False
    if not search:                 # the bound's answer only: what it does not prove stays undecided
        robust[~fast & batched & (verdicts != "error")] = "undecided"
    for i in np.flatnonzero(~fast & (verdicts != "error") & (search | ~batched)):
        try:
            sub = cluster(scene, centers[i], options["rings"], boundary, graph=graph)
            inside = (sub_index(sub, scene, member_lists[i]), share) if embedded else None
            got = data_robustness(sub, band_from(options["uncertainty"], sub), metric=metric, max_sliding=options["max_sliding"], inside=inside,
                                  search=search)
        except (SceneError, ValueError):
            robust[i] = "undecided"
            continue
        robust[i] = got.robust if got.verdict == verdicts[i] else "undecided"
        margin[i] = got.margin
        if robust[i] == "depends":
            example[i] = flat_counterexample(got.counterexample)
    return {"data_robust": robust, "robust_margin": margin, "counterexample": example}
