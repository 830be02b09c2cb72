"""LAMMPS rounded polygons (atom_style body rounded/polygon, pair_style body/rounded/polygon, 2D): two dumps of one
timestep, the data file and the input script.

    compute  q all property/atom quatw quati quatj quatk tqz
    compute  v all body/local id 1 2 3                      (each vertex: its body's id and world x y z)
    dump     atoms all custom N atoms.dump id type mass x y c_q[1] c_q[2] c_q[3] c_q[4] fx fy c_q[5]
    dump     vertices all local N vertices.dump c_v[1] c_v[2] c_v[3] c_v[4]

LAMMPS dumps no contact of these bodies (the pair style has no single(), so no pair/local; body/local gives
vertices only): the contacts are found here from the geometry, as the pair style finds them (Fraige et al. 2008):
a polygon is its vertices (in the data file's order around the perimeter, so consecutive vertices make its sides)
with disks of the rounding radius r (half the data file's last "diameter" value) swept along the sides. For every
vertex of one body and every side of another, the foot of the vertex on the side: inside the side it is a
**vertex–side** contact (the vertex's disk against the flat side: curvature −1/(r − δ/2) on the vertex's body, 0 on
the side's), at an end a **vertex–vertex** contact (both disks: −1/(r − δ/2) each); in contact when the distance
is below r_p + r_q. A side lying on a side is the two vertex–side contacts at the ends of the overlap (as LAMMPS
models it), so K^p + K^q = −1/ρ ≠ 0: the conforming limit K^p + K^q = 0 of two flat sides never reaches the scene
from this reader (docs/formats.md). The force is the pair style's normal spring, f^pq = −k_n δ n on the vertex's
body (frictionless at rest: the style's tangential force is damping only; cohesion k_na = 0 and delta_ua large, so
that LAMMPS's contact-length scaling is 1, are checked); k = k_n, μ from the pair style, α not given by it. Each
body's mass is the dump's, its inertia I_zz the data file's. bodies.py gives arms from the centre of mass.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ..model.errors import SceneError
from .bodies import body_snapshot
from .build import Snapshot
from .columns import to_indices, unique_ids
from .dumpset import Indexed, index_dumps
from .lammps import body_script, is_dump, lattice_of
from .lammps_script import read_script
from .lines import read_window
from .registry import Format, register

ATOM_COLUMNS = ("id", "x", "y")
UNROUNDED = "no curvature at a sharp vertex or edge"


def read_data_bodies(path: Path) -> dict:
    """{body id: (vertices (N, 2) body offsets, I_zz, rounding radius)} from a LAMMPS data file's Bodies section."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    start = next((k for k, line in enumerate(text) if line.split("#")[0].strip() == "Bodies"), None)
    if start is None:
        raise SceneError(f"{path}: Bodies: no Bodies section (a LAMMPS data file of body particles)")
    tokens, lines = [], []
    for number, line in enumerate(text[start + 1:], start + 2):
        words = line.split("#")[0].split()
        if words and re.match(r"[A-Za-z]", words[0]):
            break
        tokens += words
        lines += [number] * len(words)
    out, k = {}, 0
    try:
        while k < len(tokens):
            line = lines[k]
            ident, nint, ndouble = int(tokens[k]), int(tokens[k + 1]), int(tokens[k + 2])
            ints = [int(t) for t in tokens[k + 3:k + 3 + nint]]
            doubles = np.array([float(t) for t in tokens[k + 3 + nint:k + 3 + nint + ndouble]])
            k += 3 + nint + ndouble
            n = ints[0]
            if ndouble != 6 + 3 * n + 1 or len(doubles) != ndouble:
                raise SceneError(f"{path}: line {line}: body {ident}: expected 6 + 3 N + 1 = {6 + 3 * n + 1} values "
                                 f"of a rounded polygon, got {len(doubles)}")
            diameter = doubles[-1]
            if not diameter > 0:
                raise SceneError(f"{path}: line {line}: body {ident}: diameter: rounding diameter {diameter:g}: "
                                 f"a polygon without rounding has {UNROUNDED}")
            out[ident] = (doubles[6:6 + 3 * n].reshape(n, 3)[:, :2], doubles[2], diameter / 2)
    except SceneError:
        raise
    except (ValueError, IndexError):
        raise SceneError(f"{path}: line {lines[min(k, len(lines) - 1)]}: Bodies: not a body entry "
                         "(atom-ID Ninteger Ndouble, then the values)") from None
    return out


def pair_law(script: dict) -> tuple[dict, list]:
    """The parameters of `pair_style body/rounded/polygon c_n c_t mu delta_ua cut_inner` and `pair_coeff * * k_n
    k_na`; cohesion (k_na ≠ 0) is refused: the forces would not follow from the overlaps alone."""
    source, style = script["source"], script["pair"]
    if not style or style[0] != "body/rounded/polygon" or not script["coeff"]:
        raise SceneError(f"{source}: pair_style: body/rounded/polygon with pair_coeff * * k_n k_na needed")
    try:
        mu, delta_ua, cut_inner = float(style[3]), float(style[4]), float(style[5])
        kn, kna = float(script["coeff"][0]), float(script["coeff"][1])
    except (ValueError, IndexError):
        raise SceneError(f"{source}: line {script['pair_line']}: pair_style: cannot read c_n c_t mu delta_ua "
                         "cut_inner") from None
    if kna != 0:
        raise SceneError(f"{source}: line {script['coeff_line']}: k_na: {kna:g}: cohesion is not converted (the "
                         "contact forces would not follow from the overlaps alone); use k_na = 0")
    notes = [f"{Path(source).name} line {script['coeff_line']}: k = (j_a + mu) k_n per vertex–side contact, k_n "
             "per vertex–vertex report (LAMMPS's applied force over the overlap)",
             "LAMMPS's mu multiplies the normal force (Fraige's Eq. 4 as coded), it is no Coulomb limit; its "
             "tangential force is damping only (c_t): μ and α are not in the file"]
    return {"kn": kn, "mu_lammps": mu, "delta_ua": delta_ua if delta_ua >= 0 else 1.0, "cut_inner": cut_inner,
            "where": f"{Path(source).name} line {script['coeff_line']}"}, notes


EPSILON = 1e-3        # LAMMPS's absolute contact tolerance (pair_body_rounded_polygon.cpp: d < r_i + r_j + EPSILON)


def _candidates(x, verts, count, rounding, lattice, cut_inner):
    """Ordered body pairs (i, j) within reach (both orders), j's vertices moved to i's periodic image."""
    V = verts.shape[1]
    inside = np.arange(V)[None] < count[:, None]
    reach = np.max(np.where(inside, np.linalg.norm(verts - x[:, None], axis=2), 0), 1)
    cut = 2 * (reach.max() + rounding.max()) + cut_inner
    if lattice is None:
        pairs = cKDTree(x).query_pairs(cut, output_type="ndarray")
    else:
        box = np.diag(lattice)
        pairs = cKDTree(np.mod(x, box), boxsize=box).query_pairs(cut, output_type="ndarray")
    lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    i, j = np.concatenate([lo, hi]), np.concatenate([hi, lo])        # LAMMPS's two calls: i's vertices, then j's
    shift = np.zeros((len(i), 2))
    if lattice is not None:
        shift = -np.round((x[j] - x[i]) / np.diag(lattice)) * np.diag(lattice)
    return i, j, shift, len(lo)


def polygon_contacts(x, verts, count, rounding, ids, law: dict, cut_inner: float, lattice):
    """The contacts LAMMPS's pair body/rounded/polygon (29Sep2021) applies forces at, and those forces (module
    docstring), vectorised over candidate pairs: each vertex of i against each side of j, with t the position of
    its foot on the side's line and d its distance to it. 0 ≤ t ≤ 1 and d < r_i + r_j + EPSILON: a vertex–side
    contact (a body pair's first contact, or its first two at different places, get the force (j_a + mu) k_n δ);
    t outside: a vertex–vertex interaction with the side's end, applied once per side that reports it (so a vertex
    in the corner region of another's vertex is pushed twice) from the body of lower id."""
    V = verts.shape[1]
    i, j, shift, half = _candidates(x, verts, count, rounding, lattice, cut_inner)
    v = verts[i]
    a = verts[j] + shift[:, None]
    b = np.take_along_axis(a, ((np.arange(V)[None] + 1) % np.maximum(count[j], 1)[:, None])[:, :, None], axis=1)
    ab = b - a
    t = np.einsum("pvek,pek->pve", v[:, :, None] - a[:, None], ab) / np.einsum("pek,pek->pe", ab, ab)[:, None]
    foot = a[:, None] + t[..., None] * ab[:, None]
    d = np.linalg.norm(v[:, :, None] - foot, axis=3)
    reach = (rounding[i] + rounding[j])[:, None, None]
    valid = (np.arange(V)[None, :, None] < count[i][:, None, None]) & (np.arange(V)[None, None, :] < count[j][:, None, None])
    near = valid & (d <= reach + cut_inner)
    on_side = near & (t >= 0) & (t <= 1) & (d < reach + EPSILON)
    end = np.where(t < 0, 0, 1)
    w = (np.arange(V)[None, None, :] + end) % np.maximum(count[j], 1)[:, None, None]
    cw = np.take_along_axis(a[:, None].repeat(V, 1), w[..., None].repeat(2, 3), axis=2)
    dvw = np.linalg.norm(v[:, :, None] - cw, axis=3)
    corner = near & ((t < 0) | (t > 1)) & (dvw <= reach + cut_inner) & (ids[i] < ids[j])[:, None, None]
    side = _side_contacts(i, j, half, on_side, d, reach, v, foot, law)
    vv = _vertex_contacts(i, j, corner, dvw, reach, v, cw, w, law)
    side["reports"] = np.ones(len(side["p"]), np.int64)
    return {k: np.concatenate([side[k], vv[k]]) for k in side}


def _side_contacts(i, j, half, on_side, d, reach, v, foot, law):
    """Vertex–side contacts: per unordered body pair LAMMPS's list (i's vertices against j's sides, then j's
    against i's), of which the first one (alone) or the first two at different places get a force."""
    row, vk, ek = np.nonzero(on_side)
    pair = np.where(row < half, row, row - half)
    order = np.lexsort((ek, vk, row >= half, pair))
    row, vk, ek, pair = row[order], vk[order], ek[order], pair[order]
    first = np.r_[True, pair[1:] != pair[:-1]]
    rank = np.arange(len(pair)) - np.maximum.accumulate(np.where(first, np.arange(len(pair)), 0))
    size = np.bincount(pair, minlength=half)[pair] if len(pair) else np.zeros(0, int)
    xv, xe = v[row, vk], foot[row, vk, ek]
    # the first two contacts, when at different places (LAMMPS scans further pairs only when they coincide)
    lead = np.flatnonzero(first)
    apply = (size == 1) | (rank < 2)
    if len(lead):
        second = np.minimum(lead + 1, len(pair) - 1)
        direction = xe[lead] - xv[lead]
        along = xv[second] - xv[lead]
        offset = np.abs(direction[:, 0] * along[:, 1] - direction[:, 1] * along[:, 0]) / np.linalg.norm(direction, axis=1)
        ja = np.maximum(offset / (2 * law["delta_ua"]), 1.0)
        ja_of = np.repeat(ja, np.diff(np.r_[lead, len(pair)]))
    else:
        ja_of = np.zeros(0)
    factor = np.where(size == 1, 1.0, ja_of) + law["mu_lammps"]
    delta = reach[row, 0, 0] - d[row, vk, ek]
    keep = apply & (delta > 0)
    # LAMMPS stores one force per side: two applied contacts on one side of one body both push that body back with
    # the last one's force (29Sep2021): the engine breaks action and reaction there (reported, not copied)
    side_key = np.stack([pair, row >= half, ek], 1)[apply]
    shared = np.zeros(len(row), bool)
    if len(side_key):
        _, inverse, counts = np.unique(side_key, axis=0, return_inverse=True, return_counts=True)
        shared[np.flatnonzero(apply)] = counts[inverse.ravel()] > 1
    out = _rows(i[row], j[row], xv, xe, factor * law["kn"] * np.maximum(delta, 0), np.ones(len(row), bool), vk, ek,
                keep)
    out["shared_side"] = shared[keep]
    return out


def _vertex_contacts(i, j, corner, dvw, reach, v, cw, w, law):
    """Vertex–vertex interactions, one contact per vertex pair with the forces of every side that reported it."""
    row, vk, ek = np.nonzero(corner & (dvw < reach))
    key = np.stack([row, vk, w[row, vk, ek]], 1)
    uniq, first, times = np.unique(key, axis=0, return_index=True, return_counts=True)
    row, vk, ek = row[first], vk[first], ek[first]
    delta = reach[row, 0, 0] - dvw[row, vk, ek]
    out = _rows(i[row], j[row], v[row, vk], cw[row, vk, ek], times * law["kn"] * delta, np.zeros(len(row), bool),
                vk, uniq[:, 2], np.ones(len(row), bool))
    out["shared_side"], out["reports"] = np.zeros(len(row), bool), times
    return out


def _rows(p, q, c1, c2, magnitude, flat2, vertex, other, keep):
    return {"p": p[keep], "q": q[keep], "c1": c1[keep], "c2": c2[keep], "magnitude": magnitude[keep],
            "flat2": flat2[keep], "vertex": vertex[keep], "other": other[keep]}


def index_polygons(paths: list[Path], progress=None) -> Indexed:
    """The two dumps indexed once (dumpset.py: the timesteps both have), the data file and the script named."""
    dumps = [p for p in paths if is_dump(p)]
    others = [p for p in paths if p not in dumps]
    scripts = [p for p in others if body_script([p])]
    datas = [p for p in others if p not in scripts]
    if len(scripts) != 1 or len(datas) != 1 or len(dumps) != 2:
        raise SceneError(f"{paths[0]}: need two dumps (atoms, vertices), the data file and the input script, got "
                         f"{len(dumps)} dump(s), {len(datas)} data file(s), {len(scripts)} script(s)")
    script = read_script(scripts[0])
    pair_law(script)                    # refused (cohesion, other style) before any dump is read
    return Indexed(index_dumps(dumps, progress, script, datas[0]), read_step)


def read_polygons(paths: list[Path], timestep=None, progress=None) -> Snapshot:
    """The rounded-polygon snapshot of one timestep (module docstring; default the last one both dumps have)."""
    return index_polygons(paths, progress).read(timestep, None, progress)


def read_step(index, timestep=None, progress=None) -> Snapshot:
    """The rounded-polygon snapshot of one indexed timestep."""
    update = None if progress is None else progress.update
    shapes = read_data_bodies(index.data)
    law, notes = pair_law(index.script)
    step = index.frames[-1] if timestep is None else timestep
    blocks = {b.kind: (p, b) for p, b in index.at(step)}
    if set(blocks) != {"ATOMS", "ENTRIES"}:
        raise SceneError(f"{index.paths[0]}: need one per-atom dump and one local dump (compute body/local)")
    (apath, ablock), (vpath, vblock) = blocks["ATOMS"], blocks["ENTRIES"]
    missing = [c for c in ATOM_COLUMNS if c not in ablock.columns]
    if missing:
        raise SceneError(f"{apath}: line {ablock.first_line - 1}: {missing[0]}: no column in ITEM: ATOMS")
    A = read_window(apath, ablock.start, ablock.end, ablock.first_line, ablock.columns, ablock.count, "atoms", update)
    A = {c: A[:, k] for k, c in enumerate(ablock.columns)}
    W = read_window(vpath, vblock.start, vblock.end, vblock.first_line, vblock.columns, vblock.count, "entries",
                    update)
    aline = lambda row: f"{apath}: line {ablock.first_line + int(row)}"  # noqa: E731
    ids = A["id"].astype(np.int64)
    unique_ids(ids, aline, f"in timestep {step}")
    x = np.stack([A["x"], A["y"]], 1)
    owner = to_indices(ids, W[:, 0], "id", lambda r: f"{vpath}: line {vblock.first_line + int(r)}",
                       "not in the atom dump")
    verts, count, rounding, izz = _vertices(ids, owner, W[:, 1:3], shapes, index.data, aline)
    lattice = lattice_of(ablock, 2)
    if lattice is not None and (np.isnan(lattice).any() or np.any(ablock.tilt)):
        raise SceneError(f"{apath}: BOX BOUNDS: rounded polygons are read in orthogonal boxes periodic along both "
                         "axes or in none")
    found = polygon_contacts(x, verts, count, rounding, ids, law, law["cut_inner"], lattice)
    p, q, c1, c2 = found["p"], found["q"], found["c1"], found["c2"]
    d = np.linalg.norm(c2 - c1, axis=1)
    delta = rounding[p] + rounding[q] - d
    force = -(found["magnitude"] / d)[:, None] * (c2 - c1)                # on the vertex's body, along −n
    snap = Snapshot(source=f"{apath} + {vpath}", format="lammps_polygons", dim=2, ids=ids, x=x,
                    radius=_bound(x, verts, count, rounding), p=p, q=q, force=force, mass=A.get("mass"),
                    lattice=lattice, frame=int(step), frames=index.frames, notes={"law_notes": notes}, particle_line=aline,
                    law={"k": (found["magnitude"] / delta, law["where"] + " (applied force / overlap)")},
                    orientation=np.stack([A[k] for k in ("c_q[1]", "c_q[2]", "c_q[3]", "c_q[4]")], 1)
                    if "c_q[4]" in A else None)
    snap.bodies = {"inertia": izz.reshape(-1, 1, 1)}
    body, vertex = np.nonzero(np.arange(verts.shape[1]) < count[:, None])       # in order around each polygon
    snap.parts = {"kind": "rounded_polygon", "body": body, "offset": verts[body, vertex] - x[body],
                  "radius": rounding[body]}
    parts = {"c1": c1, "c2": c2, "R1": rounding[p], "R2": rounding[q], "flat1": np.zeros(len(p), bool),
             "flat2": found["flat2"], "name1": np.array([f"{ids[b]}:vertex{k}" for b, k in zip(p, found["vertex"])]),
             "name2": np.array([f"{ids[b]}:{'side' if f else 'vertex'}{k}" for b, k, f in
                                zip(q, found["other"], found["flat2"])])}
    snap = body_snapshot(snap, parts, None, None, "polygon")
    snap.notes["lammps_contact_model"] = {
        "vertex_side": int(found["flat2"].sum()), "vertex_vertex": int((~found["flat2"]).sum()),
        "vertex_vertex_pushed_twice": int(np.sum(found["reports"] > 1)),
        "sides_pushed_back_with_another_contacts_force": int(found["shared_side"].sum()),
        "why": "LAMMPS 29Sep2021 applies a vertex–vertex force once per side reporting it, and pushes a side touched "
               "by two vertices back with the last one's force twice (action ≠ reaction there); the scene keeps "
               "each contact's force on the vertex's body and its reaction"}
    return snap


def _vertices(ids, owner, xy, shapes, data_path, aline):
    """(N, V, 2) world vertices padded, their counts, rounding radii and I_zz per body, checked against the data
    file's bodies (the vertex count of each)."""
    N = len(ids)
    count = np.bincount(owner, minlength=N)
    order = np.argsort(owner, kind="stable")
    V = max(int(count.max()), 1)
    verts = np.zeros((N, V, 2))
    slot = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    verts[owner[order], slot] = xy[order]
    rounding, izz = np.zeros(N), np.zeros(N)
    for b, ident in enumerate(ids):
        if int(ident) not in shapes:
            raise SceneError(f"{aline(b)}: id: body {ident} not in {data_path}'s Bodies section")
        offsets, izz[b], rounding[b] = shapes[int(ident)]
        if len(offsets) != count[b]:
            raise SceneError(f"{aline(b)}: body {ident}: {count[b]} vertices in the local dump, {len(offsets)} in "
                             f"{data_path}")
    if np.any(count < 3):
        b = int(np.flatnonzero(count < 3)[0])
        raise SceneError(f"{aline(b)}: body {ids[b]}: {count[b]} vertices: disks and rods are not read (polygons "
                         "of 3 vertices or more)")
    return verts, count, rounding, izz


def _bound(x, verts, count, rounding):
    inside = np.arange(verts.shape[1])[None] < count[:, None]
    return np.max(np.where(inside, np.linalg.norm(verts - x[:, None], axis=2), 0), 1) + rounding


register(Format("lammps_polygons", sniff=lambda paths: any(is_dump(p) for p in paths) and body_script(paths),
                read=lambda paths, request, progress: read_polygons(paths, request.frame, progress),
                index=lambda paths, request, progress: index_polygons(paths, progress)))
