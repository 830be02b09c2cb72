"""Soft spots (Manning & Liu, PRL 107, 108302, 2011): each particle's participation in the lowest-frequency modes
of a packing, the field's baseline for where it will rearrange (issue 39).

- `frictionless_matrix`: the dynamical matrix of the same contacts without friction, the contact law's normal
  stiffness only (Hm with α = 0, eq:ContactF's k n⊗n) and the prestress of the normal force along the branch
  (the Hessian of a pair potential: per contact, over the translations [u^p, u^q] with incidence (−1, +1),
  k n⊗n − (f_n / ℓ)(I − n⊗n), f_n = −f·n the compressive normal force, ℓ = |b| the centre distance). The d
  uniform translations (zero modes) are lifted above the spectrum, so the lowest modes are the non-trivial ones.
- `participation`: the mean over modes of a particle's share of the mode's squared translation, Σ_modes
  |u_i|² / Σ_j |u_j|² / k (a particle's share of a mode is sign- and scale-free).
- `lowest_count`: the lowest 1 % of the modes (at least one), the count the field uses.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from ..mechanics.assembly import Assembly
from ..model.scene import Scene

FRACTION = 0.01
DENSE_BELOW = 2500            # translational dofs: dense eigh below, Lanczos (eigsh, smallest algebraic) above


def lowest_count(n_modes: int) -> int:
    """The lowest FRACTION of n_modes, at least one."""
    return max(1, math.ceil(FRACTION * n_modes))


def frictionless_matrix(scene: Scene) -> sp.csr_matrix:
    """D (dN, dN) over the particles' translations (module docstring), the d uniform translations not lifted."""
    n, b = scene.normal, scene.branch
    d = scene.dim
    nn = n[:, :, None] * n[:, None, :]
    fn = -np.sum(scene.force * n, axis=1)
    length = np.linalg.norm(b, axis=1)
    K = scene.k[:, None, None] * nn - (fn / length)[:, None, None] * (np.eye(d) - nn)
    blocks = np.concatenate([np.concatenate([K, -K], axis=2), np.concatenate([-K, K], axis=2)], axis=1)
    return Assembly(scene.p, scene.q, d, d * scene.n_particles)(blocks)


def lowest_modes(D: sp.csr_matrix, d: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k lowest eigenpairs of D with its d uniform translations lifted (D + c T Tᵀ, c above D's Gershgorin
    bound): eigenvalues (k,) and vectors (dN, k)."""
    n = D.shape[0]
    T = np.zeros((n, d))
    for a in range(d):
        T[a::d, a] = 1.0 / math.sqrt(n // d)
    c = 2.0 * float(abs(D).sum(axis=1).max()) + 1.0
    if n < DENSE_BELOW:
        lam, V = np.linalg.eigh(D.toarray() + c * T @ T.T)
        return lam[:k], V[:, :k]
    from scipy.sparse.linalg import LinearOperator, eigsh
    op = LinearOperator((n, n), matvec=lambda v: D @ v + c * T @ (T.T @ v), dtype=float)
    lam, V = eigsh(op, k=k, which="SA", v0=np.ones(n))
    order = np.argsort(lam)
    return lam[order], V[:, order]


def participation(modes: np.ndarray) -> np.ndarray:
    """Per particle, the mean over modes (k, N, d) of its share of each mode's squared translation (N,)."""
    t = np.sum(modes * modes, axis=2)
    total = t.sum(axis=1, keepdims=True)
    share = np.divide(t, total, out=np.zeros_like(t), where=total > 0)
    return share.mean(axis=0)


def frictionless(scene: Scene) -> tuple[dict, np.ndarray]:
    """The frictionless soft spots of a scene: ({soft_spots_count, soft_spots_lambda}, participation (N,))."""
    d, N = scene.dim, scene.n_particles
    k = lowest_count(d * N - d)
    lam, V = lowest_modes(frictionless_matrix(scene), d, k)
    return {"soft_spots_count": k, "soft_spots_frictionless_lambda_max": float(lam[-1])}, \
        participation(V.T.reshape(k, N, d))
