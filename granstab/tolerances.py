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
