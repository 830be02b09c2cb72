"""BLAS threads chosen by call size: one thread for stacks of small matrices, every core for big factorizations.

numpy/scipy's OpenBLAS starts its thread pool for every LAPACK call, even on a 27×27 matrix; for a stack of
thousands of small eigenproblems (the loading branches, the clusters of a scan) that costs far more than the
arithmetic, and on a machine busy with other work a two-thread pool waits for a core at every call (measured here:
4096 stacked 27×27 `eigh` 0.36 s single-threaded against 1.2-6.4 s with two threads on a loaded machine). Big
factorizations (dense n ≳ 100, sparse LU and ARPACK on large clusters) are the opposite: they gain from every core.

`for_size(n)` is the policy, `blas_threads(n)` applies a limit for a block with threadpoolctl when it is installed
(the app, test and report extras bring it); without it the block runs unchanged, so the core needs only numpy and
scipy.
"""
from __future__ import annotations

import os
from contextlib import nullcontext
from functools import cache

try:
    from threadpoolctl import ThreadpoolController
except ImportError:  # pragma: no cover - the optional speed-up is absent
    ThreadpoolController = None

SMALL = 96   # matrices up to this size: one BLAS thread (a LAPACK call on them takes < 1 ms; a pool costs more)


def cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def for_size(n: int) -> int:
    """BLAS threads for dense work on n×n matrices: 1 up to SMALL, every core above."""
    return 1 if n <= SMALL else cores()


@cache
def _controller():
    """One ThreadpoolController for the process: making one scans every loaded library (2.3 ms, measured: 8 % of a
    10⁵-particle scan when made per call). scipy.linalg is imported first so that its BLAS, which may be another
    library than numpy's, is among them."""
    import scipy.linalg  # noqa: F401
    return ThreadpoolController()


def blas_threads(n: int | None):
    """A context limiting BLAS to n threads (n None, or threadpoolctl absent: no limit)."""
    if n is None or ThreadpoolController is None:
        return nullcontext()
    return _controller().limit(limits=n, user_api="blas")


def sized(n: int):
    """`blas_threads(for_size(n))`: the policy applied for a block of work on n×n matrices."""
    return blas_threads(for_size(n))
