"""A `granstab track` folder as an export's sequence (issue 27's contract): frames.parquet lists the frames (its
`frame` column), particles.parquet holds frame × particle rows (`frame`, `name`, then numbers such as `d2min`,
`contacts_changed` and the predictors); each numeric column becomes a per-particle field of that frame, matched
by name (NaN for a particle the row set lacks)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.errors import SceneError, require

KEYS = ("frame", "name")


def _table(folder: Path, name: str):
    path = folder / name
    if not path.is_file():
        raise SceneError(f"{folder}: --track: no {name} (not a granstab track folder)")
    pq = require("pyarrow.parquet", "scan", "reading a track folder")
    return pq.read_table(path)


def track_frames(folder) -> list:
    """The frame numbers of a track folder, in its order."""
    table = _table(Path(folder), "frames.parquet")
    if "frame" not in table.column_names:
        raise SceneError(f"{folder}/frames.parquet: frame: missing column")
    return [v.item() if hasattr(v, "item") else v for v in table.column("frame").to_numpy(zero_copy_only=False)]


def track_fields(folder, frame, names: tuple) -> dict:
    """The numeric per-particle columns of `frame` in particles.parquet, in the order of `names`."""
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
        if key in KEYS or values.dtype.kind not in "fiub":
            continue
        padded = np.r_[values.astype(float), np.nan]
        out[key] = padded[index]
    return out
