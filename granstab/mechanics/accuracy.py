"""How accurate each computed eigenvalue of sym(𝓗^i) is: the bounds that decide zero against sign (Sec. 3.2).

A verdict rests on signs of eigenvalues, so each eigenvalue λ̂_j carries a bound δ_j with |λ_j - λ̂_j| <= δ_j
(first order in the unit round-off ε), from three sources:

* the eigensolver: for orthonormal computed vectors with residuals r_j = A v̂_j - λ̂_j v̂_j, the exact eigenvalues of
  the stored A can be matched one to one with the λ̂_j so that |λ - λ̂_j| <= √2 ‖r_j‖ (Kahan; Parlett, *The
  Symmetric Eigenvalue Problem*, Thm. 11-5-1);
* computing r_j itself: γ_{n+2} (‖|A|‖∞ + |λ̂_j|), with γ_m = mε/(1 - mε) (Higham, *Accuracy and Stability*, §3);
* forming A from its parts: H̃ = D(Hm + Hg1 + Hg2 + Hg3)D, the rank-one sliding terms and the projection
  P^nrr (eq:newstiffnesses). Each part is rounded relative to its OWN scale — the mechanical part to ε·k, the
  geometric parts to ε·|f|/r, which differ by f/k — and the projection adds γ_n κ(C̃) of both, with
  κ(C̃) = ‖C̃‖_F ‖C̃⁺‖_F. So ‖ΔA‖₂ <= (8ε + 2γ_n κ(C̃)) (‖Hm̃‖∞ + ‖Hg̃‖∞ + Σ‖a‖‖s‖).

An eigenvalue with |λ̂_j| > δ_j has a resolved sign; |λ̂_j| <= δ_j is a zero within accuracy (its sign is not
determined, unless δ_j = λ̂_j = 0: an exact zero, e.g. a particle without contacts). The bound replaces a blanket
multiple of ε‖A‖, which was 400-28,000 times the real error and hid resolved negative eigenvalues.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..model.tolerances import EPS


def gamma(m: int) -> float:
    """γ_m = mε / (1 - mε): the relative error bound of a sum of m floating-point terms (Higham §3.1)."""
    return m * EPS / (1.0 - m * EPS)


def abs_norm_inf(A, xp=np):
    """‖|A|‖∞, the largest absolute row sum (bounds ‖A‖₂ for symmetric A): per matrix of a stack (..., n, n) → (...),
    a number for one matrix (dense or sparse); xp: numpy or CuPy."""
    if sp.issparse(A):
        return float(abs(A).sum(axis=1).max()) if A.nnz else 0.0
    if A.shape[-1] == 0 or A.shape[-2] == 0:
        return xp.zeros(A.shape[:-2])[()]
    return xp.abs(A).sum(axis=-1).max(axis=-1)


def part_scales(mechanical, geometric, A: np.ndarray, S: np.ndarray) -> dict:
    """The scales of the separately rounded parts (in the metric's dofs): ‖Hm̃‖∞, ‖Hg̃‖∞, Σ‖a‖‖s‖ (sliding)."""
    sliding = float(np.sum(np.linalg.norm(A, axis=0) * np.linalg.norm(S, axis=0))) if A.size else 0.0
    return {"mechanical": abs_norm_inf(mechanical), "geometric": abs_norm_inf(geometric), "sliding": sliding}


def formation_error(scales: dict, C: np.ndarray, Cplus: np.ndarray, curvature: float = 0.0,
                    centre: float = 0.0) -> float:
    """Bound of ‖sym(𝓗^i) as formed - exact‖₂ (module docstring, docs/bounds.md): (8ε + 2γ_n κ(C̃) + `centre`, the
    projection's error from the rounded centroid, `centre_error`) Σ scales, plus `curvature` (`curvature_error`),
    the error carried in from rounding K^p + K^q."""
    kappa = float(np.linalg.norm(C) * np.linalg.norm(Cplus)) if C.size else 0.0
    return (8 * EPS + 2 * gamma(C.shape[0]) * kappa + centre) * sum(scales.values()) + curvature


def centre_error(C: np.ndarray, defect, weight=1.0):
    """2‖ΔP‖ (P H P moves by 2‖ΔP‖‖H‖) for the rotations C (..., n, r) (unscaled by the projection) whose positions
    about the centroid are off by at most `defect` (rigid.centred) each, in dofs that scale translations by at most
    `weight` (1 in the L metrics, √m in the inertia metric): ‖ΔC‖_F <= √(n r) weight defect and
    ‖ΔP‖₂ <= 2‖ΔC‖₂ / σ_min(C) (docs/bounds.md)."""
    n, r = C.shape[-2:]
    if r == 0:
        return np.zeros(C.shape[:-2])[()]
    smin = np.linalg.svd(C, compute_uv=False)[..., -1]
    return 4.0 * np.sqrt(n * r) * np.asarray(weight) * np.asarray(defect) / smin


def curvature_error(E, xp=np):
    """‖E‖₂ <= √(‖E‖₁ ‖E‖∞) of the nonnegative entrywise error bound E (n, n) (sparse or dense) or (..., n, n) of the
    stiffness from rounding K^p + K^q (stiffness.ContactBlocks.curvature_error, in the metric's dofs): a bound of
    ‖ΔH̃‖₂ and so of ‖Δ sym(𝓗)‖₂ (P orthogonal). inf where a contact's pseudo-inverse is unresolved."""
    if sp.issparse(E):
        if not E.nnz:
            return 0.0
        return float(np.sqrt(abs(E).sum(axis=0).max() * abs(E).sum(axis=1).max()))
    if E.shape[-1] == 0:
        return xp.zeros(E.shape[:-2])[()]
    return xp.sqrt(E.sum(axis=-1).max(axis=-1) * E.sum(axis=-2).max(axis=-1))


def eigen_bounds(Hsym: np.ndarray, lam: np.ndarray, V: np.ndarray, formation: float):
    """Per-eigenvalue bounds δ (L, n) and residual norms ‖r_j‖ (L, n) of stacked eigh results (module docstring)."""
    n = lam.shape[-1]
    res = np.linalg.norm(Hsym @ V - V * lam[..., None, :], axis=-2)
    scale = abs_norm_inf(Hsym)
    return np.sqrt(2.0) * res + gamma(n + 2) * (scale[..., None] + np.abs(lam)) + formation, res


def vector_bounds(lam: np.ndarray, residuals: np.ndarray, scale: float, formation: float, n: int) -> np.ndarray:
    """The same bounds from given residual norms (the sparse path: Rayleigh quotients of the exact operator)."""
    return np.sqrt(2.0) * residuals + gamma(n + 2) * (scale + np.abs(lam)) + formation


def values_backward_error(scale, n: int):
    """The a-priori bound of eigenvalues computed without eigenvectors: γ_{n²}‖|A|‖∞ (value_bounds)."""
    return gamma(n * n) * scale


def value_bounds(lam: np.ndarray, scale, formation, n: int) -> np.ndarray:
    """Bounds for eigenvalues computed WITHOUT eigenvectors (LAPACK syevd, jobz = 'N'; the scan's clusters without
    sliding contacts), a priori instead of from residuals: the Householder reduction to tridiagonal form and the
    implicit QL iteration are backward stable, the computed eigenvalues exact for A + E with ‖E‖₂ <= p(n) ε ‖A‖₂
    (LAPACK Users' Guide §4.7.1; Golub & Van Loan §8.3), and p(n) is taken as n² (γ_{n²}, with ‖A‖₂ <= ‖|A|‖∞ =
    scale): a wider bound than a residual's, so fewer signs are resolved, never a wrong one."""
    return values_backward_error(scale, n) + gamma(n + 2) * (scale + np.abs(lam)) + formation


def resolved_sign(lam: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """+1 / -1 where the bound resolves the sign of λ, 0 where it does not (a zero within accuracy)."""
    return np.where(lam > bounds, 1, np.where(lam < -bounds, -1, 0)).astype(np.int8)


def tightened(lam, bounds, idx, U, resid, E, e_K: float, rest: float, eta):
    """Per-eigenvector bounds (docs/bounds.md, "Tighter where the gap allows"), min with the Weyl-type `bounds`.

    lam, bounds (..., m): every eigenvalue of the branch with its bound (a one-to-one match with the exact ones);
    idx (c,): the columns to tighten, U (..., n, c) their computed vectors, resid (..., c) bounds of their exact
    residuals ‖A u - λ u‖ (‖r̂‖ + its rounding), eta (..., c) bounds of ‖(I - P)u‖. The formation error splits into
    an entrywise part |ΔH̃| <= E (n, n; the curvature sum, ‖E‖ <= e_K) and the `rest` (2-norm). With the exact
    matrix A_t and θ_t = uᵀA_t u: |θ_t - λ| <= t = r + |u|ᵀE|u| + e_K(2η + η²) + rest, the residual of u for A_t is
    <= ρ = r + ‖E|u|‖ + e_K η + rest, and every other exact eigenvalue lies outside the others' intervals, at least
    g = min_{k≠j}(|λ_k - λ_j| - δ_k) - t from θ_t: if ρ < g the exact eigenvalue matched with λ_j is within ρ²/g of
    θ_t (Kato–Temple), so within t + ρ²/g of λ_j."""
    if len(idx) == 0 or not np.isfinite(e_K) or E is None:
        return bounds[..., idx]
    absU = np.abs(U)
    n, c = absU.shape[-2:]
    flat = np.moveaxis(absU, -2, 0).reshape(n, -1)
    EU = np.moveaxis(np.asarray(E @ flat).reshape((n,) + absU.shape[:-2] + (c,)), 0, -2)
    quad = np.sum(absU * EU, axis=-2) + e_K * (2 * eta + eta ** 2)
    t = resid + quad + rest
    rho = resid + np.linalg.norm(EU, axis=-2) + e_K * eta + rest
    others = np.abs(lam[..., None, :] - lam[..., idx, None]) - bounds[..., None, :]      # (..., c, m)
    np.put_along_axis(others, np.broadcast_to(np.asarray(idx)[:, None], others.shape[:-1] + (1,)).copy(), np.inf,
                      axis=-1)
    gap = others.min(axis=-1, initial=np.inf) - t
    new = np.where(gap > rho, t + rho ** 2 / np.where(gap > 0, gap, 1.0), np.inf)
    return np.minimum(bounds[..., idx], new)
