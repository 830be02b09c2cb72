"""RigidLibrary data (silkehenkes/RigidLibrary): photoelastic annulus frames and periodic DEM snapshots.

Annulus folder (`particle_positions.txt`: frame, id, x, y, r [px], edge −1 inner wall / +1 outer / 0;
`Adjacency_list.txt`: frame, id1, id2, tangential, normal, every pair in both orders). As RigidLibrary:
n from id1 to id2 along the centre line, the force on id1 is f = −f_n n + f_t t with t = e3 × n; the row
with id1 > id2 is kept (p = the larger id) and the other listing is compared with it (report: duplicates).
The files give no wall forces: a flagged particle's wall force is its imbalance, which becomes its load.

DataSim folder (`Parameters_final.dat`, `posinit.dat` (radius: 4th column), `PosVel<step>.dat` (x, y, θ, vx, vy, ω,
z), `Contact<step>.dat` (i, j, n_x, n_y, fully-mobilised flag, f_n, f_t, f_t')): particles named by their 0-based
row, n and f_n as in the file, f^pq = −f_n n + f_t t, Hookean k = k_rep and μ from the parameters, Lees–Edwards
box of side boxVec1x sheared by γ = strain_rate · step · tprint. Column 8 (f_t', which RigidLibrary adds to f_t) is
a small rate-dependent part: it is left out so that mobilised contacts sit on the cone, and its size is reported.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from .build import Snapshot
from .lines import check_unique, integer_column, line_of, pick_frame, read_table
from .registry import Format, register

ANNULUS_FILES = ("particle_positions.txt", "Adjacency_list.txt")
POSITION_FIELDS = ("frame", "id", "x", "y", "r", "edge")
ADJACENCY_FIELDS = ("frame", "id1", "id2", "tangential", "normal")
CONTACT_FIELDS = ("i", "j", "n_x", "n_y", "mobilised", "f_n", "f_t", "f_t'")
POSVEL_FIELDS = ("x", "y", "theta", "vx", "vy", "omega", "z")


def is_annulus(path: Path) -> bool:
    return path.is_dir() and all((path / name).is_file() for name in ANNULUS_FILES)


def is_datasim(path: Path) -> bool:
    return path.is_dir() and (path / "Parameters_final.dat").is_file()


def tangent_force(fn, ft, n):
    """f = −f_n n + f_t t with t = e3 × n (RigidLibrary's sign convention), (M, 2)."""
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    return -fn[:, None] * n + ft[:, None] * t


def read_annulus(folder: Path, frame=None) -> Snapshot:
    pos_path, adj_path = folder / ANNULUS_FILES[0], folder / ANNULUS_FILES[1]
    pos = read_table(pos_path, POSITION_FIELDS, delimiter=",", min_rows=1)
    adj = read_table(adj_path, ADJACENCY_FIELDS, delimiter=",", min_rows=1)
    frame, frames = pick_frame(pos[:, 0], frame, pos_path)
    rows = np.flatnonzero(adj[:, 0] == frame)
    if rows.size == 0:
        raise SceneError(f"{adj_path}: frame {frame:g}: frame: no contacts for this frame (positions have it)")
    extra = np.setdiff1d(np.unique(adj[:, 0]), frames)
    if extra.size:
        raise SceneError(f"{adj_path}: frame {extra[0]:g}: frame: not in {pos_path.name} (mismatched files)")
    prow = np.flatnonzero(pos[:, 0] == frame)
    P = pos[prow]
    ids = integer_column(P[:, 1], pos_path, "id", prow)
    check_unique(ids, pos_path, "id", prow)
    A = adj[rows]
    id1 = integer_column(A[:, 1], adj_path, "id1", rows)
    id2 = integer_column(A[:, 2], adj_path, "id2", rows)
    order = np.argsort(ids)
    index = {}
    for name, column in (("id1", id1), ("id2", id2)):
        where = np.searchsorted(ids[order], column)
        where = np.minimum(where, len(ids) - 1)
        unknown = np.flatnonzero(ids[order][where] != column)
        if unknown.size:
            r = rows[unknown[0]]
            raise SceneError(f"{adj_path}: line {line_of(adj_path, r)}: {name}: unknown particle id {column[unknown[0]]} "
                             f"(not in frame {frame:g} of {pos_path.name})")
        index[name] = order[where]
    # one contact per unordered pair: p = the larger id; prefer the row listed with id1 > id2
    p = np.where(id1 > id2, index["id1"], index["id2"])
    q = np.where(id1 > id2, index["id2"], index["id1"])
    key = p.astype(np.int64) * len(ids) + q
    pick = np.lexsort(((id1 < id2), key))
    _, first, counts = np.unique(key[pick], return_index=True, return_counts=True)
    chosen = pick[first]
    duplicates = _compare_listings(key[pick], A[pick, 3:5], first, counts)
    # RigidLibrary's contact order: by the smaller id, then the larger
    chosen = chosen[np.lexsort((ids[p[chosen]], ids[q[chosen]]))]
    p, q = p[chosen], q[chosen]
    x = P[:, 2:4]
    with np.errstate(invalid="ignore", divide="ignore"):
        branch = x[q] - x[p]
        n = branch / np.linalg.norm(branch, axis=1)[:, None]
    force = tangent_force(A[chosen, 4], A[chosen, 3], n)
    edge = P[:, 5]
    walls = {"inner (edge −1)": int(np.sum(edge < 0)), "outer (edge +1)": int(np.sum(edge > 0)),
             "treatment": "no wall forces in the files: a flagged particle's wall force is its contact-force "
                          "imbalance, which becomes its external load (b = −Σf); left out of the imbalance statistics"}
    return Snapshot(source=str(folder), format="rigidlibrary-annulus", dim=2, ids=ids, x=x, radius=P[:, 4],
                    p=p, q=q, force=force, normal=n, wall_flags=edge, length_unit="px", frame=int(frame),
                    frames=[int(f) for f in frames], notes={"walls": walls, "duplicates": duplicates},
                    particle_line=lambda i: f"{pos_path}: line {line_of(pos_path, prow[i])}",
                    contact_line=lambda c: f"{adj_path}: line {line_of(adj_path, rows[chosen[c]])}")


def _compare_listings(key, forces, first, counts) -> dict:
    """How the second listing of each pair agrees with the first (tangential, normal force)."""
    twice = first[counts >= 2]
    diff = np.abs(forces[twice + 1] - forces[twice])
    scale = np.maximum(np.abs(forces[twice]).max(axis=1, initial=0), 1e-300)
    rel = diff.max(axis=1, initial=0) / scale
    return {"pairs_listed_twice": int(twice.size), "pairs_listed_once": int(np.sum(counts == 1)),
            "pairs_listed_more": int(np.sum(counts > 2)), "disagreeing_listings": int(np.sum(rel > 1e-9)),
            "largest_relative_difference": float(rel.max()) if rel.size else 0.0,
            "kept": "the row with id1 > id2 (as RigidLibrary)"}


def _parameters(path: Path) -> dict:
    """`name value` lines of a RigidLibrary parameter file (a short header: read line by line)."""
    params = {}
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        parts = line.split()
        if len(parts) >= 2:
            params[parts[0]] = parts[-1]
    return params


def _number(params: dict, key: str, path: Path) -> float:
    if key not in params:
        raise SceneError(f"{path}: {key}: missing")
    try:
        value = float(params[key])
    except ValueError:
        raise SceneError(f"{path}: {key}: not a number ({params[key]!r})") from None
    if not np.isfinite(value):
        raise SceneError(f"{path}: {key}: not a finite number ({params[key]!r})")
    return value


def datasim_steps(folder: Path) -> list[int]:
    steps = {int(m.group(1)) for f in folder.glob("PosVel*.dat") if (m := re.fullmatch(r"PosVel(\d+)\.dat", f.name))}
    return sorted(steps)


def read_datasim(folder: Path, frame=None) -> Snapshot:
    par_path = folder / "Parameters_final.dat"
    params = _parameters(par_path)
    steps = datasim_steps(folder)
    if not steps:
        raise SceneError(f"{folder}: no PosVel<step>.dat file")
    if frame is None:
        frame = steps[0]
    if int(frame) not in steps:
        raise SceneError(f"{folder}: frame {frame}: frame: no PosVel{frame}.dat (steps: {', '.join(map(str, steps[:5]))})")
    frame = int(frame)
    con_path = folder / f"Contact{frame}.dat"
    if not con_path.is_file():
        raise SceneError(f"{con_path}: frame {frame}: frame: missing (PosVel{frame}.dat has no contact file)")
    box = _number(params, "boxVec1x", par_path)
    box_y = _number(params, "boxVec2y", par_path) if "boxVec2y" in params else box
    n_particles = int(_number(params, "np", par_path))
    pos_path, init_path = folder / f"PosVel{frame}.dat", folder / "posinit.dat"
    pos = read_table(pos_path, POSVEL_FIELDS[:2], min_rows=1)
    radius = read_table(init_path, ("x", "y", "theta", "radius"), min_rows=1)[:, 3]
    for path, rows in ((pos_path, len(pos)), (init_path, len(radius))):
        if rows != n_particles:
            raise SceneError(f"{path}: line {rows + 1}: x: {rows} particles, {par_path.name} says np = {n_particles}")
    con = read_table(con_path, CONTACT_FIELDS, min_rows=0)
    i = integer_column(con[:, 0], con_path, "i")
    j = integer_column(con[:, 1], con_path, "j")
    for name, column in (("i", i), ("j", j)):
        bad = np.flatnonzero((column < 0) | (column >= n_particles))
        if bad.size:
            raise SceneError(f"{con_path}: line {line_of(con_path, bad[0])}: {name}: unknown particle {column[bad[0]]} "
                             f"(rows 0..{n_particles - 1})")
    strain = _number(params, "strain_rate", par_path) * frame * _number(params, "tprint", par_path)
    shear = strain - np.round(strain)
    x = pos[:, :2].copy()
    x[:, 0] -= box * np.round(x[:, 0] / box)
    x[:, 1] -= box_y * np.round(x[:, 1] / box_y)
    with np.errstate(invalid="ignore", divide="ignore"):  # six digits: |n| = 1 ± 1e-6; f_n along the unit normal
        n = con[:, 2:4] / np.linalg.norm(con[:, 2:4], axis=1)[:, None]
    force = tangent_force(con[:, 5], con[:, 6], n)
    fmag = np.maximum(np.linalg.norm(force, axis=1), 1e-300)
    law = {"k": (_number(params, "k_rep", par_path), f"{par_path.name} k_rep (Hookean normal spring)"),
           "mu": (_number(params, "mu", par_path), f"{par_path.name} mu")}
    notes = {"periodic": {"kind": "Lees–Edwards", "box": [box, box_y], "shear_strain": strain,
                          "offset_fraction": shear},
             "left_out": {"column": "f_t' (8th)", "largest_over_force": float(np.max(np.abs(con[:, 7]) / fmag))
                          if len(con) else 0.0,
                          "why": "rate-dependent part; RigidLibrary adds it to f_t, granstab keeps the frictional "
                                 "f_t so that flagged contacts lie on the cone"}}
    return Snapshot(source=str(folder), format="rigidlibrary-datasim", dim=2, ids=np.arange(n_particles), x=x,
                    radius=radius, p=i, q=j, force=force, normal=n, mobilised=con[:, 4] != 0,
                    lattice=np.array([[box, 0.0], [shear * box, box_y]]), law=law, length_unit="simulation units",
                    frame=frame, frames=steps, notes=notes,
                    particle_line=lambda i: f"{init_path}: line {line_of(init_path, i)}",
                    contact_line=lambda c: f"{con_path}: line {line_of(con_path, c)}")


register(Format("rigidlibrary-annulus", sniff=lambda paths: is_annulus(paths[0]),
                read=lambda paths, request, progress: read_annulus(paths[0], request.frame), folder=True))
register(Format("rigidlibrary-datasim", sniff=lambda paths: is_datasim(paths[0]),
                read=lambda paths, request, progress: read_datasim(paths[0], request.frame), folder=True))
