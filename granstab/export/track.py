"""A `granstab track` folder as an export's sequence (issue 27's contract, granstab.track): frames.parquet lists
the frames — `frame`, the 0-based position in the input's frame list, and `step`, the reader's key of that frame
(the annulus frame number, a timestep; NaN: a one-frame input) — and particles.parquet holds frame × particle rows
(`frame`, `name`, then numbers such as `d2min`, `contacts_changed` and the predictors). Each numeric column becomes
a per-particle field of that frame, matched by name (NaN for a particle the rows lack); the positions x, y, z are
the scene's own and are left out."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.errors import SceneError, require

KEYS = ("frame", "name")
SKIPPED = KEYS + ("x", "y", "z")          # the keys, and the positions (the scene's own)


def _table(folder: Path, name: str):
    path = folder / name
    if not path.is_file():
        raise SceneError(f"{folder}: --track: no {name} (not a granstab track folder)")
    pq = require("pyarrow.parquet", "scan", "reading a track folder")
    return pq.read_table(path)


def track_frames(folder) -> list[tuple[int, object]]:
    """The frames of a track folder, in its order: (position, the reader's key for `load(frame=...)`, None for a
    one-frame input)."""
    table = _table(Path(folder), "frames.parquet")
    if "frame" not in table.column_names:
        raise SceneError(f"{folder}/frames.parquet: frame: missing column")
    positions = [int(v) for v in table.column("frame").to_pylist()]
    steps = table.column("step").to_pylist() if "step" in table.column_names else positions
    keys = [None if s is None or s != s else (int(s) if float(s).is_integer() else s) for s in steps]
    return list(zip(positions, keys))


def track_fields(folder, frame: int, names: tuple) -> dict:
    """The numeric per-particle columns of the frame at position `frame` in particles.parquet, in the order of
    `names`."""
    table = _table(Path(folder), "particles.parquet")
    missing = [k for k in KEYS if k not in table.column_names]
    if missing:
        raise SceneError(f"{folder}/particles.parquet: {missing[0]}: missing column")
    rows = np.flatnonzero(table.column("frame").to_numpy(zero_copy_only=False) == frame)
    table = table.take(rows)
    where = {str(n): i for i, n in enumerate(table.column("name").to_pylist())}
    index = np.array([where.get(str(n), -1) for n in names], dtype=np.int64)
    out = {}
    for key in table.column_names:
        values = table.column(key).to_numpy(zero_copy_only=False)
        if key in SKIPPED or values.dtype.kind not in "fiub":
            continue
        padded = np.r_[values.astype(float), np.nan]
        out[key] = padded[index]
    return out
