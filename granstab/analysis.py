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
    parts = {name: assemble(blocks.blocks[name], blocks.index, blocks.n_dof) for name in blocks.blocks}
    H = (parts["Hg1"] + parts["Hg2"] + parts["Hg3"] + parts["Hm"]).toarray()
    H_el = D[:, None] * H * D[None, :]
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


def analyze(scene: Scene, *, rotation_length_: float | None = None, max_sliding: int = 16,
            on_branch=None) -> Analysis:
    """Analyse every loading branch of `scene` (Sec. 3, Appendix D).

    rotation_length_: L of the scaled dofs [du, L dθ] (default: mean contact radius; 1 = the paper's metric).
    max_sliding: refuse more than this many potentially sliding contacts (2^Ms branches).
    on_branch: called with each Branch as it is finished (streaming).
    """
    timer = Timer()
    warnings = []
    with timer("total"):
        with timer("blocks"):
            blocks = contact_blocks(scene)
        bad = np.flatnonzero(blocks.rolling_undetermined)
        if bad.size:
            warnings.append(f"{bad.size} contact(s) (first: contacts[{bad[0]}]) have K^p + K^q singular on the "
                            "tangent plane (flat-on-flat or exact hand-in-glove): rolling is undetermined there "
                            "and the pseudo-inverse drops it; the identities below measure the consequence")
        length = rotation_length_ or rotation_length(scene)
        with timer("assembly"):
            problem, parts = build_problem(scene, blocks, length)
        Ms = len(problem.sliding)
        if Ms > max_sliding:
            raise SceneError(f"{scene.source}: {Ms} potentially sliding contacts: 2^{Ms} branches exceed "
                             f"max_sliding = {max_sliding}")
        masks = enumerate_masks(problem.sliding, scene.n_contacts)
        with timer("branches"):
            branches = solve_branches(problem, masks, on_branch=on_branch)
        with timer("errors"):
            parts["H"] = parts["Hg1"] + parts["Hg2"] + parts["Hg3"] + parts["Hm"]
            errors = identity_errors(scene, parts)
            errors["rigid_leakage_modified"] = modified_leakage(problem)
            errors.update(problem.projection.errors())
            errors["equilibrium_residual"] = equilibrium_residual(scene)
            errors["eigen_residual_stability"] = max(b.residual_stability for b in branches)
            errors["eigen_residual_uniqueness"] = max(b.residual_uniqueness for b in branches)
        summary = summarize(scene, branches, problem)
    return Analysis(scene=scene, problem=problem, length=length, scale=dof_scale(scene, length), branches=branches,
                    summary=summary, errors=errors, timings=timer.times, warnings=warnings)
