"""Verdicts that survive the measurement's own uncertainty (issue 42): `data_robustness(scene, band)`.

A verdict (eq:stab, eq:instab) of measured data becomes one of
  holds      proven the same for every force within the band: by the bound of mechanics/uncertainty.py (Weyl for
             stability over every branch, contacts of uncertain mobilisation in both states; the fixed consistent
             eigenvector's work for instability), added to the floating-point bounds of accuracy.py;
  depends    a force set within the band whose `analyze` proves the other verdict, exhibited (its forces returned);
  undecided  neither, with the margin (the factor of the band that the bound proves).
The metric is the analysis's primary one (L by default). What the band moves that is not affine in the forces
(positions; a 3D sliding contact's direction) is bounded rigorously by mechanics/nonaffine.py at a few band factors
(KNOTS), convex in the factor, so that each margin is proven (`_nonaffine`).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace

import numpy as np

from . import vertices
from .analysis import analyze, focus, inside_share
from .mechanics.branches import BOTH, MINUS, PLUS, RIGID
from .mechanics.nonaffine import contact_changes, projection_change, symmetric_norm
from .mechanics.stiffness import contact_blocks
from .mechanics.uncertainty import (
    SAFETY,
    Band,
    band_from,
    contact_norms,
    focused_factors,
    mobilisation,
    radius,
    unit_blocks,
    work_gradient,
)
from .model.scene import Scene, SceneError, equilibrium_loads
from .moves import moved_positions, work_gradient_positions

__all__ = ["Band", "DataRobustness", "balance_scene", "counterexample_from_flat", "counterexample_scene",
           "data_robustness", "flat_counterexample", "perturbed"]

CONSISTENT = (PLUS, MINUS, BOTH)
SEARCH_STEPS = 3          # counter-example steps: each goes to the band's edge along the current work gradient
INSIDE = 1.0 - 1e-9       # a counter-example's corrections stay this fraction inside the band
KNOTS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)   # band factors at which the non-affine part is bounded (`_nonaffine`)


@dataclass(frozen=True)
class DataRobustness:
    """`robust` (holds / depends / undecided) of the data's `verdict` under `band`; `margin`: the factor of the band
    up to which the bound proves the verdict (> 1: holds); `bound`: ‖Δ sym(𝓗)‖₂ at the band (eigenvalue units);
    `uncertain`, `unbounded`: contacts whose mobilisation the band leaves open (counted in both states) or whose
    tangential force can vanish (no bound); `counterexample`: the forces (M, d) and its proven verdict, with the
    largest correction as a fraction of each contact's band (and with a position band, where the search moved them,
    the positions: `x` (N, d), `point` (M, d), `normal` (M, d)); `nonaffine`: the part of `bound` that is not affine
    in the forces (positions, 3D sliding turns: mechanics/nonaffine.py); `certificate`: the vertex certificate of a stable verdict where the bound does not prove it (vertices.py)."""

    robust: str
    verdict: str
    margin: float
    bound: float
    band: str
    reason: str
    uncertain: tuple = ()
    unbounded: tuple = ()
    counterexample: dict | None = None
    nonaffine: float = 0.0
    seconds: float = 0.0
    certificate: dict | None = None

    def to_dict(self) -> dict:
        out = asdict(self)
        out["uncertain"], out["unbounded"] = list(self.uncertain), list(self.unbounded)
        out["margin"], out["bound"], out["nonaffine"] = (_finite(v) for v in (self.margin, self.bound, self.nonaffine))
        if self.certificate is not None:
            out["certificate"] = {**self.certificate, "lowest": _finite(self.certificate["lowest"])}
        return out


def _finite(x: float):
    return x if np.isfinite(x) else ("inf" if x > 0 else "-inf")


@dataclass(frozen=True, eq=False)
class _Data:
    """What every step reads once: the scene, its band, the unit geometric blocks G (M, J, n, n), the contacts' dof
    index (M, n), the sliding factors a, s (M, n) and the radii δ (M,)."""

    scene: Scene
    band: Band
    G: np.ndarray
    index: np.ndarray
    slide_left: np.ndarray
    slide_right: np.ndarray
    delta: np.ndarray

    @classmethod
    def of(cls, scene: Scene, band: Band) -> _Data:
        blocks = contact_blocks(scene)
        return cls(scene, band, unit_blocks(scene), blocks.index, blocks.slide_left, blocks.slide_right,
                   radius(scene, band))


def data_robustness(scene: Scene, band: Band, *, metric: str = "L", rotation_length: float | None = None,
                    max_sliding: int = 16, analysis=None, search: bool = True, inside=None,
                    budget: int = vertices.BUDGET) -> DataRobustness:
    """Whether the verdict of `scene` (in `metric`, one of L, L/10, 10L, inertia with diagonal blocks) holds for
    every force within `band` (module docstring). `analysis`: the scene's `analyze` in that metric, if at hand.
    `inside` = (particle indices, share) (the scan's --boundary embedded): the verdict on those particles' modes
    (analysis.focus); stability is then still proven over every mode, instability by a fixed vector mostly inside.
    `budget`: the analyses the vertex certificate (vertices.py) may spend where the bound does not prove a stable
    verdict (0: none)."""
    start = time.perf_counter()
    whole = analysis or analyze(scene, metric=metric, rotation_length=rotation_length, max_sliding=max_sliding,
                                attribution=False, keep="all")
    res = whole if inside is None else focus(whole, *inside)
    m = res.metric
    if m.diagonal is None:
        raise ValueError("data uncertainty: the metric must be diagonal (L metrics, or inertia with scalar inertia)")
    mob = mobilisation(scene, band)
    data = _Data.of(scene, band)
    weight = data.delta * contact_norms(data.G, m.diagonal[data.index])     # δ_c β_c (mechanics/uncertainty.py)
    e = float(np.sum(weight))
    ext = whole
    if mob["uncertain"].any():        # contacts that may reach the cone: their sliding branches count too
        state = np.where(mob["uncertain"], "sliding", np.asarray(scene.state))
        ext = analyze(replace(scene, state=tuple(state)), metric=m.name if m.rotation_length is None else "L",
                      rotation_length=m.rotation_length, max_sliding=max_sliding, attribution=False, keep="all")
    verdict = res.verdict.verdict
    knots = _nonaffine(data, whole, mob, e)
    moves = band.position > 0 and whole.problem.projection.C.shape[-1] > 0
    margin = max(min(_margin(verdict, res, ext, data, e, k, mob, inside, moves), k[0]) for k in knots)
    extra = next((k[1] for k in knots if k[0] == 1.0), 0.0)
    common = dict(verdict=verdict, margin=margin, bound=e + extra, band=band.describe(), nonaffine=extra,
                  uncertain=tuple(int(i) for i in np.flatnonzero(mob["uncertain"])),
                  unbounded=tuple(int(i) for i in np.flatnonzero(mob["unbounded"])))
    if margin > 1 and res.verdict.sufficient and verdict in ("stable", "unstable"):
        return DataRobustness(robust="holds", reason=f"proven by the bound up to {margin:.3g}× the band",
                              seconds=time.perf_counter() - start, **common)
    cert = None
    if (budget > 0 and verdict == "stable" and res.verdict.sufficient and inside is None
            and vertices.eligible(scene, band, mob, ext)):
        cert = vertices.certify(ext, data.delta, weight, perturbed, budget=budget)
        if cert["proven"]:
            return DataRobustness(robust="holds", certificate=cert, seconds=time.perf_counter() - start,
                                  reason=f"proven at the band's vertices ({cert['analyses']} analyses)", **common)
    probe = None if cert is None or cert["probe"] is None else np.array(cert["probe"])
    found = _search(data, res, max_sliding, inside, probe) if search else None
    if found is not None:
        return DataRobustness(robust="depends", counterexample=found, seconds=time.perf_counter() - start,
                              reason=f"{'positions and forces' if 'x' in found else 'forces'} within the band give "
                                     f"{found['verdict']}", certificate=cert, **common)
    why = (f"the bound proves {margin:.3g}× the band" if np.isfinite(margin) else "no bound")
    return DataRobustness(robust="undecided", reason=f"{why}; no counter-example found", certificate=cert,
                          seconds=time.perf_counter() - start, **common)


def _nonaffine(data: _Data, res, mob, e: float) -> list:
    """[(t, slope, shift, work)]: at each band factor t of KNOTS, slope = e_x(t)/t, e_x(t) a bound of ‖Δ sym(𝓗)‖₂
    from what is not affine in the forces (mechanics/nonaffine.py: Σ_c ‖ΔX̃_c‖ over the contacts, their sliding terms
    where they may slide, and 2‖ΔP̃‖‖S̄‖ for the projection's move, P'S'P' − PS̄P in the full space, with
    ‖S̄‖ <= ‖sym H̃‖ + t e + that sum);
    shift (M,) the bound of ‖Δs̃_c‖ at t (the S values' move per unit motion); work(v) the slope of the same bound
    for the work of a fixed unit vector ṽ = P̃v (`_vector_work`). e_x is convex with e_x(0) = 0, so
    e_x(s) <= s·slope for s <= t: a margin found with that slope is proven up to t. [(inf, 0, 0, 0)] where nothing
    is non-affine; [(1, inf, inf, inf)] where no bound is given (a metric without one rotation length)."""
    band, scene = data.band, data.scene
    zero = np.zeros(scene.n_contacts)
    if band.position <= 0 and not mob["turning"].any():
        return [(np.inf, 0.0, zero, lambda v: 0.0)]
    L = res.metric.rotation_length
    rotations = res.problem.projection.C.shape[-1]
    if L is None or (res.problem.free is not None and rotations):
        return [(1.0, np.inf, zero + np.inf, lambda v: np.inf)]
    may_slide = (scene.at_yield() | mob["uncertain"]).astype(float)
    size = symmetric_norm(contact_blocks(scene), res.metric.diagonal[data.index], may_slide, scene.n_dof)
    force, moment = band.force_radius(scene.force), band.moment_radius(scene.moment)
    out = []
    for t in KNOTS:
        c = contact_changes(scene, t * band.position, L, t * force, t * moment)
        turn = projection_change(scene, t * band.position, L, rotations)
        moved = float(np.sum(c["block"] + np.where(may_slide > 0, c["slide"], 0.0)))
        with np.errstate(all="ignore"):
            total = (moved + 2 * turn * (size + t * e + moved)) * SAFETY if turn < 1 else np.inf
        work = _vector_work(data, res, t, L, may_slide, turn, float(np.sum(c["rigid"])))
        out.append((t, total / t, c["s"], work))
    return out


def _vector_work(data: _Data, res, t: float, L: float, may_slide, turn: float, rigid: float):
    """v ↦ the slope (over t) of a bound of |q'(ṽ) − q(ṽ)| for the unit vector ṽ = P̃v when the non-affine part moves
    at band factor t, q'(y) = yᵀP̃'S'P̃'y: ṽᵀ(S' − S̄)ṽ <= Σ_c |Δ(ṽ_cᵀX̃_c ṽ_c)| (nonaffine.contact_changes with the
    vector: the work's own change), and with w = (P̃ − P̃')ṽ, a rigid rotation of the moved geometry (‖w‖ <= ‖ΔP̃‖), |−2wᵀS'ṽ + wᵀS'w| <=
    (2 + ‖w‖)‖S'w‖, ‖S'w‖ <= ‖w‖ Σ_c ‖(Hg3 + ½(Hg1 + Hg2))'_c‖ (`rigid`): the elastic parts vanish on w."""
    band, scene = data.band, data.scene

    def work(v):
        u = _scaled(res, v)[data.index]
        c = contact_changes(scene, t * band.position, L, t * band.force_radius(scene.force),
                            t * band.moment_radius(scene.moment), u)
        own = float(np.sum(c["block"] + np.where(may_slide > 0, c["slide"], 0.0)))
        with np.errstate(all="ignore"):
            return (own + (2 + turn) * turn * rigid) * SAFETY / t if turn < 1 else np.inf
    return work


def _margin(verdict: str, res, ext, data: _Data, e: float, knot: tuple, mob, inside=None, moves=False) -> float:
    """The factor of the band the bound proves: stability over every branch of `ext` (the uncertain contacts sliding
    too, `_stable_margin`; focused: `_focused_margin`); instability from the data's consistent negative
    eigenvectors (`_unstable_margin`). e: the affine part's bound; knot: (t, slope, shift) of `_nonaffine` (the
    non-affine part taken linear, valid up to t); moves: the rigid-motion projection moves with the positions."""
    slope, shift, work = knot[1:]
    if mob["unbounded"].any() or verdict not in ("stable", "unstable") or not np.isfinite(slope):
        return -np.inf
    if verdict == "stable":
        if len(ext.branches) < ext.verdict.n_branches:
            return -np.inf
        if moves:             # the projection moves: Weyl on P'S'P' − PSP in the full space (nonaffine.py) only
            return _stable_margin(ext, data, e + slope, weyl_only=True)
        return max(_stable_margin(ext, data, e + slope, slope),
                   _focused_margin(ext, e + slope, inside) if inside is not None else -np.inf)
    return _unstable_margin(res, data, mob, work, shift)


def _first_order(res, data: _Data, v) -> tuple[float, float]:
    """F(v) = Σ_c δ_c ‖w_c(v)‖, the largest change of the work of the fixed unit vector v over the band (exact: H is
    affine in the forces), and K(v) = Σ_c δ_c (Σ_j ‖sym(D G_cj D) ṽ_c‖²)^½ >= ‖E v‖ (ṽ = P v, scaled dofs)."""
    scaled = _scaled(res, v)
    U = res.metric.physical(scaled)[data.index]
    Dp = res.metric.diagonal[data.index]
    X = data.G * Dp[:, None, :, None] * Dp[:, None, None, :]
    Xv = np.einsum("mjab,mb->mja", 0.5 * (X + np.swapaxes(X, -1, -2)), scaled[data.index])
    F = float(np.sum(data.delta * np.linalg.norm(work_gradient(data.G, U), axis=1)) * SAFETY)
    K = float(np.sum(data.delta * np.sqrt(np.sum(Xv ** 2, axis=(1, 2)))) * SAFETY)
    return F, K


def _stable_margin(ext, data: _Data, e: float, extra: float = 0.0, weyl_only: bool = False) -> float:
    """min over branches of the largest t for which the lowest eigenvalue of every matrix within t × the band stays
    positive: λ_min(A + E) >= the lower eigenvalue of [[λ₁ − t F(v₁) − c, t e], [t e, λ₂ − t e]] (x = c v₁ + s w, w ⟂
    v₁, ‖E‖ <= t e, |v₁ᵀEv₁| <= t F), with λ₁, λ₂ the lowest two exact eigenvalues bounded by the computed ones and
    their accuracy, and c = 2 t e ‖v̂₁ − v₁‖ for the computed vector (Davis–Kahan: ‖v̂₁ − v₁‖ <= √2 δ₁/gap). Never
    less than Weyl's (λ₁ − δ₁)/e."""
    best = np.inf
    for b in ext.branches:
        keep = b.codes != RIGID
        lam, acc = b.stability_eigenvalues[keep], b.accuracy[keep]
        if lam.size == 0:
            continue
        lo = np.sort(lam - acc)
        weyl = lo[0] / e if e > 0 else (np.inf if lo[0] > 0 else -np.inf)
        j = int(np.flatnonzero(keep)[np.argmin(lam)])
        l1, a1 = b.stability_eigenvalues[j], b.accuracy[j]
        l2 = lo[1] if lam.size > 1 else np.inf
        gap = l2 - (l1 + a1)
        if gap <= 0 or e <= 0 or not np.isfinite(l2) or weyl_only:
            best = min(best, weyl)
            continue
        F, K = _first_order(ext, data, b.stability_vectors[:, j])
        F, K = F + extra, K + extra                      # the non-affine part: |v₁ᵀE v₁|, ‖E v₁‖ <= ‖E‖
        tilt = 2 * np.sqrt(2) * min(1.0, a1 / gap)
        lo_t = _largest_factor(l1 - a1, l2, F + tilt * e, min(K + tilt * e, e), e)
        best = min(best, max(lo_t, weyl))
    return float(best)


def _focused_margin(ext, e: float, inside) -> float:
    """A focused stable verdict (analysis.focus): every non-rigid eigenpair stays positive or outside
    (mechanics.uncertainty.focused_factors), over every branch."""
    best = np.inf
    for b in ext.branches:
        keep = b.codes != RIGID
        order = np.argsort(b.stability_eigenvalues[keep])
        lam, acc = b.stability_eigenvalues[keep][order], b.accuracy[keep][order]
        share = inside_share(ext, b, inside[0])[keep][order]
        if lam.size:
            best = min(best, float(focused_factors(lam[None], acc[None], share[None], [e], inside[1]).min()))
    return best


def _largest_factor(low1: float, low2: float, F: float, K: float, e: float) -> float:
    """The largest t (bisection, to 2⁻⁶⁰ relative) with the lower eigenvalue of [[low1 − tF, tK], [tK, low2 − te]]
    positive (it decreases with t)."""
    def low(t):
        a, c = low1 - t * F, low2 - t * e
        return 0.5 * ((a + c) - np.sqrt((a - c) ** 2 + 4 * (t * K) ** 2))
    lo, hi = 0.0, 1.0
    while low(hi) > 0 and hi < 1e12:
        hi *= 2
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if low(mid) > 0 else (lo, mid)
    return lo


def _unstable_margin(res, data: _Data, mob, extra=None, shift=None) -> float:
    """max over consistent negative eigenpairs of (−λ − δ − changing)/(F(v) + extra(v)), F the exact first-order term
    of the fixed vector (`_first_order`), extra(v) the non-affine part's slope for that vector (`_vector_work`: with
    moved positions the perturbed problem's vector is P̃'ṽ) and
    `changing` the sliding work a ⊗ s of the contacts whose yield state the band leaves open and that load under the
    vector (at yield: may unload; uncertain: may load). With `shift` (M,) (the S values' move per unit motion) a
    vector counts only where no contact at yield can change the sign of its S = s·U (its consistency, eq:flow)."""
    open_ = mob["uncertain"] | (data.scene.at_yield() & (data.delta > 0))
    best = -np.inf
    for b in res.branches:
        neg = np.isin(b.codes, CONSISTENT) & (b.stability_eigenvalues < -b.accuracy)
        for j in np.flatnonzero(neg):
            U = _motion(res, b.stability_vectors[:, j])[data.index]
            s = np.einsum("mn,mn->m", data.slide_right, U)
            a = np.einsum("mn,mn->m", data.slide_left, U)
            if shift is not None:
                move = shift * np.linalg.norm(_scaled(res, b.stability_vectors[:, j])[data.index], axis=1)
                if np.any(data.scene.at_yield() & (move > 0) & ~(np.abs(s) > move)):
                    continue
            sign = 1 if b.codes[j] in (PLUS, BOTH) else -1
            changing = float(np.sum(np.abs(a * s)[open_ & (sign * s > 0)]))
            F = _first_order(res, data, b.stability_vectors[:, j])[0]
            F = F + (extra(b.stability_vectors[:, j]) if extra is not None else 0.0)
            slack = -b.stability_eigenvalues[j] - b.accuracy[j] - changing
            best = max(best, slack / F if F > 0 else (np.inf if slack > 0 else -np.inf))
    return best


def _scaled(res, v: np.ndarray) -> np.ndarray:
    """P v over every dof of the scene (fixed particles: zero), in the metric's scaled dofs."""
    u = np.zeros(res.scene.n_dof)
    u[res.problem.free if res.problem.free is not None else slice(None)] = res.problem.projection.apply(v)
    return u


def _motion(res, v: np.ndarray) -> np.ndarray:
    """U = D P v: the physical motion of a scaled eigenvector over every dof of the scene."""
    return res.metric.physical(_scaled(res, v))


def perturbed(scene: Scene, force: np.ndarray) -> Scene:
    """The scene with other contact forces and the loads that follow from them (the scene format's rule)."""
    out = replace(scene, force=np.asarray(force, dtype=float))
    b, w = equilibrium_loads(out)
    return replace(out, load=b, load_moment=w)


def _target(res, lower: bool):
    """The eigenpair a counter-example pushes: lower: the lowest non-rigid (consistent first); else the lowest
    consistent negative one. (eigenvalue, vector), or None where there is none."""
    best = None
    for b in res.branches:
        ok = np.isin(b.codes, CONSISTENT) if not lower else b.codes != RIGID
        if not lower:
            ok &= b.stability_eigenvalues <= b.accuracy
        for j in np.flatnonzero(ok):
            key = (not np.isin(b.codes[j], CONSISTENT), b.stability_eigenvalues[j])
            if best is None or key < best[0]:
                best = (key, b, j)
    return None if best is None else (best[1].stability_eigenvalues[best[2]], best[1].stability_vectors[:, best[2]])


def _step(data: _Data, res, lower: bool, first: bool):
    """Forces at the band's edge along the work gradient of the target eigenpair (mechanics.uncertainty.work_gradient):
    down (lower) or up; contacts at yield move along their own force (they stay on the cone, h unchanged). None
    where there is no target, or (first step) where the target's work cannot change sign at first order (exact for
    the fixed vector: then no step is tried)."""
    got = _target(res, lower)
    if got is None:
        return None
    lam, v = got
    U = _motion(res, v)[data.index]
    f = data.scene.force
    w = work_gradient(data.G, U)[:, :f.shape[1]]
    unit = np.linalg.norm(f, axis=1, keepdims=True)
    along = np.divide(f, unit, out=np.zeros_like(f), where=unit > 0)
    w = np.where(data.scene.at_yield()[:, None], np.sum(w * along, axis=1, keepdims=True) * along, w)
    norm = np.linalg.norm(w, axis=1, keepdims=True)
    reach = float(np.sum(data.band.force_radius(f) * norm[:, 0]))
    if first and (lam - reach > 0 if lower else lam + reach < 0):
        return None
    direction = np.divide(w, norm, out=np.zeros_like(w), where=norm > 0)
    return f + (-1 if lower else 1) * data.band.force_radius(f)[:, None] * INSIDE * direction


def _onto_cone(data: _Data):
    """The data's forces with each contact of uncertain mobilisation that can reach the cone within its band moved
    onto it (just over: at yield) by the shortest step, along ∇Q = h + μn (eq:yield); None where there is none."""
    scene = data.scene
    mob = mobilisation(scene, data.band)
    f = scene.force
    Q = scene.yield_function()
    h = f - np.sum(f * scene.normal, axis=1, keepdims=True) * scene.normal
    size = np.linalg.norm(h, axis=1, keepdims=True)
    h = np.divide(h, size, out=np.zeros_like(h), where=size > 0)
    grad = h + scene.mu[:, None] * scene.normal
    step = -(Q * (1 + 1e-6) / (1 + scene.mu ** 2))[:, None] * grad
    move = mob["uncertain"] & (size[:, 0] > 0) & (np.linalg.norm(step, axis=1) <= data.delta * INSIDE)
    return f + np.where(move[:, None], step, 0.0) if move.any() else None


def _search(data: _Data, res, max_sliding, inside=None, probe=None):
    """A force set (and, with a position band, positions) within the band whose `analyze` proves another verdict
    than the data's (the vertex certificate's `probe` first, then up to SEARCH_STEPS steps from each side the
    verdict can move to: forces alone, then positions with them, `_position_step`), or None."""
    verdict = res.verdict.verdict
    m = res.metric
    name, length = ("inertia", None) if m.rotation_length is None else ("L", m.rotation_length)

    def other(force, dx=None, dpoint=None):
        """(the analysis of `force` (at positions moved by dx, dpoint), its counter-example dict or None); (None,
        None) where analyze refuses it."""
        scene = data.scene if dx is None else moved_positions(data.scene, data.scene.x + dx, data.scene.point + dpoint)
        try:
            got = analyze(perturbed(scene, force), metric=name, rotation_length=length,
                          max_sliding=max_sliding, attribution=False, keep="all")
        except (SceneError, ValueError):         # a perturbed set the analysis refuses is no counter-example
            return None, None
        got = got if inside is None else focus(got, *inside)
        if got.verdict.verdict == verdict or not got.verdict.sufficient:
            return got, None
        used = np.linalg.norm(force - data.scene.force, axis=1)
        delta = data.band.force_radius(data.scene.force)
        frac = float(np.max(np.divide(used, delta, out=np.zeros_like(used), where=delta > 0), initial=0.0))
        out = {"verdict": got.verdict.verdict, "forces": force.tolist(), "largest_band_fraction": frac}
        if dx is not None:
            out.update(x=scene.x.tolist(), point=scene.point.tolist(), normal=scene.normal.tolist(),
                       largest_position_move=float(max(np.linalg.norm(dx, axis=1).max(initial=0.0),
                                                       np.linalg.norm(dpoint, axis=1).max(initial=0.0))))
        return got, out

    found = other(probe)[1] if probe is not None else None
    sides = {"stable": (True,), "unstable": (False,), "neutral": (True, False)}.get(verdict, ())
    for moving in (False, True) if data.band.position > 0 else (False,):
        for lower in sides if found is None else ():
            current = res
            onto = _onto_cone(data) if lower and not moving else None
            for step in range(SEARCH_STEPS):
                if moving:
                    move = _position_step(data, current, lower)
                else:
                    move = onto if step == 0 and onto is not None else _step(data, current, lower, first=step == 0)
                    move = None if move is None else (move,)
                if move is None:
                    break
                current, found = other(*move)
                if current is None or found is not None:
                    break
            if found is not None:
                break
    return found


def _position_step(data: _Data, res, lower: bool):
    """(forces, dx, dpoint): every centre and contact point moved to the band's edge (INSIDE it) along the first-order
    gradient of the target eigenpair's work (moves.work_gradient_positions at the current analysis `res`), down
    (lower) or up, and the forces of `_step` with it; None without a target."""
    got = _target(res, lower)
    if got is None:
        return None
    U = _motion(res, got[1])[data.index]
    gx, gp = work_gradient_positions(res.scene, U)
    length = (-1 if lower else 1) * data.band.position * INSIDE

    def edge(g):
        norm = np.linalg.norm(g, axis=1, keepdims=True)
        return length * np.divide(g, norm, out=np.zeros_like(g), where=norm > 0)
    force = _step(data, res, lower, first=False)
    return (data.scene.force if force is None else force), edge(gx), edge(gp)


def flat_counterexample(counterexample: dict) -> list:
    """A counter-example as one flat list (the scan's `counterexample` column): its forces (M·d), then, where it
    moved the positions, the centres (N·d) and the contact points (M·d)."""
    parts = [counterexample["forces"]] + ([counterexample["x"], counterexample["point"]] if "x" in counterexample
                                         else [])
    return [float(v) for part in parts for v in np.ravel(part)]


def counterexample_from_flat(scene: Scene, flat) -> dict:
    """The counter-example of `flat_counterexample`'s list for the cluster's `scene` (its forces, and its positions
    where the list is long enough to hold them)."""
    flat = np.asarray(flat, dtype=float)
    M, N, d = scene.n_contacts, scene.n_particles, scene.dim
    out = {"forces": flat[:M * d].reshape(M, d)}
    if flat.size == (2 * M + N) * d:
        out.update(x=flat[M * d:(M + N) * d].reshape(N, d), point=flat[(M + N) * d:].reshape(M, d))
    return out


def counterexample_scene(scene: Scene, counterexample: dict) -> Scene:
    """The scene a counter-example describes: its forces (`perturbed`) at its positions where it moved them
    (moves.moved_positions, the normals and curvatures turned with the centre lines), for `analyze` to re-check."""
    if "x" in counterexample:
        scene = moved_positions(scene, np.asarray(counterexample["x"], dtype=float),
                                np.asarray(counterexample["point"], dtype=float))
    return perturbed(scene, np.asarray(counterexample["forces"], dtype=float))


def balance_scene(scene: Scene, uncertainty: dict | None, how: str, exempt=None):
    """(scene, None) as given (how = "loads": the loads absorb the imbalance), or (the balanced scene, the balance
    report without its per-contact lists) for "least-squares" (uncertainty.balance_least_squares, weighted by the
    band of `uncertainty`'s rel and abs, or the file's per-contact columns)."""
    band = band_from(uncertainty or {}, scene)             # asked for per-contact columns it lacks: one line
    if how == "loads":
        return scene, None
    if how != "least-squares":
        raise SceneError(f"--balance: loads or least-squares, got {how!r}")
    out, report = balance_least_squares(scene, band, exempt=exempt)
    return out, {k: v for k, v in report.items() if k not in ("correction_norm", "correction_over_band")}


def balance_least_squares(scene: Scene, band: Band, exempt=None) -> tuple[Scene, dict]:
    """The forces moved to the nearest set (weighted by the band: min Σ_c ‖δf_c‖²/δ_c², or by |f_c| without one)
    under which every particle balances, force and moment (eq:equil1 with zero loads), except the `exempt` ones
    (N,) bool (walls, supports: their loads stay free) and fixed ones; the scene with those forces (loads from the
    forces) and a report: the correction per contact over its band (`correction_over_band`, inside when every one
    is <= 1: a test of the data), the imbalance before and after. Moments are not corrected."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import lsqr

    from .model.vec import rot_dim
    N, M, d, r = scene.n_particles, scene.n_contacts, scene.dim, rot_dim(scene.dim)
    delta = band.force_radius(scene.force)
    weight = np.where(delta > 0, delta, 0.0) if np.any(delta > 0) else np.linalg.norm(scene.force, axis=1)
    held = np.zeros(N, dtype=bool) if exempt is None else np.asarray(exempt, dtype=bool).copy()
    if scene.fixed is not None:
        held |= scene.fixed
    B = _equilibrium_matrix(scene)                                       # (N (d + r), M d): loads of the forces
    rows = np.flatnonzero(~np.repeat(held, d + r))
    W = sp.diags(np.repeat(weight, d))
    b_now, w_now = equilibrium_loads(scene)
    target = -np.concatenate([b_now, w_now], axis=1).reshape(-1)[rows]   # the loads the correction must cancel
    A = (B[rows] @ W).tocsr()
    y = lsqr(A, target, atol=1e-15, btol=1e-15, iter_lim=20 * (M * d + 10))[0]
    correction = (W @ y).reshape(M, d)
    balanced = perturbed(scene, scene.force + correction)
    moved = np.linalg.norm(correction, axis=1)
    ratio = np.divide(moved, delta, out=np.where(moved > 0, np.inf, 0.0), where=delta > 0)   # δ = 0: held exactly
    after = np.concatenate(equilibrium_loads(balanced), axis=1).reshape(-1)[rows]
    scale = float(np.max(np.linalg.norm(scene.force, axis=1), initial=0.0))
    report = {"method": "least-squares", "exempt_particles": int(held.sum()),
              "correction_norm": np.linalg.norm(correction, axis=1).tolist(),
              "correction_over_band": [float(v) if np.isfinite(v) else None for v in ratio] if np.any(delta > 0)
              else None, "inside_band": bool(np.all(ratio <= 1)) if np.any(delta > 0) else None,
              "largest_correction_over_band": float(ratio.max(initial=0.0)) if np.any(delta > 0) else None,
              "imbalance_before": float(np.abs(target).max(initial=0.0)) / max(scale, 1e-300),
              "imbalance_after": float(np.abs(after).max(initial=0.0)) / max(scale, 1e-300),
              "imbalance_scale": "largest |load| of a balanced particle over the largest |f|"}
    return balanced, report


def _equilibrium_matrix(scene: Scene):
    """B (N(d + r), M d): the loads b^p = −Σ f, w^p = −Σ r × f (eq:equil1) as a linear map of the contact forces."""
    import scipy.sparse as sp

    from .model.vec import cross_matrix, rot_dim
    N, M, d, r = scene.n_particles, scene.n_contacts, scene.dim, rot_dim(scene.dim)
    per = d + r
    blocks_p = -np.concatenate([np.broadcast_to(np.eye(d), (M, d, d)), cross_matrix(scene.r_pq)], axis=1)
    blocks_q = np.concatenate([np.broadcast_to(np.eye(d), (M, d, d)), cross_matrix(scene.r_qp)], axis=1)
    rows = np.concatenate([(scene.p[:, None] * per + np.arange(per))[:, :, None].repeat(d, 2),
                           (scene.q[:, None] * per + np.arange(per))[:, :, None].repeat(d, 2)])
    cols = np.concatenate([(np.arange(M)[:, None] * d + np.arange(d))[:, None, :].repeat(per, 1)] * 2)
    vals = np.concatenate([blocks_p, blocks_q])
    return sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(N * per, M * d))
