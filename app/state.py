"""The per-client session of the explorer: preset, parameters, poses, current Scene, last analysis, errors.

Pure Python (no viser): the GUI callbacks call these methods and read the results, and the unit tests drive them
directly. Every number comes from the core (granstab.analyze, granstab.model.shapes, granstab.mechanics.stiffness); a failure of
a preset, a scene or an analysis is caught here and kept as a one-line `error` — nothing raises to the caller
except programming errors (an unknown parameter name). Not thread-safe: the GUI serialises calls with a lock.
"""
from __future__ import annotations

import hashlib
import json
import os
import pickle
import tempfile
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import granstab
from granstab.analysis import analyze
from granstab.mechanics.branches import BOTH, MINUS, PLUS, RIGID
from granstab.mechanics.verdicts import frequencies_and_growth
from granstab.model import errors
from granstab.rigidity.output import is_rigidity_dir
from granstab.solve.threads import blas_threads

from .field import Field, field_png, lambda6_field
from .models import Body, ShapeModel, TwoParticleModel, load_model
from .modes import label_modes, mode_offsets, rotation_matrix
from .params import PARAMS
from .paths import PathRefused, folder_choice, typed_path
from .rigiditymap import load_rigidity_map
from .scanmap import is_scan_dir, load_scan_map
from .trackmap import is_track_dir, load_track

PRESETS_DIR = Path(__file__).resolve().parent.parent / "presets"
DEFAULT_PRESET = "two_particle"
CONSISTENT = (PLUS, MINUS, BOTH)
LARGE = 500               # particles: above this the whole packing is analysed only on request (`analyse`)
MAX_UPLOAD = 5_000_000     # bytes: a scene file larger than this is refused before it is parsed
SAME_MODE = 0.999          # |cos| of two unit motions above which they are one mode (distinct_modes)
OFFLOAD = 50               # particles: from here a server's session analyses in a worker process (analysis_pool)
_POOL: list = []           # the worker processes, made when first needed (analysis_pool)
WORKER_NICE = 10           # the workers' priority below the server's (os.nice steps: 10 of 19)
SHARED = 16                # offloaded analyses kept for every session (shared): ~3 MB each at annulus_frame's 143 disks
_SHARED: OrderedDict = OrderedDict()     # (scene, metric) digest → Analysis, the most recently used last
_SHARED_LOCK = threading.Lock()


@dataclass(frozen=True)
class Mode:
    """One eigenpair of sym(𝓗^i) of branch `branch`: what the spectrum panel lists and the animation plays."""

    branch: int
    index: int
    eigenvalue: float
    code: int                  # granstab.mechanics.branches: PLUS, MINUS, BOTH (consistent), INCONSISTENT, RIGID
    label: str
    shares: dict
    hinges: bool

    @property
    def consistent(self) -> bool:
        return self.code in CONSISTENT

    @property
    def key(self) -> str:
        mark = "" if self.code == RIGID else " ✓" if self.consistent else " ✗"
        return f"b{self.branch} #{self.index}: λ = {self.eigenvalue:.4g} {self.label}{mark}"


def one_line(exc: BaseException) -> str:
    text = errors.one_line(exc) or type(exc).__name__
    return text if isinstance(exc, (granstab.SceneError, ValueError)) else f"{type(exc).__name__}: {text}"


class Session:
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
        self.error: str | None = None
        self.notice: str | None = None
        self.elapsed = 0.0
        self.revision = 0
        self._modes: tuple[int, list] = (-1, [])
        self._motions: tuple[int, dict] = (-1, {})      # per branch, for this revision (motions)
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

    def headline(self) -> tuple[str | None, str]:
        """The verdict word and the reason under it, in one voice: the core's reason may call a neutral verdict whose
        zero is resolved only within its accuracy "NOT DETERMINED"; the page says the verdict once and that it is not
        proven (the table below says why)."""
        r = self.report()
        if r["verdict"] is None:
            return None, ""
        reason = r["reason"].replace("NOT DETERMINED:", "not proven:")
        if not r["sufficient"] and "not proven" not in reason:
            reason += " — not proven"
        return r["verdict"], reason

    def distinct_modes(self) -> dict:
        """Consistent modes by sign, each counted once: the same motion in several branches (a rolling mode that no
        sliding contact takes part in) is one mode. Two unit motions are the same where |cos| ≥ SAME_MODE.
        Returns {"negative": n, "zero": n, "positive": n}; the core's counts (report()["counts"]) are per branch."""
        names = ("negative", "zero", "positive")
        if self.analysis is None:
            return dict.fromkeys(names, 0)
        groups = {name: [] for name in names}          # consistent unit motions by sign, in (branch, index) order
        for i, b in enumerate(self.analysis.branches):
            lam, U = b.stability_eigenvalues, self.motions(i)
            sign = np.where(lam < -b.zero_tol, 0, np.where(lam > b.zero_tol, 2, 1))
            for s, name in enumerate(names):
                groups[name].append(U[:, np.isin(b.codes, CONSISTENT) & (sign == s)])
        out = {}
        for name, parts in groups.items():
            W = np.concatenate(parts, axis=1) if parts else np.zeros((0, 0))     # (no branch: nothing counted)
            same = np.abs(W.T @ W) >= SAME_MODE
            kept: list[int] = []
            for j in range(W.shape[1]):                # a motion counts unless an earlier counted one is the same
                if not same[j, kept].any():
                    kept.append(j)
            out[name] = len(kept)
        return out

    def motions(self, branch: int) -> np.ndarray:
        """The unit physical motions (n_dof, K) of every eigenvector of a branch (Analysis.motion, all at once;
        cached per analysis)."""
        if self._motions[0] != self.revision:
            self._motions = (self.revision, {})
        cache = self._motions[1]
        if branch not in cache:
            cache[branch] = self.analysis.motion(self.analysis.branches[branch].stability_vectors)
        return cache[branch]

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
        return (self.kind != "scan_map" and self.scene is not None and self.scene.n_particles > LARGE
                and self.analysis is None)

    def set_frame(self, frame) -> bool:
        """Show another frame of an imported snapshot (its validation report follows) or of a track (at_frame)."""
        if getattr(self.model, "frames", None) is None or frame == self.model.frame:
            return False
        try:
            at = getattr(self.model, "at_frame", None)
            self.model = at(frame) if at is not None else load_model(self.model.path, frame=frame)
        except Exception as exc:  # noqa: BLE001
            self.error = one_line(exc)
            return False
        self.recompute()
        return True

    @property
    def map_colours(self) -> np.ndarray | None:
        """(N, 3) colours of the scan map (share of unstable clusters per particle by the packing; grey: by the cut
        alone), or None off the map."""
        return self.model.colours if self.kind == "scan_map" else None

    def open_cluster(self, name: str) -> bool:
        """From the scan map: the cluster of particle `name` becomes the scene (back_to_map returns)."""
        scan_map = self.model if self.kind == "scan_map" else None
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
        return self.model.pick(origin, direction) if self.kind == "scan_map" else None

    def analyse(self) -> None:
        """Analyse a large packing now (recompute skips it above LARGE particles)."""
        self.recompute(force=True)

    def recompute(self, force: bool = False) -> None:
        """Build the scene and analyse it (a packing above LARGE particles only when `force`d); any failure
        becomes `error` (the analysis is then None)."""
        start = time.perf_counter()
        self.revision += 1
        self.analysis = None
        self.metrics = None
        try:
            self.scene = self.model.build(self.params)
            if self.kind == "scan_map" or (self.scene.n_particles > LARGE and not force):
                self.error = None
                self.elapsed = time.perf_counter() - start
                return
            if self.metric not in self.metric_choices:
                self.notice = f"this scene has no masses: metric {self.metric} → L"
                self.metric = "L"
            if self.offload and self.scene.n_particles >= OFFLOAD:
                self.analysis = shared(self.scene, self.metric)
            else:
                self.analysis = analysed(self.scene, self.metric)
            self.error = None
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

    def dynamics(self) -> dict | None:
        """Inertia metric only (λ = ω², eq:Hm's 𝓗 in the kinetic-energy metric): the lowest frequencies ω = √λ and the
        largest growth rates √(−λ) of the branch with the lowest eigenvalue, eigenvalues resolved by their accuracy."""
        if self.analysis is None or self.metric != "inertia":
            return None
        b = min(self.analysis.branches, key=lambda b: b.stability_eigenvalues.min())
        frequencies, growth = frequencies_and_growth(b.stability_eigenvalues, b.accuracy)
        return {"frequencies": np.sort(frequencies)[:4], "growth_rates": -np.sort(-growth)[:3], "branch": b.mask}

    def check_metrics(self) -> dict | None:
        """The verdict in every metric of the family (L/10, L, 10L, inertia where masses are known), on request:
        the page shows the single-metric verdict first and runs this only when asked (it costs ~3× the analysis).
        Returns {"robust": bool, "metrics": [per-metric verdict and counts], "time": s} (None without a scene)."""
        if self.scene is None or self.analysis is None:
            return None
        return self.keep_metrics(metric_family(self.scene), self.revision)

    def keep_metrics(self, metrics: dict, revision: int) -> dict | None:
        """Keep a family check computed (metric_family, off the lock) for `revision`; one for an older scene or older
        parameters is dropped (None): the next move superseded it."""
        if revision != self.revision:
            return None
        self.metrics = {**metrics, "revision": revision}
        return self.metrics

    def family_estimate(self) -> float:
        """Seconds the family check should take here: three analyses in L's time (four with masses)."""
        return (4 if self.scene is not None and self.scene.mass is not None else 3) * self.elapsed

    @property
    def scene_dim(self) -> int:
        return self.scene.dim if self.scene is not None else getattr(self.model, "dim", 2)

    @property
    def verdict(self) -> str | None:
        return None if self.analysis is None else self.analysis.verdict.verdict

    def report(self) -> dict:
        """What the verdict panel shows: verdict, reason, flags, counts, the largest error estimate, times."""
        if self.analysis is None:
            return {"verdict": None, "error": self.error, "elapsed": self.elapsed}
        a, s = self.analysis, self.analysis.verdict
        worst = max(a.errors.items(), key=lambda kv: kv[1]) if a.errors else ("", 0.0)
        return {
            "verdict": s.verdict, "reason": s.reason, "sufficient": s.sufficient,
            "type2": s.type2_nonuniqueness, "type1": self.type1(),
            "hinges": s.hinges_on_tolerance, "n_branches": s.n_branches,
            "counts": (s.consistent_positive, s.consistent_zero, s.consistent_negative),
            "n_particles": self.scene.n_particles, "n_contacts": self.scene.n_contacts,
            "n_sliding": int(np.sum(self.scene.at_yield())), "worst_error": worst, "errors": a.errors,
            "analysis_time": a.timings.get("total", 0.0), "elapsed": self.elapsed, "warnings": a.warnings,
            "error": self.error, "notice": self.notice, "metric": self.metric, "dynamics": self.dynamics(),
            "attribution": None if a.attribution is None else a.attribution.line(),
        }

    def type1(self) -> str:
        """Type-1 non-uniqueness (Sec. 3.1) under a proportional load increment d𝕓 = current load.

        It needs two branches, i.e. a potentially sliding contact; the core's `verdicts.load_response` decides."""
        if self.analysis is None or len(self.analysis.branches) < 2:
            return "no (a single branch: no contact at yield)"
        if not hasattr(self.analysis, "problem"):
            return "not evaluated (the core's Analysis does not expose its problem)"
        from granstab.mechanics.verdicts import load_response
        s = self.scene
        if s.fixed is not None:
            return "not evaluated (a scene held by fixed particles)"
        db = np.concatenate([s.load, s.load_moment], axis=1).reshape(-1)
        if not np.any(db):
            return "not evaluated (no load to increment)"
        res = load_response(self.analysis, db)
        return "yes (proportional loading)" if res["type1_nonuniqueness"] else "no (proportional loading)"

    def modes(self) -> list[Mode]:
        """Every eigenpair of every branch, labelled by what its motion does (cached per analysis)."""
        if self._modes[0] == self.revision:
            return self._modes[1]
        out = []
        if self.analysis is not None:
            a = self.analysis
            for i, b in enumerate(a.branches):
                labels = label_modes(self.scene, self.motions(i), b.mask, a.length, b.codes == RIGID)
                out += [Mode(i, j, float(lam), int(code), lab.label, lab.shares, bool(b.hinges[j]))
                        for j, (lam, code, lab) in enumerate(zip(b.stability_eigenvalues, b.codes, labels))]
        self._modes = (self.revision, out)
        return out

    def mode(self, key: str) -> Mode | None:
        return next((m for m in self.modes() if m.key == key), None)

    def bodies(self) -> list[Body]:
        return self.model.bodies(self.params)

    @property
    def size(self) -> float:
        """A particle length scale (mean largest semi-axis): sets arrows, markers and the animation amplitude."""
        return float(np.mean([max(b.axes) for b in self.bodies()]))

    def particle_shares(self, mode: Mode) -> np.ndarray:
        """Where the mode lives: each particle's |motion| √(|du|² + (size·|dθ|)²) over the largest one (N,), in [0, 1]."""
        b = self.analysis.branches[mode.branch]
        du, dth = mode_offsets(self.scene, self.analysis.motion(b.stability_vectors[:, mode.index]), self.size)
        share = np.sqrt(np.sum(du ** 2, axis=1) + self.size ** 2 * np.sum(dth ** 2, axis=1))
        return share / max(float(share.max()), 1e-300)

    def mode_bodies(self, mode: Mode, amplitude: float, phase: float) -> list[Body]:
        """Bodies displaced along `mode` at `phase` (radians): x + A s du, R(A s dθ) R with s the phase factor.

        A consistent-one-way mode (PLUS/MINUS) only moves in its consistent direction (s = ±|sin|)."""
        b = self.analysis.branches[mode.branch]
        U = self.analysis.motion(b.stability_vectors[:, mode.index])
        du, dth = mode_offsets(self.scene, U, self.size)
        s = np.sin(phase)
        s = abs(s) if mode.code == PLUS else -abs(s) if mode.code == MINUS else s
        index = {name: i for i, name in enumerate(self.scene.names)}
        out = []
        for body in self.bodies():
            i = index[body.name]
            dR = rotation_matrix(self.scene.dim, amplitude * s * dth[i])
            out.append(Body(body.name, body.kind, body.axes, body.x + amplitude * s * du[i], dR @ body.R))
        return out

    def field(self) -> Field | None:
        """The λ⁽⁶⁾ field for the pair (None for other scenes: no work for a panel that is not shown)."""
        if self.kind != "two_particle":
            return None
        return lambda6_field(self.params["alpha"], self.params["rolling"])

    @property
    def field_scale(self) -> float:
        """The length the λ⁽⁶⁾ surface is laid out in: the pair's r (fixed, unlike the particle size, which grows
        with ρ/r — the surface is cached, so the current-state marker must be placed on the same scale)."""
        return float(getattr(self.model, "r", 1.0))

    def rolling_eigenvalue(self) -> float | None:
        """λ⁽⁶⁾ of the current analysis in units of k: the rolling-labelled eigenvalue of the first branch,
        0 exactly when |λ⁽⁶⁾| is within the branch's zero tolerance (`zero_tolerance()`)."""
        rolling = [m for m in self.modes() if m.branch == 0 and m.label == "rolling"]
        if not rolling:
            return None
        lam = rolling[0].eigenvalue
        return 0.0 if abs(lam) <= self.analysis.branches[0].zero_tol else lam / self.params["k"]

    def zero_tolerance(self) -> float | None:
        """The eigenvalue zero tolerance of the first branch in units of k (what "λ = 0" means here)."""
        if self.analysis is None or not self.analysis.branches:
            return None
        return self.analysis.branches[0].zero_tol / self.params["k"]

    # ------------------------------------------------------------------------------------------ exports

    def export_scene(self) -> tuple[str, bytes]:
        """The current scene as a scene file that reloads to the same analysis (shape or contact format, JSON)."""
        if isinstance(self.model, ShapeModel):
            data = self.model.to_dict(self.params)
        elif self.scene is not None:
            data = granstab.scene_to_dict(self.scene)
        else:
            raise ValueError("no scene to export")
        return f"{Path(str(self.preset)).stem}-scene.json", json.dumps(data, indent=1, default=_json).encode()

    def export_analysis(self) -> tuple[str, bytes]:
        """The analysis as JSON (`granstab analyze --json` object) with the app's parameters and mode labels."""
        if self.analysis is None:
            raise ValueError(f"no analysis to export: {self.error}")
        data = self.analysis.to_dict()
        data["app"] = {"preset": self.preset, "kind": self.kind,
                       "params": {k: self.params[k] for k in self.used_params},
                       "modes": [{"branch": m.branch, "index": m.index, "eigenvalue": m.eigenvalue,
                                  "consistent": m.consistent, "label": m.label} for m in self.modes()]}
        return f"{Path(str(self.preset)).stem}-analysis.json", json.dumps(data, indent=1, default=_json).encode()

    def export_contour(self) -> tuple[str, bytes]:
        field = self.field()
        if field is None:
            raise ValueError("the λ⁽⁶⁾ contour exists for the two-particle pair only")
        return "lambda6-contour.png", field_png(field, (self.params["rho_r"], self.params["f_kr"]))


def analysed(scene, metric: str):
    """The analysis on one BLAS thread (small problems: thread start-up costs more than it saves)."""
    with blas_threads(1):
        return analyze(scene, metric=metric)


def offloaded(scene, metric: str):
    """`analysed` in a worker process of analysis_pool: a server's large analyses (annulus_frame: ~1 s of mostly
    Python) then hold another process's GIL, not the one the server's other tabs answer from (benchmarks/classroom.py:
    a pair's slider move waited seconds behind them). A worker that died is replaced at the next call."""
    from concurrent.futures.process import BrokenProcessPool
    try:
        return analysis_pool().submit(analysed, scene, metric).result()
    except BrokenProcessPool:
        close_pool()
        raise


def shared(scene, metric: str):
    """`offloaded`, once for every session of the server: an analysis is kept (the SHARED most recently used) by a
    digest of its scene and metric, so that a class moving annulus_frame's μ through the same slider steps has each
    step analysed once. Analyses are read-only once made (a Session's own caches, motions and modes, are its own);
    two sessions asking at once for the same new scene both analyse it."""
    key = hashlib.sha256(pickle.dumps((scene, metric), protocol=pickle.HIGHEST_PROTOCOL)).digest()
    with _SHARED_LOCK:
        if key in _SHARED:
            _SHARED.move_to_end(key)
            return _SHARED[key]
    analysis = offloaded(scene, metric)
    with _SHARED_LOCK:
        _SHARED[key] = analysis
        while len(_SHARED) > SHARED:
            _SHARED.popitem(last=False)
    return analysis


def analysis_pool():
    """Worker processes for offloaded analyses, one per core (spawned: the server runs threads, which fork would copy
    half-way), at a lower priority (WORKER_NICE) than the server: on a busy machine a core goes first to the server's
    process, which answers every page (its event loop, the small scenes' analyses), then to the large analyses
    (benchmarks/classroom.py: 5 annulus_frame pages kept both cores busy and a pair's move waited behind them)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from granstab.solve.threads import cores
    if not _POOL:
        _POOL.append(ProcessPoolExecutor(max_workers=cores(), mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_lower_priority))
    return _POOL[0]


def _lower_priority() -> None:
    """A worker's start: WORKER_NICE steps below the server (where the system lets a process lower itself)."""
    if hasattr(os, "nice"):
        os.nice(WORKER_NICE)


def close_pool() -> None:
    """Stop the worker processes and drop the shared analyses (the server's stop; a later offloaded analysis starts
    new ones)."""
    while _POOL:
        _POOL.pop().shutdown(wait=False, cancel_futures=True)
    with _SHARED_LOCK:
        _SHARED.clear()


def metric_family(scene) -> dict:
    """The verdict of `scene` in every metric of the family (granstab.analyze, metric="family"), on one BLAS thread:
    {"robust", "metrics", "time"}. Pure: it may run off the session's lock while the page moves on."""
    start = time.perf_counter()
    with blas_threads(1):
        family = analyze(scene, metric="family", attribution=False).verdict
    return {"robust": family.metric_robust is True, "metrics": [e.to_dict() for e in family.metrics],
            "time": time.perf_counter() - start}


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


def _json(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
