"""Everything in and out: scene files and real packings (DEM snapshots, experimental frames) through one loader.

    loaded = granstab.io.load("DataAnnulus/10", frame=1, geometry="touching", length_scale=0.027, units="cm")
    loaded.scene, loaded.report, loaded.warnings, loaded.frames
    granstab.io.load("presets/gear.toml").scene            # a scene file: report "read as a scene file", no warnings

Each reader module registers its formats (registry.py: a name, a sniff, a read): scene files (scenes.py: TOML,
JSON, NPZ; contact-level and shape-based), RigidLibrary folders, LAMMPS dumps, MercuryDPM output and generic
tables. `format="auto"` takes the one whose sniff accepts the paths; a snapshot reader's `Snapshot` goes through
`build.build`, which applies the conventions every format shares (contact point, normal, curvature, cone policy,
loads) and writes the validation report (validation.py).
"""
from __future__ import annotations

from pathlib import Path

from ..model.errors import SceneError
from ..model.scene import Scene
from ..model.tolerances import DEFAULT, Tolerances
from . import generic, lammps, liggghts_superquadric, mercury, rigidlibrary, scenes  # noqa: F401  (each registers its formats)
from .build import GEOMETRY, OUTSIDE_CONE, Options, build
from .progress import ReadProgress
from .registry import Format, Loaded, Request, detect, formats, get, reads_folder, register
from .validation import format_report

OPTION_KEYS = {"k", "alpha", "mu", "geometry", "outside_cone", "yield_rtol", "length_scale", "units", "region",
               "keep_rattlers", "density", "periodic", "cell"}
SKIPPED_IN_FOLDERS = (".json", ".toml", ".npz", ".py", ".sh", ".md")   # a snapshot folder's other files


def load(path_or_paths, *, format: str = "auto", frame=None, timestep=None, progress: bool = False,
         tol: Tolerances = DEFAULT, **options) -> Loaded:
    """Read a scene file or a snapshot (a file, a folder or several files) into a Scene with its validation report.

    Parameters
    ----------
    path_or_paths : str, Path or list of them
        A scene file (.toml, .json, .npz), or one snapshot's files or folder. A folder that no format reads
        itself (RigidLibrary layouts do) stands for the files in it (one snapshot's dumps or tables).
    format : str
        "auto" (the registered format whose sniff accepts the paths) or a name of `formats()`.
    frame, timestep : int or float, optional
        The frame (or timestep, or time) of a snapshot with several; default the first.
    progress : bool
        A bar on stderr while large inputs are read (bytes scanned and parsed), then the stages.
    tol : Tolerances
        The scene checks' tolerances.
    **options
        Snapshots only: k, alpha, mu (override the file's law), geometry ("centres" | "touching"), outside_cone
        ("sliding" | "project" | "elastic" | "error"), yield_rtol, length_scale (file length unit → scene unit),
        units (its name), region (ids, {"box": [lo, hi, ...]} on scaled centres, or the --region text),
        keep_rattlers, density, columns (formats with named columns), periodic (False: cut a periodic cell's
        seam contacts, their forces become loads; default: keep them with their images, the scene carries the
        cell), cell (the cell of a snapshot whose files give none: rows as text "a11,a12,a21,a22" or numbers).

    Returns
    -------
    Loaded
        scene; report (JSON-able; "warnings": what the import changed or assumed, none for a scene file);
        frames (the frames the input holds, or None).
    """
    paths = [Path(p) for p in ([path_or_paths] if isinstance(path_or_paths, (str, Path)) else path_or_paths)]
    if not paths:
        raise SceneError("granstab.io.load: no input")
    unknown = sorted(set(options) - OPTION_KEYS - {"columns"})
    if unknown:
        raise SceneError(f"granstab.io.load: unknown option {unknown[0]!r}")
    chosen = None if format == "auto" else get(format)
    if len(paths) == 1 and paths[0].is_dir() and not (chosen.folder if chosen else reads_folder(paths[0])):
        paths = _files_in(paths[0])
    fmt = chosen or get(detect(paths))
    if options.get("columns") and not fmt.columns:
        raise SceneError(f"--columns: the {fmt.name} format has fixed columns (only "
                         f"{' and '.join(f.name for f in map(get, formats()) if f.columns)} name them)")
    if fmt.scene_file and (options or frame is not None or timestep is not None):
        given = next(iter(options), "frame" if frame is not None else "timestep")
        raise SceneError(f"{paths[0]}: {given}: an option of snapshots; a scene file ({fmt.name}) is read as written")
    if options.get("cell") is not None and fmt.name != "table":
        raise SceneError(f"--cell: only the generic tables take a cell ({fmt.name} input gives its own or none)")
    request = Request(frame=frame if frame is not None else timestep, columns=options.pop("columns", None), tol=tol,
                      cell=options.pop("cell", None))
    with ReadProgress(paths, progress) as bar:
        read = fmt.read(paths, request, bar)
        if fmt.scene_file:
            return Loaded(read, {"source": str(paths[0]), "format": fmt.name, "read_as": "scene file",
                                 "warnings": []})
        if isinstance(options.get("region"), str):
            options["region"] = parse_region(options["region"])
        return build(read, Options(**options), progress=bar, tol=tol)


def frames(path_or_paths, *, format: str = "auto", **options) -> list:
    """The frames a snapshot input holds, in order: the keys `load(..., frame=key)` takes (an annulus frame number,
    a LAMMPS or DataSim timestep, a table's `frame` value, a MercuryDPM time); [None] for an input of one frame or a
    scene file. Reads the input's default frame with the same `options` (an unreadable input fails here, in one
    line)."""
    held = load(path_or_paths, format=format, **options).frames
    return [None] if held is None else list(held)


def load_scene(path, tol: Tolerances = DEFAULT, *, progress: bool = False) -> Scene:
    """Read a scene file (TOML, JSON or NPZ) or a snapshot into a validated `Scene`: the scene of `load(path)`.

    Parameters
    ----------
    path : str or Path
        A .toml or .json scene file (contact-level or shape-based, docs/formats.md), an .npz written by
        `save_scene`, or a snapshot (a folder or another file: DEM output, experiments) read with the import's
        defaults.
    tol : Tolerances
        Input tolerances of the checks.
    progress : bool
        A bar on stderr while a large file is read, then its stages (parse, checks).

    Returns
    -------
    Scene
        Validated; the import's validation report is dropped (`load` returns it too).

    Raises
    ------
    SceneError
        An unreadable file or a failed check, in one line naming the file, the entry and the field.
    """
    return load(path, progress=progress, tol=tol).scene


def _files_in(folder: Path) -> list[Path]:
    paths = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")
                   and p.suffix.lower() not in SKIPPED_IN_FOLDERS)
    if not paths:
        raise SceneError(f"{folder}: no snapshot files in this folder")
    return paths


def parse_region(text: str):
    """`box:lo0,hi0,lo1,hi1[,lo2,hi2]` (scaled centres), `ids:ID,ID,...` or `ids:@FILE` (a scene file's particle
    names, or ids separated by blanks or commas) → the `region` option."""
    kind, _, rest = text.partition(":")
    if kind == "box":
        try:
            return {"box": [float(v) for v in rest.split(",")]}
        except ValueError:
            raise SceneError(f"--region: box: expected comma-separated numbers, got {rest!r}") from None
    if kind != "ids" or not rest:
        raise SceneError(f"--region: expected box:lo,hi,lo,hi[,lo,hi] or ids:ID,... or ids:@FILE, got {text!r}")
    if not rest.startswith("@"):
        return [v for v in rest.split(",") if v]
    path = Path(rest[1:])
    if path.suffix.lower() in (".json", ".toml"):
        return list(load_scene(path).names)
    try:
        return path.read_text(encoding="utf-8").replace(",", " ").split()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read file ({getattr(exc, 'strerror', None) or exc})") from None


def is_snapshot(path) -> bool:
    """True for inputs that no scene-file format accepts (folders, DEM output, tables): `load` converts them."""
    path = Path(path)
    return not any(fmt.sniff([path]) for fmt in map(get, formats()) if fmt.scene_file)


__all__ = ["GEOMETRY", "OUTSIDE_CONE", "Format", "Loaded", "Request", "detect", "format_report", "formats", "frames",
           "is_snapshot", "load", "load_scene", "parse_region", "register"]
