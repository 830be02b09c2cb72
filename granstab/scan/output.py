"""What a scan writes: packing.npz (the scanned packing, so that the folder opens wherever it is copied), one part
file a finished chunk (Arrow IPC; streamed, so an interrupted scan resumes), then clusters.{parquet,csv} (one row a
cluster, rows.Row: centre and members as particle indices into the packing), particles.{parquet,csv} (the
per-particle map, in the packing's order, with the names) and summary.json.

Parquet through pyarrow (the `scan` extra); csv stores the member list as indices joined by ';'.
"""
from __future__ import annotations

import json
import uuid
from pathlib import Path

import numpy as np

from ..io import load
from ..io.scenes import save_scene
from ..model.scene import Scene, SceneError
from . import resume
from .clusters import particle_shares
from .rows import ParticleRow, Row, concat_rows, schema

FORMATS = ("parquet", "csv")
PACKING = "packing.npz"


class ScanOutput:
    """The scan directory: packing.npz, options.json (checked on resume), parts/ (streamed rows), the final tables.
    The parts are kept in memory too (`tables`), so that `finish` does not read them back."""

    def __init__(self, out_dir, fmt: str, options: dict, scene: Scene, inputs=None, overwrite: bool = False,
                 shapes=None):
        if fmt not in FORMATS:
            raise SceneError(f"--format: one of {', '.join(FORMATS)}, got {fmt!r}")
        self.path, self.fmt = Path(out_dir), fmt
        self.parts = self.path / "parts"
        self.parts.mkdir(parents=True, exist_ok=True)
        stated = {**options, "source": scene.source, "packing": PACKING, "format": fmt}
        # the packing before options.json: a scan folder has its packing
        hold_options(self.path, stated, "scan", first=lambda: _save_packing(scene, self.path / PACKING, shapes),
                     inputs=inputs, overwrite=overwrite)
        self.options = stated
        self.tables = [_feather().read_table(f) for f in sorted(self.parts.glob("*.arrow"))]   # an interrupted scan's

    def done_centers(self) -> np.ndarray:
        """Centres (particle indices) whose rows are already on disk (an interrupted scan)."""
        return np.concatenate([np.zeros(0, dtype=np.int64)] + [t.column("center").to_numpy() for t in self.tables])

    def write(self, table) -> None:
        """One chunk's rows (an Arrow table, `rows_table`) as a new part file, Arrow IPC whatever the final format
        (written whole, then renamed: a killed scan leaves no torn file)."""
        name = self.parts / f"part-{uuid.uuid4().hex}.arrow"
        tmp = name.with_suffix(".tmp")
        _feather().write_feather(table, tmp, compression="uncompressed")
        tmp.rename(name)
        self.tables.append(table)

    def finish(self, scene: Scene, chosen: np.ndarray, seconds: float, n_new: int, extra: dict | None = None) -> dict:
        """Combine the parts (each centre once, in scene order) into the tables, the map and summary.json (with
        the entries of `extra` last). Strings stay in Arrow (counted and compared there): the finish is serial,
        after the last chunk."""
        import pyarrow as pa
        import pyarrow.compute as pc
        clusters = concat_rows(self.tables)
        clusters = clusters.take(pa.array(first_rows(clusters.column("center").to_numpy(), scene.n_particles)))
        write_table(clusters, self.path / f"clusters.{self.fmt}", self.fmt)
        write_table(pa.table(particle_map(scene, clusters), schema=schema(ParticleRow)),
                    self.path / f"particles.{self.fmt}", self.fmt)
        counts = clusters.column("verdict").value_counts().to_pylist()
        n = clusters.num_rows
        summary = {"source": scene.source, "n_particles": scene.n_particles, "n_contacts": scene.n_contacts,
                   "clusters": n, "clusters_requested": int(len(chosen)), "clusters_this_run": int(n_new),
                   "verdicts": {c["values"]: c["counts"] for c in sorted(counts, key=lambda c: c["values"])},
                   "mechanisms": mechanism_counts(clusters),
                   "partial_branches": int(pc.sum(pc.equal(clusters.column("branches"), "partial")).as_py() or 0),
                   "seconds": seconds, "clusters_per_second": n_new / seconds if seconds > 0 and n_new else None,
                   "cluster_seconds_median": float(np.median(column(clusters, "seconds"))) if n else None,
                   "options": self.options, **(extra or {})}
        if self.options.get("uncertainty"):            # issue 42: the clusters per data_robust word
            robust = clusters.column("data_robust").value_counts().to_pylist()
            summary["data_robust"] = {c["values"]: c["counts"] for c in sorted(robust, key=lambda c: c["values"])}
        (self.path / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False), encoding="utf-8")
        return summary


def hold_options(folder: Path, stated: dict, what: str, first=None, inputs=None, overwrite: bool = False,
                 spans: dict | None = None) -> None:
    """A resumable folder's options.json and inputs.json (scan, track; resume.py): written when new (after
    `first()`, what must precede it); a folder holding a `what` with other options or other `inputs` (paths; the
    frames read, `spans`, hashed one by one) is a one-line error naming what changed, so that a resume never mixes
    two runs; `overwrite` starts afresh."""
    if overwrite:
        resume.start_afresh(folder)
    if resume.check(folder, stated, inputs, what, spans):
        return
    if first is not None:
        first()
    resume.record(folder, stated, inputs, spans)


def mechanism_counts(clusters) -> dict:
    """The histogram of the unstable rows' `mechanism` labels (attribution.MECHANISMS order; every label listed,
    0 where none; 'none' counts unstable rows without one: a scan with attribution off, or a row that failed)."""
    from ..mechanics.attribution import MECHANISMS
    labels = column(clusters, "mechanism") if clusters.num_rows else np.zeros(0, dtype=object)
    unstable = column(clusters, "verdict") == "unstable" if clusters.num_rows else np.zeros(0, dtype=bool)
    out = {m: int(np.sum(unstable & (labels == m))) for m in MECHANISMS}
    out["none"] = int(np.sum(unstable)) - sum(out.values())
    return out


def first_rows(position: np.ndarray, n: int) -> np.ndarray:
    """Row numbers that put rows in scene order, each centre once (its first row; a resumed scan may repeat one):
    position[i] is row i's centre, 0 <= position < n."""
    first = np.full(n, len(position), dtype=np.int64)
    np.minimum.at(first, position, np.arange(len(position)))
    return first[first < len(position)]


def _feather():
    import pyarrow.feather
    return pyarrow.feather


def _save_packing(scene: Scene, path: Path, shapes=None) -> None:
    """The packing as NPZ (granstab.save_scene, with the grains' `shapes` where it has them), written whole and then
    renamed: a killed scan leaves no torn file."""
    tmp = path.with_name(f"{path.stem}-{uuid.uuid4().hex}.npz")
    save_scene(scene, tmp, shapes)
    tmp.rename(path)


def particle_map(scene: Scene, clusters) -> dict:
    """Per particle (rows.ParticleRow): the verdict of its own cluster ('' if it was no centre) and the fraction of
    the clusters containing it that are unstable (NaN if none contains it). clusters: the Arrow table of the rows."""
    import pyarrow as pa
    import pyarrow.compute as pc
    verdict = clusters.column("verdict").combine_chunks()
    row_of = np.full(scene.n_particles, len(verdict), dtype=np.int64)      # a particle's own row; none: ''
    row_of[clusters.column("center").to_numpy()] = np.arange(len(verdict))
    own = pc.take(pa.concat_arrays([verdict, pa.array([""])]), pa.array(row_of))
    members = clusters.column("members")
    flat = pc.list_flatten(members).to_numpy()
    sizes = pc.list_value_length(members).to_numpy(zero_copy_only=False).astype(np.int64)
    contains, fraction = particle_shares(flat, sizes, scene.n_particles,
                                         pc.equal(verdict, "unstable").to_numpy(zero_copy_only=False))
    return {"name": pa.array(scene.names, type=pa.string()), "own_verdict": own, "unstable_fraction": fraction,
            "n_clusters": contains.astype(np.int64)}


def column(table, key: str) -> np.ndarray:
    """A column as numpy: object arrays for strings and lists (member lists)."""
    import pyarrow as pa
    values = table.column(key)
    if pa.types.is_list(values.type):
        return np.array(values.to_pylist() + [None], dtype=object)[:-1]
    if pa.types.is_string(values.type):
        return np.array(values.to_pylist(), dtype=object)
    return values.to_numpy(zero_copy_only=False)


def write_table(table, path: Path, fmt: str) -> None:
    """Parquet as it is (no dictionary pages: as small here, and 0.6× the time of a 10⁵-row table's); csv with the
    member lists joined by ';'."""
    if fmt == "parquet":
        import pyarrow.parquet as pq
        pq.write_table(table, path, use_dictionary=False)
        return
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv as pcsv
    for i, field in enumerate(table.schema):
        if pa.types.is_list(field.type):
            joined = pc.binary_join(table.column(i).cast(pa.list_(pa.string())), ";")
            table = table.set_column(i, field.name, joined)
    pcsv.write_csv(table, path)


def read_arrow(path: Path, fmt: str, record):
    """A table written by `write_table` with the schema of `record` (rows.Row, rows.ParticleRow), member lists as
    lists again."""
    import pyarrow as pa
    if fmt == "parquet":
        import pyarrow.parquet as pq
        return pq.read_table(path)
    import pyarrow.compute as pc
    import pyarrow.csv as pcsv
    kinds = schema(record)
    types = {f.name: pa.string() if pa.types.is_list(f.type) else f.type for f in kinds}
    table = pcsv.read_csv(path, convert_options=pcsv.ConvertOptions(
        column_types=types, null_values=[""], strings_can_be_null=False))
    for i, field in enumerate(table.schema):
        if pa.types.is_list(kinds.field(field.name).type):               # '' is a null list (work_parts)
            text = pc.if_else(pc.equal(table.column(i), ""), pa.scalar(None, pa.string()), table.column(i))
            table = table.set_column(i, field.name, pc.split_pattern(text, ";").cast(kinds.field(field.name).type))
    return table


def read_table(path: Path, fmt: str, record) -> dict:
    """A table as a dict of numpy arrays (object arrays for strings and member lists)."""
    table = read_arrow(path, fmt, record)
    return {key: column(table, key) for key in table.column_names}


def read_map(out_dir) -> dict:
    """A finished scan, as the explorer reads its map.

    Parameters
    ----------
    out_dir : str or Path
        The folder `scan` wrote.

    Returns
    -------
    dict
        ``clusters``: the columns of clusters.* (one entry a cluster: ``center``, ``members``, ``verdict``,
        ``lambda_min``, …; centres and members are particle indices into the scan's packing, `read_packing`);
        ``particles``: the columns of particles.* (``name``, ``own_verdict``, ``unstable_fraction``,
        ``n_clusters``); ``summary``: summary.json.

    Raises
    ------
    SceneError
        `out_dir` holds no finished scan.
    """
    path = Path(out_dir)
    summary_file = path / "summary.json"
    if not summary_file.exists():
        raise SceneError(f"{out_dir}: not a finished scan (no summary.json)")
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    fmt = summary["options"]["format"]
    return {"clusters": read_table(path / f"clusters.{fmt}", fmt, Row),
            "particles": read_table(path / f"particles.{fmt}", fmt, ParticleRow), "summary": summary}


def read_packing(out_dir) -> Scene:
    """The packing a scan folder holds (packing.npz): the scene its rows' indices point into."""
    return open_packing(out_dir).scene


def open_packing(out_dir):
    """The packing a scan folder holds as io.Loaded: its scene and, where kept, its grains' shapes (`grains`)."""
    path = Path(out_dir) / PACKING
    if not path.is_file():
        raise SceneError(f"{out_dir}: no {PACKING} (a scan folder written before scans kept their packing: "
                         "run the scan again)")
    return load(path)
