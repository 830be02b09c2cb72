"""Rigid motions and the no-rigid-rotation projection (Sec. 2.4), applied as low-rank updates.

C (eq:dtrigid) maps a cluster rotation dθ̄ to particle motions du^p = dθ̄ × x^p, dθ^p = dθ̄ with x measured
from the centroid; C⁺ = (CᵀC)⁻¹Cᵀ (eq:Moore1), P^rr = C C⁺ (eq:Prr), P^nrr = I - P^rr (eq:Pnrr), and
ℍ = H P^nrr, 𝓗 = P^nrrᵀ H P^nrr (eq:newstiffnesses). P is never formed: P v = v - C (C⁺ v).

Dof scaling. The paper's C⁺ is the least-squares fit of |du - dθ̄ × x|² + |dθ - dθ̄|², which adds a length² to
an angle²; and because Hg3·C ≠ 0 the spectra of ℍ and 𝓗 depend on that weighting. granstab works in scaled
dofs Ũ = [du, L dθ] (U = D Ũ, D = diag(1, 1/L)), H̃ = D H D, C̃ = D⁻¹ C, with L the mean contact radius |r^pq|:
every eigenvalue then has units of force/length and is invariant when all lengths are scaled. With L = 1 this
is the paper's literal metric (all of the paper's examples have r = 1, so they are reproduced unchanged).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.scene import Scene, mean_contact_radius
from ..model.vec import rot_dim, rotate_matrix

rotation_length = mean_contact_radius   # the default L of the scaled dofs [du, L dθ]


def dof_scale(scene: Scene, length: float) -> np.ndarray:
    """Diagonal of D = diag(1 for translations, 1/L for rotations): U = D Ũ. (n_dof,)"""
    d, r = scene.dim, rot_dim(scene.dim)
    per = np.concatenate([np.ones(d), np.full(r, 1.0 / length)])
    return np.tile(per, scene.n_particles)


def rotations(scene: Scene, length: float = 1.0) -> np.ndarray:
    """C̃ (n_dof, r): rigid rotations about the centroid (eq:dtrigid) in scaled dofs [du, L dθ]."""
    d, r, N = scene.dim, rot_dim(scene.dim), scene.n_particles
    xc = scene.x - scene.x.mean(axis=0)
    C = np.zeros((N, d + r, r))
    C[:, :d, :] = rotate_matrix(xc)                                  # dθ̄ × x^p
    C[:, d:, :] = length * np.eye(r)
    return C.reshape(N * (d + r), r)


def translations(scene: Scene) -> np.ndarray:
    """T (n_dof, d): rigid translations (the same in scaled and unscaled dofs)."""
    d, r, N = scene.dim, rot_dim(scene.dim), scene.n_particles
    T = np.zeros((N, d + r, d))
    T[:, :d, :] = np.eye(d)
    return T.reshape(N * (d + r), d)


@dataclass(frozen=True, eq=False)
class Projection:
    """P^nrr = I - C C⁺ as a low-rank operator (eq:Pnrr, eq:Prr); C (n, r), C⁺ (r, n)."""

    C: np.ndarray
    Cplus: np.ndarray

    @classmethod
    def from_rotations(cls, C: np.ndarray) -> "Projection":
        """P^nrr of the rotations C (n, r); r = 0 (a cluster held by fixed particles): the identity."""
        return cls(C=C, Cplus=np.linalg.solve(C.T @ C, C.T) if C.shape[1] else C.T.copy())

    def apply(self, v: np.ndarray) -> np.ndarray:
        """P^nrr v for v (n,) or (n, k)."""
        return v - self.C @ (self.Cplus @ v)

    def right(self, H) -> np.ndarray:
        """ℍ = H P^nrr = H - (H C) C⁺ (eq:newstiffnesses); H dense (…, n, n) or sparse."""
        return H - (H @ self.C) @ self.Cplus

    def both(self, HP: np.ndarray) -> np.ndarray:
        """𝓗 = P^nrrᵀ ℍ = ℍ - C⁺ᵀ (Cᵀ ℍ) from ℍ; P is symmetric, so P^T = P (eq:newstiffnesses)."""
        return HP - self.Cplus.T @ (self.C.T @ HP)

    def errors(self, rng: np.random.Generator | None = None) -> dict:
        """Idempotence ‖C⁺C - I‖ and symmetry |uᵀPv - vᵀPu| / (|u||v|) on random probes."""
        rng = rng or np.random.default_rng(0)
        r = self.C.shape[1]
        u, v = rng.standard_normal((2, self.C.shape[0]))
        sym = abs(u @ self.apply(v) - v @ self.apply(u)) / (np.linalg.norm(u) * np.linalg.norm(v))
        return {"projection_idempotence": float(np.abs(self.Cplus @ self.C - np.eye(r)).max(initial=0.0)),
                "projection_symmetry": float(sym)}
