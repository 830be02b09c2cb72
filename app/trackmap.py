"""A tracked sequence (`granstab track … --out DIR`) as a model of the explorer: one frame at a time, drawn as that
frame's scan map, with the next window's D²min as an overlay and the run's λ_min(t) and stress(t) (no viser).

The folder's contract is granstab/track/__init__.py's. A frame is shown as a scan map (kind "scan_map": no analysis of
the packing, a click opens a cluster, *Back to the map* returns to the same frame): every particle of the frame
(particles.parquet, rattlers included) at its position, coloured by its scan folder `scans/frame-NNNNNN/` through
scanmap.py's colours, and its cluster cut from that folder's packing by `ScanMapModel.cluster`, the cluster the
frame's scan analysed. A track run without --scan has no scan folders: the particles are grey (in no scanned
cluster), drawn at half the frame's mean contact distance, and no cluster opens.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import granstab
from granstab.model.scene import build_scene

from .params import defaults
from .protocols import MapModel
from .scanmap import is_scan_dir, load_scan_map, map_colours, pick_particle
from .scenes import Body, grain_bodies

CONTRACT = "granstab track"
TOP = 0.9                  # D²min colour scale: dark at the window's 90th percentile (the prediction test's top 10 %)
ROUND_OFF = 1e-12          # D²min under this × (mean contact distance)² is round-off: 10⁻⁶ of a contact distance
                           # moved off the affine motion, far above a double's error on the ~20 neighbours' Δr²
WHITE, BLUE = np.array([250, 250, 250]), np.array([20, 60, 170])
FRAME_COLUMNS = ("frame", "step", "n_particles", "n_contacts", "shear_stress", "pressure", "stress_ratio",
                 "mean_contact_distance", "lambda_min_unloading", "lambda_min_loading", "scan_unstable",
                 "scan_clusters")
MAPS_KEPT = 4              # frames whose scan map stays loaded (a slider moved back and forth)


def is_track_dir(path) -> bool:
    """A folder that `granstab track` wrote: frames.parquet beside a summary.json of its contract."""
    path = Path(path)
    if not (path.is_dir() and (path / "frames.parquet").is_file() and (path / "summary.json").is_file()):
        return False
    try:
        return str(json.loads((path / "summary.json").read_text(encoding="utf-8")).get("contract", "")).startswith(
            CONTRACT)
    except (OSError, ValueError, AttributeError):
        return False


def d2min_colours(d2: np.ndarray, floor: float) -> np.ndarray:
    """(N, 3) uint8 of D²min over one window: white (0) → dark blue at the window's TOP quantile and above (the
    particles the prediction test calls rearranging). The scale is never under `floor`: a window whose motion is
    affine to round-off stays white instead of showing its round-off at full scale."""
    finite = d2[np.isfinite(d2)]
    top = max(float(np.quantile(finite, TOP)) if finite.size else 0.0, floor)
    share = np.clip(np.nan_to_num(d2 / top), 0.0, 1.0)[:, None]
    return np.round(WHITE + share * (BLUE - WHITE)).astype(np.uint8)


@dataclass
class TrackModel(MapModel):
    """A tracked folder at frame `frame` (a `frame` value of its tables); `overlay`: the D²min of the window that
    starts there is shown. `table`: frames.parquet's columns; `particles`: frame, name, x, y[, z], d2min, rattler."""

    path: str
    summary: dict
    table: dict
    particles: dict
    events: list
    frame: int = 0
    overlay: bool = False
    _maps: dict = field(default_factory=dict, repr=False)
    kind = "scan_map"
    draggable = False
    params_used = ()

    def initial_params(self) -> dict:
        return defaults()

    @property
    def frames(self) -> list:
        """The frames of the run (the explorer's Frame slider steps through them)."""
        return [int(f) for f in self.table["frame"]]

    def at_frame(self, frame) -> TrackModel:
        """Show frame `frame` (one of `frames`)."""
        if int(frame) not in self.frames:
            raise granstab.SceneError(f"{self.path}: frame {frame} is not in this track ({self.frames[0]} … "
                                      f"{self.frames[-1]})")
        self.frame = int(frame)
        return self

    @property
    def row(self) -> int:
        return self.frames.index(self.frame)

    def _rows(self) -> slice:
        f = self.particles["frame"]
        return slice(int(np.searchsorted(f, self.frame, "left")), int(np.searchsorted(f, self.frame, "right")))

    @property
    def names(self) -> list[str]:
        return [str(n) for n in self.particles["name"][self._rows()]]

    @property
    def x(self) -> np.ndarray:
        return self.particles["x"][self._rows()]

    @property
    def d2min(self) -> np.ndarray:
        """D²min of each particle of the frame over the window that starts at it (NaN: no window, or gone)."""
        return self.particles["d2min"][self._rows()]

    def scan_map(self):
        """The frame's scan folder as a ScanMapModel (None: the track ran without --scan); a few kept loaded."""
        if self.frame not in self._maps:
            folder = Path(self.path) / "scans" / f"frame-{self.frame:06d}"
            while len(self._maps) >= MAPS_KEPT:
                self._maps.pop(next(iter(self._maps)))
            self._maps[self.frame] = load_scan_map(folder) if is_scan_dir(folder) else None
        return self._maps[self.frame]

    def _by_name(self, values: np.ndarray, names, fill) -> np.ndarray:
        """Values over the scan packing's particles → over the frame's (`fill` where a particle is not in it)."""
        out = np.full(len(self.names), fill, dtype=float)
        index = {n: i for i, n in enumerate(self.names)}
        rows = [index[n] for n in names]
        out[rows] = values
        return out

    @property
    def colours(self) -> np.ndarray:
        """(N, 3) uint8: the frame's scan map in scanmap.map_colours (grey: in no scanned cluster, as a rattler)."""
        scan = self.scan_map()
        if scan is None:
            return map_colours(np.full(len(self.names), np.nan), np.zeros(len(self.names)))
        names = scan.scene.names
        return map_colours(self._by_name(scan.fraction, names, np.nan), self._by_name(scan.by_cut, names, 0.0))

    def radii(self) -> np.ndarray:
        """Each particle's drawn radius: as in its scan packing (ContactModel: to its nearest contact point); without
        a scan half the frame's mean contact distance. A rattler (no contact: no size in the tables) is drawn as the
        largest disk that touches no other drawn particle, at most their median radius."""
        scan = self.scan_map()
        rows = self._rows()
        if scan is None:
            half = 0.5 * float(self.table["mean_contact_distance"][self.row])
            r = np.full(rows.stop - rows.start, half if np.isfinite(half) and half > 0 else 1.0)
        else:
            r = self._by_name(np.array([b.axes[0] for b in scan.bodies({})]), scan.scene.names, np.nan)
        free = self.particles["rattler"][rows] | ~np.isfinite(r)
        if free.any() and not free.all():
            from scipy.spatial import cKDTree
            x, sized = self.x, np.flatnonzero(~free)
            dist, j = cKDTree(x[sized]).query(x[free], k=min(8, sized.size))
            gap = np.min(np.reshape(dist, (free.sum(), -1)) - r[sized][np.reshape(j, (free.sum(), -1))], axis=1)
            median = float(np.median(r[sized]))
            r[free] = np.clip(gap, 0.1 * median, median)
        return separated(self.x, r)

    def build(self, P: dict) -> granstab.Scene:
        """The frame's particles as a scene without contacts (the map draws particles only; its scan packing holds
        the contacts each cluster is cut from)."""
        d = self.x.shape[1]
        r = 1 if d == 2 else 3
        empty = {"p": np.zeros(0, int), "q": np.zeros(0, int), "moment": np.zeros((0, r)),
                 "rolling": np.zeros((0, r, r)), "state": (),
                 **{k: np.zeros((0, d)) for k in ("point", "normal", "force")},
                 **{k: np.zeros((0, d, d)) for k in ("curvature_p", "curvature_q")},
                 **{k: np.zeros(0) for k in ("k", "alpha", "mu")}}
        return build_scene(d, self.names, self.x, empty, title=self.headline[0], source=self.path, cell=self.cell)

    @property
    def cell(self) -> np.ndarray | None:
        """The frame's periodic cell (d, d lattice rows; frames.parquet's `cell`), or None: not periodic."""
        rows = self.table.get("cell")
        cell = [] if rows is None else list(rows[self.row])
        d = self.x.shape[1]
        return np.asarray(cell, float).reshape(d, d) if len(cell) == d * d else None

    def bodies(self, P: dict) -> list[Body]:
        """The frame's particles as disks (spheres) of `radii`, or, where its scan kept the grains' true shapes,
        each scanned grain as it is (its shape and orientation) at the frame's position."""
        d = self.x.shape[1]
        kind = "disk" if d == 2 else "sphere"
        disks = [Body(n, kind, (float(r),) * d, x.copy(), np.eye(d)) for n, r, x in zip(self.names, self.radii(),
                                                                                           self.x)]
        scan = self.scan_map()
        if scan is None or scan.grains is None:
            return disks
        shaped = {b.name: b for b in grain_bodies(scan.scene, scan.grains)}
        return [replace(shaped[b.name], x=b.x) if b.name in shaped else b for b in disks]

    @property
    def headline(self) -> tuple[str, str]:
        """(title, badge) of the page's headline."""
        step = self.table["step"][self.row]
        at = f"frame {self.frame}" + ("" if np.isnan(step) else f" (step {step:g})")
        return (f"track {Path(self.path).name}, {at}: {len(self.names)} particles: click one (or type its name) "
                "for its cluster", "track")

    @property
    def report(self) -> str:
        t, i = self.table, self.row
        scan = ("no scan (track without --scan: grey, no clusters)" if t["scan_clusters"][i] < 0 else
                f"{t['scan_unstable'][i]} of {t['scan_clusters'][i]} clusters unstable")
        return (f"track {self.path} of {', '.join(map(str, self.summary.get('source', [])))}: frame {self.frame} "
                f"({i + 1} of {len(self.frames)}), {t['n_particles'][i]} particles, {t['n_contacts'][i]} contacts; "
                f"{scan}; shear stress {t['shear_stress'][i]:.4g}, pressure {t['pressure'][i]:.4g}; "
                f"{len(self.events)} event(s) in the run")

    def cluster(self, name: str):
        """The cluster of particle `name` at this frame, as the frame's scan analysed it (ScanMapModel.cluster)."""
        scan = self.scan_map()
        if scan is None:
            raise granstab.SceneError(f"{self.path}: tracked without --scan: no cluster to open (granstab track "
                                      "… --scan keeps each frame's packing and map)")
        return scan.cluster(name)

    def pick(self, origin, direction) -> str | None:
        """The particle under a click ray (scanmap.pick_particle), or None."""
        i = pick_particle(self.x, self.radii(), origin, direction)
        return None if i is None else self.names[i]

    def overlay_points(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Where the D²min overlay's dots go and their colours (d2min_colours), the particles with a window only;
        None while the overlay is off."""
        if not self.overlay:
            return None
        d2 = self.d2min
        keep = np.isfinite(d2)
        scale = float(self.table["mean_contact_distance"][self.row])
        floor = ROUND_OFF * (scale ** 2 if np.isfinite(scale) and scale > 0 else float(np.nanmax(d2, initial=0.0)))
        return self.x[keep], d2min_colours(d2, floor)[keep]

    def show_d2min(self, on: bool) -> bool:
        """The D²min overlay on or off; whether that changed anything."""
        changed, self.overlay = bool(on) != self.overlay, bool(on)
        return changed

    def series(self) -> dict:
        """What the λ_min(t)/stress(t) plot shows: frame, λ_min of both branches, the event quantity, the events
        and the frame now."""
        quantity = self.summary.get("thresholds", {}).get("event_quantity", "shear_stress")
        return {"frame": np.asarray(self.table["frame"]), "step": np.asarray(self.table["step"]),
                "unloading": np.asarray(self.table["lambda_min_unloading"], float),
                "loading": np.asarray(self.table["lambda_min_loading"], float), "quantity": quantity,
                "stress": np.asarray(self.table[quantity], float),
                "events": [(e["frame"], e["next_frame"]) for e in self.events], "now": self.frame}


def separated(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The drawn radii `r` shrunk so that no two disks (spheres) at centres `x` overlap: each overlapping pair in
    proportion to its radii, a particle by its worst pair. All are drawn at one depth, so an overlapping neighbour
    hid part of a particle's colour (issue 36); disks that touch (to 1e-9 of their distance) are kept."""
    top = np.nanmax(r) if len(r) else np.nan
    if not np.isfinite(top):
        return r
    from scipy.spatial import cKDTree
    i, j = cKDTree(x).query_pairs(2 * top, output_type="ndarray").T
    d = np.linalg.norm(x[i] - x[j], axis=1)
    over = r[i] + r[j] > d * (1 + 1e-9)
    share = d[over] / (r[i] + r[j])[over]
    scale = np.ones_like(r)
    np.minimum.at(scale, i[over], share)
    np.minimum.at(scale, j[over], share)
    return r * scale


def load_track(path) -> TrackModel:
    """The model of a tracked folder at its first frame; one-line SceneError when it cannot be read."""
    from granstab.model.errors import require
    require("pyarrow.parquet", "scan", "a tracked folder")
    import pyarrow.parquet as pq
    path = Path(path)
    try:
        summary = json.loads((path / "summary.json").read_text(encoding="utf-8"))
        has = set(pq.read_schema(path / "frames.parquet").names)
        table = pq.read_table(path / "frames.parquet", columns=[*FRAME_COLUMNS, *({"cell"} & has)]).to_pydict()
        schema = pq.read_schema(path / "particles.parquet").names
        cols = ["frame", "name", "d2min", "rattler", *[a for a in "xyz" if a in schema]]
        raw = pq.read_table(path / "particles.parquet", columns=cols).to_pydict()
        events = json.loads((path / "events.json").read_text(encoding="utf-8"))
    except (OSError, ValueError, KeyError) as exc:
        raise granstab.SceneError(f"{path}: not a readable track folder: {' '.join(str(exc).split())}") from None
    if not table["frame"]:
        raise granstab.SceneError(f"{path}: frames.parquet: no frame")
    dims = [a for a in "xyz" if a in raw]
    particles = {"frame": np.asarray(raw["frame"], np.int64), "name": np.asarray(raw["name"], dtype=object),
                 "d2min": np.asarray(raw["d2min"], float), "rattler": np.asarray(raw["rattler"], bool),
                 "x": np.stack([np.asarray(raw[a], float) for a in dims], axis=1)}
    table = {k: np.asarray(v, dtype=object if k == "cell" else None) for k, v in table.items()}
    return TrackModel(str(path), summary, table, particles, events, frame=int(table["frame"][0]))
