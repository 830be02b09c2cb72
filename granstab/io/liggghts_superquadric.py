"""LIGGGHTS 3.8 superquadric dumps (atom_style superquadric): a per-atom dump, a pair/gran/local dump, the script.

    dump atoms all custom N atoms.dump id type x y z quat1 quat2 quat3 quat4 shapex shapey shapez \
         blockiness1 blockiness2 radius mass
    compute pg all pair/gran/local id force force_normal force_tangential contactPoint
    dump contacts all local N contacts.dump c_pg[1] c_pg[2] ... c_pg[15]      (LIGGGHTS 3.8 refuses c_pg[*])

Conventions (docs/formats.md, each checked on examples/liggghts_superquadric's packing, tests/io/test_superquadric.py):
- quat1..quat4 are (w, x, y, z): LAMMPS's quat_to_mat, body → world (a grain turned 90° about z by
  `set ... quat 0 0 1 90` dumps quat1 = cos 45°, quat4 = sin 45°);
- shapex..z are the semi-axes a, b, c and blockiness1, blockiness2 the n1, n2 of the surface
  (|x/a|^n2 + |y/b|^n2)^(n1/n2) + |z/c|^n1 = 1 (model/surface.py); `radius` is the bounding sphere, not a size
  of the surface (it is not used, except as the broad size in the report);
- contactPoint lies inside both grains, on neither surface (LIGGGHTS's point between the two surfaces); it is
  the scene's contact point, so each arm runs from the grain's centre to it;
- force is f^pq, the force on id1 by id2; force_normal/force_tangential split it along the centre line from id1
  to id2, not along the surface normal (so they are not read);
- the contact normal is the kernel's: n = (ν_p − ν_q)/|ν_p − ν_q| with ν the outward normals at the foot points
  (the surface points nearest the contact point); the angle between ν_p and −ν_q is reported;
- the curvature of each grain is that of its parallel surface through the contact point (surface.contact_curvature);
- gravity (`fix ... gravity g vector x y z` in the script, with the dump's masses) is an external load of every
  grain; grains within WALL_GAP of a `fix wall/gran ... primitive ... zplane|xplane|yplane` wall are flagged
  (their wall force is not dumped) and left out of the balance residuals.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..model import surface
from ..model.errors import SceneError
from ..model.vec import quaternion_matrix
from .build import Snapshot, branch_vectors
from .columns import particle_orientation, to_indices, unique_ids
from .dumpset import Indexed
from .lammps import Block, has_shape_columns, index_lammps, lattice_of
from .lammps_script import compute_columns, contact_law, liggghts_property
from .lines import read_window
from .registry import Format, register

SHAPE_COLUMNS = ("shapex", "shapey", "shapez", "blockiness1", "blockiness2")
QUAT = {"quat1": "quatw", "quat2": "quati", "quat3": "quatj", "quat4": "quatk"}
NORMAL_AGREE_DEG = 1.0   # ν_p and −ν_q further apart than this (degrees) are counted in the report
OUTSIDE_TOL = 1e-4       # contact points outside a grain by less than this fraction of its size are rounding (a
                         # default dump prints 6 digits); further out is an error
WALL_GAP = 0.02          # a grain whose mesh reaches within WALL_GAP·(bounding radius) of a wall plane touches it
                         # (the mesh's chord error at resolution 24 is below 1e-2 of the radius)


def read_superquadric(paths: list[Path], timestep=None, progress=None) -> Snapshot:
    """The snapshot of one timestep, with each contact's arm, normal and curvatures from the shape kernel."""
    return read_step(index_lammps(paths, progress), timestep, progress)


def read_step(index, timestep=None, progress=None) -> Snapshot:
    """One timestep of the dumps indexed once (lammps.index_lammps: the timesteps both have; default the last)."""
    update = None if progress is None else progress.update
    script, apath, cpath = index.script, index.atoms, index.local
    step = index.frames[-1] if timestep is None else timestep
    ablock = _block(apath, index.atom_blocks, step)
    cblock = _block(cpath, index.local_blocks, step)
    if progress is not None:
        progress.stage("parse", total=ablock.end - ablock.start + cblock.end - cblock.start)
    ids, x, rot, axes, blockiness, radius, mass, quat = _atoms(apath, ablock, update)
    names = _contact_names(cpath, cblock, script)
    data = read_window(cpath, cblock.start, cblock.end, cblock.first_line, names, cblock.count, "entries", update)
    col = {name: data[:, k] for k, name in enumerate(names) if name != "-"}
    line = lambda row: f"{cpath}: line {cblock.first_line + row}"  # noqa: E731
    for need in ("id1", "id2", "fx", "cx"):
        if need not in col:
            raise SceneError(f"{cpath}: timestep {step}: {need}: no column (compute pair/gran/local needs the "
                             "keywords id force contactPoint)")
    what = f"not in the atom dump at timestep {step}"
    p, q = (to_indices(ids, col[name], name, line, what) for name in ("id1", "id2"))
    force = np.stack([col["fx"], col["fy"], col["fz"]], axis=1)
    point = np.stack([col["cx"], col["cy"], col["cz"]], axis=1)
    if progress is not None:
        progress.stage("curvature")
    lattice = lattice_of(ablock, 3)
    geometry = contact_geometry(point, x, rot, axes, blockiness, p, q, line, lattice)
    law, notes = hertz_law(script, force, geometry) if _model(script) == "hertz" else \
        contact_law(script, radius[p], radius[q], np.zeros(len(p)))
    shape = np.concatenate([axes, blockiness], axis=1)
    groups = shape_groups(shape)
    gravity, wall_flags, wall_note = _external(script, x, rot, groups, radius, mass)
    geometry.update(_inertia(rot, groups), shape=shape)
    return Snapshot(
        source=f"{apath} + {cpath}", format="liggghts-superquadric", dim=3, ids=ids, x=x, radius=radius, mass=mass,
        orientation=quat, p=p, q=q, force=force, normal=geometry.pop("normal"), law=law, frame=int(step),
        lattice=lattice,
        frames=index.frames, wall_flags=wall_flags, wall_load=gravity, shaped=geometry,
        notes={"law_notes": notes, "dimension": 3, "forces_from": "force (f on id1 by id2)",
               "walls": wall_note, "shapes": _shape_note(axes, blockiness)},
        particle_line=lambda i: f"{apath}: line {ablock.first_line + i}",
        contact_line=line)


def contact_geometry(point, x, rot, axes, blockiness, p, q, line, lattice=None) -> dict:
    """Arms, normals and curvatures of the contacts (M,) at `point` from the grains' shapes (surface.py), with
    the report's entry: the depths of the point in each grain and the angle between ν_p and −ν_q. In a periodic
    box (`lattice` rows) each arm is the minimum image from the grain's centre to the point."""
    both = np.concatenate([p, q])
    M = len(p)
    ends = np.concatenate([x, point])
    arms = branch_vectors(ends, both, len(x) + np.concatenate([np.arange(M), np.arange(M)]), lattice)[0]
    pts = x[both] + arms
    try:
        V, nu, depth = surface.parallel_curvature(pts, x[both], rot[both], axes[both], blockiness[both])
    except RuntimeError as exc:
        raise SceneError(f"{line(0)}: contactPoint: {exc}") from None
    normal = nu[:M] - nu[M:]
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    size = axes[both].max(axis=1)
    outside = np.flatnonzero(depth < -OUTSIDE_TOL * size)
    if outside.size:
        c = outside[0] % M
        raise SceneError(f"{line(c)}: contactPoint: outside grain {'id1' if outside[0] < M else 'id2'} by "
                         f"{-depth[outside[0]]:.6g} (LIGGGHTS's contact point lies inside both grains: wrong "
                         "quaternion order, shape or frame?)")
    K = surface.tangent_curvature(V, np.concatenate([normal, normal]))
    angle = np.degrees(np.arccos(np.clip(-np.sum(nu[:M] * nu[M:], axis=1), -1.0, 1.0)))
    report = {"rule": "contactPoint as dumped; normal (ν_p − ν_q)/|ν_p − ν_q| at the foot points; curvature of "
                      "each grain's parallel surface through the point (model/surface.py)",
              "normals_disagree_deg": {"max": float(angle.max(initial=0.0)), "median": float(np.median(angle))
                                       if M else 0.0, "threshold": NORMAL_AGREE_DEG,
                                       "count": int(np.sum(angle > NORMAL_AGREE_DEG))},
              "depth_over_size": {"max": float((depth / size).max(initial=0.0)),
                                  "median": float(np.median(depth / size)) if M else 0.0,
                                  "outside_within_rounding": int(np.sum(depth < 0)), "tolerance": OUTSIDE_TOL}}
    return {"normal": normal, "arm_p": arms[:M], "arm_q": arms[M:], "curvature_p": K[:M],
            "curvature_q": K[M:], "depth_p": depth[:M], "depth_q": depth[M:], "report": report}


def _model(script) -> str | None:
    words = (script or {}).get("pair") or []
    return words[words.index("model") + 1] if "model" in words[:-1] else None


def hertz_law(script: dict, force, geometry) -> tuple[dict, list]:
    """LIGGGHTS `pair_style gran model hertz tangential history`: F_n = (4/3) E* √R* δ^(3/2), so the tangent
    stiffness k = dF_n/dδ = 1.5 F_n/δ per contact, δ the overlap (the contact point's depths in both grains; no
    effective radius needed); k_t/k = 8G*/(2E*) = 2(1 − ν)/(2 − ν) (one material); μ = coefficientFriction."""
    words = script["pair"]
    name = Path(script["source"]).name
    line = f"{name} line {script['pair_line']} (gran model hertz)"
    if words[words.index("tangential") + 1:words.index("tangential") + 2] != ["history"] if "tangential" in words \
            else True:
        return {}, [f"{line}: only tangential history is converted: give --k --alpha --mu"]
    nu, mu = liggghts_property(script, "poissonsRatio"), liggghts_property(script, "coefficientFriction")
    for value in (nu, mu):
        if isinstance(value, str):
            return {}, [f"{line}: {value}: give --k --alpha --mu"]
    fn = -np.sum(force * geometry["normal"], axis=1)
    delta = geometry["depth_p"] + geometry["depth_q"]
    k = np.where((fn > 0) & (delta > 0), 1.5 * fn / np.where(delta > 0, delta, 1.0), np.nan)
    unloaded = ~np.isfinite(k)
    k[unloaded] = np.nanmedian(k) if np.any(~unloaded) else 1.0
    notes = [f"{int(unloaded.sum())} contact(s) without compression or overlap: k = the median of the others"] \
        if unloaded.any() else []
    return {"k": (k, f"{line}: Hertz tangent stiffness 1.5 F_n/δ, δ = the contact point's depths in both grains"),
            "alpha": (2 * (1 - nu[0]) / (2 - nu[0]), f"{nu[1]}: 2(1 − ν)/(2 − ν)"), "mu": mu}, notes


def _block(path: Path, blocks: dict, step) -> Block:
    """The block of timestep `step` (blocks: timestep → Block); one line naming the file's timesteps if absent."""
    if step not in blocks:
        steps = sorted(blocks)
        shown = ", ".join(map(str, steps[:5])) + (", …" if len(steps) > 5 else "")
        raise SceneError(f"{path}: timestep {step}: timestep: not in the file (it has {shown})")
    return blocks[step]


def _atoms(path: Path, block: Block, progress=None):
    names = block.columns
    for need in ("id", "x", "y", "z", *QUAT, *SHAPE_COLUMNS, "radius"):
        if need not in names:
            raise SceneError(f"{path}: timestep {block.timestep}: {need}: no column in ITEM: ATOMS (docs/formats.md, "
                             "LIGGGHTS superquadrics)")
    data = read_window(path, block.start, block.end, block.first_line, names, block.count, "atoms", progress)
    col = {name: data[:, k] for k, name in enumerate(names)}
    row = lambda r: f"{path}: line {block.first_line + r}"  # noqa: E731
    ids = col["id"].astype(np.int64)
    if np.any(ids != col["id"]):
        r = int(np.flatnonzero(ids != col["id"])[0])
        raise SceneError(f"{row(r)}: id: not an integer ({col['id'][r]})")
    unique_ids(ids, row, f"in timestep {block.timestep}")
    axes = np.stack([col[n] for n in SHAPE_COLUMNS[:3]], axis=1)
    blockiness = np.stack([col["blockiness1"], col["blockiness2"]], axis=1)
    for name, values, low in (("shapex", axes, 0.0), ("blockiness1", blockiness, 2.0)):
        bad = np.flatnonzero(~np.all((values > low) if low == 0 else (values >= low), axis=1))
        if bad.size:
            r = int(bad[0])
            raise SceneError(f"{row(r)}: {name}: must be {'> 0' if low == 0 else '>= 2'}, got "
                             f"{' '.join(f'{v:g}' for v in values[r])}")
    quat = particle_orientation({QUAT[k]: col[k] for k in QUAT}, 3, row, f"{path}: timestep {block.timestep}")
    x = np.stack([col["x"], col["y"], col["z"]], axis=1)
    return ids, x, quaternion_matrix(quat), axes, blockiness, col["radius"], col.get("mass"), quat


def _contact_names(path: Path, block: Block, script) -> list:
    """pair/gran/local's columns: from the script's compute line, else LIGGGHTS's order for
    `id force force_normal force_tangential contactPoint` (the command docs/formats.md gives)."""
    known = compute_columns(script["computes"], (script["pair"] or [None])[0]) if script else {}
    if not known:
        default = ["id1", "id2", "-", "fx", "fy", "fz"] + ["-"] * 6 + ["cx", "cy", "cz"]
        if len(block.columns) != len(default):
            raise SceneError(f"{path}: line {block.first_line - 1}: ENTRIES: {len(block.columns)} columns; without "
                             f"the input script the reader expects the {len(default)} of `compute pair/gran/local "
                             "id force force_normal force_tangential contactPoint` (give the script as well)")
        return default
    names = [known.get(c, known.get(re.sub(r"\[\d+\]$", "[*]", c))) for c in block.columns]
    if None in names:
        raise SceneError(f"{path}: line {block.first_line - 1}: {block.columns[names.index(None)]}: not a column "
                         "of the script's compute pair/gran/local")
    return names


def _external(script, x, rot, groups, radius, mass):
    """Gravity loads m g (N, 3) from the script's fix gravity (None without), and wall flags from its primitive
    wall/gran planes (the reach of each grain from its shared mesh, within WALL_GAP·radius)."""
    text = Path(script["source"]).read_text(encoding="utf-8", errors="replace") if script else ""
    gravity = None
    found = re.search(r"^\s*fix\s+\S+\s+\S+\s+gravity\s+(\S+)\s+vector\s+(\S+)\s+(\S+)\s+(\S+)", text, re.M)
    if found and mass is not None:
        g = float(found.group(1)) * np.array([float(v) for v in found.group(2, 3, 4)])
        gravity = mass[:, None] * g
    planes = re.findall(r"^\s*fix\s+\S+\s+\S+\s+wall/gran\b.*primitive\s+type\s+\d+\s+([xyz])plane\s+(\S+)", text,
                        re.M)
    flags = np.zeros(len(x), np.int64)
    for axis_name, offset in planes:
        axis = "xyz".index(axis_name)
        reach = np.empty(len(x))
        for k, key in enumerate(groups[0]):
            same = groups[1] == k
            verts, _ = surface.mesh(surface.Superquadric(*key), resolution=24)
            along = np.einsum("nj,vj->nv", rot[same][:, axis, :], verts)      # world coordinate `axis` of each vertex
            wall, centre = float(offset), x[same, axis]
            reach[same] = np.where(centre > wall, centre + along.min(axis=1) - wall, wall - centre - along.max(axis=1))
        flags[reach <= WALL_GAP * radius] = 1
    note = (f"{len(planes)} primitive wall plane(s) in the script: {int(flags.sum())} grains flagged at a wall "
            "(their wall force is not dumped)" if planes else "none in the script")
    return gravity, (flags if planes else None), note


def shape_groups(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of `keys` (N, k) and each row's index among them: a packing has few distinct shapes, so
    rows are told apart by one random projection (a fast 1D unique) and checked equal (np.unique's row mode,
    several times slower, where two shapes would share a projection)."""
    weights = np.random.default_rng(0).uniform(1.0, 2.0, keys.shape[1])
    _, first, inverse = np.unique(keys @ weights, return_index=True, return_inverse=True)
    unique = keys[first]
    if not np.array_equal(unique[inverse], keys):
        unique, inverse = np.unique(keys, axis=0, return_inverse=True)
    return unique, inverse.ravel()


def _inertia(rot, groups) -> dict:
    """Volumes (N,) and inertia tensors per unit mass (N, 3, 3), world axes, of uniform solid superquadrics."""
    unique, inverse = groups
    props = [surface.mass_properties(surface.Superquadric(*key)) for key in unique]
    volume = np.array([v for v, _ in props])[inverse]
    body = np.array([J for _, J in props])[inverse]
    return {"volume": volume, "inertia": rot @ body @ np.swapaxes(rot, 1, 2),
            "inertia_note": "solid superquadrics (closed form, model/surface.py mass_properties)"}


def _shape_note(axes, blockiness) -> dict:
    aspect = axes.max(axis=1) / axes.min(axis=1)
    return {"grains": len(axes), "aspect_ratio": {"min": float(aspect.min()), "max": float(aspect.max())},
            "blockiness": {"min": float(blockiness.min()), "max": float(blockiness.max())}}


register(Format("liggghts-superquadric", sniff=lambda paths: any(has_shape_columns(p) for p in paths),
                read=lambda paths, request, progress: read_superquadric(paths, request.frame, progress),
                index=lambda paths, request, progress: Indexed(index_lammps(paths, progress), read_step)))
