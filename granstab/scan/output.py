"""What a scan writes: one part file a finished chunk (streamed, so an interrupted scan resumes), then
clusters.{parquet,csv} (one row a cluster), particles.{parquet,csv} (the per-particle map) and summary.json.

Parquet through pyarrow (the `scan` extra); csv stores the member list as names joined by ';'.
"""
from __future__ import annotations

import json
import uuid
from pathlib import Path

import numpy as np

from ..scene import Scene, SceneError

FORMATS = ("parquet", "csv")
STRING_COLUMNS = ("center", "members", "path", "branches", "verdict", "insufficient_because", "reason", "name",
                  "own_verdict")


class ScanOutput:
    """The scan directory: options.json (checked on resume), parts/ (streamed rows), the final tables."""

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

    def done_centers(self) -> set[str]:
        """Centres whose rows are already on disk (an interrupted scan)."""
        return {str(c) for c in self._read_parts().get("center", [])}

    def write(self, rows: list[dict]) -> None:
        """One chunk's rows as a new part file (written whole, then renamed: a killed scan leaves no torn file)."""
        name = self.parts / f"part-{uuid.uuid4().hex}.{self.fmt}"
        tmp = name.with_suffix(".tmp")
        write_table(rows_to_columns(rows), tmp, self.fmt)
        tmp.rename(name)

    def _read_parts(self) -> dict:
        tables = [read_table(f, self.fmt) for f in sorted(self.parts.glob(f"*.{self.fmt}"))]
        if not tables:
            return {}
        return {key: np.concatenate([t[key] for t in tables]) for key in tables[0]}

    def finish(self, scene: Scene, chosen: np.ndarray, seconds: float, n_new: int) -> dict:
        """Combine the parts (each centre once, in scene order) into the tables, the map and summary.json."""
        clusters = self._read_parts()
        if clusters:
            index = {name: i for i, name in enumerate(scene.names)}
            position = np.array([index[str(c)] for c in clusters["center"]])
            _, first = np.unique(position, return_index=True)
            order = first[np.argsort(position[first])]
            clusters = {key: value[order] for key, value in clusters.items()}
        write_table(clusters, self.path / f"clusters.{self.fmt}", self.fmt)
        particles = particle_map(scene, clusters)
        write_table(particles, self.path / f"particles.{self.fmt}", self.fmt)
        verdicts, counts = np.unique(clusters.get("verdict", np.array([], dtype=object)), return_counts=True)
        n = len(clusters.get("center", []))
        summary = {"source": scene.source, "n_particles": scene.n_particles, "n_contacts": scene.n_contacts,
                   "clusters": n, "clusters_requested": int(len(chosen)), "clusters_this_run": int(n_new),
                   "verdicts": {str(v): int(c) for v, c in zip(verdicts, counts)},
                   "partial_branches": int(np.sum(clusters.get("branches", np.array([])) == "partial")),
                   "seconds": seconds, "clusters_per_second": n_new / seconds if seconds > 0 and n_new else None,
                   "cluster_seconds_median": float(np.median(clusters["seconds"])) if n else None,
                   "options": self.options}
        (self.path / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False), encoding="utf-8")
        return summary


def particle_map(scene: Scene, clusters: dict) -> dict:
    """Per particle: the verdict of its own cluster ('' if it was no centre) and the fraction of the clusters
    containing it that are unstable (NaN if none contains it)."""
    names = np.asarray(scene.names, dtype=object)
    own = np.full(scene.n_particles, "", dtype=object)
    contains = np.zeros(scene.n_particles)
    unstable = np.zeros(scene.n_particles)
    if clusters:
        index = {name: i for i, name in enumerate(scene.names)}
        own[[index[str(c)] for c in clusters["center"]]] = clusters["verdict"]
        sizes = np.array([len(m) for m in clusters["members"]])
        flat = np.array([index[str(m)] for row in clusters["members"] for m in row], dtype=np.int64)
        contains = np.bincount(flat, minlength=scene.n_particles).astype(float)
        weight = np.repeat(clusters["verdict"] == "unstable", sizes).astype(float)
        unstable = np.bincount(flat, weights=weight, minlength=scene.n_particles)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(contains > 0, unstable / np.maximum(contains, 1), np.nan)
    return {"name": names, "own_verdict": own, "unstable_fraction": fraction, "n_clusters": contains.astype(np.int64)}


def rows_to_columns(rows: list[dict]) -> dict:
    return {key: np.array([r[key] for r in rows] + [None], dtype=object)[:-1] if key == "members"
            else np.array([r[key] for r in rows], dtype=object if key in STRING_COLUMNS else None)
            for key in rows[0]}


def write_table(columns: dict, path: Path, fmt: str) -> None:
    import pyarrow as pa
    table = pa.table({key: (pa.array([list(map(str, m)) for m in value], type=pa.list_(pa.string()))
                            if key == "members" and fmt == "parquet"
                            else pa.array([";".join(map(str, m)) for m in value], type=pa.string())
                            if key == "members"
                            else pa.array(list(value), type=pa.string()) if key in STRING_COLUMNS
                            else pa.array(value))
                      for key, value in columns.items()})
    if fmt == "parquet":
        import pyarrow.parquet as pq
        pq.write_table(table, path)
    else:
        import pyarrow.csv as pcsv
        pcsv.write_csv(table, path)


def read_table(path: Path, fmt: str) -> dict:
    """A table as a dict of numpy arrays (object arrays for strings and member lists)."""
    import pyarrow as pa
    if fmt == "parquet":
        import pyarrow.parquet as pq
        table = pq.read_table(path)
    else:
        import pyarrow.csv as pcsv
        header = Path(path).open(encoding="utf-8").readline().strip().split(",")
        types = {c.strip('"'): pa.string() for c in header if c.strip('"') in STRING_COLUMNS}
        table = pcsv.read_csv(path, convert_options=pcsv.ConvertOptions(column_types=types,
                                                                       strings_can_be_null=False))
    out = {}
    for key in table.column_names:
        values = table.column(key).to_pylist()
        if key == "members":
            values = [m.split(";") if isinstance(m, str) else m for m in values] + [None]
            out[key] = np.array(values, dtype=object)[:-1]
        else:
            out[key] = np.array(values, dtype=object if key in STRING_COLUMNS else None)
    return out


def read_map(out_dir) -> dict:
    """A finished scan: {"clusters": columns, "particles": columns, "summary": summary.json} (the app's map)."""
    path = Path(out_dir)
    summary_file = path / "summary.json"
    if not summary_file.exists():
        raise SceneError(f"{out_dir}: not a finished scan (no summary.json)")
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    fmt = summary["options"]["format"]
    return {"clusters": read_table(path / f"clusters.{fmt}", fmt),
            "particles": read_table(path / f"particles.{fmt}", fmt), "summary": summary}
