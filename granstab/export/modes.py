"""The whole packing's lowest consistent modes as fields: each mode's displacement and rotation per particle, its
branch and the slip it makes at each contact (eq:ContactF, eq:flow)."""
from __future__ import annotations

import time

import numpy as np

from ..analysis import analyze
from ..mechanics.stiffness import kinematics
from ..model.errors import SceneError
from ..model.law import sliding_direction, yield_normal
from ..model.scene import Scene
from ..model.vec import rot_dim
from .fields import FrameFields, as3, axial

#: two consistent vectors of equal eigenvalue on two branches are one mode when |cos| exceeds this (a mode that
#: moves no sliding contact is consistent on every branch: exported once)
SAME_MODE = 1.0 - 1e-9


def lowest_modes(result, count: int) -> list[tuple[float, float, np.ndarray, np.ndarray]]:
    """The `count` lowest consistent non-rigid eigenpairs over every branch of an Analysis, each once: (eigenvalue,
    its error bound (accuracy.py), unit physical motion U (n_dof,) in the direction the branch's consistency allows
    (eq:flow), the branch mask (M,)). A one-line error when the packing has fewer."""
    found = sorted(((c["eigenvalue"], i, c["index"], c["vector_sign"]) for i, b in enumerate(result.branches)
                    for c in b.consistent()), key=lambda t: t[:3])
    chosen: list[tuple[float, float, np.ndarray, np.ndarray]] = []
    for lam, i, j, sign in found:
        branch = result.branches[i]
        U = (-1.0 if sign == -1 else 1.0) * result.motion(branch.stability_vectors[:, j])   # MINUS: -v is consistent
        if any(abs(lam - other) <= branch.accuracy[j] and abs(U @ V) > SAME_MODE for other, _, V, _ in chosen):
            continue
        chosen.append((lam, float(branch.accuracy[j]), U, np.asarray(branch.mask)))
        if len(chosen) == count:
            return chosen
    raise SceneError(f"{result.scene.source}: --modes {count}: the packing has {len(chosen)} distinct consistent "
                     f"non-rigid mode(s) on its {len(result.branches)} branch(es): ask for at most {len(chosen)}")


def contact_slip(scene: Scene, U: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Slip along h of every contact in motion U on the branch `mask`: S/(kα) with S = g·δu_def (eq:flow,
    eq:dudef) on the contacts the branch has sliding (+1), where F's tangential part along h, kα h·δu - S, is
    what is left of the elastic shear (eq:ContactF); 0 elsewhere, (M,)."""
    per = scene.dim + rot_dim(scene.dim)
    local = np.arange(per)
    index = np.concatenate([scene.p[:, None] * per + local, scene.q[:, None] * per + local], axis=1)
    Bu, _ = kinematics(scene)
    du = np.einsum("mdn,mn->md", Bu, U[index])
    g = yield_normal(sliding_direction(scene.force, scene.normal), scene.normal, scene.k, scene.alpha, scene.mu)
    S = np.sum(g * du, axis=1)
    kalpha = scene.k * scene.alpha
    slides = (np.asarray(mask) == 1) & (kalpha > 0)
    return np.divide(S, kalpha, out=np.zeros(scene.n_contacts), where=slides)


def modes_options(count: int, sample_branches: int | None = None, max_sliding: int = 16) -> dict:
    """The options of the whole-packing analysis behind --modes (its plan, solve/plan.py, and its run): modes only,
    in the L metric, the lowest max(6, count) on the sparse path; beyond max_sliding a sample of the branches."""
    return {"metric": "L", "method": "auto", "k": max(6, count), "attribution": False,
            "sample_branches": sample_branches, "max_sliding": max_sliding}


def add_modes(frame: FrameFields, scene: Scene, count: int, result=None, analysis: dict | None = None) -> None:
    """mode{j}_displacement, mode{j}_rotation (per particle, unit motion U = D Ũ, `Analysis.motion`), mode{j}_branch
    and mode{j}_slip (per contact), mode{j}_eigenvalue and its error bound mode{j}_accuracy (info), j = 1 … count,
    lowest first, in the L metric; modes_seconds: what the whole-packing analysis cost. `analysis`: its options
    (default modes_options(count))."""
    if count < 1:
        return
    if count > scene.n_dof:
        raise SceneError(f"{scene.source}: --modes {count}: more than the packing's {scene.n_dof} dofs")
    start = time.perf_counter()
    result = result or analyze(scene, **(analysis or modes_options(count)))
    d = scene.dim
    frame.info["modes_metric"] = f"{result.metric.name} (eigenvalues in {result.metric.units})"
    frame.info["modes_seconds"] = time.perf_counter() - start
    for j, (lam, bound, U, mask) in enumerate(lowest_modes(result, count), start=1):
        per = U.reshape(scene.n_particles, -1)
        frame.particles[f"mode{j}_displacement"] = as3(per[:, :d])
        frame.particles[f"mode{j}_rotation"] = axial(per[:, d:], d)
        frame.contacts[f"mode{j}_branch"] = mask.astype(np.int32)
        frame.contacts[f"mode{j}_slip"] = contact_slip(scene, U, mask)
        frame.info[f"mode{j}_eigenvalue"] = float(lam)
        frame.info[f"mode{j}_accuracy"] = bound
