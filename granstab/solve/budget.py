"""Time budget of an analysis: an estimate from a measured per-branch cost, refusal of work that cannot finish in
the time asked, and a deadline that stops work that runs over (`granstab analyze --timeout`).

The full dense path solves, per branch, an n×n symmetric eigenproblem, a non-symmetric one and an SVD, and forms
projections and residuals with a few matrix products (dense.py, mechanics/branches.py); the low-rank path an n×n
symmetric eigenproblem, a Gram matrix's eigenvalues and a few products (lowrank.py); both are repeated for every
metric of the family. Their cost is measured here on this machine, on a stack of random matrices of the same
size (up to MEASURE_DIM; larger sizes scale as n³), in CPU time, so the estimate follows the machine it runs on
but not its load of the moment.
"""
from __future__ import annotations

import math
import signal
import time
from contextlib import contextmanager

import numpy as np

MEASURE_DIM = 160      # matrices larger than this are timed at this size and scaled by (n / MEASURE_DIM)³
MEASURE_STACK = 4      # matrices timed at once (a few tenths of a second in all, only for work that may be long)
ASK_SECONDS = 10.0     # without --timeout, the CLI refuses work estimated longer than this (one line, what to do)
TRIVIAL_WORK = 2e7     # metrics · branches · n³ below this is certainly under a second: nothing is measured


class OverBudget(Exception):
    """The work does not fit the time asked; the message is one line saying what to do."""


def branch_seconds(n: int, stack: int = MEASURE_STACK, lowrank: bool = False) -> float:
    """Measured seconds per branch for n dofs on one BLAS thread (a shared machine's threads give no more; the
    branch paths run one thread a core), in CPU time: the time on this machine's cores when they are free, so that
    what is refused does not depend on the load of the moment (a loaded machine takes longer; the heartbeat says
    so, and --timeout's deadline stops it). Full path (dense.py): eigh + eig + SVD and four products of a stack of
    random n×n matrices; low-rank path (lowrank.py): eigh, the Gram matrix's eigvalsh and three products."""
    from .threads import blas_threads

    m = max(1, min(n, MEASURE_DIM))
    rng = np.random.default_rng(0)
    A = rng.standard_normal((stack, m, m))
    S = A + np.swapaxes(A, 1, 2)
    with blas_threads(1):
        np.linalg.eig(A[:1, :2, :2])                        # first call loads LAPACK: not part of the cost
        start = time.thread_time()                          # CPU time: what a core gives, whatever the load
        np.linalg.eigh(S)
        if lowrank:
            np.linalg.eigvalsh(S)
        else:
            np.linalg.eig(A)
            np.linalg.svd(A, compute_uv=False)
        for _ in range(3 if lowrank else 4):                # projections, residuals, Gram matrix, signs
            A @ S
        per = (time.thread_time() - start) / stack
    return per * (n / m) ** 3


def estimate(n_dof: int, n_branches: int, n_metrics: int = 1, lowrank: bool = False, workers: int = 1) -> float:
    """Estimated seconds for `n_branches` dense branches of `n_dof` dofs in each of `n_metrics` metrics (the
    family repeats every branch per metric), on the full or the low-rank path (`workers` cores share the low-rank
    branches). One measurement, at most a few tenths of a second, skipped (0) for trivially small work."""
    if n_metrics * n_branches * float(n_dof) ** 3 < TRIVIAL_WORK:
        return 0.0
    per = branch_seconds(n_dof, min(MEASURE_STACK, n_branches), lowrank)
    return n_metrics * n_branches * per / (max(workers, 1) if lowrank else 1)


def refuse_over(source: str, seconds: float, timeout: float | None, work: str, alternatives: str = "") -> None:
    """Raise OverBudget (one line, with what to do) when the estimate exceeds the time asked (`timeout`; None: the
    CLI's ASK_SECONDS, which --timeout lifts)."""
    limit = ASK_SECONDS if timeout is None else timeout
    if seconds <= limit:
        return
    asked = (f"more than the {limit:.3g} s a run takes without --timeout: give --timeout {math.ceil(1.2 * seconds)} "
             "to run it (a line a minute on stderr says where it is), or " if timeout is None else
             f"more than the {limit:.3g} s left of --timeout: ")
    raise OverBudget(f"{source}: refused: {work} need about {seconds:.3g} s on this machine's free cores, {asked}"
                     f"{alternatives}cap the potentially sliding contacts (--max-sliding, or state = \"elastic\" for "
                     "contacts known to stick), analyse a smaller cluster around the region of interest"
                     + (", or raise --timeout" if timeout is not None else ""))


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
