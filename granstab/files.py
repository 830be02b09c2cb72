"""Scene files: parse TOML/JSON and read either format, contact-level (scene.py) or shape-based (shapes.py).

The one place that knows both readers, so that neither imports the other.
"""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

from .reading import SceneError, one_line
from .scene import Scene, contact_scene_from_dict
from .shapes import is_shape_scene, shape_scene_from_dict
from .tolerances import DEFAULT, Tolerances


def load_scene(path, tol: Tolerances = DEFAULT) -> Scene:
    """Read a TOML (or JSON) scene file; raises SceneError with a one-line message naming the file.
    Folders and other files (DEM snapshots, experiments) go to granstab.io.load with its defaults."""
    from .io import is_snapshot, load
    if is_snapshot(path):
        return load(path).scene
    path = Path(path)
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError(f"{source}: cannot read file ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise SceneError(f"{source}: not a UTF-8 text file") from None
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SceneError(f"{source}: malformed JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    else:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SceneError(f"{source}: malformed TOML: {one_line(str(exc))}") from None
    return scene_from_dict(data, source=source, tol=tol)


def scene_from_dict(data, source: str = "<scene>", tol: Tolerances = DEFAULT) -> Scene:
    """Build and validate a Scene from the parsed file format (a dict).

    A scene with no `contacts` whose particles carry a `shape` is shape-based: its contacts are
    derived from the geometry (shapes.py); any other is contact-level (scene.py)."""
    if is_shape_scene(data):
        return shape_scene_from_dict(data, source=source, tol=tol)
    return contact_scene_from_dict(data, source=source, tol=tol)
