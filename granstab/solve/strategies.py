"""The eigen step of the pipeline (analysis.py) as backends with one interface; each says what it leaves out.

    state = backend.prepare(scene, timer)          # contact blocks, assembled parts (shared by every metric)
    problem = backend.problem(state, metric)       # the projection in a metric (metric.py)
    branches, notes = backend.solve(problem, masks, on_branch=None, progress=False, label="branches")
    errors = backend.errors(state, problem, branches)

* `DenseBackend`: every eigenpair of every branch's sym(𝓗^i) and ℍ^i, stacked LAPACK (branches.py).
* `SparseBackend`: per branch the lowest k non-rigid eigenpairs of sym(𝓗^i) and the exact number of its negative
  eigenvalues from Sylvester's law of inertia (sparse.py); no n_dof × n_dof matrix. It leaves out ℍ^i
  (uniqueness, Type-2) and the eigenpairs above the k lowest: counts beyond them are labelled lower bounds.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..mechanics.accuracy import (
    formation_error,
    part_scales,
    resolved_sign,
    vector_bounds,
)
from ..mechanics.branches import (
    INCONSISTENT,
    RIGID,
    Branch,
    Problem,
    eigen_groups,
    search_subspace,
    test_codes,
)
from ..mechanics.checks import equilibrium_residual, identity_errors
from ..mechanics.metric import Metric
from ..mechanics.rigid import Projection
from ..mechanics.stiffness import ContactBlocks, assemble, contact_blocks
from ..model.scene import Scene, SceneError
from ..model.vec import tangent_basis
from .dense import solve_branches

METHODS = ("auto", "dense", "sparse")


class Timer:
    """Named wall-clock timings in seconds."""

    def __init__(self):
        self.times: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - start


@dataclass(eq=False)
class State:
    """What every metric shares: the scene, its contact blocks, the assembled parts (dense path), sliding set."""

    scene: Scene
    sliding: np.ndarray
    blocks: ContactBlocks | None = None
    parts: dict | None = None


def choose_backend(scene: Scene, method: str, k: int, device: str = "cpu", lowrank: bool | None = None):
    """"dense", "sparse" or "auto" (sparse above sparse.DENSE_MAX_DOF dofs); device and lowrank: see DenseBackend."""
    from .device import backend
    from .sparse import DENSE_MAX_DOF
    backend(device)                                                   # an unusable device fails before any work
    if method == "sparse" or (method == "auto" and scene.n_dof > DENSE_MAX_DOF):
        if scene.fixed is not None:
            raise SceneError(f"{scene.source}: fixed particles are supported on the dense path only (at most "
                             f"{DENSE_MAX_DOF} dofs; method='dense')")
        return SparseBackend(k, device=device)
    return DenseBackend(device, lowrank)


def _progress_bar(total: int, desc: str = "branches"):
    """A tqdm bar with the time left (tqdm is optional: None without it)."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc=desc, unit="branch", mininterval=0.5)


def _require_finite(scene: Scene, value: float) -> None:
    """Refuse a stiffness with overflowed entries: nothing computed from it could be trusted."""
    if not np.isfinite(value):
        raise SceneError(f"{scene.source}: the stiffness H has non-finite entries (overflow: forces, stiffnesses or "
                         "curvatures beyond the double-precision range)")


# ------------------------------------------------------------------------------------------------ dense

def assemble_parts(scene: Scene, blocks: ContactBlocks) -> dict:
    """Hg1, Hg2, Hg3, Hm and H as CSR (physical dofs), and the sliding factors A, S (n, Ms) (eq:ContactF)."""
    parts = {name: assemble(blocks.blocks[name], scene.p, scene.q, scene.dof_per_particle, blocks.n_dof)
             for name in blocks.blocks}
    parts["H"] = (parts["Hg1"] + parts["Hg2"] + parts["Hg3"] + parts["Hm"]).tocsr()
    sliding = np.flatnonzero(scene.at_yield())
    n = scene.n_dof
    A = np.zeros((n, len(sliding)))
    S = np.zeros((n, len(sliding)))
    rows = blocks.index[sliding]                                      # (Ms, n_loc)
    cols = np.broadcast_to(np.arange(len(sliding))[:, None], rows.shape)
    np.add.at(A, (rows, cols), blocks.slide_left[sliding])
    np.add.at(S, (rows, cols), blocks.slide_right[sliding])
    parts["A"], parts["S"] = A, S
    return parts


def dense_problem(scene: Scene, blocks: ContactBlocks, parts: dict, metric: Metric) -> Problem:
    """Elastic H̃ = D H D, sliding factors D A, D S and the projection in the metric's dofs (metric.py), with the
    bound of the error made in forming sym(𝓗^i) (accuracy.py)."""
    D = metric.matrix()
    H_el = metric.congruence(parts["H"])
    _require_finite(scene, float(np.abs(H_el).sum()) if H_el.size else 0.0)
    A, S = D @ parts["A"], D @ parts["S"]
    geometric = parts["Hg1"] + parts["Hg2"] + parts["Hg3"]
    mechanical, geometric = D @ parts["Hm"] @ D, D @ geometric @ D
    free = scene.free_dofs
    if free is None:
        C = metric.rotations(scene)
        rigid, _ = np.linalg.qr(np.concatenate([metric.translations(scene), C], axis=1))
    else:                          # held by fixed particles: their dofs dropped, no rigid motion, no projection
        H_el, A, S = H_el[np.ix_(free, free)], A[free], S[free]
        mechanical, geometric = mechanical[free][:, free], geometric[free][:, free]
        C = rigid = np.zeros((len(free), 0))
    projection = Projection.from_rotations(C)
    scales = part_scales(mechanical, geometric, A, S)
    return Problem(H_el=H_el, A=A, S=S, projection=projection, rigid=rigid, sliding=np.flatnonzero(scene.at_yield()),
                   n_contacts=scene.n_contacts, tol=scene.tol,
                   formation_error=formation_error(scales, C, projection.Cplus), free=free)


def modified_leakage(problem: Problem) -> float:
    """‖ℍ R‖ / ‖H‖ for all rigid motions R: ℍ = H - (H C) C⁺ applied without forming it (eq:newstiffnesses)."""
    H, R, proj = problem.H_el, problem.rigid, problem.projection
    HR = H @ R - (H @ proj.C) @ (proj.Cplus @ R)
    return float(np.abs(HR).max(initial=0.0) / max(np.linalg.norm(H), 1e-300))


class DenseBackend:
    """Every eigenpair of every branch (branches.solve_branches); leaves nothing out. From lowrank.MIN_BRANCHES
    branches on, or when `device` resolves to a GPU (backend.py), the branches are solved as low-rank updates of
    the elastic problem (lowrank.py; `lowrank` True/False forces the choice): it leaves out the ℍ^i spectra of the
    branches it solves (their ℍ^i nullity is proven instead) and says so."""

    name = "dense"

    def __init__(self, device: str = "cpu", lowrank: bool | None = None):
        self.device, self.lowrank = device, lowrank

    def prepare(self, scene: Scene, timer: Timer) -> State:
        with timer("blocks"):
            blocks = contact_blocks(scene)
        with timer("assembly"):
            parts = assemble_parts(scene, blocks)
        return State(scene=scene, sliding=np.flatnonzero(scene.at_yield()), blocks=blocks, parts=parts)

    def problem(self, state: State, metric: Metric) -> Problem:
        return dense_problem(state.scene, state.blocks, state.parts, metric)

    def solve(self, problem: Problem, masks: np.ndarray, on_branch=None, progress: bool = False,
              label: str = "branches", keep_all: bool = True):
        bar = _progress_bar(len(masks), label) if progress and len(masks) > 1 else None

        def stream(b):
            if bar is not None:
                bar.update()
            if on_branch is not None:
                on_branch(b)

        from .device import backend
        from .lowrank import MIN_BRANCHES, solve_branches_lowrank
        lowrank = self.lowrank
        if lowrank is None:
            lowrank = len(masks) >= MIN_BRANCHES or backend(self.device).name == "gpu"
        notes = {"complete": True}
        if lowrank:
            branches, info = solve_branches_lowrank(problem, masks, device=self.device, keep_all=keep_all,
                                                    on_branch=stream if bar is not None or on_branch else None)
            notes["lowrank"] = info
            notes["residual_stability"] = info["residual_stability"]
            if not keep_all:
                notes.update(tally=info["tally"], n_branches=info["n_branches"])
            notes["warnings"] = [f"low-rank branch path on {info['device']} (unit round-off {info['eps']:.1e}): "
                                 f"{len(branches) - info['full_path']} of {len(branches)} branches without ℍ^i "
                                 "spectra (ℍ^i nullity proven from a bound on its smallest singular value), "
                                 f"{info['full_path']} on the full path"]
        else:
            branches = solve_branches(problem, masks, on_branch=stream)
        if bar is not None:
            bar.close()
        return branches, notes

    def errors(self, state: State, problem: Problem, branches) -> dict:
        errors = identity_errors(state.scene, state.parts)
        errors["rigid_leakage_modified"] = modified_leakage(problem)
        errors.update(problem.projection.errors())
        errors["equilibrium_residual"] = equilibrium_residual(state.scene)
        errors["eigen_residual_stability"] = max(b.residual_stability for b in branches)
        errors["eigen_residual_uniqueness"] = max(b.residual_uniqueness for b in branches)
        return errors

    def curvature_warnings(self, state: State) -> list[str]:
        return curvature_warnings(state.scene, state.blocks)


# ------------------------------------------------------------------------------------------------ sparse

@dataclass(frozen=True, eq=False)
class SparseBranchProblem:
    """The sparse problem of one metric and the branches.Problem view of it (consistency tests, subspace search)."""

    sp: object
    core: Problem

    def __getattr__(self, name):                                     # the Problem's fields (projection, rigid, …)
        return getattr(self.core, name)


class SparseBackend:
    """Lowest k eigenpairs and the exact negative count per branch (sparse.py). Leaves out: ℍ^i (uniqueness
    eigenvalues empty, uniqueness_n_zero = -1, no Type-2, no eigen_residual_uniqueness) and the eigenpairs above
    the k lowest (consistent counts over them are lower bounds; the summary says so and suggests a k)."""

    name = "sparse"

    def __init__(self, k: int = 6, tol: float = 0.0, device: str = "cpu"):
        self.k = int(k)
        self.tol = tol
        self.device = device

    def prepare(self, scene: Scene, timer: Timer) -> State:
        from .sparse import sparse_parts
        parts = sparse_parts(scene)
        timer.times.update(parts.timings)                                # blocks, assembly
        return State(scene=scene, sliding=parts.sliding, blocks=parts.local, parts=parts)

    def problem(self, state: State, metric: Metric) -> SparseBranchProblem:
        from .sparse import sparse_problem
        scene = state.scene
        spb = sparse_problem(scene, metric=metric, parts=state.parts)
        _require_finite(scene, spb.norm)
        scales = part_scales(spb.Hm, spb.Hs - spb.Hm, spb.A, spb.S)
        proj = spb.projection
        core = Problem(H_el=spb.H, A=spb.A, S=spb.S, projection=proj, rigid=spb.R, sliding=spb.sliding,
                       n_contacts=scene.n_contacts, tol=scene.tol,
                       formation_error=formation_error(scales, proj.C, proj.Cplus))
        return SparseBranchProblem(sp=spb, core=core)

    def solve(self, problem: SparseBranchProblem, masks: np.ndarray, on_branch=None, progress: bool = False,
              label: str = "branches", keep_all: bool = True):
        spb, k = problem.sp, self.k
        bar = _progress_bar(len(masks), f"{label} (sparse)") if progress else None
        branches, unverified, cut, ritz = [], 0, 0, 0
        for mask, modes in zip(masks, self._modes(spb, masks, k + 1)):
            ritz += modes.method == "ritz"
            b, was_cut = sparse_branch(problem.core, spb, modes, mask, k)
            unverified += not modes.verified
            cut += was_cut
            branches.append(b)
            if on_branch is not None:
                on_branch(b)
            if bar is not None:
                bar.update()
        if bar is not None:
            bar.close()
        n_free = spb.n - spb.n_rigid
        complete = all(b.negative_count["total"] for b in branches)
        notes = {"complete": complete, "full": k >= n_free, "k": k, "warnings": [
            f"sparse path: the lowest {min(k, n_free)} of {n_free} non-rigid eigenpairs of sym(𝓗^i) per branch; "
            "uniqueness (ℍ^i spectra, Type-2 non-uniqueness) is not evaluated"]}
        if ritz:
            notes["warnings"].append(f"{ritz} of {len(branches)} branches as Ritz updates of one elastic solve "
                                     "(lowrank.SparseRitz: count below σ exact by inertia, residuals ≤ 1e-12·‖Hs‖), "
                                     "the others by shift-invert")
        if unverified:
            notes["warnings"].append(f"{unverified} branch(es): the inertia check could not prove that the computed "
                                     "eigenvalues are the lowest ones")
        if cut:
            notes["warnings"].append(f"{cut} branch(es): the highest computed eigenvalue belongs to a repeated cluster "
                                     "that extends beyond k; its consistency search covers only the computed part")
        need = max((b.negative_count["count"] for b in branches), default=0)
        if not complete:
            notes["suggest_k"] = int(need + 1 + max(b.n_zero - spb.n_rigid for b in branches))
        return branches, notes

    def _modes(self, spb, masks, kk: int):
        """Modes of every branch: several branches as low-rank updates of one elastic solve (lowrank.SparseRitz,
        verified per branch, shift-invert ARPACK where that fails), a single one by shift-invert directly."""
        from .sparse import lowest_modes
        if len(masks) > 1:
            from .lowrank import SparseRitz
            yield from SparseRitz(spb, kk, tol=self.tol, device=self.device).modes(masks, kk)
            return
        yield lowest_modes(spb, kk, masks[0], tol=self.tol)

    def errors(self, state: State, problem: SparseBranchProblem, branches) -> dict:
        from .sparse import identity_errors as sparse_identities
        errors = sparse_identities(problem.sp)
        errors["equilibrium_residual"] = equilibrium_residual(state.scene)
        errors["eigen_residual_stability"] = max(b.residual_stability for b in branches)
        return errors

    def curvature_warnings(self, state: State) -> list[str]:
        return curvature_warnings(state.scene, state.blocks)


def sparse_branch(problem: Problem, spb, modes, mask, k: int):
    """A branches.Branch from the k+1 lowest modes: rigid modes first in the basis, per-eigenvalue accuracy bounds
    (accuracy.py), consistency codes, the subspace search of Appendix D on repeated and non-rigid zero eigenvalues
    (as dense._branch does) and the negative count of sym(𝓗^i) (`negative_count`: count, total = whether every
    negative eigenvalue is among the computed ones, below = the shift σ of the inertia count)."""
    n = spb.n
    lam_k, V_k = modes.eigenvalues, modes.vectors
    res_k = modes.residuals * spb.norm                                  # absolute residual norms
    bounds_k = vector_bounds(lam_k, res_k, spb.norm, problem.formation_error, n)
    cut = len(lam_k) > k and k > 0 and lam_k[k] - lam_k[k - 1] <= bounds_k[k] + bounds_k[k - 1]
    top = (lam_k[k], bounds_k[k]) if len(lam_k) > k else (np.inf, 0.0)
    lam_k, V_k, bounds_k = lam_k[:k], V_k[:, :k], bounds_k[:k]
    n_rigid = spb.n_rigid
    lam = np.r_[np.zeros(n_rigid), lam_k]
    bounds = np.r_[np.full(n_rigid, problem.formation_error), bounds_k]
    V = np.concatenate([spb.R, V_k], axis=1)
    order = np.argsort(lam, kind="stable")
    lam, V, bounds = lam[order], V[:, order], bounds[order]
    rigid = order < n_rigid
    codes, hinges = test_codes(problem, np.asarray(mask)[None], V[None])
    codes, hinges = codes[0].copy(), hinges[0].copy()
    codes[rigid] = RIGID
    hinges[rigid] = False
    zero = np.abs(lam) <= bounds
    for group in eigen_groups(lam, bounds):
        if len(group) == 1 or np.any(zero[group]):
            continue
        found = search_subspace(problem, mask, V[:, group])
        codes[group] = INCONSISTENT
        if found is not None:
            V[:, group[0]], codes[group[0]], hinges[group[0]] = found
    extra = np.flatnonzero(zero & ~rigid)
    if extra.size:
        codes[extra] = INCONSISTENT
        found = search_subspace(problem, mask, V[:, extra])
        if found is not None:
            V[:, extra[0]], codes[extra[0]], hinges[extra[0]] = found
    signs = resolved_sign(lam_k, bounds_k)
    # every negative eigenvalue is among the computed ones when the next one (k+1) is resolved positive, or when
    # the inertia count below σ is covered and nothing between σ and the bound is left uncomputed
    total = bool(top[0] > top[1]) or k >= n - n_rigid
    count = int(np.sum(signs < 0))
    if modes.n_below is not None and modes.verified:
        count = max(count, int(modes.n_below))
    res = float(modes.residuals[:k].max(initial=0.0)) if k else 0.0
    b = Branch(mask=np.asarray(mask), stability_eigenvalues=lam, stability_vectors=V, codes=codes, hinges=hinges,
               n_zero=int(zero.sum()), zero_tol=float(bounds.max(initial=0.0)),
               uniqueness_eigenvalues=np.zeros(0, complex), uniqueness_n_zero=-1, type2=[],
               residual_stability=res, residual_uniqueness=0.0, bounds=bounds,
               negative_count={"count": count, "total": total,
                               "below": float(modes.sigma) if np.isfinite(modes.sigma) else None})
    return b, bool(cut)


# ----------------------------------------------------------------------------------- input warnings

CONFORMING_RATIO = 1e-6   # |K^p + K^q| below this times max(|K^p|, |K^q|): a nearly conforming contact (warned)


def curvature_warnings(scene: Scene, blocks: ContactBlocks) -> list[str]:
    """Warnings for contacts where the pseudo-inverse (K^p + K^q)^+ of eq:rolling decides the answer: exactly
    singular (flat-on-flat, exact hand-in-glove; the cut-off drops the rolling) or nearly so (the rolling term
    grows like 1/ratio and the answer is as sensitive to the curvature data)."""
    out = []
    bad = np.flatnonzero(blocks.rolling_undetermined)
    if bad.size:
        out.append(f"{bad.size} contact(s) (first: contacts[{bad[0]}]) have K^p + K^q singular on the "
                   "tangent plane (flat-on-flat or exact hand-in-glove): rolling is undetermined there "
                   "and the pseudo-inverse drops it; the identities below measure the consequence")
    ratio = conforming_ratio(scene)
    near = np.flatnonzero((ratio <= CONFORMING_RATIO) & ~blocks.rolling_undetermined
                          & (np.linalg.norm(scene.force, axis=1) > 0))
    if near.size:
        c = near[np.argmin(ratio[near])]
        out.append(f"{near.size} nearly conforming contact(s) (smallest |K^p + K^q| / max(|K^p|, |K^q|) = "
                   f"{ratio[c]:.1e} at contacts[{c}], cut-off pinv_rtol = {scene.tol.pinv_rtol:.0e}): the rolling "
                   "term scales like the inverse of that ratio, so the result is only as accurate as the "
                   "curvature data relative to it")
    return out


def conforming_ratio(scene: Scene) -> np.ndarray:
    """Per contact: smallest |eigenvalue| of K^p + K^q on the tangent plane over max(|K^p|, |K^q|) (inf when
    both are zero is reported as 0: flat-on-flat)."""
    if scene.n_contacts == 0:
        return np.zeros(0)
    T = tangent_basis(scene.normal)
    Tt = np.swapaxes(T, 1, 2)
    kp = Tt @ scene.curvature_p @ T
    kq = Tt @ scene.curvature_q @ T
    kp = 0.5 * (kp + np.swapaxes(kp, 1, 2))
    kq = 0.5 * (kq + np.swapaxes(kq, 1, 2))
    lam = np.abs(np.linalg.eigvalsh(kp + kq)).min(axis=1)
    scale = np.maximum(np.abs(np.linalg.eigvalsh(kp)).max(axis=1), np.abs(np.linalg.eigvalsh(kq)).max(axis=1))
    return np.divide(lam, scale, out=np.zeros_like(lam), where=scale > 0)
