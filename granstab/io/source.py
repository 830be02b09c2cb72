"""An input's frames, indexed once and each read on demand: `granstab.io.open` → `Source` (issue 40).

    source = granstab.io.open(["atoms.dump", "contacts.dump", "in.disks"], mu=0.5)
    source.frames                  # the keys, from one pass over the dumps (each timestep's byte offsets)
    loaded = source.read(18000)    # that timestep's rows only, then build.build: scene + validation report
    granstab.io.load(paths, frame=18000)           # open(paths).read(18000)

A format that registers an `index` (LAMMPS dumps) is indexed by it. Any other (a reader registered with `read`
alone) goes through `Reread`: the read that lists its frames is kept for the frame it read, and every other frame
is one `read`. What the index left out (timesteps in one dump only, a truncated last timestep) is its `warnings`,
on every frame's report.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..model.errors import SceneError
from ..model.tolerances import DEFAULT, Tolerances
from .build import Options, build
from .progress import ReadProgress
from .registry import Loaded, Request, detect, formats, get, reads_folder

OPTION_KEYS = {"k", "alpha", "mu", "geometry", "outside_cone", "yield_rtol", "length_scale", "units", "region",
               "keep_rattlers", "density", "periodic", "cell"}
SKIPPED_IN_FOLDERS = (".json", ".toml", ".npz", ".py", ".sh", ".md")   # a snapshot folder's other files


def snapshot_files(folder: Path) -> list[Path]:
    """The files of a snapshot folder that a reader may take (not hidden, not a scene file, script or note), sorted:
    what the folder stands for where no format reads the folder itself."""
    return sorted(p for p in Path(folder).iterdir() if p.is_file() and not p.name.startswith(".")
                  and p.suffix.lower() not in SKIPPED_IN_FOLDERS)


class Reread:
    """The index of a format registered with `read` alone: the first read (of the frame asked for, or the default)
    lists the frames and is kept; any other frame is read again from the paths."""

    warnings: tuple = ()

    def __init__(self, name: str, paths: list[Path], request: Request, progress):
        self.name, self.paths = name, paths
        self.first = get(name).read(paths, request, progress)
        self.asked, self.key = request.frame, getattr(self.first, "frame", None)
        held = getattr(self.first, "frames", None)
        self.frames = None if held is None else list(held)

    def read(self, frame, request: Request, progress):
        if self.first is not None and frame in (self.asked, self.key):
            return self.first
        return get(self.name).read(self.paths, replace(request, frame=frame), progress)

    def __getstate__(self):
        """Sent to a worker without the kept read (its line lookups are closures; the worker reads its frames)."""
        return {**self.__dict__, "first": None}


class Source:
    """An input opened once: `frames` (the keys `read` takes; [None] for one frame or a scene file), `warnings`
    (frames left out, one line each) and `read(frame)` → `Loaded`."""

    def __init__(self, paths: list[Path], name: str, request: Request, options: dict, progress: bool, bar=None):
        self.paths, self.format, self.options, self.progress = paths, name, options, progress
        self.request, self.tol = replace(request, frame=None), request.tol
        fmt = get(name)
        with ReadProgress(paths, progress and bar is None) as own:
            self.index = (fmt.index or (lambda *a: Reread(name, *a)))(paths, request, bar or own)

    @property
    def frames(self) -> list:
        return [None] if self.index.frames is None else list(self.index.frames)

    @property
    def warnings(self) -> list[str]:
        return list(self.index.warnings)

    def spans(self, frames=None) -> dict:
        """{path: [(frame, first byte, end)]} of the frames whose bytes the index knows (lammps.DumpIndex.spans;
        {} for a format read whole): what a resumable folder hashes frame by frame (scan/resume.py)."""
        spans = getattr(self.index, "spans", None)
        return {} if spans is None else spans(frames)

    def read(self, frame=None, bar=None) -> Loaded:
        """Frame `frame` (default the input's own default) as a scene and its validation report."""
        fmt = get(self.format)
        with ReadProgress(self.paths, self.progress and bar is None) as own:
            got = self.index.read(frame, self.request, bar or own)
            if fmt.scene_file:
                return Loaded(got[0], {"source": str(self.paths[0]), "format": fmt.name, "read_as": "scene file",
                                       "warnings": []}, grains=got[1])     # its grains' shapes (model/grains.py)
            loaded = build(got, Options(**self.options), progress=bar or own, tol=self.tol)
        if self.warnings:
            loaded.report["frames_left_out"] = self.warnings
            loaded.report["warnings"][:0] = self.warnings
        return loaded


def resolve(path_or_paths, format: str = "auto"):
    """(the paths read, the Format): a folder that no format reads itself stands for its `snapshot_files`."""
    paths = [Path(p) for p in ([path_or_paths] if isinstance(path_or_paths, (str, Path)) else path_or_paths)]
    if not paths:
        raise SceneError("granstab.io.load: no input")
    chosen = None if format == "auto" else get(format)
    if len(paths) == 1 and paths[0].is_dir() and not (chosen.folder if chosen else reads_folder(paths[0])):
        folder, paths = paths[0], snapshot_files(paths[0])
        if not paths:
            raise SceneError(f"{folder}: no snapshot files in this folder")
    return paths, chosen or get(detect(paths))


def open_source(path_or_paths, *, format: str = "auto", progress: bool = False, tol: Tolerances = DEFAULT,
                frame=None, timestep=None, bar=None, **options) -> Source:
    """`granstab.io.open`: the input's format found and its frames indexed (module docstring); the options are
    `load`'s, checked here. `frame` (or `timestep`): the frame a first read is for (formats without an index read
    it now); `bar`: a ReadProgress already open (load's)."""
    unknown = sorted(set(options) - OPTION_KEYS - {"columns"})
    if unknown:
        raise SceneError(f"granstab.io.load: unknown option {unknown[0]!r}")
    paths, fmt = resolve(path_or_paths, format)
    if options.get("columns") and not fmt.columns:
        raise SceneError(f"--columns: the {fmt.name} format has fixed columns (only "
                         f"{' and '.join(f.name for f in map(get, formats()) if f.columns)} name them)")
    if fmt.scene_file and (options or frame is not None or timestep is not None):
        given = next(iter(options), "frame" if frame is not None else "timestep")
        raise SceneError(f"{paths[0]}: {given}: an option of snapshots; a scene file ({fmt.name}) is read as written")
    if options.get("cell") is not None and fmt.name != "table":
        raise SceneError(f"--cell: only the generic tables take a cell ({fmt.name} input gives its own or none)")
    request = Request(frame=frame if frame is not None else timestep, columns=options.pop("columns", None), tol=tol, cell=options.pop("cell", None))
    if isinstance(options.get("region"), str):
        options["region"] = parse_region(options["region"])
    return Source(paths, fmt.name, request, options, progress, bar)


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
        return list(open_source(path).read().scene.names)
    try:
        return path.read_text(encoding="utf-8").replace(",", " ").split()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read file ({getattr(exc, 'strerror', None) or exc})") from None


def frame_key(text: str):
    """A frame as the input names it (--frame, --timestep, --frames): an integer where it is one (frame numbers,
    steps), else a float (times); ValueError for anything else."""
    value = float(text)
    return int(value) if value.is_integer() else value


def pick_frames(text: str, available: list | None, source) -> list:
    """--frames: 'A,B,C' or 'A:B[:STEP]' (the input's frames from A to B inclusive, every STEP-th), checked against
    the frames the input holds (export, track: one meaning)."""
    if not available:
        raise SceneError(f"--frames: {source} holds one frame")
    try:
        if ":" in text:
            parts = [frame_key(v) for v in text.split(":")]
            if len(parts) not in (2, 3) or (len(parts) == 3 and (parts[2] < 1 or parts[2] != int(parts[2]))):
                raise ValueError
            chosen = [f for f in available if parts[0] <= f <= parts[1]][::int(parts[2]) if len(parts) == 3 else 1]
        else:
            chosen = [frame_key(v) for v in text.split(",")]
    except ValueError:
        raise SceneError(f"--frames: expected A,B,C or A:B[:STEP], got {text!r}") from None
    missing = [f for f in chosen if f not in available]
    if missing or not chosen:
        raise SceneError(f"--frames: {source} has no frame {missing[0] if missing else text} (its frames: "
                         f"{', '.join(map(str, available[:8]))}{', …' if len(available) > 8 else ''})")
    return chosen
