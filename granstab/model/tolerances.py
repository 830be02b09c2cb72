"""Every tolerance of granstab in one place, each with the scale it is relative to.

Input tolerances decide whether a scene file is accepted; numerical tolerances decide
how computed numbers are read (zero eigenvalues, signs of S, pseudo-inverse cut-off).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Tolerances:
    """Relative tolerances; the scale of each is named in its comment."""

    input_rtol: float = 1e-6   # |n|-1, K·n (vs |K|), K-K^T (vs |K|), load balance (vs Σ|f| of the particle)
    yield_rtol: float = 1e-9   # Q within yield_rtol·|f| of 0 counts as "at yield" (eq:yield)
    pinv_rtol: float = 1e-10   # eigenvalues of K^p+K^q below pinv_rtol·max(|K^p|,|K^q|) are cut (eq:rolling)
    zero_factor: float = 64.0  # singular values of ℍ^i <= zero_factor·n·eps·‖ℍ‖₂ count as zero (its null space);
    #                            eigenvalues of sym(𝓗^i) are judged by their own accuracy bounds (accuracy.py)
    s_rtol: float = 1e-8       # |S| <= s_rtol·max|g|·max|δu_def| counts as S = 0 (eq:flow)

    def zero_tol(self, norm: float, n: int) -> float:
        """Absolute zero-eigenvalue tolerance for an n×n matrix of 2-norm `norm` (round-off level)."""
        return self.zero_factor * max(n, 1) * EPS * norm


DEFAULT = Tolerances()

# Accepted input ranges (scene.check_ranges). H, its identity checks and the eigen-solvers' norms multiply up to six
# input numbers (e.g. the squared norm of k·α·r·r/L²), so with every |value| <= 1e50 no product passes 1e300, below
# float64's 1.8e308; k, α and the mean contact radius L at least 1e-50 keep such products clear of underflow
# (2.2e-308). Coordinates: r^pq = point - x is rounded to eps·|x|; with |x| <= 1e9·L that is below
# 2.3e-7·L < input_rtol·L, so every contact radius is known to the input tolerance.
MAX_MAGNITUDE = 1e50
MIN_SCALE = 1e-50
COORDINATE_RATIO = 1e9
