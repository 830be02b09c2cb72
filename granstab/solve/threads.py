"""BLAS threads chosen by call size: one thread for stacks of small matrices, every core for big factorizations.

numpy/scipy's OpenBLAS starts its thread pool for every LAPACK call, even on a 27×27 matrix; for a stack of
thousands of small eigenproblems (the loading branches, the clusters of a scan) that costs far more than the
arithmetic, and on a machine busy with other work a two-thread pool waits for a core at every call (measured here:
4096 stacked 27×27 `eigh` 0.36 s single-threaded against 1.2-6.4 s with two threads on a loaded machine). Big
factorizations (dense n ≳ 100, sparse LU and ARPACK on large clusters) are the opposite: they gain from every core.

`for_size(n)` is the policy, `blas_threads(n)` applies a limit for a block with threadpoolctl when it is installed
(the app, test and report extras bring it); without it the block runs unchanged, so the core needs only numpy and
scipy. A limit is an upper bound for the blocks nested in it (in the same thread): `with blas_threads(1):` around a
call keeps it on one thread even where the call's own `sized(n)` would take every core (before, the explorer's
one-thread limit was lifted inside every dense analysis of more than SMALL dofs, and on a busy 2-core machine the
two-thread pool waiting for a core made a 0.3 s analysis 18× slower, where a fair share predicts 3×).
`cap_process(n)` bounds every block of the process (a server of many small sessions: app/server.py). Above SMALL the
threads are the FREE cores (`free_cores`: the cores less the other runnable threads at this process's priority,
read from /proc when the block starts), so that a busy machine gets one thread, not two that wait for each other (issue 38: 26× slower).

The rule for results: the thread count may change round-off, never what is reported. Above SMALL dofs the full
path keeps every core (the speed of 900 × 900 branches), and every discrete output is taken from quantities whose
round-off it cannot cross: signs by the per-eigenvalue bounds (accuracy.py), eigenvector signs by one canonical rule
with a tie margin (branches.column_signs). tests/solve/test_backend.py analyses a 147-dof packing on 1 and 2 threads
(verdict, counts, codes equal; eigenvalues within their bounds; isolated eigenvectors equal to 1e-8), and
tests/paper/test_reproduce.py the paper's tables with 1 and 2 threads, two OpenBLAS kernels and a busy core.
"""
from __future__ import annotations

import os
import time
from collections import Counter
from contextlib import contextmanager, nullcontext
from contextvars import ContextVar
from functools import cache
from pathlib import Path

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


_bound: ContextVar[int | None] = ContextVar("granstab_blas_bound", default=None)   # the enclosing block's limit
_process_cap: int | None = None                                                    # cap_process


def bound() -> int | None:
    """The most BLAS threads a block may take here: the enclosing limit or the process cap (None: no bound)."""
    limits = [n for n in (_bound.get(), _process_cap) if n is not None]
    return min(limits) if limits else None


RUNNABLE_SECONDS = 2.0   # `runnable` is read at most this often (a scan of /proc: ~15 ms for 600 threads)
FRESH_SAMPLES = 5        # a fresh read (a plan's, once a run) averages this many scans, SAMPLE_GAP s apart: one scan
SAMPLE_GAP = 0.02        # sees the threads that happen to be ready at that instant (measured on this shared machine:
                         # 6 and 9 in two scans a second apart with two busy processes started between; the plan
                         # estimated 1.1× more for a run that took 6.6× longer, 3.4× its estimate)
_runnable_cache = [-1.0, 0.0, 1.0]   # when read, ready threads of others, slowdown (`slowdown`)
FRESH_SECONDS = 1.0      # a fresh read is reused this long while it is the last read: a plan reads the load three
                         # times and the explorer's pair moves several times a second (5 scans each cost its slider
                         # move 0.3 s at load 6, its analysis 0.02 s: the page's 100 ms goal, issue 36)
_fresh_at = [-1.0]       # when the last fresh read was made


def runnable(fresh: bool = False) -> float:
    """Threads of other processes running or waiting for a core now at this process's priority or above (nice <= its
    own, from /proc/*/task/*/stat; re-read every RUNNABLE_SECONDS): what takes a core from this one. Niced
    background work is left out, since it yields (the 1-minute load average counts it: a shared machine at load
    10 of niced work ran an analysis at full speed, and an estimate scaled by that load was 5× too high). Without
    /proc: the 1-minute load average less this process. fresh: read now (a plan: once a run), the mean of
    FRESH_SAMPLES scans, not within RUNNABLE_SECONDS of the last read (the BLAS policy, at every dense call: one
    scan); a fresh read within FRESH_SECONDS of the last one, if nothing read since, is that one. The same scans
    give `slowdown`."""
    now = time.monotonic()
    if not fresh and now - _runnable_cache[0] < RUNNABLE_SECONDS:
        return _runnable_cache[1]
    if fresh and _runnable_cache[0] == _fresh_at[0] and now - _fresh_at[0] < FRESH_SECONDS:
        return _runnable_cache[1]
    try:
        counts, slow = [], []
        for i in range(FRESH_SAMPLES if fresh else 1):
            if i:
                time.sleep(SAMPLE_GAP)
            others = ready()
            counts.append(len(others))
            slow.append(group_slowdown([g for _, g in others], _group(os.getpid()), cores()))
            if not others and i == 0:
                break                                   # nobody else ready: no more scans (an idle machine)
        count, factor = sum(counts) / len(counts), sum(slow) / len(slow)
    except OSError:  # pragma: no cover - not Linux
        try:
            count = max(os.getloadavg()[0] - 1, 0.0)
        except OSError:
            count = 0.0
        factor = max(1.0, (count + 1) / cores())
    _runnable_cache[:] = [time.monotonic(), max(float(count), 0.0), factor]
    if fresh:
        _fresh_at[0] = _runnable_cache[0]
    return _runnable_cache[1]


def ready() -> list[tuple[int, str]]:
    """(process id, scheduling group) of each thread in state R with nice <= this process's, outside this process
    (/proc; OSError where it is absent). The group is the process's autogroup (`_group`)."""
    if not Path("/proc/self/stat").exists():
        raise OSError("no /proc")
    with open("/proc/loadavg", encoding="ascii") as f:          # running or ready, every priority, this included
        if int(f.read().split()[3].split("/")[0]) <= 1:
            return []                                           # nobody else: no scan
    me, mine, out = os.getpid(), os.getpriority(os.PRIO_PROCESS, 0), []
    for stat in Path("/proc").glob("[0-9]*/task/*/stat"):
        try:
            text = stat.read_bytes()
        except OSError:                              # a thread that ended while the folder was read
            continue
        fields = text[text.rfind(b")") + 2:].split()
        pid = int(stat.parts[2])
        if fields[0] == b"R" and int(fields[16]) <= mine and pid != me:
            out.append((pid, _group(pid, stat.parts[4])))
    return out


def runnable_threads() -> list[int]:
    """The process ids of `ready`'s threads, one entry a thread."""
    return [pid for pid, _ in ready()]


def _group(pid: int, tid: str = "") -> str:
    """The CFS group that shares the cores with the others: the process's autogroup (/proc/PID/autogroup, one a
    session where the kernel groups them: sched_autogroup_enabled), else the thread itself."""
    try:
        with open(f"/proc/{pid}/autogroup", encoding="ascii") as f:
            return f.read().split()[0]
    except (OSError, IndexError):
        return f"thread {pid}/{tid}"


def group_slowdown(others: list, mine: str, n_cores: int) -> float:
    """How much longer this thread's work takes than on a free core, from the groups of the other ready threads:
    CFS shares the cores between the groups with ready threads equally (none more than its threads can use: filled
    from the smallest), and a group's share between its threads. Busy processes in this session (one autogroup)
    take from this thread's share alone: two of them beside it made a run 3.4× slower where the count of ready
    threads said 1.4× (measured, issue 38); threads each in a group of their own: (ready + 1) / cores."""
    demand = Counter(others)
    demand[mine] += 1
    left, share = float(n_cores), {}
    for i, (group, d) in enumerate(sorted(demand.items(), key=lambda kv: kv[1])):
        share[group] = min(d, left / (len(demand) - i))
        left -= share[group]
    return max(1.0, demand[mine] / share[mine])


def free_cores() -> int:
    """Cores this process may use without waiting for one: its cores less the other runnable processes (rounded
    down to a whole process), at least 1. Two BLAS threads on a 2-core machine beside two busy processes spin,
    waiting for each other at every call: a 1.0 s analysis took 26 s there (issue 38), against 2-3 s on one."""
    return max(1, cores() - int(runnable() + 0.5))


def slowdown() -> float:
    """How much longer CPU-bound work takes now than on free cores (at least 1), from the groups of the ready threads
    (`group_slowdown`, read with `runnable`): beside two busy processes in other sessions on 2 cores, 1.5; beside
    two in this session, 1.5 alone and 3× the time at rest where other sessions also want the cores."""
    runnable()
    return _runnable_cache[2]


def for_size(n: int) -> int:
    """BLAS threads for dense work on n×n matrices: 1 up to SMALL, every free core above (free_cores: a thread that
    must wait for a core costs more than it gives), at most `bound()`."""
    threads = 1 if n <= SMALL else free_cores()
    cap = bound()
    return threads if cap is None else min(threads, cap)


@cache
def _controller():
    """One ThreadpoolController for the process: making one scans every loaded library (2.3 ms, measured: 8 % of a
    10⁵-particle scan when made per call). scipy.linalg is imported first so that its BLAS, which may be another
    library than numpy's, is among them."""
    import scipy.linalg  # noqa: F401
    return ThreadpoolController()


def blas_threads(n: int | None):
    """A context limiting BLAS to n threads, and every block nested in it to at most n (n None: the enclosing bound
    only; threadpoolctl absent: no limit)."""
    cap = bound()
    n = cap if n is None else n if cap is None else min(n, cap)
    if n is None or ThreadpoolController is None:
        return nullcontext()
    return _limited(n)


@contextmanager
def _limited(n: int):
    token = _bound.set(n)
    try:
        with _controller().limit(limits=n, user_api="blas"):
            yield
    finally:
        _bound.reset(token)


def cap_process(n: int | None) -> None:
    """At most n BLAS threads for the whole process from now on (None: lift the cap), applied to the loaded
    libraries at once and bounding every later block."""
    global _process_cap
    _process_cap = n
    if ThreadpoolController is not None:
        _controller().limit(limits=n if n is not None else cores(), user_api="blas")


def sized(n: int):
    """`blas_threads(for_size(n))`: the policy applied for a block of work on n×n matrices."""
    return blas_threads(for_size(n))
