"""The eigen step of the pipeline (analysis.py) as two methods with one interface; each says what it leaves out.

    state = method.prepare(scene, timer)           # contact blocks, assembled parts (shared by every metric)
    problem = method.problem(state, metric)        # the projection in a metric (mechanics/metric.py)
    branches, notes = method.solve(problem, masks, on_branch=None, progress=False, label="branches")
    errors = method.errors(state, problem, branches)

* `DenseMethod`: every eigenpair of every branch's sym(𝓗^i) and ℍ^i, stacked LAPACK (dense.py), or, from
  lowrank.MIN_BRANCHES branches or branches · n³ >= lowrank.MIN_WORK on (lowrank.use_lowrank), the low-rank
  updates of the elastic problem (lowrank.py).
* `SparseMethod`: per branch the lowest k non-rigid eigenpairs of sym(𝓗^i) and the exact number of its negative
  eigenvalues from Sylvester's law of inertia (sparse.py; several branches as Ritz updates, ritz.py); no
  n_dof × n_dof matrix. It leaves out ℍ^i (uniqueness, Type-2) and the eigenpairs above the k lowest: counts beyond
  them are labelled lower bounds.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from ..mechanics.accuracy import centre_error, curvature_error, formation_error, part_scales
from ..mechanics.assembly import sliding_factors
from ..mechanics.branches import Problem
from ..mechanics.checks import equilibrium_residual, identity_errors, modified_leakage
from ..mechanics.metric import Metric
from ..mechanics.rigid import Projection, centred, free_spins, rigid_basis, unit_columns
from ..mechanics.stiffness import ContactBlocks, assemble_parts, assembled_error, contact_blocks, geometric
from ..model.scene import Scene, SceneError
from .budget import use_ritz
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


def choose_method(scene: Scene, method: str, k: int, device: str = "cpu", lowrank: bool | None = None,
                  uniqueness: bool = True):
    """"dense", "sparse" or "auto" (sparse above sparse.DENSE_MAX_DOF dofs); device, lowrank, uniqueness: see
    DenseMethod (the sparse path never evaluates ℍ^i)."""
    from .device import backend
    from .sparse import DENSE_MAX_DOF
    backend(device)                                                   # an unusable device fails before any work
    if method == "sparse" or (method == "auto" and scene.n_dof > DENSE_MAX_DOF):
        if scene.fixed is not None:
            raise SceneError(f"{scene.source}: fixed particles are supported on the dense path only (at most "
                             f"{DENSE_MAX_DOF} dofs; method='dense')")
        return SparseMethod(k, device=device)
    return DenseMethod(device, lowrank, uniqueness)


def _progress_bar(total: int, desc: str = "branches", progress=True):
    """A tqdm bar with the time left (tqdm is optional: None without it), or, when `progress` is a reporter with
    stages (io.progress.Heartbeat), that reporter at a new stage."""
    if hasattr(progress, "stage"):
        progress.stage(desc, total)
        return progress
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

def dense_parts(scene: Scene, blocks: ContactBlocks) -> dict:
    """Hg1, Hg2, Hg3, Hm and H as CSR (physical dofs), the sliding factors A, S (n, Ms) (eq:ContactF), and the
    entrywise bound of H's error from rounding K^p + K^q ("curvature_error", CSR, or None where unresolved)."""
    parts = assemble_parts(scene, blocks)
    parts["A"], parts["S"] = sliding_factors(blocks, np.flatnonzero(scene.at_yield()))
    parts["curvature_error"] = assembled_error(scene, blocks.curvature_error)
    return parts


def centre_term(scene: Scene, metric: Metric, C: np.ndarray) -> float:
    """accuracy.centre_error of the metric's rotations C (n, r): the centroid's defect (rigid.centred) and the largest
    scaling of a translation by D⁻¹ (1 in the L metrics, √m in the inertia metric)."""
    if C.shape[-1] == 0 or scene.n_particles == 0:
        return 0.0
    _, defect = centred(scene.x, metric.weights, defect=True)
    d = scene.dim
    weight = float(np.linalg.norm(np.linalg.inv(metric.blocks[:, :d, :d]), ord=2, axis=(1, 2)).max())
    return float(centre_error(C, defect, weight))


def metric_entrywise(error, metric: Metric, free=None):
    """|D| E |D| (CSR, symmetrised: it bounds |sym ΔH̃|) of an assembled error bound E, in the metric's dofs; None
    for None (unresolved)."""
    if error is None:
        return None
    E = metric.sparse_congruence(error, absolute=True)
    if free is not None:
        E = E[free][:, free]
    return (0.5 * (E + E.T)).tocsr()


def metric_error(error, metric: Metric, free=None) -> float:
    """‖|D| E |D|‖₂ bound (accuracy.curvature_error) of an assembled error bound E in the metric's dofs; inf for
    None (unresolved)."""
    E = metric_entrywise(error, metric, free)
    return np.inf if E is None else curvature_error(E)


def dense_problem(scene: Scene, blocks: ContactBlocks, parts: dict, metric: Metric) -> Problem:
    """Elastic H̃ = D H D, sliding factors D A, D S and the projection in the metric's dofs (metric.py), with the
    bound of the error made in forming sym(𝓗^i) (accuracy.py)."""
    D = metric.matrix()
    H_el = metric.congruence(parts["H"])
    _require_finite(scene, float(np.abs(H_el).sum()) if H_el.size else 0.0)
    A, S = D @ parts["A"], D @ parts["S"]
    mechanical, Hg = D @ parts["Hm"] @ D, D @ geometric(parts) @ D
    free = scene.free_dofs
    spins = np.zeros(0, dtype=np.intp)
    if free is None:
        spins = free_spins(scene, H_el, A, S, scale=max(float(np.abs(H_el).sum(axis=1).max(initial=0.0)), 1e-300))
        R = metric.rotations(scene)
        C = np.concatenate([R, unit_columns(len(H_el), spins)], axis=1)
        rigid, _ = rigid_basis(np.concatenate([metric.translations(scene), C], axis=1))
    else:                          # held by fixed particles: their dofs dropped, no rigid motion, no projection
        H_el, A, S = H_el[np.ix_(free, free)], A[free], S[free]
        mechanical, Hg = mechanical[free][:, free], Hg[free][:, free]
        C = R = rigid = np.zeros((len(free), 0))
    projection = Projection.from_rotations(C)
    scales = part_scales(mechanical, Hg, A, S)
    E = metric_entrywise(parts["curvature_error"], metric, free)
    e_K = np.inf if E is None else curvature_error(E)
    return Problem(H_el=H_el, A=A, S=S, projection=projection, rigid=rigid, sliding=np.flatnonzero(scene.at_yield()),
                   n_contacts=scene.n_contacts, tol=scene.tol,
                   formation_error=formation_error(scales, projection.C, projection.Cplus, e_K,
                                                   centre_term(scene, metric, R)), free=free,
                   free_spins=len(spins), curvature_entrywise=E, curvature_bound=e_K)


class DenseMethod:
    """Every eigenpair of every branch (dense.solve_branches); leaves nothing out. Where lowrank.use_lowrank says
    so (many branches, or large ones), or when `device` resolves to a GPU (device.py), the branches are solved as
    low-rank updates of the elastic problem (lowrank.py; `lowrank` True/False forces the choice): it leaves out the ℍ^i spectra of the
    branches it solves (their ℍ^i nullity is proven instead) and says so. uniqueness=False leaves ℍ^i out altogether
    (no eig, SVD or Type-2; uniqueness_n_zero -1, no eigen_residual_uniqueness) and says so: what needs only the
    stability of the branches (track --whole) is spared the costlier half of the work."""

    name = "dense"

    def __init__(self, device: str = "cpu", lowrank: bool | None = None, uniqueness: bool = True):
        self.device, self.lowrank, self.uniqueness = device, lowrank, uniqueness

    def prepare(self, scene: Scene, timer: Timer) -> State:
        with timer("blocks"):
            blocks = contact_blocks(scene)
        with timer("assembly"):
            parts = dense_parts(scene, blocks)
        return State(scene=scene, sliding=np.flatnonzero(scene.at_yield()), blocks=blocks, parts=parts)

    def release(self, state: State) -> None:
        """Nothing: the dense parts serve the identity checks after the last metric's problem (errors)."""

    def problem(self, state: State, metric: Metric) -> Problem:
        return dense_problem(state.scene, state.blocks, state.parts, metric)

    def solve(self, problem: Problem, masks: np.ndarray, on_branch=None, progress: bool = False,
              label: str = "branches", keep_all: bool = True):
        bar = _progress_bar(len(masks), label, progress) if progress and len(masks) > 1 else None

        def stream(b):
            if bar is not None:
                bar.update()
            if on_branch is not None:
                on_branch(b)

        from .device import backend
        from .lowrank import solve_branches_lowrank, use_lowrank
        lowrank = self.lowrank
        if lowrank is None:
            lowrank = use_lowrank(len(masks), problem.H_el.shape[0], self.uniqueness) or \
                backend(self.device).name == "gpu"
        notes = {"complete": True, "paths": {"full": len(masks)}, "warnings": [] if self.uniqueness else [
            "uniqueness=False: ℍ^i (uniqueness eigenvalues, Type-2 non-uniqueness) not evaluated"]}
        if lowrank:
            branches, info = solve_branches_lowrank(problem, masks, device=self.device, keep_all=keep_all,
                                                    on_branch=stream if bar is not None or on_branch else None,
                                                    uniqueness=self.uniqueness)
            notes["lowrank"] = info
            notes["paths"] = {"low_rank": len(masks) - info["full_path"], "full": info["full_path"]}
            notes["residual_stability"] = info["residual_stability"]
            if not keep_all:
                notes.update(tally=info["tally"], n_branches=info["n_branches"])
            proven = " (ℍ^i nullity proven from a bound on its smallest singular value)" if self.uniqueness else ""
            notes["warnings"].append(f"low-rank branch path on {info['device']} (unit round-off {info['eps']:.1e}): "
                                     f"{len(branches) - info['full_path']} of {len(branches)} branches without ℍ^i "
                                     f"spectra{proven}, {info['full_path']} on the full path")
        else:
            branches = solve_branches(problem, masks, on_branch=stream, uniqueness=self.uniqueness)
        if bar is not None:
            bar.close()
        return branches, notes

    def errors(self, state: State, problem: Problem, branches) -> dict:
        errors = identity_errors(state.scene, state.parts)
        errors["rigid_leakage_modified"] = modified_leakage(problem.H_el, problem.rigid, problem.projection)
        errors.update(problem.projection.errors())
        errors["equilibrium_residual"] = equilibrium_residual(state.scene)
        errors["eigen_residual_stability"] = max(b.residual_stability for b in branches)
        if self.uniqueness:
            errors["eigen_residual_uniqueness"] = max(b.residual_uniqueness for b in branches)
        return errors


# ------------------------------------------------------------------------------------------------ sparse

@dataclass(frozen=True, eq=False)
class SparseBranchProblem:
    """The sparse problem of one metric and the branches.Problem view of it (consistency tests, subspace search)."""

    sp: object
    core: Problem

    def __getattr__(self, name):                                     # the Problem's fields (projection, rigid, …)
        return getattr(self.core, name)


class SparseMethod:
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

    def release(self, state: State) -> None:
        """After the last metric's problem: the physical H and Hm (two matrices of the size of Hs, 1.5 GB on 10⁶
        disks) go; the identity checks need only the scaled H̃ and the parts applied to the rigid basis."""
        state.parts = replace(state.parts, H=None, Hm=None)

    def problem(self, state: State, metric: Metric) -> SparseBranchProblem:
        from .sparse import sparse_problem
        scene = state.scene
        spb = sparse_problem(scene, metric=metric, parts=state.parts)
        _require_finite(scene, spb.norm)
        scales = part_scales(spb.Hm, spb.Hs - spb.Hm, spb.A, spb.S)
        proj = spb.projection
        core = Problem(H_el=spb.H, A=spb.A, S=spb.S, projection=proj, rigid=spb.R, sliding=spb.sliding,
                       n_contacts=scene.n_contacts, tol=scene.tol,
                       formation_error=formation_error(scales, proj.C, proj.Cplus,
                                                       metric_error(state.parts.curvature_error, metric),
                                                       centre_term(scene, metric, metric.rotations(scene))),
                       free_spins=spb.free_spins)
        return SparseBranchProblem(sp=spb, core=core)

    def solve(self, problem: SparseBranchProblem, masks: np.ndarray, on_branch=None, progress: bool = False,
              label: str = "branches", keep_all: bool = True):
        from .sparse import sparse_branch
        from .threads import blas_threads
        spb, k = problem.sp, self.k
        bar = _progress_bar(len(masks), f"{label} (sparse)", progress) if progress else None
        branches, unverified, cut, ritz = [], 0, 0, 0
        with blas_threads(1):     # tall-skinny products and block solves: a 2-thread pool waiting for a core on a
            found = list(zip(masks, self._modes(spb, masks, k + 1)))   # busy machine cost 3× (threads.py)
            for mask, modes in found:
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
        notes = {"complete": complete, "full": k >= n_free, "k": k, "paths": {"sparse": len(masks)}, "warnings": [
            f"sparse path: the lowest {min(k, n_free)} of {n_free} non-rigid eigenpairs of sym(𝓗^i) per branch; "
            "uniqueness (ℍ^i spectra, Type-2 non-uniqueness) is not evaluated"]}
        if ritz:
            notes["warnings"].append(f"{ritz} of {len(branches)} branches as Ritz updates of one elastic solve "
                                     "(ritz.SparseRitz: count below σ exact by inertia, residuals ≤ 1e-12·‖Hs‖), "
                                     "the others by shift-invert")
        if any(b_modes.method == "lobpcg-gpu" for _, b_modes in found):
            notes["warnings"].append("on the GPU: LOBPCG with block-Jacobi preconditioning (solve/blockiter.py), "
                                     "residuals and bounds recomputed in float64 on the host; no inertia counts")
        iterative = sum(m.method.startswith("lobpcg") for _, m in found)
        if unverified > iterative:
            notes["warnings"].append(f"{unverified - iterative} branch(es): the inertia check could not prove that the "
                                     "computed eigenvalues are the lowest ones")
        if iterative:
            from .memory import no_inertia
            notes["partial_because"] = no_inertia(spb.scene, spb.n)
            notes["warnings"].append(f"{iterative} branch(es): {notes['partial_because']}")
        if cut:
            notes["warnings"].append(f"{cut} branch(es): the highest computed eigenvalue belongs to a repeated cluster "
                                     "that extends beyond k; its consistency search covers only the computed part")
        need = max((b.negative_count["count"] for b in branches), default=0)
        if not complete:
            notes["suggest_k"] = int(need + 1 + max(b.n_zero - spb.n_rigid for b in branches))
        return branches, notes

    def _modes(self, spb, masks, kk: int):
        """Modes of every branch: by budget.use_ritz (RITZ_MIN_BRANCHES or more, or two with a narrow basis) as low-rank
        updates of one elastic solve (ritz.SparseRitz,
        verified per branch, shift-invert ARPACK where that fails), a single one, or branches whose Ritz problem
        would not fit budget.RITZ_BYTES (many sliding contacts: its basis grows by about 8.5 columns and its updates by
        one width² matrix a contact: ritz_fits), by shift-invert directly, one after the other."""
        from .device import backend
        from .sparse import lowest_modes
        Ms = spb.A.shape[1]
        if backend(self.device).name == "gpu":                     # LOBPCG on the device, no factor (blockiter.py)
            from .blockiter import device_lowest
            for mask in masks:
                yield device_lowest(spb, kk, mask, device=self.device)
            return
        if use_ritz(len(masks), spb.n, Ms, kk):
            from .ritz import SparseRitz
            yield from SparseRitz(spb, kk, tol=self.tol, device=self.device).modes(masks, kk)
            return
        for mask in masks:
            yield lowest_modes(spb, kk, mask, tol=self.tol)

    def errors(self, state: State, problem: SparseBranchProblem, branches) -> dict:
        from .sparse import identity_errors as sparse_identities
        errors = sparse_identities(problem.sp, parts=state.parts)
        errors["equilibrium_residual"] = equilibrium_residual(state.scene)
        errors["eigen_residual_stability"] = max(b.residual_stability for b in branches)
        return errors
