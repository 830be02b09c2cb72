"""The explorer's compute pools: where an analysis runs (this thread on one BLAS thread, or a worker process of the
server's pool, shared by every session), and the metric-family check. Pure (no viser); app/state.py calls them.
"""
from __future__ import annotations

import hashlib
import os
import pickle
import threading
import time
from collections import OrderedDict

from granstab.analysis import analyze
from granstab.solve.threads import blas_threads

MAX_SLIDING = 16           # contacts at yield enumerated (2^16 branches); more: SAMPLED random branches
SAMPLED = 32
SAMPLED_LARGE = 2          # random branches on the sparse path (over DENSE_MAX_DOF dofs): each costs a shift-invert
                           # eigensolve (~10 s at the annulus's 4,851 dofs), 32 of them minutes: the page waited on
OFFLOAD = 50               # particles: from here a server's session analyses in a worker process (analysis_pool)
_POOL: list = []           # the worker processes, made when first needed (analysis_pool)
WORKER_NICE = 10           # the workers' priority below the server's (os.nice steps: 10 of 19)
SHARED = 16                # offloaded analyses kept for every session (shared): ~3 MB each at annulus_frame's 143 disks
_SHARED: OrderedDict = OrderedDict()     # (scene, metric) digest → Analysis, the most recently used last
_SHARED_LOCK = threading.Lock()


def analysed(scene, metric: str, attribution: bool = True):
    """The analysis on one BLAS thread (small problems: thread start-up costs more than it saves). More than
    MAX_SLIDING contacts at the friction limit (2^Ms branches: 2^85 on RigidLibrary's 1,617-disk annulus) are
    analysed on the sampled path (`sampled`), which proves instability only; the page says so."""
    with blas_threads(1):
        return analyze(scene, metric=metric, max_sliding=MAX_SLIDING, attribution=attribution,
                       sample_branches=samples(scene))


def attributed(analysis) -> bool:
    """Give an unstable `analysis` made without it its attribution (granstab.analysis.attribute: why it is unstable;
    half of a pair's analysis time, so the explorer sends the verdict first). Whether it changed."""
    from granstab.analysis import attribute
    if analysis.verdict.verdict != "unstable" or analysis.attribution is not None or analysis.backend != "dense":
        return False
    with blas_threads(1):
        try:
            analysis.attribution = attribute(analysis, max_sliding=MAX_SLIDING,
                                             sample_branches=samples(analysis.scene))
        except ValueError:                  # no consistent negative eigenpair among the kept branches
            return False
    return True


def sampled(scene) -> bool:
    """Whether `scene` has too many contacts at the friction limit to enumerate its branches."""
    return scene.n_contacts > 0 and int(scene.at_yield().sum()) > MAX_SLIDING


def samples(scene) -> int | None:
    """How many random branches the sampled path tries on `scene` (None: its branches are enumerated): SAMPLED,
    SAMPLED_LARGE above DENSE_MAX_DOF dofs (the sparse path, where each branch is an eigensolve of its own)."""
    from granstab.solve.sparse import DENSE_MAX_DOF
    if not sampled(scene):
        return None
    return SAMPLED if scene.n_dof <= DENSE_MAX_DOF else SAMPLED_LARGE


def offloaded(scene, metric: str):
    """`analysed` in a worker process of analysis_pool: a server's large analyses (annulus_frame: ~1 s of mostly
    Python) then hold another process's GIL, not the one the server's other tabs answer from (benchmarks/classroom.py:
    a pair's slider move waited seconds behind them). A worker that died is replaced at the next call."""
    from concurrent.futures.process import BrokenProcessPool
    try:
        return analysis_pool().submit(analysed, scene, metric).result()
    except BrokenProcessPool:
        close_pool()
        raise


def shared(scene, metric: str):
    """`offloaded`, once for every session of the server: an analysis is kept (the SHARED most recently used) by a
    digest of its scene and metric, so that a class moving annulus_frame's μ through the same slider steps has each
    step analysed once. Analyses are read-only once made (a Session's own caches, motions and modes, are its own);
    two sessions asking at once for the same new scene both analyse it."""
    key = hashlib.sha256(pickle.dumps((scene, metric), protocol=pickle.HIGHEST_PROTOCOL)).digest()
    with _SHARED_LOCK:
        if key in _SHARED:
            _SHARED.move_to_end(key)
            return _SHARED[key]
    analysis = offloaded(scene, metric)
    with _SHARED_LOCK:
        _SHARED[key] = analysis
        while len(_SHARED) > SHARED:
            _SHARED.popitem(last=False)
    return analysis


def analysis_pool():
    """Worker processes for offloaded analyses, one per core (spawned: the server runs threads, which fork would copy
    half-way), at a lower priority (WORKER_NICE) than the server: on a busy machine a core goes first to the server's
    process, which answers every page (its event loop, the small scenes' analyses), then to the large analyses
    (benchmarks/classroom.py: 5 annulus_frame pages kept both cores busy and a pair's move waited behind them)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from granstab.solve.threads import cores
    if not _POOL:
        _POOL.append(ProcessPoolExecutor(max_workers=cores(), mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_lower_priority))
    return _POOL[0]


def _lower_priority() -> None:
    """A worker's start: WORKER_NICE steps below the server (where the system lets a process lower itself)."""
    if hasattr(os, "nice"):
        os.nice(WORKER_NICE)


def close_pool() -> None:
    """Stop the worker processes and drop the shared analyses (the server's stop; a later offloaded analysis starts
    new ones)."""
    while _POOL:
        _POOL.pop().shutdown(wait=False, cancel_futures=True)
    with _SHARED_LOCK:
        _SHARED.clear()


def metric_family(scene) -> dict:
    """The verdict of `scene` in every metric of the family (granstab.analyze, metric="family"), on one BLAS thread:
    {"robust", "metrics", "time"}. Pure: it may run off the session's lock while the page moves on."""
    start = time.perf_counter()
    with blas_threads(1):
        family = analyze(scene, metric="family", attribution=False).verdict
    return {"robust": family.metric_robust is True, "metrics": [e.to_dict() for e in family.metrics],
            "time": time.perf_counter() - start}
