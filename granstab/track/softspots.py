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
- `lowest_modes`: those modes; on large packings by shift-invert below the spectrum, the count checked by inertia.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from ..mechanics.assembly import Assembly
from ..model.scene import Scene
from ..solve.multifrontal import Multifrontal, dissection_order

FRACTION = 0.01
DENSE_BELOW = 2500            # translational dofs: dense eigh below, shift-invert below the spectrum above (Lanczos
                              # where its checks fail): 2.0 s → 1.2 s of CPU on a 2,000-disk frame (40 modes; issue 39)


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


def lowest_modes(D: sp.csr_matrix, d: int, k: int, nodes=None) -> tuple[np.ndarray, np.ndarray, dict]:
    """The k lowest eigenpairs of D on the complement of its d uniform translations T: eigenvalues (k,), vectors
    (dN, k) and how they were found ({"method", "residual"}: max ‖Dv − λv‖). Below DENSE_BELOW dofs a dense eigh of
    D + c T Tᵀ (c above D's Gershgorin bound); above, shift-invert below the spectrum (`_below_spectrum`), or where
    its checks fail, Lanczos on D + c T Tᵀ (eigsh, smallest algebraic). `nodes`: (order, sizes) of the particles
    (multifrontal.dissection_order), for the sparse factor; default one node per particle in their order."""
    n = D.shape[0]
    T = np.zeros((n, d))
    for a in range(d):
        T[a::d, a] = 1.0 / math.sqrt(n // d)
    c = 2.0 * float(abs(D).sum(axis=1).max()) + 1.0
    method = "dense"
    if n < DENSE_BELOW:
        lam, V = np.linalg.eigh(D.toarray() + c * T @ T.T)
        lam, V = lam[:k], V[:, :k]
    else:
        from scipy.sparse.linalg import LinearOperator, eigsh
        op = LinearOperator((n, n), matvec=lambda v: D @ v + c * T @ (T.T @ v), dtype=float)
        got = _below_spectrum(D, T, op, k, nodes)
        method, (lam, V) = ("shift-invert, count checked", got) if got is not None else \
            ("lanczos", eigsh(op, k=k, which="SA", v0=np.ones(n)))
    order = np.argsort(lam)
    lam, V = lam[order], V[:, order]
    residual = float(np.linalg.norm(D @ V - V * lam, axis=0).max(initial=0.0))
    return lam, V, {"method": method, "residual": residual}


def _below_spectrum(D, T, op, k: int, nodes):
    """The k lowest eigenpairs of D on T's complement by shift-invert at σ below D's spectrum, or None: σ is a
    loose Lanczos estimate of the lowest eigenvalue less a margin, proven below the spectrum by a Cholesky of
    D − σI in every front (multifrontal.Multifrontal.definite; moved down up to 4 times); ARPACK then finds the
    k + 1 eigenvalues nearest σ (the lowest) with (D − σI)⁻¹ restricted to T's complement, and the inertia of
    D − τI at τ midway between the k-th and (k+1)-th must count exactly k below τ (plus T's d zero modes where
    τ > 0): else None (the caller's Lanczos)."""
    from scipy.sparse.linalg import LinearOperator, eigsh
    n, d = T.shape
    order, sizes = nodes if nodes is not None else (np.arange(n // d), np.ones(n // d, np.intp))
    perm = (np.asarray(order)[:, None] * d + np.arange(d)).reshape(-1)
    inv = np.empty_like(perm)
    inv[perm] = np.arange(n)
    bounds = np.r_[0, np.cumsum(sizes) * d]
    P = D[perm][:, perm].tocsc()
    eye = sp.identity(n, format="csc")

    def factor(shift):
        return Multifrontal(P - shift * eye, bounds)

    theta = float(eigsh(op, k=1, which="SA", v0=np.ones(n), tol=1e-3)[0][0])
    margin = 0.05 * abs(theta) + 1e-9 * float(abs(D).sum(axis=1).max())
    sigma = min(theta, 0.0) - margin
    for _ in range(5):
        mf = factor(sigma)
        if mf.definite:
            break
        sigma -= 2 * margin
        margin *= 2
    else:
        return None

    def solve(v):
        v = v - T @ (T.T @ v)
        x = mf.solve(v[perm])[inv]
        return x - T @ (T.T @ x)

    start = np.linspace(1.0, 2.0, n)
    start -= T @ (T.T @ start)
    lam, V = eigsh(op, k=k + 1, sigma=sigma, which="LM", v0=start,
                   OPinv=LinearOperator((n, n), matvec=solve, dtype=float))
    order = np.argsort(lam)
    lam, V = lam[order], V[:, order]
    tau = 0.5 * (lam[k - 1] + lam[k])
    count = factor(tau).negative
    if count is None or count != k + (d if tau > 0 else 0):
        return None
    return lam[:k], V[:, :k]


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
    lam, V, info = lowest_modes(frictionless_matrix(scene), d, k, dissection_order(scene.x, scene.p, scene.q,
                                                                                   nodes=True))
    return {"soft_spots_count": k, "soft_spots_frictionless_lambda_max": float(lam[-1]),
            "soft_spots_frictionless_method": info["method"],
            "soft_spots_frictionless_residual": info["residual"]}, \
        participation(V.T.reshape(k, N, d))
