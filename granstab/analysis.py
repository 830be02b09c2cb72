"""`analyze(scene)`: every branch's spectra, consistent modes and verdicts, with error estimates and timings.

Pipeline: contact blocks (stiffness.py) → elastic H and sliding factors → scaled dofs and the rigid-rotation
projection (rigid.py) → all 2^Ms branches (branches.py) → verdicts (verdicts.py). Every result carries the
accuracy it achieved (identities, rigid-mode leakage, eigen-residuals, projection checks) and its wall time.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from .branches import Problem, enumerate_masks, solve_branches
from .rigid import Projection, dof_scale, rotation_length, rotations, translations
from .checks import equilibrium_residual, identity_errors
from .scene import Scene, SceneError
from .stiffness import ContactBlocks, assemble, contact_blocks
from .verdicts import summarize


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
class Analysis:
    """Result of `analyze`: branches, summary (verdicts), errors (relative, dimensionless), timings (s)."""

    scene: Scene
    problem: Problem
    length: float
    scale: np.ndarray
    branches: list
    summary: dict
    errors: dict
    timings: dict
    warnings: list = field(default_factory=list)

    def motion(self, vector: np.ndarray) -> np.ndarray:
        """Physical motion U = D Ũ of a scaled eigenvector, normalised to unit length."""
        u = self.scale * vector
        return u / np.linalg.norm(u)

    def to_dict(self) -> dict:
        """The `granstab analyze --json` object."""
        s = self.scene
        return {
            "dim": s.dim,
            "title": s.title,
            "n_particles": s.n_particles,
            "n_contacts": s.n_contacts,
            "n_dof": s.n_dof,
            "n_sliding": int(np.sum(s.at_yield())),
            "rotation_length": self.length,
            "branches": [_branch_dict(b) for b in self.branches],
            "summary": self.summary,
            "errors": self.errors,
            "timings": self.timings,
            "warnings": self.warnings,
        }


def _branch_dict(b) -> dict:
    return {
        "mask": [int(v) for v in b.mask],
        "stability_eigenvalues": [float(v) for v in b.stability_eigenvalues],
        "n_zero": b.n_zero,
        "zero_tolerance": b.zero_tol,
        "consistent": [{k: c[k] for k in ("eigenvalue", "vector_sign", "hinges_on_tolerance")} for c in b.consistent()],
        "uniqueness_eigenvalues": [[float(v.real), float(v.imag)] for v in b.uniqueness_eigenvalues],
        "uniqueness_n_zero": b.uniqueness_n_zero,
        "type2": [{"vector_sign": t["vector_sign"], "dimension": t["dimension"]} for t in b.type2],
    }


def build_problem(scene: Scene, blocks: ContactBlocks, length: float):
    """Elastic H, sliding factors and projection in scaled dofs Ũ = D⁻¹U (rigid.py); returns (problem, parts)."""
    D = dof_scale(scene, length)
    parts = {name: assemble(blocks.blocks[name], scene.p, scene.q, scene.dof_per_particle, blocks.n_dof)
             for name in blocks.blocks}
    parts["H"] = parts["Hg1"] + parts["Hg2"] + parts["Hg3"] + parts["Hm"]
    H_el = D[:, None] * parts["H"].toarray() * D[None, :]
    sliding = np.flatnonzero(scene.at_yield())
    n = scene.n_dof
    A = np.zeros((n, len(sliding)))
    S = np.zeros((n, len(sliding)))
    rows = blocks.index[sliding]                                      # (Ms, n_loc)
    cols = np.broadcast_to(np.arange(len(sliding))[:, None], rows.shape)
    np.add.at(A, (rows, cols), blocks.slide_left[sliding])
    np.add.at(S, (rows, cols), blocks.slide_right[sliding])
    A *= D[:, None]
    S *= D[:, None]
    C = rotations(scene, length)
    T = translations(scene)
    rigid, _ = np.linalg.qr(np.concatenate([T, C], axis=1))
    problem = Problem(H_el=H_el, A=A, S=S, projection=Projection.from_rotations(C), rigid=rigid,
                      sliding=sliding, n_contacts=scene.n_contacts, tol=scene.tol)
    return problem, parts


def modified_leakage(problem: Problem) -> float:
    """‖ℍ R‖ / ‖H‖ for all rigid motions R: ℍ = H - (H C) C⁺ applied without forming it (eq:newstiffnesses)."""
    H, R, proj = problem.H_el, problem.rigid, problem.projection
    HR = H @ R - (H @ proj.C) @ (proj.Cplus @ R)
    return float(np.abs(HR).max() / max(np.linalg.norm(H), 1e-300))


METHODS = ("auto", "dense", "sparse")


def analyze(scene: Scene, *, rotation_length_: float | None = None, max_sliding: int = 16,
            on_branch=None, method: str = "auto", k: int = 6, progress: bool = False, device: str = "cpu",
            lowrank: bool | None = None) -> Analysis:
    """Analyse every loading branch of `scene` (Sec. 3, Appendix D).

    rotation_length_: L of the scaled dofs [du, L dθ] (default: mean contact radius; 1 = the paper's metric).
    max_sliding: refuse more than this many potentially sliding contacts (2^Ms branches).
    on_branch: called with each Branch as it is finished (streaming).
    method: "dense" (every eigenpair of every branch, ℍ spectra, Type-2), "sparse" (the lowest k non-rigid
    eigenpairs of sym(𝓗^i) per branch without any n_dof × n_dof matrix: granstab.sparse, for large clusters; see
    `analyze_sparse` for what it leaves out) or "auto" (dense up to sparse.DENSE_MAX_DOF dofs, sparse above).
    k: eigenpairs per branch on the sparse path. progress: a tqdm bar with time left over the branches.
    device: "cpu", "gpu" (CuPy, else backend.DeviceError) or "auto" for the stacked branch eigenproblems
    (backend.py). lowrank: solve the branches as low-rank updates of the elastic problem (lowrank.py: no ℍ^i
    spectra, eigenvectors on demand); None = when there are at least lowrank.MIN_BRANCHES branches or the
    device resolves to a GPU.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    from .backend import backend
    from .sparse import DENSE_MAX_DOF, analyze_sparse
    backend(device)                                                   # an unusable device fails before any work
    if method == "sparse" or (method == "auto" and scene.n_dof > DENSE_MAX_DOF):
        return analyze_sparse(scene, k=k, rotation_length_=rotation_length_, max_sliding=max_sliding,
                              on_branch=on_branch, progress=progress, device=device)
    timer = Timer()
    warnings = []
    with timer("total"):
        with timer("blocks"):
            blocks = contact_blocks(scene)
        warnings += curvature_warnings(scene, blocks)
        length = rotation_length_ or rotation_length(scene)
        with timer("assembly"):
            problem, parts = build_problem(scene, blocks, length)
        Ms = len(problem.sliding)
        if Ms > max_sliding:
            raise SceneError(f"{scene.source}: {Ms} potentially sliding contacts: 2^{Ms} branches exceed "
                             f"max_sliding = {max_sliding}")
        masks = enumerate_masks(problem.sliding, scene.n_contacts)
        with timer("branches"):
            bar = _progress_bar(len(masks)) if progress and len(masks) > 1 else None
            def stream(b, _user=on_branch):
                bar.update()
                if _user is not None:
                    _user(b)
            branches, info = _solve(problem, masks, stream if bar is not None else on_branch, device, lowrank)
            if bar is not None:
                bar.close()
        with timer("errors"):
            errors = identity_errors(scene, parts)
            errors["rigid_leakage_modified"] = modified_leakage(problem)
            errors.update(problem.projection.errors())
            errors["equilibrium_residual"] = equilibrium_residual(scene)
            errors["eigen_residual_stability"] = max(b.residual_stability for b in branches)
            errors["eigen_residual_uniqueness"] = max(b.residual_uniqueness for b in branches)
            if info:
                errors["branch_leakage"] = info["leakage"]
                errors["branch_backward_error"] = info["backward_error"]
                warnings.append(f"low-rank branch path on {info['device']} (unit round-off {info['eps']:.1e}): "
                                f"{len(branches) - info['full_path']} of {len(branches)} branches without ℍ^i "
                                "spectra (ℍ^i nullity proven from a bound on its smallest singular value), "
                                f"{info['full_path']} on the full path")
        summary = flag_undetermined(summarize(scene, branches, problem), blocks)
    return Analysis(scene=scene, problem=problem, length=length, scale=dof_scale(scene, length), branches=branches,
                    summary=summary, errors=errors, timings=timer.times, warnings=warnings)


def _solve(problem, masks, on_branch, device, lowrank):
    """The branches on the full stacked path or on the low-rank path (lowrank.py), with that path's info."""
    from .backend import backend
    from .lowrank import MIN_BRANCHES, solve_branches_lowrank
    if lowrank is None:
        lowrank = len(masks) >= MIN_BRANCHES or backend(device).name == "gpu"
    if not lowrank:
        return solve_branches(problem, masks, on_branch=on_branch), {}
    return solve_branches_lowrank(problem, masks, device=device, on_branch=on_branch)


def _progress_bar(total: int):
    """A tqdm bar with the time left (tqdm is optional: None without it)."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc="branches", unit="branch", mininterval=0.5)


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
    from .vec import tangent_basis
    T = tangent_basis(scene.normal)
    Tt = np.swapaxes(T, 1, 2)
    kp = Tt @ scene.curvature_p @ T
    kq = Tt @ scene.curvature_q @ T
    kp = 0.5 * (kp + np.swapaxes(kp, 1, 2))
    kq = 0.5 * (kq + np.swapaxes(kq, 1, 2))
    lam = np.abs(np.linalg.eigvalsh(kp + kq)).min(axis=1)
    scale = np.maximum(np.abs(np.linalg.eigvalsh(kp)).max(axis=1), np.abs(np.linalg.eigvalsh(kq)).max(axis=1))
    return np.divide(lam, scale, out=np.zeros_like(lam), where=scale > 0)


def flag_undetermined(summary: dict, blocks: ContactBlocks) -> dict:
    """Where a loaded contact's rolling is undetermined (K^p + K^q singular: the pseudo-inverse cut-off decides),
    the verdict is not a proof: sufficient = False, hinges_on_tolerance = True, and the reason says why."""
    n_bad = int(np.sum(blocks.rolling_undetermined))
    if n_bad:
        summary["sufficient"] = False
        summary["hinges_on_tolerance"] = True
        summary["reason"] += (f"; NOT DETERMINED: {n_bad} loaded contact(s) with K^p + K^q singular (flat-on-flat or "
                              "exact hand-in-glove) — their rolling is undetermined and the verdict rests on the "
                              "pseudo-inverse cut-off (pinv_rtol)")
    return summary
