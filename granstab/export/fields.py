"""What an export carries: one frame's arrays by name — per particle, per contact, the cell — built once from a
scene (and a scan folder, and the whole packing's consistent modes) and handed unchanged to every writer, so that
the .vtp, the extended XYZ and the dump hold the same numbers under the same names (docs/export.md lists them).

Vectors are 3-component whatever the dimension (VTK, OVITO and ASE draw in 3D): 2D positions and forces get z = 0,
2D rotations (about e3) become the axial vector (0, 0, θ).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model.errors import SceneError
from ..model.scene import Scene
from ..model.vec import quaternion_matrix

#: the contact state codes: below the yield surface (or declared elastic), at yield (the branch decides whether it
#: slides: Appendix D's ±1), declared sliding
STATE_CODES = {"elastic": 0, "at_yield": 1, "sliding": 2}
#: a particle's own cluster verdict as a number (OVITO and the dump colour by numbers); -1: the particle was no centre
VERDICT_CODES = {"": -1, "stable": 0, "neutral": 1, "unstable": 2, "not determined": 3, "error": 4}


@dataclass
class FrameFields:
    """One exported frame. positions (N, 3); particles: name → (N,) or (N, 3) arrays (strings as str arrays);
    ends (M, 2, 3): each contact's line from x^p to q's copy (x^q + image @ cell, so a seam contact does not cross
    the cell); contacts: name → (M,) or (M, 3); cell (d, d) lattice rows or None; info: scalars (mode
    eigenvalues, the metric); time: the frame's number in a sequence."""

    dim: int
    positions: np.ndarray
    particles: dict
    ends: np.ndarray
    contacts: dict
    cell: np.ndarray | None
    info: dict = field(default_factory=dict)
    time: float = 0.0


def as3(a: np.ndarray) -> np.ndarray:
    """(n, d) vectors as (n, 3), zero-padded."""
    a = np.asarray(a, dtype=float)
    return np.pad(a, ((0, 0), (0, 3 - a.shape[1])))


def axial(rotation: np.ndarray, dim: int) -> np.ndarray:
    """(n, r) rotations as (n, 3) axial vectors: 2D θ3 → (0, 0, θ3), 3D unchanged."""
    rotation = np.asarray(rotation, dtype=float)
    return np.pad(rotation, ((0, 0), (2, 0))) if dim == 2 else rotation


def contact_radius(scene: Scene) -> np.ndarray:
    """Per particle the mean distance from its centre to its contact points, |r^pq| (the radius of a disk or sphere
    at its contacts; NaN for a particle without contacts): scenes keep contact geometry, not particle shapes."""
    dist = np.r_[np.linalg.norm(scene.r_pq, axis=1), np.linalg.norm(scene.r_qp, axis=1)]
    owner = np.r_[scene.p, scene.q]
    count = np.bincount(owner, minlength=scene.n_particles)
    total = np.bincount(owner, weights=dist, minlength=scene.n_particles)
    return np.divide(total, count, out=np.full(scene.n_particles, np.nan), where=count > 0)


def quaternion_xyzw(orientation, scene: Scene) -> np.ndarray:
    """(N, 4) unit quaternions (w, x, y, z), as readers give them, in OVITO's order (x, y, z, w): its Orientation
    property, which extended XYZ's `orientation` column and a dump's quati quatj quatk quatw fill."""
    q = np.asarray(orientation, dtype=float)
    if q.shape != (scene.n_particles, 4):
        raise SceneError(f"{scene.source}: orientation: shape {q.shape}, expected ({scene.n_particles}, 4)")
    return q[:, [1, 2, 3, 0]]


def shape_fields(shape, orientation, scene: Scene) -> dict:
    """OVITO's and ParaView's shape fields of superquadrics ((N, 5) a, b, c, n1, n2): `aspherical_shape` (N, 3) the
    semi-axes (OVITO's Aspherical Shape), `superquadric_roundness` (N, 2) = (2/n1, 2/n2) (OVITO's Superquadric
    Roundness Phi, Theta: 1 round, → 0 blocky) and, with an orientation, `shape_tensor` (N, 9) = R diag(a, b, c) Rᵀ
    (a symmetric tensor whose eigenvectors are the body axes and eigenvalues the semi-axes: ParaView's Tensor Glyph)."""
    shape = np.asarray(shape, dtype=float)
    if shape.shape != (scene.n_particles, 5):
        raise SceneError(f"{scene.source}: shape: shape {shape.shape}, expected ({scene.n_particles}, 5)")
    out = {"aspherical_shape": shape[:, :3].copy(), "superquadric_roundness": 2.0 / shape[:, 3:]}
    if orientation is not None:
        R = quaternion_matrix(orientation)
        out["shape_tensor"] = ((R * shape[:, None, :3]) @ np.swapaxes(R, 1, 2)).reshape(-1, 9)
    return out


def contact_state(scene: Scene) -> np.ndarray:
    """STATE_CODES per contact: 2 declared sliding, 1 at yield (Q = 0 within tolerance, `Scene.at_yield`), else 0."""
    state = np.asarray(scene.state)
    return np.where(state == "sliding", STATE_CODES["sliding"],
                    np.where(scene.at_yield(), STATE_CODES["at_yield"], STATE_CODES["elastic"])).astype(np.int32)


def scene_frame(scene: Scene, time: float = 0.0) -> FrameFields:
    """The scene's own fields: names, positions, contact radius, mass where known; per contact the particles, the
    contact point, the branch vector, the normal, the force on p by q, its normal part (compression positive: -f·n)
    and tangential part, the state."""
    particles = {"name": np.array(scene.names, dtype=str), "radius": contact_radius(scene)}
    if scene.mass is not None:
        particles["mass"] = np.asarray(scene.mass, dtype=float)
    if scene.fixed is not None:
        particles["fixed"] = np.asarray(scene.fixed, dtype=np.int32)
    fn = np.sum(scene.force * scene.normal, axis=1)
    contacts = {"p": scene.p.astype(np.int64), "q": scene.q.astype(np.int64), "point": as3(scene.point),
                "normal": as3(scene.normal),
                "force": as3(scene.force), "normal_force": -fn, "tangential_force": as3(scene.tangential_force()),
                "state": contact_state(scene)}
    contacts["branch"] = as3(scene.branch)                         # x^p → q's copy: ends = x^p, x^p + branch
    ends = np.stack([as3(scene.x[scene.p]), as3(scene.q_copy)], axis=1)
    return FrameFields(dim=scene.dim, positions=as3(scene.x), particles=particles, ends=ends, contacts=contacts,
                 cell=None if scene.cell is None else np.asarray(scene.cell, dtype=float), time=time)


def matching_packing(scene: Scene, packing: Scene, folder) -> None:
    """A scan folder's packing must be the exported one: the same names in the same order at the same positions
    (within 1e-9 of the packing's extent: a saved NPZ is exact, a re-read text file rounds at ~1e-15); one line."""
    if packing.names != scene.names:
        n, m = packing.n_particles, scene.n_particles
        where = next((i for i, (a, b) in enumerate(zip(packing.names, scene.names)) if a != b), min(n, m))
        raise SceneError(f"{folder}: --scan-dir: the scan's packing ({n} particles, from {packing.source}) is not "
                         f"{scene.source} ({m} particles): the names differ at particle #{where}")
    extent = float(np.ptp(scene.x, axis=0).max()) if scene.n_particles > 1 else 1.0
    moved = np.linalg.norm(packing.x - scene.x, axis=1)
    if np.any(moved > 1e-9 * max(extent, 1e-300)):
        i = int(np.argmax(moved))
        raise SceneError(f"{folder}: --scan-dir: particle {scene.names[i]}: x: the scan's packing has it "
                         f"{moved[i]:.3g} away from {scene.source}'s position (another frame?)")


def add_scan(frame: FrameFields, scene: Scene, folder) -> None:
    """The scan's per-particle verdict fields (granstab.scan: particles.*, clusters.*): the unstable fraction of the
    clusters containing the particle, its own cluster's verdict (text and VERDICT_CODES), that cluster's λ_min and
    how many clusters contain the particle."""
    from ..scan import read_map, read_packing
    matching_packing(scene, read_packing(folder), folder)
    data = read_map(folder)
    rows, own = data["clusters"], data["particles"]
    lam = np.full(scene.n_particles, np.nan)
    lam[np.asarray(rows["center"], dtype=np.int64)] = np.asarray(rows["lambda_min"], dtype=float)
    verdict = np.array([str(v) for v in own["own_verdict"]], dtype=str)
    unknown = sorted(set(verdict) - set(VERDICT_CODES))
    if unknown:
        raise SceneError(f"{folder}: particles: own_verdict: unknown verdict {unknown[0]!r}")
    frame.particles.update(unstable_fraction=np.asarray(own["unstable_fraction"], dtype=float),
                           own_verdict=verdict,
                           verdict_code=np.array([VERDICT_CODES[v] for v in verdict], dtype=np.int32),
                           cluster_lambda_min=lam, n_clusters=np.asarray(own["n_clusters"], dtype=np.int64))
