"""What a scan writes: one part file a finished chunk (Arrow IPC; streamed, so an interrupted scan resumes), then
clusters.{parquet,csv} (one row a cluster), particles.{parquet,csv} (the per-particle map) and summary.json.

Parquet through pyarrow (the `scan` extra); csv stores the member list as names joined by ';'.
"""
from __future__ import annotations

import json
import uuid
from pathlib import Path

import numpy as np

from ..model.scene import Scene, SceneError

FORMATS = ("parquet", "csv")
ROW_COLUMNS = ("center", "members", "n_particles", "path", "n_contacts", "n_sliding", "branches", "n_branches",
               "lambda_min", "consistent_negative", "consistent_positive", "verdict", "sufficient",
               "insufficient_because", "metric_robust", "zero_margin", "eigen_residual", "rigid_leakage", "reason",
               "seconds")     # a row of clusters.*, in order (run.summary_row)
STRING_COLUMNS = ("center", "members", "path", "branches", "verdict", "insufficient_because", "reason", "name",
                  "own_verdict")


class ScanOutput:
    """The scan directory: options.json (checked on resume), parts/ (streamed rows), the final tables. The parts are
    kept in memory too (`tables`), so that `finish` does not read them back."""

    def __init__(self, out_dir, fmt: str, options: dict, source: str):
        if fmt not in FORMATS:
            raise SceneError(f"--format: one of {', '.join(FORMATS)}, got {fmt!r}")
        self.path, self.fmt = Path(out_dir), fmt
        self.parts = self.path / "parts"
        self.parts.mkdir(parents=True, exist_ok=True)
        stated = {**options, "source": source, "format": fmt}
        saved = self.path / "options.json"
        if saved.exists():
            before = json.loads(saved.read_text(encoding="utf-8"))
            if before != stated:
                raise SceneError(f"{out_dir}: holds a scan with other options ({before}); resume with the same "
                                 "options or choose another --out")
        else:
            saved.write_text(json.dumps(stated), encoding="utf-8")
        self.options = stated
        self.tables = [_feather().read_table(f) for f in sorted(self.parts.glob("*.arrow"))]   # an interrupted scan's

    def done_centers(self) -> set[str]:
        """Centres whose rows are already on disk (an interrupted scan)."""
        return {str(c) for t in self.tables for c in t.column("center").to_pylist()}

    def write(self, table) -> None:
        """One chunk's rows (an Arrow table, `rows_table`) as a new part file, Arrow IPC whatever the final format
        (written whole, then renamed: a killed scan leaves no torn file)."""
        name = self.parts / f"part-{uuid.uuid4().hex}.arrow"
        tmp = name.with_suffix(".tmp")
        _feather().write_feather(table, tmp, compression="uncompressed")
        tmp.rename(name)
        self.tables.append(table)

    def finish(self, scene: Scene, chosen: np.ndarray, seconds: float, n_new: int) -> dict:
        """Combine the parts (each centre once, in scene order) into the tables, the map and summary.json. Strings
        stay in Arrow (counted and compared there): the finish is serial, after the last chunk."""
        import pyarrow as pa
        import pyarrow.compute as pc
        clusters = concat_rows(self.tables)
        clusters = clusters.take(pa.array(first_rows(name_positions(scene, clusters.column("center")),
                                                      scene.n_particles)))
        write_table(clusters, self.path / f"clusters.{self.fmt}", self.fmt)
        write_table(pa.table(particle_map(scene, clusters)), self.path / f"particles.{self.fmt}", self.fmt)
        counts = clusters.column("verdict").value_counts().to_pylist()
        n = clusters.num_rows
        summary = {"source": scene.source, "n_particles": scene.n_particles, "n_contacts": scene.n_contacts,
                   "clusters": n, "clusters_requested": int(len(chosen)), "clusters_this_run": int(n_new),
                   "verdicts": {c["values"]: c["counts"] for c in sorted(counts, key=lambda c: c["values"])},
                   "partial_branches": int(pc.sum(pc.equal(clusters.column("branches"), "partial")).as_py() or 0),
                   "seconds": seconds, "clusters_per_second": n_new / seconds if seconds > 0 and n_new else None,
                   "cluster_seconds_median": float(np.median(column(clusters, "seconds"))) if n else None,
                   "options": self.options}
        (self.path / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False), encoding="utf-8")
        return summary


def first_rows(position: np.ndarray, n: int) -> np.ndarray:
    """Row numbers that put rows in scene order, each centre once (its first row; a resumed scan may repeat one):
    position[i] is row i's centre, 0 <= position < n."""
    first = np.full(n, len(position), dtype=np.int64)
    np.minimum.at(first, position, np.arange(len(position)))
    return first[first < len(position)]


def _feather():
    import pyarrow.feather
    return pyarrow.feather


def name_positions(scene: Scene, names) -> np.ndarray:
    """Indices in the scene of an Arrow array of particle names (vectorised: pyarrow.compute.index_in)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    return pc.index_in(names, value_set=pa.array(scene.names, type=pa.string())).to_numpy(zero_copy_only=False)


def particle_map(scene: Scene, clusters) -> dict:
    """Per particle: the verdict of its own cluster ('' if it was no centre) and the fraction of the clusters
    containing it that are unstable (NaN if none contains it). clusters: the Arrow table of the rows."""
    import pyarrow as pa
    import pyarrow.compute as pc
    verdict = clusters.column("verdict").combine_chunks()
    row_of = np.full(scene.n_particles, len(verdict), dtype=np.int64)      # a particle's own row; none: ''
    row_of[name_positions(scene, clusters.column("center"))] = np.arange(len(verdict))
    own = pc.take(pa.concat_arrays([verdict.cast(pa.string()), pa.array([""])]), pa.array(row_of))
    members = clusters.column("members")
    flat = name_positions(scene, pc.list_flatten(members))
    sizes = pc.list_value_length(members).to_numpy(zero_copy_only=False).astype(np.int64)
    contains = np.bincount(flat, minlength=scene.n_particles).astype(float)
    weight = np.repeat(pc.equal(verdict, "unstable").to_numpy(zero_copy_only=False), sizes).astype(float)
    unstable = np.bincount(flat, weights=weight, minlength=scene.n_particles)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(contains > 0, unstable / np.maximum(contains, 1), np.nan)
    return {"name": pa.array(scene.names, type=pa.string()), "own_verdict": own, "unstable_fraction": fraction,
            "n_clusters": contains.astype(np.int64)}


def rows_table(rows: list[dict]):
    """A chunk's rows (dicts of run.summary_row's fields) as an Arrow table, member lists as lists of names. Made
    where the chunk ran (a Dask worker), so that the client only writes it."""
    import pyarrow as pa
    keys = rows[0] if rows else ("center", "members", "verdict", "branches", "seconds")
    return pa.table({key: pa.array([r[key] for r in rows], type=_arrow_type(key)) for key in keys})


def columns_table(columns: dict):
    """A chunk's rows given as columns (run.batched_columns: numpy arrays; members as (names, offsets)) as an
    Arrow table like `rows_table`'s."""
    import pyarrow as pa
    names, offsets = columns["members"]
    members = pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()), pa.array(names, type=pa.string()))
    return pa.table({key: members if key == "members" else pa.array(columns[key], type=_arrow_type(key))
                     for key in ROW_COLUMNS})


def concat_rows(tables: list):
    """Row tables (rows_table, columns_table) as one; none: an empty one."""
    import pyarrow as pa
    return pa.concat_tables(tables, promote_options="default") if tables else rows_table([])


def _arrow_type(key: str):
    import pyarrow as pa
    return pa.list_(pa.string()) if key == "members" else pa.string() if key in STRING_COLUMNS else None


def column(table, key: str) -> np.ndarray:
    """A column as numpy: object arrays for strings and member lists (lists of names)."""
    values = table.column(key)
    if key == "members":
        return np.array(values.to_pylist() + [None], dtype=object)[:-1]
    if key in STRING_COLUMNS:
        return np.array(values.to_pylist(), dtype=object)
    return values.to_numpy(zero_copy_only=False)


def write_table(table, path: Path, fmt: str) -> None:
    """Parquet as it is (no dictionary pages: as small here, and 0.6× the time of a 10⁵-row table's); csv with the
    member lists joined by ';'."""
    import pyarrow as pa
    if fmt == "parquet":
        import pyarrow.parquet as pq
        pq.write_table(table, path, use_dictionary=False)
        return
    import pyarrow.compute as pc
    import pyarrow.csv as pcsv
    if "members" in table.column_names:
        table = table.set_column(table.column_names.index("members"), "members",
                                 pc.binary_join(table.column("members"), ";"))
    pcsv.write_csv(table.cast(pa.schema([pa.field(f.name, pa.string()) if pa.types.is_null(f.type) else f
                                         for f in table.schema])), path)


def read_arrow(path: Path, fmt: str):
    """A table written by `write_table`, member lists as lists again."""
    import pyarrow as pa
    if fmt == "parquet":
        import pyarrow.parquet as pq
        return pq.read_table(path)
    import pyarrow.compute as pc
    import pyarrow.csv as pcsv
    header = Path(path).open(encoding="utf-8").readline().strip().split(",")
    types = {c.strip('"'): pa.string() for c in header if c.strip('"') in STRING_COLUMNS}
    table = pcsv.read_csv(path, convert_options=pcsv.ConvertOptions(column_types=types, strings_can_be_null=False))
    if "members" in table.column_names:
        table = table.set_column(table.column_names.index("members"), "members",
                                 pc.split_pattern(table.column("members"), ";"))
    return table


def read_table(path: Path, fmt: str) -> dict:
    """A table as a dict of numpy arrays (object arrays for strings and member lists)."""
    table = read_arrow(path, fmt)
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
        ``lambda_min``, …); ``particles``: the columns of particles.* (``name``, ``own_verdict``,
        ``unstable_fraction``, ``n_clusters``); ``summary``: summary.json.

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
    return {"clusters": read_table(path / f"clusters.{fmt}", fmt),
            "particles": read_table(path / f"particles.{fmt}", fmt), "summary": summary}
