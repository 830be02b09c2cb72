"""Scene files: TOML, JSON and NPZ in (`load_scene`), JSON and NPZ out (`save_scene`), and the dispatch between the
contact-level (scene.py) and shape-based (shapes.py) readers — the one place that knows both, so that neither
imports the other. The syntax of each format lives in fileformat.py.
"""
from __future__ import annotations

from pathlib import Path

from .fileformat import PROGRESS_BYTES, decode, load_npz, parse_json, parse_toml, read_bytes, write_json, write_npz
from .reading import SceneError
from .scene import Scene, contact_scene_from_dict, scene_arrays, scene_from_arrays
from .shapes import is_shape_scene, shape_scene_from_dict
from .tolerances import DEFAULT, Tolerances


def load_scene(path, tol: Tolerances = DEFAULT, *, progress: bool = False) -> Scene:
    """Read a scene file: TOML, JSON (same schema) or NPZ (`save_scene`'s binary form of it), chosen by the
    suffix (.toml, .json, .npz). Raises SceneError with a one-line message naming the file.
    progress: a bar on stderr while a large file is read, then its stages (parse, checks).
    Folders and other files (DEM snapshots, experiments) go to granstab.io.load with its defaults."""
    from .io import is_snapshot, load
    if is_snapshot(path):
        return load(path).scene
    path = Path(path)
    source = str(path)
    with _ReadProgress(path, progress) as bar:
        if path.suffix.lower() == ".npz":
            arrays = load_npz(path, source)
            bar.stage("checks")
            return scene_from_arrays(arrays, source=source, tol=tol)
        raw = read_bytes(path, bar.update)
        bar.stage("parse")
        if path.suffix.lower() == ".json":
            data = parse_json(raw, source)
        else:
            data = parse_toml(decode(raw, source), source)
        del raw
        bar.stage("checks")
        return scene_from_dict(data, source=source, tol=tol)


def save_scene(scene: Scene, path) -> Path:
    """Write `scene` as .json (strict: no NaN/Infinity) or .npz (binary: the same fields as whole arrays, fast for
    10⁵–10⁶ contacts); `load_scene` reads either back to the same arrays. Other suffixes are refused."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        write_npz(scene_arrays(scene), path)
    elif suffix == ".json":
        write_json(scene.to_dict(), path)           # both pause the garbage collector (fileformat.paused_gc)
    else:
        raise SceneError(f"{path}: save_scene writes .json or .npz, not {suffix or 'a file without suffix'!r}")
    return path


class _ReadProgress:
    """tqdm bar over a file's bytes, then its stages (optional dependency, only for files > PROGRESS_BYTES)."""

    def __init__(self, path: Path, enabled: bool):
        self.bar = None
        if enabled:
            try:
                size = path.stat().st_size
                from tqdm.auto import tqdm
            except (OSError, ImportError):
                return
            if size > PROGRESS_BYTES:
                self.bar = tqdm(total=size, unit="B", unit_scale=True, desc=f"reading {path.name}", mininterval=0.5)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()

    def update(self, n: int) -> None:
        if self.bar is not None:
            self.bar.update(n)

    def stage(self, name: str) -> None:
        if self.bar is not None:
            self.bar.set_description(f"{name} {self.bar.desc.split(' ', 1)[-1]}")
            self.bar.refresh()


def scene_from_dict(data, source: str = "<scene>", tol: Tolerances = DEFAULT) -> Scene:
    """Build and validate a Scene from the parsed file format (a dict).

    A scene with no `contacts` whose particles carry a `shape` is shape-based: its contacts are derived from the
    geometry (shapes.py); any other is contact-level (scene.py)."""
    if is_shape_scene(data):
        return shape_scene_from_dict(data, source=source, tol=tol)
    return contact_scene_from_dict(data, source=source, tol=tol)
