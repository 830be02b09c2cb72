"""Where a scan runs when the user does not say, what each way needs installed, and a quiet Ctrl-C on Dask.

The default (issue 26: one Dask worker per core made a scan 2–20× slower than `--workers 1` on a busy 2-core
machine): the first clusters run in this process and measure a cluster's cost; the rest, estimated at S seconds of
serial compute, stay in this process when S < PARALLEL_SECONDS, and otherwise run on

    W = min(cores this process may use (os.sched_getaffinity),
            round(those cores − the 1-minute load average),     # the cores other processes leave idle
            ceil(S / WORKER_SECONDS))                            # each worker gets enough work to pay its start

local Dask workers; in this process when W is 1, or when Dask is not installed (said so). A GPU scan stays in this
process (workers would share the one GPU). `--workers N` and `--scheduler` are taken as given.
"""
from __future__ import annotations

import logging
import math
import os
import signal
import threading
import time
from contextlib import contextmanager, suppress

from ..model.errors import require

PARALLEL_SECONDS = 10.0   # serial work below which Dask does not pay: starting a local cluster takes seconds
                          # (spawning processes that import numpy, scipy and granstab: ~3 s for 2 workers measured
                          # here at rest, more under load), and each task costs ~20 ms of scheduling
WORKER_SECONDS = 5.0      # least estimated work a worker is started for


def machine() -> tuple[int, float]:
    """(cores this process may run on, the 1-minute load average; 0 where the system has none)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        load = 0.0
    return cores, load


def default_workers(seconds: float, cores: int, load: float, dask: bool = True) -> tuple[int, str]:
    """(workers, why in words) for the rest of a scan estimated at `seconds` of serial compute (module docstring)."""
    if seconds < PARALLEL_SECONDS:
        return 1, (f"the rest was estimated at {seconds:.2g} s of work, under the {PARALLEL_SECONDS:g} s that pays "
                   "for starting Dask workers")
    idle = int(math.floor(cores - load + 0.5))
    n = max(1, min(cores, idle, math.ceil(seconds / WORKER_SECONDS)))
    if n == 1:
        return 1, f"{cores} core(s) here at load {load:.1f}: none idle for a second worker"
    if not dask:
        return 1, "Dask is not installed (pip install \"granstab[scan]\" for parallel workers)"
    return n, (f"{cores} core(s) here at load {load:.1f}, ~{seconds:.2g} s of work: one worker per idle core, "
               f"at least {WORKER_SECONDS:g} s of work each")


def dask_installed() -> bool:
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        return False
    return True


def require_extras(scheduler: str | None, workers: int | None, figures: bool) -> None:
    """MissingExtra (one line naming the extra) for what this scan needs and lacks, before its folder is made:
    pyarrow (the tables), matplotlib (the map, unless figures=False), Dask (--workers N > 1, --scheduler)."""
    require("pyarrow", "scan", "the scan's tables")
    if figures:
        require("matplotlib", "scan", "the scan's map")
    if scheduler is not None or (workers or 1) > 1:
        require("dask.distributed", "scan", "--scheduler" if scheduler is not None else f"--workers {workers}")


@contextmanager
def sigint_held():
    """Processes started inside (Dask's workers) never get Ctrl-C: SIGINT is blocked in this thread meanwhile, and a
    child keeps its parent thread's signal mask across exec (the threads Dask starts here, which spawn them, inherit
    the mask). Ctrl-C at a terminal reaches the whole process group, and only this process should answer
    it (one line), not every worker with its tracebacks. A Ctrl-C meanwhile is held, not lost: it reaches this
    process's handler (sigint_flag's) through another thread, or when the block ends. It was ignored here
    (SIG_IGN) before, and a Ctrl-C in the 3-8 s of a cluster's start was lost: the scan ran on. Main thread only,
    where signals can be masked (elsewhere: no change)."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    from multiprocessing import resource_tracker
    resource_tracker.ensure_running()       # started later, it would unblock SIGINT in this thread (its own start)
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextmanager
def sigint_flag():
    """Ctrl-C sets the Event this yields instead of raising, and a second Ctrl-C raises: a KeyboardInterrupt
    raised in the main thread while it runs one of Dask's garbage-collector callbacks is printed and swallowed,
    and the scan went on. The Dask loop checks the Event between results. Main thread only (elsewhere an Event
    that Ctrl-C never sets)."""
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def stop_soon(signum, frame):
        if stop.is_set():
            raise KeyboardInterrupt
        stop.set()

    previous = signal.signal(signal.SIGINT, stop_soon)
    try:
        yield stop
    finally:
        signal.signal(signal.SIGINT, previous)


def finished(running, stop, poll: float):
    """The futures of `running` (Dask's as_completed) as they finish, polling every `poll` seconds when none is
    ready; KeyboardInterrupt once `stop` (sigint_flag's Event) is set."""
    while not running.is_empty():
        if stop.is_set():
            raise KeyboardInterrupt
        batch = running.next_batch(block=False)
        if not batch:
            time.sleep(poll)
            continue
        yield from batch


LOGGERS = ("distributed", "tornado", "asyncio")


def silence(levels: list | None = None) -> list:
    """Set Dask's loggers (and those of its event loops) above CRITICAL; `levels`: set them back to these instead.
    Returns the levels they had."""
    loggers = [logging.getLogger(name) for name in LOGGERS]
    before = [lg.level for lg in loggers]
    for lg, level in zip(loggers, levels or [logging.CRITICAL + 1] * len(loggers)):
        lg.setLevel(level)
    return before


def close_quietly(client, cluster) -> None:
    """After Ctrl-C: close the Dask client and the local cluster with Dask's logging off, here and in the workers
    (their warnings about tasks cancelled mid-run are not the user's business), whatever they raise. A cluster
    reached by --scheduler (cluster None) keeps its workers' logging; either None: not made yet."""
    before = silence()
    try:
        if cluster is not None and client is not None:
            with suppress(Exception):
                client.run(silence)
        for owner in (client, cluster):
            if owner is not None:
                with suppress(Exception):
                    owner.close()
    finally:
        silence(before)
