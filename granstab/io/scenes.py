"""Scene files: TOML, JSON and NPZ in (`load_scene`), JSON and NPZ out (`save_scene`), and the dispatch between the
contact-level (schema.py) and shape-based (shapefile.py) formats — the one place that knows both, so that neither
imports the other. The syntax of each file type lives in syntax.py. The formats: docs/formats.md.
"""
from __future__ import annotations

from pathlib import Path

from ..model.errors import SceneError
from ..model.scene import Scene
from ..model.tolerances import DEFAULT, Tolerances
from .schema import (
    contact_scene_from_dict,
    scene_arrays,
    scene_from_arrays,
    scene_to_dict,
)
from .shapefile import is_shape_scene, shape_scene_from_dict
from .syntax import (
    PROGRESS_BYTES,
    decode,
    load_npz,
    parse_json,
    parse_toml,
    read_bytes,
    write_json,
    write_npz,
)


def load_scene(path, tol: Tolerances = DEFAULT, *, progress: bool = False) -> Scene:
    """Read a scene file (TOML, JSON or NPZ, by suffix) or a snapshot into a validated `Scene`.

    Parameters
    ----------
    path : str or Path
        A .toml or .json scene file (contact-level or shape-based, docs/formats.md), an .npz written by
        `save_scene`, or a snapshot (a folder or another file: DEM output, experiments), which goes to
        granstab.io.load with its defaults.
    tol : Tolerances
        Input tolerances of the checks.
    progress : bool
        A bar on stderr while a large file is read, then its stages (parse, checks).

    Returns
    -------
    Scene
        Validated; of a snapshot the scene only (granstab.io.load also returns its validation report).

    Raises
    ------
    SceneError
        An unreadable file or a failed check, in one line naming the file, the entry and the field.
    """
    from . import is_snapshot, load
    if is_snapshot(path):
        return load(path, progress=progress).scene
    path = Path(path)
    source = str(path)
    with ReadProgress(path, progress) as bar:
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
    """Write `scene` to `path` as .json (strict: no NaN/Infinity) or .npz (the same fields as whole arrays, fast
    for 10⁵–10⁶ contacts); `load_scene` reads either back to the same arrays.

    Returns
    -------
    Path
        `path`.

    Raises
    ------
    SceneError
        Another suffix.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        write_npz(scene_arrays(scene), path)
    elif suffix == ".json":
        write_json(scene_to_dict(scene), path)           # both pause the garbage collector (fileformat.paused_gc)
    else:
        raise SceneError(f"{path}: save_scene writes .json or .npz, not {suffix or 'a file without suffix'!r}")
    return path


class ReadProgress:
    """tqdm bar over the bytes of a file (or of several: a snapshot's dumps or tables), then its stages (optional
    dependency, only for inputs > PROGRESS_BYTES). Used by load_scene and granstab.io.load."""

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



def scene_from_dict(data, source: str = "<scene>", tol: Tolerances = DEFAULT) -> Scene:
    """Build and validate a `Scene` from a parsed scene file (docs/formats.md).

    Parameters
    ----------
    data : dict
        The file's content: ``dim``, ``particles`` (N entries) and ``contacts`` (M entries), optional ``title``
        and ``defaults``. Without ``contacts`` and with a ``shape`` on every particle it is shape-based: the
        contacts are derived from the geometry (granstab.model.shapes).
    source : str
        The name error messages give the input.
    tol : Tolerances
        Input tolerances of the checks.

    Returns
    -------
    Scene
        Contact-level, or with the contacts the shapes make.

    Raises
    ------
    SceneError
        `data` breaks the format; the line names `source`, the entry and the field.
    """
    if is_shape_scene(data):
        return shape_scene_from_dict(data, source=source, tol=tol)
    return contact_scene_from_dict(data, source=source, tol=tol)
