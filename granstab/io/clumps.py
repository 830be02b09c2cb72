"""Clumps of spheres as rigid bodies: the clump tables (YADE's exporter, examples/yade/export_clumps.py, or any
engine) and the conversion every clump reader shares (LIGGGHTS multisphere: multisphere.py).

    bodies.csv    # gravity: gx gy gz                        (optional; m g acts at each centre of mass)
                  # cell: a11 a12 a13 a21 ... a33                (optional: a periodic cell, rows a_i)
                  body,x,y,z,mass,quatw,quati,quatj,quatk,inertia1,inertia2,inertia3
    members.csv   id,body,x,y,z,radius
    contacts.csv  id1,id2,fx,fy,fz,cx,cy,cz[,kn,kt,mu]

x y z of a body: its centre of mass; quat: body → world rotation (w first); inertia1-3: the principal moments about
the rotated body axes (YADE's State.inertia with State.ori). A contact names two member spheres (a negative id2 is
a wall: its force is a load on the member's clump, with its moment about the centre of mass); f is the force on id1
by id2; c the engine's contact point (checked against the members' geometry, and the point of a wall's force).
bodies.py gives the geometry: arm from the centre of mass, normal and curvature of the member spheres. In a
periodic cell (`# cell:` above the body or member table's header, as generic.py's) members and contacts may cross
the cell's faces: clump_snapshot takes minimum images (members from their centre of mass, a contact's second member
from its first).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from ..model.periodic import minimum_image
from .bodies import body_snapshot, inertia_tensor, rotation
from .build import Snapshot
from .columns import to_indices, unique_ids
from .generic import header, table_cell, table_names
from .lines import read_table
from .registry import Format, register

BODY_COLUMNS = ("body", "x", "y", "z", "mass", "quatw", "quati", "quatj", "quatk", "inertia1", "inertia2", "inertia3")
MEMBER_COLUMNS = ("id", "body", "x", "y", "z", "radius")
CONTACT_COLUMNS = ("id1", "id2", "fx", "fy", "fz", "cx", "cy", "cz")
LAW_COLUMNS = ("kn", "kt", "mu")


def clump_snapshot(source: str, fmt: str, bodies: dict, members: dict, contacts: dict, gravity, law: dict,
                   lines: dict, notes: dict, lattice=None) -> Snapshot:
    """The body snapshot of clumps. bodies: "id" (N,), "x" (N, 3), "mass" (N,), "inertia" (N, 3, 3) or None,
    "quat" (N, 4) or None; members: "id", "body" (body ids), "x", "radius"; contacts: "id1", "id2" (member ids, id2
    < 0 a wall), "force" on id1, "point"; lines: "body", "member", "contact" (row → "<file>: line L").

    lattice: a periodic cell's rows (NaN row: an open axis) or None. Each member then sits at its clump's centre of
    mass plus the minimum image of its offset (the engine may wrap members and centres separately), a member
    contact's second member at the minimum image from the first, which fixes the image of q's clump (the contact's
    lattice shift, handed to build.py); engine and wall points are moved to the first member's image."""
    body_of = to_indices(bodies["id"], members["body"], "body", lines["member"], "not in the body table")
    wall = contacts["id2"] < 0
    m1 = to_indices(members["id"], contacts["id1"], "id1", lines["contact"], "not a member sphere")
    rows = np.flatnonzero(~wall)
    m2 = to_indices(members["id"], contacts["id2"][rows], "id2", lambda r: lines["contact"](rows[r]),
                    "not a member sphere")
    m1w, m1 = m1[wall], m1[rows]
    offset = minimum_image(members["x"] - bodies["x"][body_of], lattice)[0]    # member from its centre of mass
    _check_reach(offset, lattice, members["id"], lines["member"])
    x, R = bodies["x"][body_of] + offset, members["radius"]
    c2, shift = minimum_image(x[m2] - x[m1], lattice)             # the second member's image next to the first
    c2 = x[m1] + c2
    reach = np.linalg.norm(offset, axis=1) + R
    bound = np.zeros(len(bodies["id"]))
    np.maximum.at(bound, body_of, reach)
    snap = Snapshot(source=source, format=fmt, dim=3, ids=bodies["id"], x=bodies["x"], radius=bound,
                    p=body_of[m1], q=body_of[m2], force=contacts["force"][rows], mass=bodies["mass"],
                    orientation=bodies.get("quat"), law={k: (v[rows], w) for k, (v, w) in law.items()},
                    notes=notes, particle_line=lines["body"], contact_line=lambda c: lines["contact"](rows[c]),
                    lattice=lattice)
    snap.bodies = {"inertia": bodies.get("inertia")}
    snap.parts = {"kind": "clump", "body": body_of, "offset": offset, "radius": R}
    parts = {"c1": x[m1], "c2": c2, "R1": R[m1], "R2": R[m2], "flat1": np.zeros(len(rows), bool),
             "flat2": np.zeros(len(rows), bool), "name1": members["id"][m1], "name2": members["id"][m2],
             "point": _near(contacts["point"][rows], x[m1], lattice), "shift": shift}
    walls = {"body": body_of[m1w], "force": contacts["force"][wall],
             "point": _near(contacts["point"][wall], x[m1w], lattice)}
    return body_snapshot(snap, parts, walls, gravity, "clump")


def _check_reach(offset: np.ndarray, lattice, ids, line) -> None:
    """Each member closer to its clump's centre of mass than half the cell's narrowest width (the spacing of its
    lattice planes, 1/|b_i| for the reciprocal vectors b_i of the periodic axes): its image is then unambiguous."""
    if lattice is None:
        return
    periodic = ~np.isnan(lattice).any(axis=1)
    rows = np.where(periodic[:, None], np.nan_to_num(lattice), 1e6 * np.abs(np.nan_to_num(lattice)).max()
                    * np.eye(len(lattice)))                   # an open axis: a row too long to matter
    half = 0.5 / np.linalg.norm(np.linalg.inv(rows), axis=0)[periodic].max()
    far = np.linalg.norm(offset, axis=1)
    bad = np.flatnonzero(far >= half)
    if bad.size:
        m = bad[0]
        raise SceneError(f"{line(m)}: member {ids[m]}: x: {far[m]:.6g} from its clump's centre of mass, not less than "
                         f"half the periodic cell's width ({half:.6g}): which image belongs to the clump is ambiguous")


def _near(point: np.ndarray, anchor: np.ndarray, lattice) -> np.ndarray:
    """The image of each point nearest to its anchor (a member's centre in its clump's image)."""
    return anchor + minimum_image(point - anchor, lattice)[0]


# ------------------------------------------------------------------------------------------------ clump tables

def _kind(path: Path):
    """"bodies", "members", "contacts" or None: which clump table a file's header says it is."""
    names = table_names(path)
    if names is None:
        return None
    for kind, need in (("bodies", BODY_COLUMNS[:5]), ("members", MEMBER_COLUMNS), ("contacts", CONTACT_COLUMNS)):
        if set(need) <= set(names) and (kind != "members" or "mass" not in names):
            return kind
    return None


def is_clump_tables(paths: list[Path]) -> bool:
    """A body table and a member table among the paths (a clump table set)."""
    kinds = {_kind(p) for p in paths}
    return {"bodies", "members"} <= kinds


def _table(path: Path, need) -> tuple[dict, callable]:
    names, delimiter, line = header(path)
    missing = [n for n in need if n not in names]
    if missing:
        raise SceneError(f"{path}: line {line}: {missing[0]}: missing column")
    data = read_table(path, names, delimiter=delimiter, skiprows=line)
    first = line

    def line_of(row):
        return f"{path}: line {first + 1 + int(row)}"     # the exporter writes no comment lines between rows
    return {n: data[:, k] for k, n in enumerate(names)}, line_of


def _gravity(path: Path):
    """The `# gravity: gx gy gz` comment above a body table's header, or None."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, text in enumerate(fh, 1):
            text = text.strip()
            if not text.startswith("#"):
                return None
            if text[1:].strip().startswith("gravity:"):
                words = text.split(":", 1)[1].split()
                try:
                    g = np.array([float(w) for w in words])
                except ValueError:
                    raise SceneError(f"{path}: line {number}: gravity: not a number ({text[:60]!r})") from None
                if g.shape != (3,) or not np.all(np.isfinite(g)):
                    raise SceneError(f"{path}: line {number}: gravity: expected 3 finite numbers, got {len(words)}")
                return g
    return None


def read_clump_tables(paths: list[Path]) -> Snapshot:
    """The snapshot of a clump table set (module docstring)."""
    kinds = {}
    for p in paths:
        kind = _kind(p)
        if kind is None:
            raise SceneError(f"{p}: header: not a clump table (bodies: {','.join(BODY_COLUMNS)}; members: "
                             f"{','.join(MEMBER_COLUMNS)}; contacts: {','.join(CONTACT_COLUMNS)})")
        if kind in kinds:
            raise SceneError(f"{p}: header: a second {kind} table (the first: {kinds[kind]})")
        kinds[kind] = p
    if "contacts" not in kinds:
        raise SceneError(f"{paths[0]}: contacts: no contact table ({','.join(CONTACT_COLUMNS)})")
    B, bline = _table(kinds["bodies"], BODY_COLUMNS)
    M, mline = _table(kinds["members"], MEMBER_COLUMNS)
    C, cline = _table(kinds["contacts"], CONTACT_COLUMNS)
    for table, key, line in ((B, "body", bline), (M, "id", mline), (C, "id1", cline), (C, "id2", cline),
                             (M, "body", mline)):
        bad = np.flatnonzero(table[key] != np.round(table[key]))
        if bad.size:
            raise SceneError(f"{line(bad[0])}: {key}: not an integer ({table[key][bad[0]]})")
    unique_ids(B["body"], bline, "in the body table")
    unique_ids(M["id"], mline, "in the member table")
    quat = np.stack([B[k] for k in ("quatw", "quati", "quatj", "quatk")], 1)
    norm = np.linalg.norm(quat, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1) > 1e-6)
    if bad.size:
        raise SceneError(f"{bline(bad[0])}: quatw: not a unit quaternion (|q| = {norm[bad[0]]:.6g})")
    principal = np.stack([B[f"inertia{k}"] for k in (1, 2, 3)], 1)
    bad = np.flatnonzero(~np.all(principal > 0, axis=1))
    if bad.size:
        raise SceneError(f"{bline(bad[0])}: inertia1: principal moments must be > 0")
    bodies = {"id": B["body"].astype(np.int64), "x": np.stack([B[a] for a in "xyz"], 1), "mass": B["mass"],
              "quat": quat / norm[:, None], "inertia": inertia_tensor(principal, rotation(quat))}
    members = {"id": M["id"].astype(np.int64), "body": M["body"], "x": np.stack([M[a] for a in "xyz"], 1),
               "radius": M["radius"]}
    contacts = {"id1": C["id1"], "id2": C["id2"], "force": np.stack([C[f"f{a}"] for a in "xyz"], 1),
                "point": np.stack([C[f"c{a}"] for a in "xyz"], 1)}
    law = {key: (C[col], f"{kinds['contacts'].name} column {col}") for key, col in
           (("k", "kn"), ("mu", "mu")) if col in C}
    if "kn" in C and "kt" in C:
        law["alpha"] = (C["kt"] / C["kn"], f"{kinds['contacts'].name} columns kt / kn")
    source = " + ".join(str(kinds[k]) for k in ("bodies", "members", "contacts"))
    return clump_snapshot(source, "clumps", bodies, members, contacts, _gravity(kinds["bodies"]), law,
                          {"body": bline, "member": mline, "contact": cline}, {},
                          table_cell([kinds["bodies"], kinds["members"]], 3))


register(Format("clumps", sniff=is_clump_tables, read=lambda paths, request, progress: read_clump_tables(paths)))
