"""Where a run's memory and time go, by phase, without a profiler's overhead: a thread samples the process's resident
memory (/proc/self/statm) every PERIOD seconds while named functions are wrapped to record when they run; each
phase then says its wall time, its CPU time, the resident memory when it began and the highest sampled while it ran
(issue 41: the 10⁶-disk whole packing's peaks, found and cut)."""
from __future__ import annotations

import importlib
import os
import threading
import time

PERIOD = 0.02
PAGE = os.sysconf("SC_PAGE_SIZE")


def resident() -> int:
    """This process's resident memory now (bytes)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * PAGE


class Trace:
    """Sample RSS in a thread; `watch("pkg.module:Class.method", ...)` wraps those callables (restored on exit)."""

    def __init__(self, *targets: str, limit: float | None = None):
        self.targets, self.samples, self.spans, self._undo = targets, [], [], []
        self.limit = limit              # bytes: above this the process exits (3) at once, before the kernel's OOM killer
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self):
        while not self._stop.is_set():
            self.samples.append((time.perf_counter(), resident()))
            if self.limit and self.samples[-1][1] > self.limit:
                os.write(2, f"memtrace: resident memory above {self.limit / 2 ** 30:.1f} GB: stopped\n".encode())
                os._exit(3)
            self._stop.wait(PERIOD)

    def _wrap(self, target: str):
        mod, _, attr = target.partition(":")
        owner = importlib.import_module(mod)
        *path, name = attr.split(".")
        for p in path:
            owner = getattr(owner, p)
        original = getattr(owner, name)
        spans = self.spans

        def wrapped(*args, **kwargs):
            t, c, m = time.perf_counter(), time.process_time(), resident()
            try:
                return original(*args, **kwargs)
            finally:
                spans.append((attr, t, time.perf_counter(), time.process_time() - c, m))

        setattr(owner, name, wrapped)
        self._undo.append((owner, name, original))

    def __enter__(self):
        for target in self.targets:
            self._wrap(target)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        for owner, name, original in reversed(self._undo):
            setattr(owner, name, original)

    def phases(self) -> list[dict]:
        """Per wrapped call (in order of its start): name, wall, CPU, RSS at entry and peak RSS during (GB)."""
        out = []
        for name, t0, t1, cpu, at_entry in sorted(self.spans, key=lambda s: s[1]):
            during = [m for t, m in self.samples if t0 <= t <= t1] + [at_entry]
            out.append({"phase": name, "wall": t1 - t0, "cpu": cpu, "entry_gb": at_entry / 2 ** 30,
                        "peak_gb": max(during) / 2 ** 30})
        return out

    def peak_gb(self) -> float:
        return max((m for _, m in self.samples), default=0) / 2 ** 30
