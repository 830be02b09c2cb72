"""Error estimates of H from exact identities that hold for every motion (Sec. 2.3), in O(nnz) work.

Σ_p db^p = 0 (force balance of the increments), Σ_p (x^p × db^p + dw^p + du^p × b^p) = 0 (moment balance,
eq:equil1 differentiated; not in a periodic scene, which has no rigid rotation), Hg1, Hg2 and Hm vanish on all
rigid motions, H on translations. Each is reported
relative to the Frobenius norm of H (moment balance also per unit length of the cluster); so is the rigid leakage
of ℍ = H P^nrr (eq:newstiffnesses), which is zero only up to the rounding of the projection.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import norm as sparse_norm

from ..model.scene import Scene, equilibrium_loads
from ..model.vec import cross_matrix
from .rigid import rotation_length, rotations, translations


def _norm(A) -> float:
    value = sparse_norm(A) if sp.issparse(A) else np.linalg.norm(A)
    return max(float(value), 1e-300)


def identity_errors(scene: Scene, parts: dict) -> dict:
    """Relative residuals of the exact identities for H and its parts (dense arrays or sparse matrices)."""
    H = parts["H"]
    norm = _norm(H)
    T, C = translations(scene), rotations(scene, 1.0)
    rigid = np.concatenate([T, C], axis=1)
    d, per = scene.dim, scene.dof_per_particle
    L = np.zeros((scene.n_particles, C.shape[1], per))
    if C.shape[1]:                                                    # none in a periodic scene
        L[:, :, :d] = -cross_matrix(scene.load)                      # du^p × b^p = -b^p × du^p
    L = np.transpose(L, (1, 0, 2)).reshape(C.shape[1], scene.n_dof)
    size = max(float(np.abs(scene.x - scene.x.mean(axis=0)).max()), rotation_length(scene))
    HT = np.asarray(H.T @ T)
    HC = np.asarray(H.T @ C).T
    return {
        "force_balance": float(np.abs(HT).max() / norm),
        "moment_balance": float(np.abs(HC + L).max(initial=0.0) / (norm * size)),
        "rigid_leakage_parts": float(max(np.abs(np.asarray(parts[k] @ rigid)).max() for k in ("Hg1", "Hg2", "Hm"))
                                     / norm),
        "rigid_leakage_H_translations": float(np.abs(np.asarray(H @ T)).max() / norm),
    }


def modified_leakage(H, R: np.ndarray, projection) -> float:
    """max |ℍ R| / ‖H‖_F for all rigid motions R (n, d + r): ℍ = H - (H C) C⁺ (eq:newstiffnesses) applied without
    forming it, for a dense or sparse H and a rigid.Projection."""
    HR = H @ R - (H @ projection.C) @ (projection.Cplus @ R)
    return float(np.abs(HR).max(initial=0.0) / _norm(H))


def equilibrium_residual(scene: Scene) -> float:
    """max_p |b^p + Σ f^pq| / Σ|f| (0 when the loads were derived from the forces, eq:equil1)."""
    b, _ = equilibrium_loads(scene)
    scale = max(np.linalg.norm(scene.force, axis=1).sum(), 1e-300)
    return float(np.linalg.norm(scene.load - b, axis=1).max() / scale) if scene.n_particles else 0.0
