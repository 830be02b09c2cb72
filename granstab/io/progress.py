"""The reading bar: a tqdm bar over the bytes of the files a read takes in, then its stages (parse, build,
checks). Every reader of granstab.io (scene files and snapshots) reports to one; tqdm is optional."""
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
