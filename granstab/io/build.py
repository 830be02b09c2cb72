"""Contact-level scenes from particle snapshots: the conventions every reader shares.

A reader hands over a `Snapshot` (particles with centres and radii, contacts as index pairs with the force on
the first particle, in the file's units); `build` turns it into a granstab Scene and a validation report (a
`registry.Loaded`; validation.py lists its warnings and writes it as lines):

- **Normal** n^pq: the file's normal where it has one, else the centre line from p to q (minimum image in
  periodic cells). Overlap δ = R_p + R_q − d, d the centre distance.
- **Geometry rule** `centres` (default, DEM): contact point on the centre line at the middle of the overlap,
  x_p + (R_p − δ/2) e; curvature of the parallel surface through it, radius ρ = R − δ/2 for each particle
  (docs/errata.md: the curvature that enters Hg is that of the parallel curve through the contact point), κ = −1/ρ
  (3D: K = −(I − n⊗n)/ρ). `touching` (data whose radii do not match the distances, e.g. photoelastic frames):
  the point splits d in proportion to the radii, ρ_p = d R_p/(R_p+R_q), ρ_q = d − ρ_p.
- **Forces** f^pq as given (the force on p by q; f^qp = −f^pq); compression has f·n < 0, checked.
- **Cone policy** (eq:yield, Q = |f_t| + μ f·n): a contact with f_n > 0 flagged fully mobilised by the file (where
  the file flags contacts: the flag stands, `yield_rtol` is not used), or, in a file without flags, with |f_t|
  within `yield_rtol` of μ f_n, is put exactly on the cone and marked "sliding". One outside the cone
  (|f_t| > μ f_n (1 + yield_rtol)) follows `outside_cone`: "sliding" (project onto the cone, mark at yield),
  "project" (project, treat as sticking: "elastic"), "elastic" (keep the force, "elastic") or "error".
  Contacts with f_n ≤ 0 and a force are "elastic" (tension is cohesion). Every change is counted and named.
- **Masses** (for the inertia metric, mechanics/metric.py): the file's per-particle masses, else `density` × volume
  (2D: disk area π R², 3D: sphere volume 4/3 π R³); moments of inertia of solid disks (½ m R²) and spheres
  (2/5 m R² I). Neither: the scene carries no masses and `--metric inertia` says so.
- **Loads** follow the contact forces (scene rule b^p = −Σ f^pq): walls, contacts cut by a region or around a
  periodic cell and the snapshot's own imbalance become external loads; the report gives each.
- **Periodic cells** (lattice rows a_i, Lees–Edwards = sheared lattice): minimum-image branch vectors. By default
  the scene is periodic: it carries the cell, every contact keeps q's image (d integers: q's copy at
  x_q + Σ image_i a_i, the branch from x_p to it), positions stay as the file gives them. `periodic=False`
  (`--no-periodic`), a region, or a cell open along an axis: particles are unwrapped along the contact network,
  and contacts that close a loop around the cell are cut (their forces become loads): the analysis then sees the
  cell as a free cluster held by dead loads. The report says which (`periodic`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..model.errors import SceneError
from ..model.periodic import minimum_image
from ..model.scene import build_scene
from ..model.tolerances import DEFAULT, Tolerances
from ..model.vec import norms, sum_at
from .registry import Loaded
from .unwrap import cell_of, periodic_report, unwrap
from .validation import LAW_DEFAULT, import_warnings

GEOMETRY = ("centres", "touching")
OUTSIDE_CONE = ("sliding", "project", "elastic", "error")
OVERLAP_WARN = 0.1     # overlap 2δ/(R_p + R_q) beyond which the report warns: a DEM keeps overlaps at a few per cent
                       # of a radius or less (its stiffness is chosen so); 0.1 and more means the radii, units or
                       # frame do not fit the positions, and the centres rule's curvatures (ρ = R − δ/2) with them


@dataclass
class Snapshot:
    """Raw data of one frame as a reader found it (file units). Optional fields are None when absent."""

    source: str
    format: str
    dim: int
    ids: np.ndarray                 # (N,) particle ids as the file names them
    x: np.ndarray                   # (N, d) centres
    radius: np.ndarray              # (N,)
    p: np.ndarray                   # (M,) particle indices
    q: np.ndarray
    force: np.ndarray               # (M, d) f^pq, the force on p by q
    normal: np.ndarray | None = None     # (M, d) the file's unit normals p → q
    moment: np.ndarray | None = None     # (M, r) contact moments m^pq
    mobilised: np.ndarray | None = None  # (M,) the file's "fully mobilised" flags
    lattice: np.ndarray | None = None    # (d, d) lower-triangular periodic lattice vectors (rows); NaN row = open
    wall_flags: np.ndarray | None = None  # (N,) nonzero: touches a wall whose force the file does not give
    wall_load: np.ndarray | None = None  # (N, d) wall forces the file gives
    mass: np.ndarray | None = None       # (N,) per-particle masses the file gives (e.g. LAMMPS `mass`)
    orientation: np.ndarray | None = None  # (N, 4) unit quaternions (w, x, y, z) the file gives (columns.ORIENTATION_NAMES)
    bodies: dict | None = None  # rigid bodies (x: centres of mass, radius: bounding radii): contact points, ρ of
                                # both sides, inertia, wall moments and the geometry entry (io/bodies.py says which)
    law: dict = field(default_factory=dict)   # k, alpha, mu the file gives: {key: (value, where)}
    force_uncertainty: tuple | None = None  # ((M,) radius of each force's stated uncertainty, which columns)
    shaped: dict | None = None     # shaped grains (not spheres): arm_p, arm_q (M, d) from each centre to the contact
                                   # point, curvature_p/q (M, d, d), report; optional inertia (N, d, d)
    parts: dict | None = None      # a rigid body's round parts, for drawing (model/grains.py): kind, body (K,),
                                   # offset (K, d) from the body's centre (world axes), radius (K,)
    length_unit: str = "file units"
    frame: object = None
    frames: list | None = None
    notes: dict = field(default_factory=dict)  # format-specific report entries (duplicates, walls, ...)
    particle_line: object = None   # particle index → "<file>: line L" (one-line errors), or None
    contact_line: object = None    # contact index → "<file>: line L", or None

    def where(self, kind: str, index: int) -> str:
        """"<file>: line L" of a particle or contact (or the source), for one-line errors."""
        locate = self.particle_line if kind == "particle" else self.contact_line
        return self.source if locate is None else locate(int(index))


@dataclass
class Options:
    """What the user says on top of the file (None: the file's value, else the built-in default)."""

    k: float | None = None
    alpha: float | None = None
    mu: float | None = None
    geometry: str = "centres"
    outside_cone: str = "sliding"
    yield_rtol: float = 1e-4
    length_scale: float = 1.0
    units: str | None = None
    region: object = None
    keep_rattlers: bool = False
    density: float | None = None    # mass per scene volume (2D: per area), when the file gives no masses
    periodic: bool = True           # keep a periodic cell's seam contacts with their images (False: cut them)


LAW_DEFAULTS = {"k": 1.0, "alpha": 1.0, "mu": 0.5}
YIELD_RULES = {False: "yield_rtol: |f_t| within yield_rtol of μ f_n (the file flags no contact)",
               True: "the file's flag: a contact is at yield when the file flags it fully mobilised "
                     "(yield_rtol not used)"}


def build(snap: Snapshot, opts: Options, progress=None, tol: Tolerances = DEFAULT) -> Loaded:
    """Scene + validation report from a snapshot (see the module docstring for every convention); `progress`: a
    progress.ReadProgress, told the stages; `tol`: the scene checks' tolerances."""
    if progress is not None:
        progress.stage("build")
    _check_options(opts, snap)
    names = np.asarray(snap.ids).astype(str).astype(object)     # C-speed (a list of str() costs 0.3 s per 10⁵)
    pair = Pairs(names, snap.p, snap.q)
    scale = opts.length_scale
    x = snap.x * scale
    radius = snap.radius * scale
    branch, shifts = _branches(snap, x, scale)
    d = norms(branch)
    if np.any(d == 0):
        c = int(np.flatnonzero(d == 0)[0])
        raise SceneError(f"{snap.where('contact', c)}: contact {pair[c]}: x: the two centres coincide")
    e = branch / d[:, None]
    normal = e if snap.normal is None else _unit_normals(snap, pair)
    arm_p, arm_q, curvature, geometry_report = _contact_geometry(snap, opts, x, radius, (branch, d, e), normal,
                                                                 pair)
    law, law_report = _law(snap, opts, len(d))
    force, state, cone_report, force_report = _cone(snap, normal, law["mu"], opts, pair)
    report = {"source": snap.source, "format": snap.format, "read_as": "snapshot", "frame": snap.frame,
              "frames_available": None if snap.frames is None else len(snap.frames)}
    imbalance = _imbalance(snap, arm_p, arm_q)

    keep_c, keep_p, selection = _select(snap, x, opts, names)
    cell, why_cut = cell_of(snap, opts, scale)
    if cell is None:
        unwrapped, cut = unwrap(snap, x, shifts, keep_c, scale)
        keep_c &= ~cut
    else:
        unwrapped, cut = x, np.zeros(len(d), bool)
    if not np.any(keep_p if opts.keep_rattlers else keep_c):
        raise SceneError(f"{snap.source}: contacts: none left in the scene ({len(d)} in the frame, "
                         f"{int(cut.sum())} cut around the cell, {selection['contacts']} outside the region)")
    index = np.cumsum(keep_p) - 1
    c = np.flatnonzero(keep_c)
    sel = slice(None) if len(c) == len(d) else c        # every contact kept: views, no copies
    p, q = index[snap.p[sel]], index[snap.q[sel]]
    r = 1 if snap.dim == 2 else 3
    point = unwrapped[snap.p[sel]] + arm_p[sel]
    arrays = {
        "p": p, "q": q, "point": point, "normal": normal[sel],
        **{key: value[sel] for key, value in curvature.items()},
        "force": force[sel], "moment": np.zeros((len(c), r)) if snap.moment is None else snap.moment[sel],
        "k": law["k"][sel], "alpha": law["alpha"][sel], "mu": law["mu"][sel],
        "rolling": np.zeros((len(c), r, r)), "state": tuple(state[c]),
    }
    title = f"{snap.format} {snap.source}" + ("" if snap.frame is None else f" frame {snap.frame}")
    mass, inertia, report["masses"] = _masses(snap, opts.density, radius, scale)
    if progress is not None:
        progress.stage("checks")
    periodic = {} if cell is None else {"cell": cell, "image": -shifts[c]}
    scene = build_scene(snap.dim, list(names[keep_p]), unwrapped[keep_p], arrays, title=title, source=snap.source,
                        tol=tol, entries=lambda k: f"contact {pair[c[k]]}", **periodic,
                        **({} if mass is None else {"mass": mass[keep_p], "inertia": inertia[keep_p]}))
    scene, inside, dropped = _rattlers(scene, np.flatnonzero(keep_p), opts.keep_rattlers)
    report.update({
        "particles": {"in_file": len(x), "in_scene": len(inside), "outside_region": selection["particles"],
                      "without_contacts_dropped": len(dropped), "dropped": _names(names[dropped])},
        "contacts": {"in_file": len(d), "in_scene": len(c), "cut_by_region": selection["contacts"],
                     "cut_around_periodic_cell": int(cut.sum()), "sliding": int(np.sum(state[c] == "sliding")),
                     "elastic": int(np.sum(state[c] == "elastic"))},
        "units": {"length": opts.units or (snap.length_unit if scale == 1.0 else f"{scale:g} {snap.length_unit}"),
                  "length_scale": scale, "force": "as in the file"},
        "geometry": geometry_report, "law": law_report, "forces": force_report, "cone": cone_report,
        "imbalance": imbalance, "periodic": periodic_report(snap, cut, pair, cell, why_cut, shifts, c),
        "walls": snap.notes.get("walls", "none in the file"),
        "duplicates": snap.notes.get("duplicates", "none (one row per contact)"),
    })
    report.update({k: v for k, v in snap.notes.items() if k not in report})
    report["warnings"] = import_warnings(report)
    err = _force_uncertainty(snap, c, report)               # the scene carries it too: scan's clusters slice it
    return Loaded(scene=scene if err is None else replace(scene, force_err=err), report=report, frames=snap.frames,
                  force_uncertainty=err,
                  wall_flags=None if snap.wall_flags is None else snap.wall_flags[inside],
                  orientation=None if snap.orientation is None else snap.orientation[inside],
                  shape=_shape(snap, inside, scale), parts=_parts(snap.parts, inside, scale))


def _shape(snap: Snapshot, inside: np.ndarray, scale: float):
    """The scene particles' superquadric parameters (semi-axes in scene units), or None."""
    if not snap.shaped or "shape" not in snap.shaped:
        return None
    shape = np.array(snap.shaped["shape"][inside], float)
    shape[:, :3] *= scale
    return shape


def _parts(parts: dict | None, inside: np.ndarray, scale: float):
    """The scene particles' round parts (Snapshot.parts), body indices renumbered, lengths in scene units."""
    if parts is None:
        return None
    new = np.full(int(max(parts["body"].max(initial=-1), inside.max(initial=-1))) + 1, -1)
    new[inside] = np.arange(len(inside))
    keep = new[parts["body"]] >= 0
    return {"kind": parts["kind"], "body": new[parts["body"][keep]], "offset": parts["offset"][keep] * scale,
            "radius": parts["radius"][keep] * scale}


def _rattlers(scene, inside, keep: bool):
    """(scene, the file's index of each scene particle, of each dropped one): particles without contacts dropped
    (Scene.without_rattlers) unless `keep`."""
    if keep:
        return scene, inside, np.zeros(0, np.int64)
    scene, kept = scene.without_rattlers()
    gone = np.ones(len(inside), bool)
    gone[kept] = False                                     # kept: indices into inside (sorted)
    return scene, inside[kept], inside[gone]


def _check_options(opts: Options, snap: Snapshot) -> None:
    """The options' values and the snapshot's particles: one line naming the first bad one."""
    if opts.geometry not in GEOMETRY:
        raise SceneError(f"--geometry: must be one of {', '.join(GEOMETRY)}, got {opts.geometry!r}")
    if opts.outside_cone not in OUTSIDE_CONE:
        raise SceneError(f"--outside-cone: must be one of {', '.join(OUTSIDE_CONE)}, got {opts.outside_cone!r}")
    if not opts.length_scale > 0:
        raise SceneError(f"--length-scale: must be > 0, got {opts.length_scale}")
    _check_particles(snap)


def _contact_geometry(snap: Snapshot, opts: Options, x, radius, centre_line, normal, pair):
    """Each contact's arms from the centres to its point, the curvatures there and the geometry report: the
    reader's (shaped grains, rigid bodies) or the geometry rule's (`centres`, `touching`). `centre_line`: the
    branch vectors, their lengths d and unit vectors e."""
    scale = opts.length_scale
    branch, d, e = centre_line
    if snap.shaped is not None:   # the reader's contact points and curvatures (e.g. superquadrics: model/surface.py)
        arm_p, arm_q = snap.shaped["arm_p"] * scale, snap.shaped["arm_q"] * scale
        curvature = {key: snap.shaped[key] / scale for key in ("curvature_p", "curvature_q")}
        geometry_report = snap.shaped["report"]
    else:
        if snap.bodies is None:
            geom, geometry_report = _geometry(opts.geometry, radius[snap.p], radius[snap.q], d, e, normal, snap, pair)
            arm_p = geom["rho_p"][:, None] * e
        else:                       # rigid bodies: the reader's contact points and parallel-surface radii
            geom = {"rho_p": snap.bodies["rho"][:, 0] * scale, "rho_q": snap.bodies["rho"][:, 1] * scale}
            geometry_report, arm_p = snap.bodies["geometry"], snap.bodies["point"] * scale - x[snap.p]
        arm_q = arm_p - branch
        kp, kq = -1.0 / geom["rho_p"], -1.0 / geom["rho_q"]
        curvature = {"curvature_p": _curvature(kp, normal), "curvature_q": _curvature(kq, normal),
                     "curvature_sum": _curvature(kp + kq, normal)}          # summed first
    return arm_p, arm_q, curvature, geometry_report


# ------------------------------------------------------------------------------------------------ checks

def _masses(snap: Snapshot, density: float | None, radius: np.ndarray, scale: float = 1.0):
    """(mass (N,), inertia (N, r, r), report line) of solid disks (2D) or spheres (3D); (None, None, None) when
    neither the file's masses nor a density are given. `radius` in scene units."""
    if density is not None and not (np.isfinite(density) and density > 0):
        raise SceneError(f"--density: must be a positive number, got {density}")
    if snap.bodies is not None and (snap.mass is None or snap.bodies.get("inertia") is None):
        return None, None, "none: the file gives no masses and inertia tensors of its rigid bodies"
    if snap.mass is not None:
        bad = np.flatnonzero(~(snap.mass > 0) | ~np.isfinite(snap.mass))
        if bad.size:
            raise SceneError(f"{snap.where('particle', bad[0])}: particle {snap.ids[bad[0]]}: mass: must be a "
                             f"positive number, got {snap.mass[bad[0]]}")
        mass, how = np.asarray(snap.mass, float), "the file's masses"
        if snap.bodies is not None:
            return mass, snap.bodies["inertia"] * scale**2, how + " and inertia tensors (rigid bodies)"
    elif density is not None:
        volume = np.pi * radius**2 if snap.dim == 2 else 4.0 / 3.0 * np.pi * radius**3
        shape = "disk area" if snap.dim == 2 else "sphere volume"
        if snap.shaped is not None and "volume" in snap.shaped:
            volume, shape = snap.shaped["volume"] * scale**snap.dim, "grain volume"
        mass, how = density * volume, f"density {density:g} x {shape}"
    else:
        return None, None, None
    if snap.shaped is not None and "inertia" in snap.shaped:
        return mass, snap.shaped["inertia"] * mass[:, None, None] * scale**2, how + "; " + snap.shaped["inertia_note"]
    if snap.dim == 2:
        return mass, (0.5 * mass * radius**2).reshape(-1, 1, 1), how + "; solid disks"
    return mass, 0.4 * (mass * radius**2)[:, None, None] * np.eye(3), how + "; solid spheres"


def _check_particles(snap: Snapshot) -> None:
    where = snap.source
    if len(snap.ids) == 0:
        raise SceneError(f"{where}: no particles")
    ids = np.asarray(snap.ids)
    twice = _repeated(ids)
    if twice is not None:
        i = int(np.flatnonzero(ids == twice)[1])
        raise SceneError(f"{snap.where('particle', i)}: particle {ids[i]}: id: listed twice in one frame")
    bad = np.flatnonzero(~(snap.radius > 0))
    if bad.size:
        raise SceneError(f"{snap.where('particle', bad[0])}: particle {ids[bad[0]]}: radius: must be > 0, "
                         f"got {snap.radius[bad[0]]}")
    if snap.bodies is not None:       # two bodies may touch at several points: the reader checks its own pairs
        return
    lo, hi = np.minimum(snap.p, snap.q), np.maximum(snap.p, snap.q)
    key = lo.astype(np.int64) * len(ids) + hi
    twice = _repeated(key)
    if twice is not None:
        c = np.flatnonzero(key == twice)[1]
        raise SceneError(f"{snap.where('contact', c)}: contact {ids[snap.p[c]]}-{ids[snap.q[c]]}: id2: listed twice in one frame")
    same = np.flatnonzero(snap.p == snap.q)
    if same.size:
        raise SceneError(f"{snap.where('contact', same[0])}: contact {ids[snap.p[same[0]]]}-{ids[snap.q[same[0]]]}: id2: a particle cannot "
                         "touch itself")


def _repeated(values: np.ndarray):
    """The smallest value listed more than once, or None: one sort (np.unique's counts cost a stable argsort)."""
    s = np.sort(values, kind="quicksort")
    same = s[1:] == s[:-1]
    return s[1:][same][0] if same.any() else None


def _unit_normals(snap: Snapshot, pair) -> np.ndarray:
    norm = norms(snap.normal)
    bad = np.flatnonzero(~(np.abs(norm - 1.0) <= 1e-3))
    if bad.size:
        raise SceneError(f"{snap.where('contact', bad[0])}: contact {pair[bad[0]]}: normal: not a unit vector (|n| = {norm[bad[0]]:.6g})")
    return snap.normal / norm[:, None]


def _names(values) -> list:
    return [str(v) for v in values]


class Pairs:
    """Contact names "id1-id2", made only for the contacts an error or the report names: a million of them cost
    as much as the rest of the conversion. pairs[c]: one name; pairs[mask or indices]: a list."""

    def __init__(self, names, p, q):
        self.names, self.p, self.q = names, p, q

    def __getitem__(self, which):
        if np.ndim(which) == 0:
            return f"{self.names[self.p[which]]}-{self.names[self.q[which]]}"
        which = np.asarray(which)
        which = np.flatnonzero(which) if which.dtype == bool else which
        return list(self.names[self.p[which]] + "-" + self.names[self.q[which]])   # object arrays: no Python loop


def _force_uncertainty(snap: Snapshot, c: np.ndarray, report: dict):
    """The file's per-contact force uncertainty of the scene's contacts `c` (None without one), said in the report."""
    if snap.force_uncertainty is None:
        return None
    err = snap.force_uncertainty[0][c]
    report["force_uncertainty"] = {"source": snap.force_uncertainty[1], **_stats(err)}
    return err


def _stats(values) -> dict:
    values = np.asarray(values, float)
    if values.size == 0:
        return {"min": None, "median": None, "p95": None, "max": None}
    return {"min": float(values.min()), "median": float(np.median(values)),
            "p95": float(np.percentile(values, 95)), "max": float(values.max())}


# ------------------------------------------------------------------------------------------------ geometry

def branch_vectors(x, p, q, lattice):
    """x_q − x_p, their minimum image when `lattice` (rows; NaN row = open axis) is given, and the integer lattice
    shifts s used (M, d): the branch is x_q − s·lattice − x_p, so q's image is −s (model.periodic.minimum_image)."""
    return minimum_image(x[q] - x[p], lattice)


def _branches(snap: Snapshot, x, scale: float):
    """branch_vectors, or in a periodic cell the images of q a rigid-body reader found through the touching parts
    (`bodies["shift"]`: a body reaches beyond the minimum image of the centres of mass when it is large)."""
    lattice = None if snap.lattice is None else snap.lattice * scale
    shifts = (snap.bodies or {}).get("shift")
    if lattice is None or shifts is None:
        return branch_vectors(x, snap.p, snap.q, lattice)
    return x[snap.q] - x[snap.p] - shifts @ np.nan_to_num(lattice), shifts


def _geometry(rule, rad_p, rad_q, d, e, normal, snap, pair):
    """Contact point distance from p along e and the radii ρ of the parallel surfaces (module docstring); the
    report counts and names (worst first) the contacts whose overlap exceeds OVERLAP_WARN of the mean radius."""
    delta = rad_p + rad_q - d
    if rule == "centres":
        rho_p, rho_q = rad_p - delta / 2, rad_q - delta / 2
        bad = np.flatnonzero((rho_p <= 0) | (rho_q <= 0))
        if bad.size:
            c = bad[0]
            raise SceneError(f"{snap.where('contact', c)}: contact {snap.ids[snap.p[c]]}-{snap.ids[snap.q[c]]}: "
                             f"radius: overlap "
                             f"{delta[c]:.6g} exceeds twice a radius; try --geometry touching")
    else:
        rho_p = d * rad_p / (rad_p + rad_q)
        rho_q = d - rho_p
    cosine = np.clip(np.sum(e * normal, axis=1), -1.0, 1.0)
    overlap = 2 * delta / (rad_p + rad_q)
    extreme = np.flatnonzero(overlap > OVERLAP_WARN)
    report = {"rule": rule, "distance_over_sum_of_radii": _stats(d / (rad_p + rad_q)),
              "overlap_over_mean_radius": _stats(overlap),
              "extreme_overlaps": {"threshold": OVERLAP_WARN, "count": len(extreme),
                                   "names": pair[extreme[np.argsort(-overlap[extreme], kind="stable")]]},
              "gaps": int(np.sum(delta < 0)),
              "normal_to_centre_line_deg_max": float(np.degrees(np.arccos(cosine.min()))) if len(d) else 0.0}
    return {"rho_p": rho_p, "rho_q": rho_q}, report


def _curvature(kappa, normal):
    """2D: κ t⊗t with t = e3 × n; 3D: κ (I − n⊗n) (a sphere's parallel surface). Written entry by entry: numpy
    broadcasts (M, d, 1) × (M, 1, d) slowly for d = 2, 3 (the same operations on each entry: the same numbers)."""
    M, d = normal.shape
    out = np.empty((M, d, d))
    if d == 2:
        t = (-normal[:, 1], normal[:, 0])
        for i in range(2):
            kt = kappa * t[i]                               # (κ t_i) t_j
            for j in range(2):
                np.multiply(kt, t[j], out=out[:, i, j])
        return out
    for i in range(3):
        for j in range(3):
            np.multiply(normal[:, i], normal[:, j], out=out[:, i, j])
            np.subtract(1.0 if i == j else 0.0, out[:, i, j], out=out[:, i, j])     # I − n⊗n
            out[:, i, j] *= kappa
    return out


# ------------------------------------------------------------------------------------------------ law, cone

def _law(snap: Snapshot, opts: Options, M: int):
    """k, α, μ per contact: command line, else the file's model, else the built-in default (report says which)."""
    law, report = {}, {}
    for key in ("k", "alpha", "mu"):
        given = getattr(opts, key)
        if given is not None:
            value, where = given, "command line"
        elif key in snap.law:
            value, where = snap.law[key]
            if key == "k" and opts.length_scale != 1.0:  # force per file length → force per scene length
                value, where = np.asarray(value) / opts.length_scale, f"{where}, / length scale"
        else:
            value, where = LAW_DEFAULTS[key], LAW_DEFAULT
        value = np.broadcast_to(np.asarray(value, float), (M,)).copy()
        low = 0.0 if key == "mu" else None
        bad = ~np.isfinite(value) | ((value < 0) if low == 0.0 else (value <= 0))
        if np.any(bad):
            raise SceneError(f"{snap.source}: {key}: must be {'>= 0' if key == 'mu' else '> 0'}, "
                             f"got {value[bad][0]} ({where})")
        law[key] = value
        shown = float(value[0]) if M and np.all(value == value[0]) else ("per contact" if M else None)
        report[key] = {"value": shown, "source": where}
        if M and shown == "per contact":
            report[key].update(_stats(value))
    return law, report


def _cone(snap: Snapshot, normal, mu, opts: Options, pair):
    """Forces on or inside the friction cone by the stated policy; states per contact (module docstring)."""
    f = snap.force.copy()
    fdotn = np.sum(f * normal, axis=1)
    fn = -fdotn
    ft_vec = f - fdotn[:, None] * normal
    ft = norms(ft_vec)
    fmag = norms(f)
    loaded = fmag > 0
    positive = fn > 0
    if np.sum(loaded) and np.sum(fdotn[loaded] > 0) > np.sum(loaded) / 2:
        raise SceneError(f"{snap.source}: force: f·n > 0 (tension) for {np.sum(fdotn[loaded] > 0)} of "
                         f"{np.sum(loaded)} contacts: the forces look like the force on the second particle; "
                         "granstab needs f^pq, the force on the first (swap the columns or the ids)")
    tension = loaded & ~positive
    limit = mu * np.where(positive, fn, 0.0)
    outside = positive & (ft > limit * (1 + opts.yield_rtol))
    flagged = np.zeros(len(f), bool) if snap.mobilised is None else snap.mobilised.astype(bool)
    near = positive & (ft >= limit * (1 - opts.yield_rtol)) & ~outside
    decides = near if snap.mobilised is None else flagged & positive & ~outside     # the file's flag stands
    at_yield = decides & (ft > 0) & (mu > 0)
    state = np.full(len(f), "auto", dtype=object)
    state[tension] = "elastic"
    projected = at_yield.copy()
    if np.any(outside):
        if opts.outside_cone == "error":
            c = int(np.flatnonzero(outside)[0])
            raise SceneError(f"{snap.where('contact', c)}: contact {pair[c]}: force: outside the friction cone, |f_t|/(μ f_n) = "
                             f"{ft[c] / limit[c]:.6g} ({int(outside.sum())} such contacts; see --outside-cone)")
        if opts.outside_cone in ("sliding", "project"):
            projected |= outside
        state[outside] = "sliding" if opts.outside_cone == "sliding" else "elastic"
    state[at_yield] = "sliding"
    change = np.zeros(len(f))
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = np.where(projected & (ft > 0), limit / np.where(ft > 0, ft, 1.0), 1.0)
    f[projected] = (-fn[projected, None] * normal[projected]) + factor[projected, None] * ft_vec[projected]
    change[projected] = np.abs(ft[projected] - limit[projected]) / fmag[projected]
    action = {"sliding": "projected onto the cone, marked sliding (at yield)",
              "project": "projected onto the cone, treated as sticking (elastic)",
              "elastic": "kept as in the file, treated as elastic",
              "error": "none outside"}[opts.outside_cone]
    cone = {"yield_rtol": opts.yield_rtol, "at_yield": int(at_yield.sum()),
            "rule": YIELD_RULES[snap.mobilised is not None],
            "at_yield_by_file_flag": int(np.sum(at_yield & flagged & ~near)),
            "within_tolerance_not_flagged": int(np.sum(near & ~flagged)) if snap.mobilised is not None else 0,
            "outside": {"count": int(outside.sum()), "fraction": float(outside.mean()) if len(f) else 0.0,
                        "policy": opts.outside_cone, "action": action, "names": pair[outside]},
            "largest_ratio_ft_over_mu_fn": float(np.max(ft[positive] / np.maximum(limit[positive], 1e-300)))
            if np.any(positive & (mu > 0)) else None,
            "largest_change_over_force": float(change.max()) if len(f) else 0.0}
    report = {"convention": "f^pq on p by q; compression f·n < 0",
              "compressive": int(np.sum(positive)), "fn_nonpositive": {"count": int(np.sum(~positive)),
                                                                    "with_force": int(tension.sum()),
                                                                    "treated_as": "elastic",
                                                                    "names": pair[~positive]},
              "fn": _stats(fn)}
    return f, state, cone, report


# ------------------------------------------------------------------------------------------------ imbalance

def _imbalance(snap: Snapshot, arm_p, arm_q) -> dict:
    """Per particle |Σ f + wall| / Σ|f| and |Σ (r×f + m)| / Σ(|r||f| + |m|) over the file's contacts and forces."""
    N, d = snap.x.shape
    r = 1 if d == 2 else 3
    force = snap.force
    fmag = norms(force)
    moment = np.zeros((len(force), r)) if snap.moment is None else snap.moment
    mmag = norms(moment)
    side = np.concatenate([snap.p, snap.q])        # p's contributions, then q's: the order np.add.at sums in
    net = sum_at(side, np.concatenate([force, -force]), N)
    torque = sum_at(side, np.concatenate([_cross(arm_p, force) + moment, _cross(arm_q, -force) - moment]), N)
    fscale = sum_at(side, np.concatenate([fmag, fmag]), N)
    mscale = sum_at(side, np.concatenate([norms(arm_p) * fmag + mmag,
                                           norms(arm_q) * fmag + mmag]), N)
    bodies = snap.bodies or {}
    if snap.wall_load is not None:        # a body resting on a wall alone: its scale is Σ|f|, not |Σ f| ≈ 0
        net += snap.wall_load
        fscale += bodies["wall_force_scale"] if "wall_force_scale" in bodies else norms(snap.wall_load)
    if bodies.get("wall_moment") is not None:
        torque += bodies["wall_moment"]
        mscale += bodies["wall_moment_scale"]
    counted = fscale > 0
    excluded = "particles without contacts"
    if snap.wall_flags is not None:
        counted &= snap.wall_flags == 0
        excluded += ", particles touching a wall whose force the file does not give"
    return {"particles": int(counted.sum()), "excluded": excluded,
            "force": _stats(norms(net[counted]) / fscale[counted]),
            "moment": _stats(norms(torque[counted]) / np.maximum(mscale[counted], 1e-300)),
            "scale": "|Σf| over Σ|f| of the particle; |Σ(r×f + m)| over Σ(|r||f| + |m|)"}


def _cross(a, b):
    """a × b (2D: the e3 component, (M, 1)) by components: vec.cross's values (its zeros' signs may differ; the
    report takes norms) without its (M, 3, 3) matrices, 4× faster in 3D."""
    if a.shape[1] == 2:
        return (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])[:, None]
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


# ------------------------------------------------------------------------------------------------ selection

def _select(snap: Snapshot, x, opts: Options, names):
    """Contacts and particles inside the region (both ends inside); counts of what was left out."""
    keep_p = np.ones(len(x), bool) if opts.region is None else region_mask(opts.region, x, names, snap.source)
    keep_c = keep_p[snap.p] & keep_p[snap.q]
    return keep_c, keep_p, {"particles": int(np.sum(~keep_p)), "contacts": int(np.sum(~keep_c))}


def region_mask(region, x, names, source) -> np.ndarray:
    """Particles inside `region`: a sequence of ids (names) or {"box": [lo0, hi0, lo1, hi1, ...]} on centres."""
    if isinstance(region, dict):
        box = np.asarray(region["box"], float).reshape(-1, 2)
        if box.shape[0] != x.shape[1]:
            raise SceneError(f"--region: box needs {2 * x.shape[1]} numbers (lo, hi per axis), got {box.size}")
        return np.all((x >= box[:, 0]) & (x <= box[:, 1]), axis=1)
    wanted = np.array([str(v) for v in region], dtype=object)
    missing = ~np.isin(wanted, names)
    if np.any(missing):
        raise SceneError(f"{source}: --region: particle {wanted[missing][0]}: id: not in this frame "
                         f"({int(missing.sum())} of {len(wanted)} ids missing)")
    return np.isin(names, wanted)


