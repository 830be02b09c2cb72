"""Restarted flexible GMRES (FGMRES, right-preconditioned; Saad, *Iterative Methods for Sparse Linear Systems*, §9.4.1)
for several right-hand sides at once: each column keeps its own Krylov basis and least-squares problem, but the
operator and the preconditioner are applied to all columns together (one sparse product, one block solve of a factor:
BLAS-3), which is what the moduli's non-symmetric H needs with sym(H)'s factor as the preconditioner (moduli.py).
Flexible: the preconditioned vectors Z_j are kept and the update is Σ y_j Z_j, so a preconditioner applied in float32
(not exactly linear) does not spoil the Arnoldi relation H Z = V H̄.

The returned residuals are recomputed from the operator (not the recurrence's estimate)."""
from __future__ import annotations

import numpy as np

RESTART = 20   # Krylov vectors per column before a restart (memory: 2 RESTART + 1 n-vectors of float64 per column)


def _least_squares(Hh: np.ndarray, beta: np.ndarray, j: int):
    """y (m, j) minimising ‖β e₁ - H̄ y‖ per column, and that minimum (m,) (the recurrence's residual estimate)."""
    m = len(beta)
    rhs = np.zeros((m, j + 1))
    rhs[:, 0] = beta
    y = np.empty((m, j))
    est = np.empty(m)
    for c in range(m):                                     # m small least-squares problems of size (j + 1) × j
        y[c], *_ = np.linalg.lstsq(Hh[c, :j + 1, :j], rhs[c], rcond=None)
        est[c] = np.linalg.norm(rhs[c] - Hh[c, :j + 1, :j] @ y[c])
    return y, est


def gmres(apply, precondition, B: np.ndarray, tol: float, restart: int = RESTART, cycles: int = 10):
    """X (n, m) with ‖B - apply(X)‖ ≤ tol·‖B‖ per column where reached, its residuals R (n, m) (from `apply`),
    and the number of preconditioned products. `apply(V)`, `precondition(V)`: (n, m) → (n, m)."""
    n, m = B.shape
    X = np.zeros_like(B)
    target = tol * np.linalg.norm(B, axis=0)
    R = B.copy()
    steps = 0
    for _ in range(cycles):
        beta = np.linalg.norm(R, axis=0)
        if np.all(beta <= target):
            break
        V, Z = np.empty((restart + 1, n, m)), np.empty((restart, n, m))
        V[0] = R / np.where(beta > 0, beta, 1.0)
        Hh = np.zeros((m, restart + 1, restart))
        for j in range(restart):
            Z[j] = precondition(V[j])
            W = apply(Z[j])
            steps += 1
            for i in range(j + 1):                         # modified Gram-Schmidt, column by column
                h = np.einsum("nm,nm->m", V[i], W)
                Hh[:, i, j] = h
                W -= V[i] * h
            hn = np.linalg.norm(W, axis=0)
            Hh[:, j + 1, j] = hn
            V[j + 1] = W / np.where(hn > 0, hn, 1.0)
            y, est = _least_squares(Hh, beta, j + 1)
            if np.all(est <= 0.5 * target) or np.all(hn == 0):
                break
        X += np.einsum("jnm,mj->nm", Z[:j + 1], y)
        del V, Z
        R = B - apply(X)
    return X, R, steps
