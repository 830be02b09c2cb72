"""Time budget of an analysis: an estimate from a measured per-branch cost, refusal of work that cannot finish in
the time asked, and a deadline that stops work that runs over (`granstab analyze --timeout`).

The dense path solves, per branch, an n×n symmetric eigenproblem, a non-symmetric one and an SVD, and forms
projections and residuals with a few matrix products (dense.py, mechanics/branches.py), batched over the 2^Ms
branches. Their cost is measured here on this machine, on a stack of random matrices of the same size (up to
MEASURE_DIM; larger sizes scale as n³), so the estimate follows the machine it runs on.
"""
from __future__ import annotations

import signal
import time
from contextlib import contextmanager

import numpy as np

MEASURE_DIM = 96       # matrices larger than this are timed at this size and scaled by (n / MEASURE_DIM)³
MEASURE_STACK = 4      # matrices timed at once (a few hundredths of a second in all)


class OverBudget(Exception):
    """The work does not fit the time asked; the message is one line saying what to do."""


def branch_seconds(n: int, stack: int = MEASURE_STACK) -> float:
    """Measured seconds per branch for n dofs: eigh + eig + SVD and four products of a stack of random n×n
    matrices, on one BLAS thread (a shared machine's threads give no more; measured here the real branches ran
    no faster than this)."""
    from .threads import blas_threads

    m = max(1, min(n, MEASURE_DIM))
    rng = np.random.default_rng(0)
    A = rng.standard_normal((stack, m, m))
    S = A + np.swapaxes(A, 1, 2)
    with blas_threads(1):
        np.linalg.eig(A[:1, :2, :2])                        # first call loads LAPACK: not part of the cost
        start = time.perf_counter()
        np.linalg.eigh(S)
        np.linalg.eig(A)
        np.linalg.svd(A, compute_uv=False)
        for _ in range(4):                                  # projections and the two eigen-residuals
            A @ S
        per = (time.perf_counter() - start) / stack
    return per * (n / m) ** 3


def estimate(n_dof: int, n_branches: int) -> float:
    """Estimated seconds for `n_branches` dense branches of `n_dof` dofs (one measurement, at most ~0.1 s)."""
    return n_branches * branch_seconds(n_dof, min(MEASURE_STACK, n_branches))


def refuse_over(source: str, seconds: float, timeout: float, n_dof: int, n_sliding: int) -> None:
    """Raise OverBudget (one line, with what to do) when the estimate exceeds the time asked."""
    if seconds <= timeout:
        return
    raise OverBudget(f"{source}: refused: 2^{n_sliding} = {2 ** n_sliding} branches of {n_dof} dofs need about "
                     f"{seconds:.3g} s on this machine (measured {1e3 * seconds / 2 ** n_sliding:.3g} ms a branch), "
                     f"more than the {timeout:.3g} s left of --timeout: cap the potentially sliding contacts (--max-sliding, or "
                     "state = \"elastic\" for contacts known to stick), analyse a smaller cluster around the region "
                     "of interest, or raise --timeout")


DENSE_ADVICE = ("cap the potentially sliding contacts (--max-sliding), use --method sparse with a small --k, "
                "analyse a smaller cluster, or raise --timeout")
SPARSE_ADVICE = ("lower --k, cap the potentially sliding contacts (--max-sliding), one metric instead of the family "
                 "(--metric L), analyse a smaller cluster, or raise --timeout")


@contextmanager
def deadline(seconds: float | None, source: str, advice: list):
    """Stop the enclosed work with OverBudget after `seconds` of wall time (SIGALRM; main thread only, where the
    CLI runs; elsewhere, or with None, no deadline). `advice[0]` (which the caller may update once it knows the
    path taken) ends the message."""
    import threading
    if not seconds or threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum, frame):
        raise OverBudget(f"{source}: stopped after --timeout {seconds:g} s, unfinished; {advice[0]}")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
