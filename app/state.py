"""The per-client session of the explorer: preset, parameters, poses, current Scene, last analysis, errors.

Pure Python (no viser): the GUI callbacks call these methods and read the results, and the unit tests drive them
directly. Every number comes from the core (granstab.analyze, granstab.model.shapes, granstab.mechanics.stiffness); a failure of
a preset, a scene or an analysis is caught here and kept as a one-line `error` — nothing raises to the caller
except programming errors (an unknown parameter name). Not thread-safe: the GUI serialises calls with a lock.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

import granstab
from granstab.model import errors
from granstab.rigidity.output import is_rigidity_dir

from .modes import rotation_matrix
from .params import PARAMS
from .paths import PathRefused, folder_choice, typed_path
from .pools import MAX_SLIDING, OFFLOAD, analysed, samples, shared
from .protocols import MapModel
from .readings import Readings
from .rigiditymap import load_rigidity_map
from .scanmap import is_scan_dir, load_scan_map
from .scenes import Body, ShapeModel, TwoParticleModel, load_model
from .trackmap import is_track_dir, load_track

PRESETS_DIR = Path(__file__).resolve().parent.parent / "presets"
DEFAULT_PRESET = "two_particle"
LARGE = 500               # particles: above this the whole packing is analysed only on request (`analyse`)
MAX_UPLOAD = 5_000_000     # bytes: a scene file larger than this is refused before it is parsed


def one_line(exc: BaseException) -> str:
    text = errors.one_line(exc) or type(exc).__name__
    return text if isinstance(exc, (granstab.SceneError, ValueError)) else f"{type(exc).__name__}: {text}"


class Session(Readings):
    """State of one browser tab. `error` is None or the one-line message of the last failure."""

    def __init__(self, preset: str | None = None, presets_dir=None, data_root=None, typed_paths: bool = True,
                 offload: bool = False):
        self.offload = offload               # large scenes analysed in a worker process (the server's sessions)
        self.presets_dir = Path(presets_dir) if presets_dir else PRESETS_DIR
        self.data_root = Path(data_root) if data_root else None   # typed paths: read inside it (app/paths.py)
        self.typed_paths = typed_paths or self.data_root is not None
        self.preset: str | None = None
        self.model = None
        self.params: dict[str, float] = {}
        self.scene: granstab.Scene | None = None
        self.analysis = None
        self.metrics: dict | None = None     # the metric-family check, when asked for (check_metrics)
        self.metric = "L"                    # the projection metric of the verdict: "L" or "inertia" (with masses)
        self.force_band = 0.0                # ± % on every contact force (panel/uncertainty.py; 0: not asked)
        self.position_band = 0.0             # ± % of a radius on every contact position (the same; 0: not asked)
        self.robust: tuple = (None, None)    # ((revision, band), its data_robustness), computed when shown
        self.error: str | None = None
        self.notice: str | None = None
        self.caveat: str | None = None       # what the analysis leaves out (recompute)
        self.adjusted = ""                   # what building the scene changed beyond the sliders (recompute)
        self.elapsed = 0.0
        self.revision = 0
        self._modes: tuple[int, list] = (-1, [])
        self._motions: tuple[int, dict] = (-1, {})      # per branch, for this revision (motions)
        self._report: tuple = (None, {})                # report(), for what it was computed from (once per revision)
        self._type1_of: tuple = (None, "")              # (analysis, its Type-1 line): solved once per analysis
        self._pair: TwoParticleModel | None = None   # the slider-driven pair a drag turned into shapes
        self.map = None                              # the scan map a cluster was opened from (back_to_map)
        if not self.load_preset(preset or DEFAULT_PRESET) and self.model is None and preset not in (None, DEFAULT_PRESET):
            message = self.error
            self.load_preset(DEFAULT_PRESET)
            self.error = message

    # ------------------------------------------------------------------------------------------ inputs

    def presets(self) -> list[str]:
        """Preset names (file stems) in the presets folder, the two-particle pair first."""
        names = sorted({p.stem for p in self.presets_dir.glob("*") if p.suffix in (".toml", ".json")})
        return sorted(names, key=lambda n: (n != DEFAULT_PRESET, n))

    def resolve(self, name_or_path: str) -> Path:
        path = Path(name_or_path)
        if path.is_file():
            return path
        for suffix in (".toml", ".json"):
            candidate = self.presets_dir / f"{name_or_path}{suffix}"
            if candidate.is_file():
                return candidate
        return path

    def load_preset(self, name_or_path: str) -> bool:
        """Switch to a preset name or scene file. On failure keep the current scene and set `error`."""
        path = self.resolve(str(name_or_path))
        try:
            model = (load_track(path) if is_track_dir(path) else load_scan_map(path) if is_scan_dir(path)
                     else load_rigidity_map(path) if is_rigidity_dir(path) else load_model(path))
        except Exception as exc:  # noqa: BLE001 — any bad file must end up as a message, not a crash
            self.error = one_line(exc) if isinstance(exc, granstab.SceneError) else f"{path}: {one_line(exc)}"
            return False
        self.preset = path.stem if path.parent == self.presets_dir else str(path)
        self.model = model
        self._pair = self.map = None
        self.params = model.initial_params()
        self.notice = None
        self.recompute()
        return self.error is None

    def open_typed(self, text: str) -> bool:
        """Open what was typed into *Path on server*: a preset name, or a path under the server's policy
        (app/paths.py: off beyond loopback without a data root, else confined to it); a folder that is neither a scan
        nor a snapshot is named as a folder with its scene files, never tried file by file."""
        name = text.strip()
        if name in self.presets():                   # a preset's name (a bare file stem: no way out of the folder)
            return self.load_preset(name)
        try:
            path = typed_path(name, self.data_root, self.typed_paths)
        except PathRefused as exc:
            self.error = str(exc)
            return False
        if path.is_dir() and not opens_as_folder(path):
            self.error = folder_choice(path)
            return False
        return self.load_preset(str(path))

    def load_upload(self, name: str, content: bytes) -> bool:
        """Open a file sent from the page: size-guarded (MAX_UPLOAD bytes), read from a private temporary folder that
        is removed afterwards; the page sees only the file's own name, never the server's path."""
        name = Path(name).name or "upload"
        if self.refuse_large(name, len(content)):
            return False
        suffix = Path(name).suffix.lower()          # a snapshot's suffix picks its reader (granstab.io)
        with tempfile.TemporaryDirectory(prefix="granstab-upload-") as folder:
            path = Path(folder) / (Path(name).stem + suffix)
            path.write_bytes(content)
            ok = self.load_preset(str(path))
            hidden = str(path)
        if self.error:
            self.error = self.error.replace(hidden, name)
        if ok:
            self.preset = f"{name} (opened)"
        return ok

    def refuse_large(self, name: str, size: int) -> bool:
        """Whether a file of `size` bytes is over MAX_UPLOAD; if so `error` says so, with the size and the limit."""
        if size <= MAX_UPLOAD:
            return False
        self.error = f"{Path(name).name}: rejected, {size / 1e6:.1f} MB is over the {MAX_UPLOAD / 1e6:.0f} MB limit"
        return True

    @property
    def kind(self) -> str:
        return self.model.kind

    @property
    def on_map(self) -> bool:
        """A packing shown as a map (a scan, a track's frame, a rigidity folder): no verdict of its own."""
        return isinstance(self.model, MapModel)

    @property
    def used_params(self) -> tuple:
        """The parameters the current scene uses (the only sliders shown)."""
        return tuple(self.model.params_used)

    def set_params(self, **values) -> bool:
        """Set parameters (clipped and rounded to their slider steps); recompute only if something changed."""
        clean = {key: self.param(key).clean(value) for key, value in values.items()}
        if all(self.params.get(key) == value for key, value in clean.items()):
            return False
        self.params.update(clean)
        self.recompute()
        return True

    def param(self, key: str):
        """The slider of parameter `key` for this scene (params.Param.around its start value: k of a DEM run)."""
        return PARAMS[key].around(self.model.initial_params()[key])

    def pick_field(self, rho_r: float, f_kr: float) -> bool:
        """A click on the λ⁽⁶⁾ surface: ρ/r and f/(kr) snapped to their slider steps, so that what is analysed is
        what the sliders show (2.4308, 0.002077 → 2.43, 0.0021)."""
        if self.kind != "two_particle":
            return False
        return self.set_params(rho_r=PARAMS["rho_r"].snap(rho_r), f_kr=PARAMS["f_kr"].snap(f_kr))

    @property
    def draggable(self) -> bool:
        return bool(self.model.draggable)

    def move(self, name: str, x, R) -> None:
        """Move particle `name` to position x and orientation R (2D: in-plane; R (d, d) or an angle in 2D).

        The slider-driven pair becomes a shape model of the same two ellipses on its first drag (contacts, normals,
        curvatures and forces then follow the geometry)."""
        if not self.draggable:
            self.error = "this scene is contact-level (no shapes): its geometry cannot be dragged"
            return
        if isinstance(self.model, TwoParticleModel):
            self._pair = self.model
            self.model = self.model.to_shapes(self.params)
            self.notice = ("dragging turned the pair into shapes: contacts now follow the geometry; *Reset* "
                           "returns to the ρ/r, f/(kr) sliders")
        if np.ndim(R) == 0:
            R = rotation_matrix(2, R)
        self.model.set_pose(name, np.asarray(x, float), np.asarray(R, float)[:self.scene_dim, :self.scene_dim])
        self.recompute()

    @property
    def resettable(self) -> bool:
        """Whether *Reset* has something to undo: dragged poses, or a pair turned into shapes by a drag."""
        return self._pair is not None or isinstance(self.model, ShapeModel)

    def reset_poses(self) -> None:
        """Back to the start poses; a dragged pair goes back to the slider-driven pair (ρ/r, f/(kr) as before)."""
        if self._pair is not None:
            self.model, self._pair, self.notice = self._pair, None, None
            self.params = {**self.model.initial_params(), **self.params}
            self.recompute()
        elif isinstance(self.model, ShapeModel):
            self.model.reset_poses()
            self.recompute()

    # ------------------------------------------------------------------------------------------ compute

    @property
    def deferred(self) -> bool:
        """A large packing: drawn at once, analysed only when asked (`analyse`)."""
        return (not self.on_map and self.scene is not None and self.scene.n_particles > LARGE
                and self.analysis is None)

    def set_frame(self, frame) -> bool:
        """Show another frame of an imported snapshot (its validation report follows) or of a track (at_frame)."""
        if self.model.frames is None or frame == self.model.frame:
            return False
        try:
            self.model = self.model.at_frame(frame) or load_model(self.model.path, frame=frame)
        except Exception as exc:  # noqa: BLE001
            self.error = one_line(exc)
            return False
        self.recompute()
        return True

    @property
    def map_colours(self) -> np.ndarray | None:
        """(N, 3) colours of the scan map (share of unstable clusters per particle by the packing; grey: by the cut
        alone), or None off the map."""
        return self.model.colours if self.on_map else None

    def open_cluster(self, name: str) -> bool:
        """From the scan map: the cluster of particle `name` becomes the scene (back_to_map returns)."""
        scan_map = self.model if self.on_map else None
        if scan_map is None:
            self.error = "open a scan folder first: clusters are opened from its map"
            return False
        try:
            self.model = scan_map.cluster(str(name))
        except granstab.SceneError as exc:
            self.error = one_line(exc)
            return False
        self.map, self.params, self.notice = scan_map, self.model.initial_params(), None
        self.recompute()
        return True

    def back_to_map(self) -> bool:
        if self.map is None:
            return False
        self.model, self.map = self.map, None
        self.params = self.model.initial_params()
        self.recompute()
        return True

    def pick(self, origin, direction) -> str | None:
        """The particle of the scan map under a click ray (None off the map or between particles)."""
        return self.model.pick(origin, direction) if self.on_map else None

    def analyse(self) -> None:
        """Analyse a large packing now (recompute skips it above LARGE particles)."""
        self.recompute(force=True)

    def recompute(self, force: bool = False) -> None:
        """Build the scene and analyse it (a packing above LARGE particles only when `force`d); any failure
        becomes `error` (the analysis is then None)."""
        start = time.perf_counter()
        self.revision += 1
        self.analysis = None
        self.caveat = None                  # what the analysis leaves out, in one line (the sampled path)
        self.metrics = None
        try:
            self.scene = self.model.build(self.params)
            self.adjusted = self.model.adjustments(self.params)     # what the build changed beyond the sliders
            if self.on_map or (self.scene.n_particles > LARGE and not force):
                self.error = None
                self.elapsed = time.perf_counter() - start
                return
            if self.metric not in self.metric_choices:
                self.notice = f"this scene has no masses: metric {self.metric} → L"
                self.metric = "L"
            if self.offload and self.scene.n_particles >= OFFLOAD:
                self.analysis = shared(self.scene, self.metric)
            else:
                self.analysis = analysed(self.scene, self.metric, attribution=False)   # attribute(): after the verdict
            self.error = None
            if samples(self.scene):
                n = int(self.scene.at_yield().sum())
                self.caveat = (f"{n} contacts at the friction limit: their 2^{n} cases are too many to try all; the "
                               f"all-sliding, all-sticking and {samples(self.scene)} random cases were analysed (sampled: an "
                               f"unstable verdict holds, a stable one is not proven; at most {MAX_SLIDING} such "
                               "contacts are tried in full, e.g. with a larger μ).")
        except Exception as exc:  # noqa: BLE001 — shown in the page, never raised into the server
            self.error = one_line(exc)
        self.elapsed = time.perf_counter() - start

    @property
    def metric_choices(self) -> tuple:
        """The metrics the verdict can use here: L always, the inertia metric where the scene has masses."""
        return ("L", "inertia") if self.scene is not None and self.scene.mass is not None else ("L",)

    def set_metric(self, name: str) -> bool:
        """Analyse in metric `name` (one of metric_choices); recompute only on a change."""
        if name not in self.metric_choices:
            self.error = f"metric: {name!r} is not available here (choices: {', '.join(self.metric_choices)})"
            return False
        if name == self.metric:
            return False
        self.metric = name
        self.recompute()
        return True

    @property
    def scene_dim(self) -> int:
        return self.scene.dim if self.scene is not None else self.model.dimension()

    def bodies(self) -> list[Body]:
        return self.model.bodies(self.params)

    @property
    def size(self) -> float:
        """A particle length scale (mean largest semi-axis): sets arrows, markers and the animation amplitude."""
        return float(np.mean([max(b.axes) for b in self.bodies()]))

    
def opens_as_folder(folder: Path, most: int = 64) -> bool:
    """Whether a folder opens whole: a scan, a folder a format reads itself (RigidLibrary), or a snapshot whose files
    (at most `most`, those granstab.io.load would take) one format reads together (a LAMMPS run's dumps)."""
    from granstab.io import snapshot_files
    from granstab.io.registry import detect, reads_folder
    if is_scan_dir(folder) or is_rigidity_dir(folder) or reads_folder(folder):
        return True
    files = snapshot_files(folder)
    if not files or len(files) > most:
        return False
    try:
        detect(files)
    except (granstab.SceneError, OSError):
        return False
    return True

