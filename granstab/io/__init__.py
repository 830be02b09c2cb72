"""Everything in and out: scene files and real packings (DEM snapshots, experimental frames) through one loader.

    loaded = granstab.io.load("DataAnnulus/10", frame=1, geometry="touching", length_scale=0.027, units="cm")
    loaded.scene, loaded.report, loaded.warnings, loaded.frames
    granstab.io.load("presets/gear.toml").scene            # a scene file: report "read as a scene file", no warnings

Each reader module registers its formats (registry.py: a name, a sniff, a read): scene files (scenes.py: TOML,
JSON, NPZ; contact-level and shape-based), RigidLibrary folders, LAMMPS dumps, MercuryDPM output and generic
tables. `format="auto"` takes the one whose sniff accepts the paths; `open` indexes the input's frames once
(source.py), `load` is `open(...).read(frame)`; a snapshot reader's `Snapshot` goes through `build.build`, which
applies the conventions every format shares (contact point, normal, curvature, cone policy,
loads) and writes the validation report (validation.py).
"""
from __future__ import annotations

from pathlib import Path

from ..model.scene import Scene
from ..model.tolerances import DEFAULT, Tolerances
from . import clumps, generic, lammps, liggghts_superquadric, mercury, multisphere, polygons, rigidlibrary, scenes  # noqa: F401  (each registers its formats)
from .build import GEOMETRY, OUTSIDE_CONE
from .progress import ReadProgress
from .registry import Format, Loaded, Request, detect, formats, get, register
from .source import (  # noqa: F401
    OPTION_KEYS,
    SKIPPED_IN_FOLDERS,
    Source,
    open_source,
    parse_region,
    resolve,
    snapshot_files,
)
from .validation import format_report


def open(path_or_paths, *, format: str = "auto", progress: bool = False, tol: Tolerances = DEFAULT,  # noqa: A001
         **options) -> Source:
    """The input's frames, indexed once: `Source.frames` (the keys `read` takes, [None] for one frame or a scene
    file) and `Source.read(frame)` → `Loaded`, each frame read alone (a LAMMPS dump: its timestep's rows only).
    Arguments as `load`'s (without `frame`); source.py."""
    return open_source(path_or_paths, format=format, progress=progress, tol=tol, **options)


def load(path_or_paths, *, format: str = "auto", frame=None, timestep=None, progress: bool = False,
         tol: Tolerances = DEFAULT, **options) -> Loaded:
    """Read a scene file or a snapshot (a file, a folder or several files) into a Scene with its validation report:
    `open(...).read(frame)`.

    Parameters
    ----------
    path_or_paths : str, Path or list of them
        A scene file (.toml, .json, .npz), or one snapshot's files or folder. A folder that no format reads
        itself (RigidLibrary layouts do) stands for the files in it (one snapshot's dumps or tables).
    format : str
        "auto" (the registered format whose sniff accepts the paths) or a name of `formats()`.
    frame, timestep : int or float, optional
        The frame (or timestep, or time) of a snapshot with several; default the format's (the first; LAMMPS: the
        last timestep both dumps have).
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
    paths = resolve(path_or_paths, format)[0] if progress else path_or_paths     # the bar names the files read
    with ReadProgress(paths, progress) as bar:
        source = open_source(paths, format=format, frame=frame, timestep=timestep, tol=tol, bar=bar, **options)
        return source.read(frame if frame is not None else timestep, bar=bar)


def frames(path_or_paths, *, format: str = "auto", **options) -> list:
    """The frames a snapshot input holds, in order: the keys `load(..., frame=key)` takes (an annulus frame number,
    a LAMMPS or DataSim timestep, a table's `frame` value, a MercuryDPM time); [None] for an input of one frame or a
    scene file: `open(...).frames`."""
    return open_source(path_or_paths, format=format, **options).frames


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


def is_snapshot(path) -> bool:
    """True for inputs that no scene-file format accepts (folders, DEM output, tables): `load` converts them."""
    path = Path(path)
    return not any(fmt.sniff([path]) for fmt in map(get, formats()) if fmt.scene_file)


__all__ = ["GEOMETRY", "OUTSIDE_CONE", "Format", "Loaded", "Request", "Source", "detect", "format_report", "formats",
           "frames", "is_snapshot", "load", "load_scene", "open", "parse_region", "register", "snapshot_files"]
