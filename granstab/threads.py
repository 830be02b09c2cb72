"""BLAS threads for stacks of small matrices.

numpy/scipy's OpenBLAS starts its thread pool for every LAPACK call, even on a 27×27 matrix; for a stack of
thousands of small eigenproblems (the loading branches) that costs far more than the arithmetic (measured here:
4096 stacked 27×27 `eigh` 0.36 s single-threaded against 1.2-6.4 s with two threads on a loaded machine).
`blas_threads(n)` limits the BLAS thread pools for the duration of a block with threadpoolctl when it is
installed (the app, test and report extras bring it); without it the block runs unchanged, so the core needs
only numpy and scipy.
"""
from __future__ import annotations

from contextlib import nullcontext

try:
    from threadpoolctl import threadpool_limits
except ImportError:  # pragma: no cover - the optional speed-up is absent
    threadpool_limits = None


def blas_threads(n: int | None):
    """A context limiting BLAS to n threads (n None, or threadpoolctl absent: no limit)."""
    if n is None or threadpool_limits is None:
        return nullcontext()
    return threadpool_limits(limits=n, user_api="blas")
