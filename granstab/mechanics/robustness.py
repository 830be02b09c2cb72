"""Metric robustness proven, not sampled (issue 26; docs/bounds.md#metric-robustness).

A metric M (SPD, the dofs' weighting) fixes which complement of the rigid motions R the spectrum of sym(𝓗^i) lives
on: W(M) = {U : Rᵀ M U = 0}, the M-orthogonal complement of R (the span of R, translations and rotations, does not
depend on M or on the centre of the rotations). The eigenvalues of sym(𝓗^i) depend on M; their SIGNS are the
inertia of the quadratic form S_i = sym(H^i) restricted to W(M) (Sylvester: any basis of W(M) gives it). So:

* over EVERY SPD metric: S_i is positive on every complement of R iff uᵀ S_i u > 0 for every u ∉ R, i.e. S_i ⪰ 0
  with null space exactly the translations (S_i T = 0 always; S_i C ≠ 0 in general): branch i is stable in every
  metric. With n₋ negative eigenvalues of S_i, every W(M) has at least n₋ - r of them (r rotations: W is of
  codimension r in the complement of the translations, Cauchy interlacing): n₋ > r makes the branch unstable in
  every metric. Otherwise the signs depend on the metric.
* over the one-parameter family of rotation lengths L (D = diag(1, 1/L), so M(L) = diag(1, L²) per particle, the
  family L/10, L, 10L of metric.py and every L between): in the dofs of a reference L₀, M(s) = M_T + s M_R with
  s = (L/L₀)², and S_i restricted to W(s) is singular iff the bordered matrix B(s) = [[S_i, M(s)R], [RᵀM(s), 0]] is.
  B(s) = B(1) + (s - 1) U Vᵀ with rank 2r, so its zeros are s = 1 - 1/μ for the real eigenvalues μ of the 2r × 2r
  matrix Vᵀ B(1)⁻¹ U: the only rotation lengths where an eigenvalue of branch i crosses zero. Between consecutive
  crossings every branch's inertia is constant; it is evaluated once per interval.

A verdict follows from inertia where consistency (Appendix D) does not enter: stable when every branch is positive
definite; unstable when a branch has a negative eigenvalue and the cluster has no potentially sliding contact (one
elastic branch: every eigenvector is consistent). Elsewhere the verdict rests on the eigenvectors' consistency,
which inertia does not decide: that interval is undetermined. The inertia metric (kinetic energy, M = mass matrix)
is one SPD metric: decided by the first classification, or by its own computed verdict.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.tolerances import EPS
from .accuracy import abs_norm_inf, values_backward_error
from .branches import branch_matrices

MAX_WORK = 4e9            # branches × n³ beyond which the scan is not attempted (undetermined): ~1 s of LAPACK


@dataclass(frozen=True)
class Robustness:
    """The proven answer: `robust` True / False / "undetermined"; `everywhere` the verdict that holds in every SPD
    metric (None if none is proven); `intervals` [(L_low, L_high, verdict or None)] over (0, ∞) of the rotation
    length; `flips` the rotation lengths where the proven verdict changes."""

    robust: object
    everywhere: str | None
    intervals: tuple
    flips: tuple


def _signs(A: np.ndarray, formation: float) -> tuple[np.ndarray, np.ndarray]:
    """(n₋, n₀) per matrix of a stack of symmetric A (..., k, k): eigenvalues below/within their a-priori bound
    (accuracy.value_bounds without the γ_{n+2} term: no vectors) are negative / unresolved."""
    lam = np.linalg.eigvalsh(A)
    k = A.shape[-1]
    scale = abs_norm_inf(A)
    bound = values_backward_error(scale, k)[..., None] + formation + 4 * k * EPS * np.abs(lam)
    return np.sum(lam < -bound, axis=-1), np.sum(np.abs(lam) <= bound, axis=-1)


def _selectors(n: int, per: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """M_T, M_R (n,): 1 on translation / rotation dofs."""
    rot = np.tile(np.r_[np.zeros(d), np.ones(per - d)], n // per)
    return 1.0 - rot, rot


def complement(R: np.ndarray, m: np.ndarray) -> np.ndarray:
    """An orthonormal basis (n, n - k) of W = {w : Rᵀ diag(m) w = 0}."""
    Q, _ = np.linalg.qr(m[:, None] * R, mode="complete")
    return Q[:, R.shape[1]:]


def crossings(S: np.ndarray, R: np.ndarray, d: int, per: int) -> tuple[np.ndarray, bool]:
    """The s = (L/L₀)² > 0 where some S_i (B, n, n) restricted to W(s) is singular (module docstring), sorted, and
    whether B(1) was invertible for every branch (False: the reference metric itself is singular: undetermined)."""
    B, n, _ = S.shape
    k = R.shape[1]
    mT, mR = _selectors(n, per, d)
    rot = np.flatnonzero(np.abs(mR[:, None] * R).max(axis=0) > 0)        # the columns of R that rotate
    r = len(rot)
    Z = (mR[:, None] * R)[:, rot]                                       # (n, r)
    M1 = (mT + mR)[:, None] * R
    big = np.zeros((B, n + k, n + k))
    big[:, :n, :n] = S
    big[:, :n, n:] = M1
    big[:, n:, :n] = M1.T
    E = np.zeros((k, r))
    E[rot, np.arange(r)] = 1.0
    U = np.zeros((n + k, 2 * r))
    U[:n, :r], U[n:, r:] = Z, E
    V = np.zeros((n + k, 2 * r))
    V[n:, :r], V[:n, r:] = E, Z
    try:
        X = np.linalg.solve(big, np.broadcast_to(U, (B, n + k, 2 * r)))
    except np.linalg.LinAlgError:
        return np.zeros(0), False
    mu = np.linalg.eigvals(V.T @ X).ravel()
    real = mu[(np.abs(mu.imag) <= 1e-8 * np.abs(mu)) & (mu.real != 0)].real
    s = 1.0 - 1.0 / real
    return np.unique(s[(s > 0) & np.isfinite(s)]), True


def _interval_verdicts(S, R, d, per, formation, s_points, elastic_only: bool) -> list:
    """The verdict decided by inertia at each s of `s_points` (or None: it rests on consistency / unresolved)."""
    n = S.shape[-1]
    mT, mR = _selectors(n, per, d)
    out = []
    for s in s_points:
        Q = complement(R, mT + s * mR)
        neg, zero = _signs(np.swapaxes(Q, -1, -2) @ S @ Q, formation)
        if np.any(zero):
            out.append(None)
        elif not np.any(neg):
            out.append("stable")
        else:
            out.append("unstable" if elastic_only else None)
    return out


def everywhere(S: np.ndarray, R: np.ndarray, d: int, formation: float, elastic_only: bool) -> str | None:
    """The verdict proven for EVERY SPD metric by the inertia of S_i off the translations (module docstring)."""
    n = S.shape[-1]
    T = R[:, :d]
    Q = complement(T, np.ones(n))
    neg, zero = _signs(np.swapaxes(Q, -1, -2) @ S @ Q, formation)
    r = R.shape[1] - d
    if np.all(neg == 0) and np.all(zero == 0):
        return "stable"
    if elastic_only and np.all(zero == 0) and np.any(neg > r):
        return "unstable"
    return None


def metric_robustness(problem, masks: np.ndarray, d: int, per: int, length: float, entries) -> Robustness:
    """The proven answer over the metrics (module docstring) for the branches `masks` of `problem` (the dense
    problem in the L₀ = `length` metric's dofs; Ms = 0 when no contact may slide); `entries` (MetricVerdict) the
    family's computed verdicts (each one proven where `sufficient`)."""
    proven = {e.verdict for e in entries if e.sufficient}
    n = problem.H_el.shape[0]
    if problem.rigid.shape[1] == 0 or len(masks) * float(n) ** 3 > MAX_WORK:   # supports, or too much work
        return Robustness(False if len(proven) > 1 else "undetermined", None, (), ())
    H = branch_matrices(problem, masks)[0]
    S = 0.5 * (H + np.swapaxes(H, -1, -2))
    R, formation = problem.rigid, problem.formation_error
    elastic_only = len(problem.sliding) == 0
    all_metrics = everywhere(S, R, d, formation, elastic_only)
    if all_metrics is not None:
        return Robustness(True, all_metrics, ((0.0, np.inf, all_metrics),), ())
    s_roots, regular = crossings(S, R, d, per)
    if not regular:
        return Robustness(False if len(proven) > 1 else "undetermined", None, (), ())
    edges = np.r_[0.0, s_roots, np.inf]
    points = [s_roots[0] / 4 if len(s_roots) else 1.0] + [np.sqrt(a * b) for a, b in zip(s_roots[:-1], s_roots[1:])]
    points += [4 * s_roots[-1]] if len(s_roots) else []
    verdicts = _interval_verdicts(S, R, d, per, formation, points, elastic_only)
    L = length * np.sqrt(edges)
    intervals = tuple((float(a), float(b), v) for a, b, v in zip(L[:-1], L[1:], verdicts))
    decided = {v for v in verdicts if v is not None}
    flips = tuple(float(L[i + 1]) for i in range(len(verdicts) - 1)
                  if verdicts[i] is not None and verdicts[i + 1] is not None and verdicts[i] != verdicts[i + 1])
    others = {e.verdict for e in entries if e.sufficient and e.rotation_length is None}   # the inertia metric
    if len(decided | proven) > 1:
        robust = False
    elif None not in verdicts and not (len(others) == 0 and any(e.rotation_length is None for e in entries)):
        robust = True
    else:
        robust = "undetermined"
    return Robustness(robust, None, intervals, flips)
