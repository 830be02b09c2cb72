"""LIGGGHTS multisphere clumps (fix multisphere): four dumps of one timestep and the input script.

    dump atoms all custom N atoms.dump id mol x y z radius           (mol: the member's clump, id_multisphere)
    compute cpg all pair/gran/local id force contactPoint             (member contacts: force on id1)
    compute cwg all wall/gran/local id force force_normal delta        (mesh-wall contacts: force on the atom)
    compute bX all multisphere property P     for P in id_multisphere xcm masstotal inertia ex_space ey_space
                                              ez_space quat (one compute a property: one row a body)
    dump contacts all local N contacts.dump c_cpg[1] ... ;  dump walls ... c_cwg[...] ;  dump bodies ... c_bX ...

The script says what each column is (its compute lines), the contact law (lammps.py: hooke/stiffness with kn, kt,
coefficientFriction) and gravity (`fix ID all gravity g vector gx gy gz`: m g on each body). A wall contact's
point: LIGGGHTS 3.8 writes contactPoint = 0 for mesh walls, so it is the member centre moved by R − δ/2 against the
normal force (a sphere on a plane). quat is (w, x, y, z) (LAMMPS order), checked against ex/ey/ez_space (the
rotation's columns) and reported. The clump geometry is clumps.py's and bodies.py's. A periodic box (`boundary p p
f`, `p p p`; the dumps' BOX BOUNDS): LIGGGHTS wraps each member atom and each xcm into the box separately, and a
member's contactPoint lies beside the first atom; clumps.clump_snapshot takes the minimum images.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from .bodies import inertia_tensor, rotation
from .clumps import clump_snapshot
from .columns import to_indices, unique_ids
from .dumpset import DumpSet, Indexed, index_dumps
from .lammps import _script_says, is_dump, lattice_of, multisphere_script
from .lammps_script import compute_columns, contact_law, read_script
from .lines import read_window
from .registry import Format, register

PROPERTY = {"id_multisphere": ["body"], "xcm": ["x", "y", "z"], "masstotal": ["mass"],
            "inertia": ["inertia1", "inertia2", "inertia3"], "ex_space": ["exx", "exy", "exz"],
            "ey_space": ["eyx", "eyy", "eyz"], "ez_space": ["ezx", "ezy", "ezz"],
            "quat": ["quatw", "quati", "quatj", "quatk"]}
ATOM_COLUMNS = ("id", "mol", "x", "y", "z", "radius")
NEEDED = {"bodies": ["body", "x", "mass", "inertia1", "exx", "eyx", "ezx"], "contacts": ["id1", "id2", "fx", "cx"],
          "walls": ["id1", "fx", "fnx", "delta"]}


def _names(script: dict) -> dict:
    """c_ID[k] / c_ID → column name, for the granular and multisphere computes of the script."""
    names = compute_columns(script["computes"], (script["pair"] or [None])[0])
    for cid, (style, args) in script["computes"].items():
        if style == "multisphere" and args[:1] == ["property"] and args[1:2] and args[1] in PROPERTY:
            cols = PROPERTY[args[1]]
            names.update({f"c_{cid}[{k}]": c for k, c in enumerate(cols, 1)})
            if len(cols) == 1:
                names[f"c_{cid}"] = cols[0]
    return names


def _local(path: Path, block, names: dict, update):
    cols = [names.get(c, "-") for c in block.columns]
    kind = "bodies" if "body" in cols else "contacts" if "id2" in cols else "walls" if "id1" in cols else None
    if kind is None:
        raise SceneError(f"{path}: line {block.first_line - 1}: ENTRIES: neither contacts (pair/gran/local), walls "
                         "(wall/gran/local) nor bodies (compute multisphere) by the script's computes")
    missing = [n for n in NEEDED[kind] if n not in cols]
    if missing:
        raise SceneError(f"{path}: line {block.first_line - 1}: {missing[0]}: no column in this {kind} dump "
                         "(docs/formats.md, LIGGGHTS multisphere)")
    data = read_window(path, block.start, block.end, block.first_line, cols, block.count, "entries", update)
    col = {n: data[:, k] for k, n in enumerate(cols) if n != "-"}
    return kind, col, lambda row: f"{path}: line {block.first_line + int(row)}"


def _vec(col: dict, prefix: str, axes=("x", "y", "z")) -> np.ndarray:
    return np.stack([col[prefix + a] for a in axes], 1)


def index_multisphere(paths: list[Path], progress=None) -> Indexed:
    """The dumps indexed once (dumpset.py: the timesteps all four have) and the script read."""
    dumps = [p for p in paths if is_dump(p)]
    scripts = [p for p in paths if p not in dumps]
    if len(scripts) != 1:
        raise SceneError(f"{paths[0]}: need the input script (with fix multisphere) once, got {len(scripts)} "
                         "non-dump files")
    return Indexed(index_dumps(dumps, progress, read_script(scripts[0])), read_step)


def read_multisphere(paths: list[Path], timestep=None, progress=None):
    """The clump snapshot of one timestep (module docstring; default the last one all dumps have)."""
    return index_multisphere(paths, progress).read(timestep, None, progress)


def read_step(index: DumpSet, timestep=None, progress=None):
    """The clump snapshot of one indexed timestep."""
    update = None if progress is None else progress.update
    script, source = index.script, Path(index.script["source"])
    names = _names(script)
    step = index.frames[-1] if timestep is None else timestep
    tables, atoms = {}, None
    for path, block in index.at(step):
        if block.kind == "ATOMS":
            if atoms is not None:
                raise SceneError(f"{path}: ITEM: ATOMS: a second per-atom dump ({atoms[0].name} is the first)")
            missing = [c for c in ATOM_COLUMNS if c not in block.columns]
            if missing:
                raise SceneError(f"{path}: line {block.first_line - 1}: {missing[0]}: no column in ITEM: ATOMS "
                                 f"(needs {' '.join(ATOM_COLUMNS)}; mol: each member's clump)")
            atoms = (path, block)
            continue
        kind, col, line = _local(path, block, names, update)
        if kind in tables:
            raise SceneError(f"{path}: ENTRIES: a second {kind} dump ({tables[kind][2](0).split(':')[0]} is the first)")
        tables[kind] = (path, col, line)
    if "walls" not in tables and not _script_says([source], r"^\s*fix\s+\S+\s+\S+\s+wall/gran"):
        empty = {n: np.zeros(0) for n in NEEDED["walls"] + ["fny", "fnz", "fy", "fz"]}
        tables["walls"] = (source, empty, lambda row: f"{source}: (no walls)")   # a box without walls
    for kind in ("bodies", "contacts", "walls"):
        if kind not in tables or atoms is None:
            raise SceneError(f"{index.paths[0]}: need the dumps of atoms (with mol), contacts, walls (wall/gran/local, "
                             f"when the script has walls) and bodies: no {'atoms' if atoms is None else kind} dump")
    apath, ablock = atoms
    snap = _snapshot(script, apath, ablock, tables, step, update)
    snap.frames = index.frames
    return snap


def _snapshot(script, apath, ablock, tables, step, update):
    cols = list(ablock.columns)
    data = read_window(apath, ablock.start, ablock.end, ablock.first_line, cols, ablock.count, "atoms", update)
    A = {c: data[:, cols.index(c)] for c in ATOM_COLUMNS}
    aline = lambda row: f"{apath}: line {ablock.first_line + int(row)}"  # noqa: E731
    ids, x, radius, mol = A["id"].astype(np.int64), _vec(A, ""), A["radius"], A["mol"]
    unique_ids(ids, aline, f"in timestep {step}")
    if np.any(mol < 0):
        raise SceneError(f"{aline(np.flatnonzero(mol < 0)[0])}: mol: {mol[mol < 0][0]:g}: the atom belongs to no "
                         "clump (spheres beside clumps are not read)")
    (bpath, B, bline), (_, C, cline), (wpath, W, wline) = (tables[k] for k in ("bodies", "contacts", "walls"))
    axes = np.stack([_vec(B, "ex"), _vec(B, "ey"), _vec(B, "ez")], 2)          # columns e_1 e_2 e_3
    quat = np.stack([B[k] for k in PROPERTY["quat"]], 1) if "quatw" in B else None
    quat_check = None
    if quat is not None:
        quat_check = float(np.abs(rotation(quat) - axes).max()) if len(quat) else 0.0
        if quat_check > 1e-6:
            raise SceneError(f"{bpath}: quat: the quaternion (w, x, y, z) does not rotate the body axes onto "
                             f"ex/ey/ez_space (largest difference {quat_check:.3g})")
    bodies = {"id": B["body"].astype(np.int64), "x": _vec(B, ""), "mass": B["mass"],
              "inertia": inertia_tensor(np.stack([B[f"inertia{k}"] for k in (1, 2, 3)], 1), axes),
              "quat": None if quat is None else quat / np.linalg.norm(quat, axis=1, keepdims=True)}
    members = {"id": ids, "body": mol, "x": x, "radius": radius}
    # a wall contact: sphere on a plane, point R − δ/2 from the centre against the normal force
    wrow = to_indices(ids, W["id1"], "id1", wline, "not in the atom dump")
    fn = _vec(W, "fn")
    fn_norm = np.linalg.norm(fn, axis=1)
    if np.any(fn_norm == 0):
        raise SceneError(f"{wline(np.flatnonzero(fn_norm == 0)[0])}: fnx: zero normal force (no wall normal)")
    wpoint = x[wrow] - ((radius[wrow] - W["delta"] / 2) / fn_norm)[:, None] * fn
    contacts = {"id1": np.concatenate([C["id1"], W["id1"]]), "id2": np.concatenate([C["id2"], -np.ones(len(wrow))]),
                "force": np.concatenate([_vec(C, "f"), _vec(W, "f")]),
                "point": np.concatenate([_vec(C, "c"), wpoint])}
    nc = len(C["id1"])
    lines = {"body": bline, "member": aline,
             "contact": lambda row: cline(row) if row < nc else wline(row - nc)}
    nrows = nc + len(wrow)
    law, law_notes = contact_law(script, *(np.zeros(nrows),) * 3)     # hooke/stiffness: no radii needed
    gravity = _gravity(script)
    notes = {"law_notes": law_notes, "quaternion": "w x y z (LAMMPS order); largest difference of its rotation "
             f"from ex/ey/ez_space {quat_check:.3g}" if quat_check is not None else "not dumped"}
    law = {k: (np.broadcast_to(np.asarray(v, float), (nrows,)), w) for k, (v, w) in law.items()}
    snap = clump_snapshot(f"{apath} + {tables['contacts'][0]} + {wpath} + {bpath}", "liggghts_multisphere", bodies,
                          members, contacts, gravity, law, lines, notes, lattice_of(ablock, 3))
    snap.frame = int(step)
    return snap


def _gravity(script: dict):
    """m g's g from `fix ID group gravity magnitude vector gx gy gz`, or None."""
    if "gravity" not in script:
        return None
    words, number = script["gravity"]
    try:
        magnitude = float(words[0])
        if words[1] != "vector" or len(words) < 5:
            raise ValueError
        direction = np.array([float(w) for w in words[2:5]])
    except (ValueError, IndexError):
        raise SceneError(f"{script['source']}: line {number}: gravity: expected `gravity g vector gx gy gz`") from None
    return magnitude * direction / np.linalg.norm(direction)


register(Format("liggghts_multisphere", sniff=lambda paths: any(is_dump(p) for p in paths) and multisphere_script(paths),
                read=lambda paths, request, progress: read_multisphere(paths, request.frame, progress),
                index=lambda paths, request, progress: index_multisphere(paths, progress)))
