"""Progress: the reading bar, a tqdm bar over the bytes of the files a read takes in, then its stages (parse,
build, checks), to which every reader of granstab.io reports (tqdm is optional); and, where stderr is not a
terminal, the `Heartbeat`: a line a minute with the stage and the estimate, to which the branch loops report
(solve/methods.py) as they do to their bars."""
from __future__ import annotations

from pathlib import Path

PROGRESS_BYTES = 1 << 25   # inputs larger than this show progress when asked


class ReadProgress:
    """tqdm bar over the bytes of a file (or of several: a snapshot's dumps or tables), then its stages (optional
    dependency, only for inputs > PROGRESS_BYTES). `granstab.io.load` opens one around every read."""

    def __init__(self, paths, enabled: bool):
        self.bar, self.label = None, ""
        if enabled:
            paths = [Path(paths)] if isinstance(paths, (str, Path)) else [Path(p) for p in paths]
            try:
                size = sum(p.stat().st_size for p in paths)
                from tqdm.auto import tqdm
            except (OSError, ImportError):
                return
            if size > PROGRESS_BYTES:
                self.label = " + ".join(p.name for p in paths)
                self.bar = tqdm(total=size, unit="B", unit_scale=True, desc=f"reading {self.label}", mininterval=0.5)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()

    def update(self, n: int) -> None:
        if self.bar is not None:
            self.bar.update(n)

    def stage(self, name: str, total: int | None = None) -> None:
        """The next stage; `total`: it reads that many bytes more (the bar starts again from 0)."""
        if self.bar is not None:
            if total is not None:
                self.bar.reset(total=total)
            self.bar.set_description(f"{name} {self.label}")
            self.bar.refresh()


HEARTBEAT_FIRST = 10.0    # seconds before a non-interactive run's first heartbeat line …
HEARTBEAT_EVERY = 60.0    # … and between the next ones (module attributes: a test sets them small)


class Heartbeat:
    """Progress where no bar can be drawn (stderr not a terminal: logs, pipes, CI): after HEARTBEAT_FIRST seconds
    and then every HEARTBEAT_EVERY (or `often`'s period), one line on `stream` with the stage, its count and the estimate. The same
    interface as the bars (`stage`, `update`, `close`), so the work reports to either; stdout is never touched."""

    def __init__(self, what: str, estimate: float | None = None, stream=None, enabled: bool = True):
        import sys
        self.what, self.estimate, self.enabled = what, estimate, enabled
        self.stream = stream if stream is not None else sys.stderr
        self.name, self.done, self.total = "starting", 0, None
        self.every = None                  # seconds between lines after the first (None: HEARTBEAT_EVERY; `often`)
        self._wake = self._thread = None

    def __enter__(self):
        import threading
        import time
        self._start = time.monotonic()
        self._wake, self._stopped = threading.Event(), False
        if self.enabled:
            self._thread = threading.Thread(target=self._beat, daemon=True, name="granstab-heartbeat")
            self._thread.start()
        return self

    def __exit__(self, *exc):
        """Stop, and wait for a line being written: none may follow the run's own output (or its closed stream)."""
        self._stopped = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join()

    def often(self, seconds: float) -> None:
        """A line every `seconds` from now on (the next one at most `seconds` after the last, or the start): a run
        over budget.ASK_SECONDS without --timeout (plan.fit's unasked plan)."""
        self.every = seconds
        self._wake.set()

    def _beat(self) -> None:
        import time
        last, due = self._start, self._start + HEARTBEAT_FIRST
        while not self._stopped:
            self._wake.wait(max(0.0, due - time.monotonic()))
            self._wake.clear()
            if self._stopped:
                return
            now = time.monotonic()
            every = HEARTBEAT_EVERY if self.every is None else self.every
            if now < due:                                  # woken by `often`: the next line due sooner
                due = min(due, last + every)
                continue
            self.stream.write(self.line() + "\n")
            self.stream.flush()
            last, due = now, now + every

    def note(self, text: str) -> None:
        """One line now, in the heartbeat's form ('granstab: <what>: 3 s, <text>'), whether or not it beats."""
        import time
        self.stream.write(f"granstab: {self.what}: {time.monotonic() - self._start:.0f} s, {text}\n")
        self.stream.flush()

    def line(self) -> str:
        """'granstab: <what>: 70 s, branches, metric L/10 (37 of 128); estimated 46 s in all'."""
        import time
        count = f" ({self.done} of {self.total})" if self.total else ""
        guess = f"; estimated {self.estimate:.3g} s in all" if self.estimate else ""
        return f"granstab: {self.what}: {time.monotonic() - self._start:.0f} s, {self.name}{count}{guess}"

    def stage(self, name: str, total: int | None = None) -> None:
        self.name, self.done, self.total = name, 0, total

    def update(self, n: int = 1) -> None:
        self.done += n

    def close(self) -> None:
        """The end of a stage (the bars' close)."""
