"""A rigidity result as a folder the explorer opens (`granstab rigidity INPUT --out DIR`): rigidity.json (the
command's JSON) and packing.npz (the scene its contact indices point into), as a scan folder keeps its packing."""
from __future__ import annotations

import json
from pathlib import Path

from ..io import load
from ..io.scenes import save_scene
from ..model.errors import SceneError
from ..model.scene import Scene

RESULT, PACKING = "rigidity.json", "packing.npz"


def is_rigidity_dir(path) -> bool:
    """A folder `write_result` wrote."""
    path = Path(path)
    return path.is_dir() and (path / RESULT).is_file() and (path / PACKING).is_file()


def write_result(scene: Scene, result: dict, out, shapes=None) -> Path:
    """rigidity.json and packing.npz (with the grains' `shapes`, model.grains.Grains, where they have them)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    save_scene(scene, out / PACKING, shapes)
    (out / RESULT).write_text(json.dumps(result, allow_nan=False))
    return out


def read_result(out):
    """The packing (io.Loaded: its scene and grains) and the result of a rigidity folder; one-line SceneError when
    they do not belong together."""
    out = Path(out)
    packing = load(out / PACKING)
    scene = packing.scene
    result = json.loads((out / RESULT).read_text())
    model = next((m for m in ("physical", "generic") if m in result), None)
    if model is None or len(result[model]["contacts"]) < scene.n_contacts:
        raise SceneError(f"{out}: {RESULT}: no model's contacts match the {scene.n_contacts} contacts of {PACKING}")
    return packing, result
