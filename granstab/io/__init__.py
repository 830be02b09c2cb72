"""Real packings in: DEM snapshots and experimental frames become contact-level scenes (issue 9).

    imported = granstab.io.load("DataAnnulus/10", frame=1, geometry="touching", length_scale=0.027, units="cm")
    imported.scene, imported.report, imported.frames

One module per source format turns files into a `Snapshot` (numpy-vectorised reading); `build.build` applies the
conventions every format shares (contact point, normal, curvature, cone policy, loads: see build.py) and writes
the validation report. `format="auto"` picks the reader from the files.
"""
from __future__ import annotations

from pathlib import Path

from ..model.errors import SceneError
from . import generic as table
from . import lammps, mercury, rigidlibrary
from .build import GEOMETRY, OUTSIDE_CONE, Imported, Options, build
from .scenes import ReadProgress
from .validation import format_report

FORMATS = ("rigidlibrary-annulus", "rigidlibrary-datasim", "lammps", "mercurydpm", "table")
OPTION_KEYS = {"k", "alpha", "mu", "geometry", "outside_cone", "yield_rtol", "length_scale", "units", "region",
               "keep_rattlers", "density"}


def detect(paths: list[Path]) -> str:
    """The format of `paths` from their names and layout; a one-line error if none fits."""
    first = paths[0]
    for path in paths:
        if not path.exists():
            raise SceneError(f"{path}: cannot read file (no such file or directory)")
    if rigidlibrary.is_annulus(first):
        return "rigidlibrary-annulus"
    if rigidlibrary.is_datasim(first):
        return "rigidlibrary-datasim"
    if any(lammps.is_dump(p) for p in paths):
        return "lammps"
    if mercury.is_mercury(paths):
        return "mercurydpm"
    if all(table.is_table(p) for p in paths):
        return "table"
    raise SceneError(f"{first}: format: not recognised (known: {', '.join(FORMATS)}); name it with --format")


def load(path_or_paths, *, format: str = "auto", frame=None, timestep=None, progress: bool = False,
         **options) -> Imported:
    """Read a snapshot (a file, a folder or several files) into a Scene with its validation report.
    A folder that is not a RigidLibrary layout stands for the files in it (one snapshot's dumps or tables).

    Options: k, alpha, mu (override the file's law), geometry ("centres" | "touching"), outside_cone
    ("sliding" | "project" | "elastic" | "error"), yield_rtol, length_scale (file length unit → scene unit),
    units (its name), region (ids, or {"box": [lo, hi, ...]} on scaled centres), keep_rattlers,
    columns (formats with named columns). progress: a bar on stderr while large files are read (LAMMPS dumps and
    tables: bytes scanned and parsed), then the stages (build, checks), as load_scene(..., progress=True) shows."""
    paths = [Path(p) for p in ([path_or_paths] if isinstance(path_or_paths, (str, Path)) else path_or_paths)]
    if not paths:
        raise SceneError("granstab.io.load: no input")
    if len(paths) == 1 and paths[0].is_dir() and not (rigidlibrary.is_annulus(paths[0])
                                                      or rigidlibrary.is_datasim(paths[0])):
        paths = sorted(p for p in paths[0].iterdir() if p.is_file() and not p.name.startswith(".")
                       and p.suffix.lower() not in (".json", ".toml", ".npz", ".py", ".sh", ".md"))
        if not paths:
            raise SceneError(f"{path_or_paths}: no snapshot files in this folder")
    unknown = sorted(set(options) - OPTION_KEYS - {"columns"})
    if unknown:
        raise SceneError(f"granstab.io.load: unknown option {unknown[0]!r}")
    fmt = detect(paths) if format == "auto" else format
    if fmt not in FORMATS:
        raise SceneError(f"--format: must be auto or one of {', '.join(FORMATS)}, got {fmt!r}")
    if options.get("columns") and fmt not in ("lammps", "table"):
        raise SceneError(f"--columns: the {fmt} format has fixed columns (only lammps and table name them)")
    which = frame if frame is not None else timestep
    with ReadProgress(paths, progress) as bar:
        if fmt == "rigidlibrary-annulus":
            snap = rigidlibrary.read_annulus(paths[0], which)
        elif fmt == "rigidlibrary-datasim":
            snap = rigidlibrary.read_datasim(paths[0], which)
        elif fmt == "mercurydpm":
            snap = mercury.read_mercury(paths, which)
        elif fmt == "lammps":
            snap = lammps.read_lammps(paths, which, options.get("columns"), progress=bar)
        else:
            snap = table.read_tables(paths, which, options.get("columns"), progress=bar)
        if isinstance(options.get("region"), str):
            options["region"] = parse_region(options["region"])
        opts = Options(**{k: v for k, v in options.items() if k in OPTION_KEYS})
        return build(snap, opts, progress=bar)


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
        from .scenes import load_scene
        return list(load_scene(path).names)
    try:
        return path.read_text(encoding="utf-8").replace(",", " ").split()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read file ({getattr(exc, 'strerror', None) or exc})") from None


def is_snapshot(path) -> bool:
    """True for inputs `granstab.load_scene` hands to `load`: folders, and files that are not scene files."""
    path = Path(path)
    return path.is_dir() or path.suffix.lower() not in (".toml", ".json", ".npz")


__all__ = ["FORMATS", "GEOMETRY", "OUTSIDE_CONE", "Imported", "detect", "format_report", "is_snapshot", "load", "parse_region"]
