"""The formats granstab reads, and the record every read returns.

Each reader module registers its formats when it is imported (as MDAnalysis's readers do): a name, a `sniff`
that says from the paths alone whether they hold that format, and a `read`. `granstab.io` imports every reader,
so that `granstab.io.load` finds them all here; this module imports none of them (they import it).

    register(Format("lammps", sniff=..., read=...))
    detect([Path("atoms.dump"), Path("contacts.dump")])        # "lammps": the one format whose sniff says yes

A scene file's `read` gives the Scene itself; a snapshot's gives a `build.Snapshot`, which build.py turns into a
Scene and its validation report. A format whose files can be indexed (LAMMPS dumps: each timestep's byte offsets)
also registers an `index`; `granstab.io.open` reads any other through its `read` (source.py: one read lists the
frames, each further frame is one read).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..model.errors import SceneError
from ..model.scene import Scene
from ..model.tolerances import DEFAULT, Tolerances


@dataclass(frozen=True)
class Loaded:
    """What `granstab.io.load` read: the scene, its validation report (a JSON-able dict whose "warnings" lists
    what the import changed or assumed; a scene file's has none) and the frames the input holds (None: one)."""

    scene: Scene
    report: dict
    frames: list | None = None
    wall_flags: object = None     # (N,) per scene particle: -1 / +1 at a wall the file flags (annulus), else None
    orientation: object = None    # (N, 4) per scene particle: the file's unit quaternions (w, x, y, z), else None
    shape: object = None          # (N, 5) per scene particle: superquadric semi-axes a, b, c and blockiness n1, n2
    force_uncertainty: object = None  # (M,) per scene contact: the file's force uncertainty radius (f_err), else None
    parts: object = None          # rigid bodies' round parts (clump spheres, polygon vertices): build._parts
    grains: object = None         # a scene file's grains (model.grains.Grains: its shapes, for drawing), else None

    @property
    def warnings(self) -> list[str]:
        return self.report["warnings"]


@dataclass(frozen=True)
class Request:
    """What a read is asked for beyond the paths: the frame (or timestep, or time), the --columns mapping, the
    tolerances of the scene checks and the --cell of tables without one (text or numbers, file units)."""

    frame: object = None
    columns: str | None = None
    tol: Tolerances = DEFAULT
    cell: object = None


@dataclass(frozen=True)
class Format:
    """One readable format. sniff(paths) -> bool; read(paths, request, progress) -> (Scene, grains) (scene_file) or
    build.Snapshot; `folder`: it reads a folder itself (a folder of any other format stands for its files);
    `columns`: it takes --columns; `index` (optional): index(paths, request, progress) -> an object with `frames`
    (the keys, in order), `warnings` (frames left out, one line each) and `read(frame, request, progress)` ->
    build.Snapshot, the input's frames found in one pass and each read alone (source.py)."""

    name: str
    sniff: Callable[[list[Path]], bool]
    read: Callable
    scene_file: bool = False
    folder: bool = False
    columns: bool = False
    index: Callable | None = None


_FORMATS: dict[str, Format] = {}


def register(fmt: Format) -> Format:
    """Add a format (its sniff must not accept what another's accepts: detection refuses ambiguous input)."""
    if fmt.name in _FORMATS or fmt.name == "auto":
        raise ValueError(f"format {fmt.name!r} is registered already")
    _FORMATS[fmt.name] = fmt
    return fmt


def formats() -> tuple[str, ...]:
    """The registered format names, in detection order."""
    return tuple(_FORMATS)


def get(name: str) -> Format:
    """The format called `name`; a one-line error listing the registered names if there is none."""
    if name not in _FORMATS:
        raise SceneError(f"--format: must be auto or one of {', '.join(_FORMATS)}, got {name!r}")
    return _FORMATS[name]


def reads_folder(path: Path) -> bool:
    """Whether a format reads the folder `path` itself (else the folder stands for the files in it)."""
    return any(fmt.folder and fmt.sniff([path]) for fmt in _FORMATS.values())


def detect(paths: list[Path]) -> str:
    """The format of `paths`: the registered one whose sniff accepts them; a one-line error if none or several do."""
    for path in paths:
        if not path.exists():
            raise SceneError(f"{path}: cannot read file (no such file or directory)")
    found = [fmt.name for fmt in _FORMATS.values() if fmt.sniff(paths)]
    if len(found) > 1:
        raise SceneError(f"{paths[0]}: format: ambiguous ({', '.join(found)}); name it with --format")
    if not found:
        raise SceneError(f"{paths[0]}: format: not recognised (known: {', '.join(_FORMATS)}); name it with --format")
    return found[0]
