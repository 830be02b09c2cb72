"""Wall-time medians: one call, repeated calls, two calls interleaved (so drifting load hits both alike).

`ONCE` (set by the tests): every timing is one call, no warm-up and no repeats, so that a test checks that the
benchmark code runs and what it reports, without spending CI minutes on measuring."""
from __future__ import annotations

import time

import numpy as np

ONCE = False


def repeats(n: int) -> int:
    """n repeats of a measurement, or one when ONCE."""
    return 1 if ONCE else n


def once(fn):
    """(seconds, value) of one call."""
    t = time.perf_counter()
    value = fn()
    return time.perf_counter() - t, value


def timeit(fn, repeat: int = 5, min_time: float = 0.3, max_repeat: int = 50, warmup: int = 1,
           slow: float = 3.0):
    """Median wall time of fn() over at least `repeat` runs (more while the total is under min_time), after
    `warmup` untimed runs; returns (median seconds, the value of the last call). A call slower than `slow`
    seconds is timed once (its warm-up run is the measurement)."""
    if ONCE:
        return once(fn)
    value = None
    times = []
    for i in range(warmup):
        t = time.perf_counter()
        value = fn()
        if i == 0 and time.perf_counter() - t > slow:
            return time.perf_counter() - t, value
    start = time.perf_counter()
    while len(times) < repeat or (time.perf_counter() - start < min_time and len(times) < max_repeat):
        t = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), value


def timeit_pair(fa, fb, repeat: int = 7, min_time: float = 1.0, values: bool = False):
    """Medians of fa() and fb() timed interleaved (a, b, a, b, …), after one warm-up each."""
    if ONCE:
        (ta, va), (tb, vb) = once(fa), once(fb)
        return ((ta, va), (tb, vb)) if values else (ta, tb)
    va, vb = fa(), fb()
    ta, tb = [], []
    start = time.perf_counter()
    while len(ta) < repeat or (time.perf_counter() - start < min_time and len(ta) < 100):
        t = time.perf_counter()
        va = fa()
        ta.append(time.perf_counter() - t)
        t = time.perf_counter()
        vb = fb()
        tb.append(time.perf_counter() - t)
    ma, mb = float(np.median(ta)), float(np.median(tb))
    return ((ma, va), (mb, vb)) if values else (ma, mb)


def slope(x, y) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(np.asarray(x, float)), np.log(np.asarray(y, float)), 1)[0])
