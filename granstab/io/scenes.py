"""Scene files: TOML, JSON and NPZ in (the formats scene-toml, scene-json and scene-npz of the registry, read by
`granstab.io.load`), JSON and NPZ out (`save_scene`), and the dispatch between the contact-level (schema.py) and
shape-based (shapefile.py) schemas — the one place that knows both, so that neither imports the other. The syntax
of each file type lives in syntax.py.
"""
from __future__ import annotations

from pathlib import Path

from ..model.errors import SceneError
from ..model.scene import Scene
from ..model.tolerances import DEFAULT, Tolerances
from .progress import ReadProgress
from .registry import Format, Request, register
from .schema import (
    contact_scene_and_grains,
    scene_and_grains_from_arrays,
    scene_arrays,
    scene_to_dict,
)
from .shapefile import is_shape_scene, shape_scene_from_dict
from .syntax import (
    decode,
    load_npz,
    parse_json,
    parse_toml,
    read_bytes,
    write_json,
    write_npz,
)


def read_scene_file(path: Path, syntax: str, tol: Tolerances, progress: ReadProgress):
    """Read one scene file in `syntax` ("toml", "json" or "npz": `save_scene`'s binary form of the same schema) and
    check it: (Scene, its grains' shapes (model.grains.Grains) or None). Raises SceneError with a one-line message
    naming the file, entry and field. `progress`: told the bytes read, then the stages (parse, checks)."""
    source = str(path)
    if syntax == "npz":
        arrays = load_npz(path, source)
        progress.stage("checks")
        return scene_and_grains_from_arrays(arrays, source=source, tol=tol)
    raw = read_bytes(path, progress.update)
    progress.stage("parse")
    data = parse_json(raw, source) if syntax == "json" else parse_toml(decode(raw, source), source)
    del raw
    progress.stage("checks")
    if is_shape_scene(data):
        return shape_scene_from_dict(data, source=source, tol=tol), None
    return contact_scene_and_grains(data, source=source, tol=tol)


def _scene_format(syntax: str) -> Format:
    """The registered format of one scene-file syntax: sniffed by the suffix of a single file."""
    suffix = f".{syntax}"

    def sniff(paths: list[Path]) -> bool:
        return len(paths) == 1 and paths[0].suffix.lower() == suffix and not paths[0].is_dir()

    def read(paths: list[Path], request: Request, progress: ReadProgress) -> Scene:
        if len(paths) != 1:
            raise SceneError(f"{paths[0]}: format scene-{syntax}: reads one scene file, got {len(paths)} inputs")
        return read_scene_file(paths[0], syntax, request.tol, progress)

    return register(Format(f"scene-{syntax}", sniff, read, scene_file=True))


for _syntax in ("toml", "json", "npz"):
    _scene_format(_syntax)


def save_scene(scene: Scene, path, shapes=None) -> Path:
    """Write `scene` as .json (strict: no NaN/Infinity) or .npz (binary: the same fields as whole arrays, fast for
    10⁵–10⁶ contacts); `granstab.load_scene` reads either back to the same arrays. Other suffixes are refused.
    `shapes` (model.grains.Grains, optional): the grains' true shapes, kept beside the scene (`granstab.io.load`
    returns them as Loaded.grains; docs/formats.md)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        write_npz(scene_arrays(scene, shapes), path)
    elif suffix == ".json":
        write_json(scene_to_dict(scene, shapes), path)   # both pause the garbage collector (syntax.paused_gc)
    else:
        raise SceneError(f"{path}: save_scene writes .json or .npz, not {suffix or 'a file without suffix'!r}")
    return path


def scene_from_dict(data, source: str = "<scene>", tol: Tolerances = DEFAULT) -> Scene:
    """Build and validate a Scene from the parsed file format (a dict).

    A scene with no `contacts` whose particles carry a `shape` is shape-based: its contacts are derived from the
    geometry (shapefile.py, model/shapes.py); any other is contact-level (schema.py)."""
    if is_shape_scene(data):
        return shape_scene_from_dict(data, source=source, tol=tol)
    return contact_scene_and_grains(data, source=source, tol=tol)[0]
