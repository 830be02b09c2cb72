"""Contact law of Sec. 2.6 (Michalowski & Mróz; Radi et al.), vectorised over contacts.

Q (eq:yield), sliding direction h (eq:Hdirection), yield normal g (eq:G), S = g·δu_def (eq:flow),
and the elastic / sliding contact stiffness F (eq:ContactF). μ = 0 is frictionless: no tangential stiffness in any
branch, F = k n⊗n (a frictionless contact cannot carry a tangential force, so it has no αk either and never slides).
"""
from __future__ import annotations

import numpy as np


def tangential_ratio(alpha: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """α where μ > 0, and 0 where μ = 0 (frictionless: no tangential stiffness), (M,)."""
    return np.where(np.asarray(mu) > 0, alpha, 0.0)


def elastic_stiffness(n: np.ndarray, k: np.ndarray, alpha: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """F^elastic = k[αI + (1-α) n⊗n] (eq:ContactF, first branch) with α → 0 where μ = 0 (k n⊗n): (M, d, d)."""
    d = n.shape[1]
    a = tangential_ratio(alpha, mu)
    nn = n[:, :, None] * n[:, None, :]
    return k[:, None, None] * (a[:, None, None] * np.eye(d) + (1.0 - a)[:, None, None] * nn)


def sliding_direction(force: np.ndarray, n: np.ndarray) -> np.ndarray:
    """h = f_t/|f_t| (eq:Hdirection), zero where there is no tangential force: (M, d)."""
    ft = force - np.sum(force * n, axis=1, keepdims=True) * n
    norm = np.linalg.norm(ft, axis=1, keepdims=True)
    return np.divide(ft, norm, out=np.zeros_like(ft), where=norm > 0)


def yield_normal(h: np.ndarray, n: np.ndarray, k: np.ndarray, alpha: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """g = k(αh + μn) (eq:G): (M, d)."""
    return k[:, None] * (alpha[:, None] * h + mu[:, None] * n)


def contact_stiffness(n, k, alpha, mu, force, sliding: np.ndarray) -> np.ndarray:
    """F^pq per contact (eq:ContactF): elastic, minus h⊗g where `sliding` (bool, (M,)) selects the sliding branch."""
    F = elastic_stiffness(n, k, alpha, mu)
    if np.any(sliding):
        h = sliding_direction(force, n)
        g = yield_normal(h, n, k, alpha, mu)
        F = F - sliding[:, None, None] * (h[:, :, None] * g[:, None, :])
    return F
