"""Rigid bodies made of round parts — clumps of spheres (LIGGGHTS multisphere, YADE clumps) and LAMMPS rounded
polygons — as snapshots whose particles are the bodies (build.py then applies the shared conventions).

A body is one rigid particle: its reference point x is its centre of mass, its mass and inertia tensor are the
engine's. Its parts are round: a clump's member spheres, a rounded polygon's vertex disks (radius r) and its sides
(flat, at distance r from the polygon's skeleton). Every contact touches one part of each body; the engine's pair
of parts gives

- the normal n: the line from p's part centre to q's (a side's "centre" is the foot of the other part's centre on
  it, so n is the side's normal);
- the overlap δ = R_1 + R_2 − d of the two parts and the contact point x_1 + (R_1 − δ/2) n, midway in the overlap
  (the point granstab's sphere convention uses: build.py, docs/errata.md);
- the curvature of each body's parallel surface through that point: a sphere or disk part of radius R has
  ρ = R − δ/2, K = −(I − n⊗n)/ρ (2D: −t⊗t/ρ); a flat side has K = 0 (ρ = ∞);
- the arm r^pq = point − x_p from the body's centre of mass (not along the normal).

Two parts of one body never touch (engines exclude them from the neighbour lists): a file that lists such a pair
is refused in one line. Wall contacts and gravity are external loads on the body; their moments about x enter the
import report's balance residual (`imbalance`), which checks that points, arms and loads are right.
"""
from __future__ import annotations

import numpy as np

from ..model.errors import SceneError
from ..model.vec import sum_at
from .build import Pairs, Snapshot, _geometry, _stats


def rotation(quat: np.ndarray) -> np.ndarray:
    """(N, 3, 3) body → world rotation matrices of unit quaternions (w, x, y, z)."""
    w, x, y, z = (quat / np.linalg.norm(quat, axis=1, keepdims=True)).T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)


def inertia_tensor(principal: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(N, 3, 3) world-frame inertia Σ_k I_k e_k⊗e_k from principal moments (N, 3) and axes (N, 3, 3), e_k the
    k-th column."""
    return np.einsum("nik,nk,njk->nij", axes, principal, axes)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b, (M, r): 2D its e3 component."""
    if a.shape[1] == 2:
        return (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])[:, None]
    return np.cross(a, b)


def part_geometry(c1, c2, R1, R2):
    """Per part contact: centre distance d, unit normal e (part 1 → part 2), overlap δ and the contact point
    c1 + (R1 − δ/2) e."""
    branch = c2 - c1
    d = np.linalg.norm(branch, axis=1)
    e = branch / np.where(d > 0, d, 1.0)[:, None]
    delta = R1 + R2 - d
    return d, e, delta, c1 + (R1 - delta / 2)[:, None] * e


def body_snapshot(snap: Snapshot, parts: dict, walls: dict | None, gravity, what: str) -> Snapshot:
    """Fill `snap` (ids, x = centres of mass, radius = bounding radii, mass, p, q = bodies, force f^pq on p, law,
    lines) with the bodies' contact geometry from its parts.

    parts: "c1", "c2" (M, d) part centres (a side's: the foot point), "R1", "R2" (M,) part radii, "flat1",
    "flat2" (M,) bool sides, "name1", "name2" (M,) part ids (errors), optionally "point" (M, d) the engine's own
    contact points (checked, reported), optionally "shift" (M, d) the lattice shift of q's image in a periodic
    cell (x_q − shift·lattice is the copy the contact touches: build.py's branch). walls: "body" (W,), "force" (W, d) on the body, "point" (W, d), or None.
    gravity: (d,) or None (with masses: m g on each body). `what`: "clump"/"polygon", for messages. Sets
    snap.bodies (build.py reads it): "point" (M, d), "rho" (M, 2) (∞: flat), "inertia" (N, r, r) or None,
    "wall_moment" (N, r) and "wall_moment_scale" (N,) (Σ r × f and Σ|r||f| of the walls about x),
    "wall_force_scale" (N,) (Σ|f| of the walls plus |m g|: the loads' own size, not that of their sum), "geometry"."""
    pair = Pairs(np.array([str(i) for i in snap.ids], dtype=object), snap.p, snap.q)
    same = np.flatnonzero(snap.p == snap.q)
    if same.size:
        c = same[0]
        raise SceneError(f"{snap.where('contact', c)}: contact {parts['name1'][c]}-{parts['name2'][c]}: id2: both "
                         f"parts belong to {what} {snap.ids[snap.p[c]]} (a rigid body's parts cannot touch each "
                         "other; engines exclude them)")
    _unique_parts(snap, parts)
    d, e, delta, point = part_geometry(parts["c1"], parts["c2"], parts["R1"], parts["R2"])
    if np.any(d == 0):
        c = int(np.flatnonzero(d == 0)[0])
        raise SceneError(f"{snap.where('contact', c)}: contact {pair[c]}: x: the two parts' centres coincide")
    rho, geometry = _geometry("centres", parts["R1"], parts["R2"], d, e, e, snap, pair)
    geometry["rule"] = f"{what} parts: point midway in the parts' overlap, ρ = R − δ/2 of the part, flat side ρ = ∞"
    rho = np.stack([np.where(parts["flat1"], np.inf, rho["rho_p"]), np.where(parts["flat2"], np.inf, rho["rho_q"])], 1)
    if "point" in parts:
        off = np.linalg.norm(parts["point"] - point, axis=1) / np.minimum(parts["R1"], parts["R2"])
        geometry["engine_point_offset_over_radius"] = _stats(off)
    N, dim = snap.x.shape
    load, moment, scale = np.zeros((N, dim)), np.zeros((N, 1 if dim == 2 else 3)), np.zeros(N)
    force_scale = np.zeros(N)
    if walls is not None and len(walls["body"]):
        arm = walls["point"] - snap.x[walls["body"]]
        load = sum_at(walls["body"], walls["force"], N)
        moment = sum_at(walls["body"], _cross(arm, walls["force"]), N)
        size = np.linalg.norm(walls["force"], axis=1)
        scale = sum_at(walls["body"], np.linalg.norm(arm, axis=1) * size, N)
        force_scale = sum_at(walls["body"], size, N)
    if gravity is not None and snap.mass is not None:
        load = load + snap.mass[:, None] * np.asarray(gravity, float)[None, :]
        force_scale = force_scale + snap.mass * np.linalg.norm(gravity)
    snap.normal, snap.wall_load = e, load
    snap.bodies = {"point": point, "rho": rho, "inertia": snap.bodies and snap.bodies.get("inertia"),
                   "shift": parts.get("shift"),
                   "wall_moment": moment, "wall_moment_scale": scale, "wall_force_scale": force_scale,
                   "geometry": geometry}
    snap.notes["walls"] = {"wall_contacts": 0 if walls is None else int(len(walls["body"])),
                           "gravity": None if gravity is None else [float(g) for g in gravity],
                           "treatment": "wall forces and gravity (m g at the centre of mass) are loads on the "
                                        "body, their moments about its centre of mass counted in the balance"}
    snap.notes["bodies"] = {"kind": what, "bodies": int(N), "parts_touching": int(2 * len(d)),
                            "flat_sides_in_contact": int(np.sum(parts["flat1"]) + np.sum(parts["flat2"])),
                            "conforming_contacts": int(np.sum(parts["flat1"] & parts["flat2"])),
                            "arms": "from each body's centre of mass to the contact point"}
    return snap


def _unique_parts(snap: Snapshot, parts: dict) -> None:
    """Each pair of parts at most once (two bodies may touch at several points, each pair of parts once)."""
    names = np.concatenate([parts["name1"], parts["name2"]]).astype(str)
    _, code = np.unique(names, return_inverse=True)
    M = len(parts["name1"])
    a, b = code[:M], code[M:]
    key = np.minimum(a, b).astype(np.int64) * (code.max() + 1) + np.maximum(a, b)
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        c = np.flatnonzero(key == key[first[counts > 1][0]])[1]
        raise SceneError(f"{snap.where('contact', c)}: contact {parts['name1'][c]}-{parts['name2'][c]}: id2: listed "
                         "twice in one frame")
