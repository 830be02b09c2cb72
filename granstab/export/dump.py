"""A LAMMPS-style dump pair, the text format DEM users already load in OVITO: NAME.atoms.dump (`dump custom`: one
`ITEM: ATOMS` block a frame, id = particle index + 1, type 1, then every numeric particle field; a vector's
components as NAME[1] NAME[2] NAME[3], LAMMPS's own naming of per-atom vectors) and NAME.local.dump (`dump
local`: one `ITEM: ENTRIES` block a frame, one row a contact, `p` and `q` as atom ids).

The box is LAMMPS's: a periodic cell must be in its restricted triclinic form (a1 along x, a2 in the xy plane; 2D:
z from -0.5 to 0.5, as LAMMPS keeps a 2D box), written as the bounding box with the tilts xy xz yz and origin 0;
a scene without a cell gets the bounding box of its particles' spheres and fixed (ff) boundaries. Strings (names,
verdict text) are left out: their numeric codes are there. Reals at 17 significant digits (exact float64).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from .fields import FrameFields, as3


def box(frame: FrameFields, where: str) -> str:
    """The ITEM: BOX BOUNDS block (module docstring)."""
    if frame.cell is None:
        radius = frame.particles.get("radius", np.zeros(len(frame.positions)))
        pad = np.nan_to_num(radius, nan=0.0)[:, None] if len(frame.positions) else 0.0
        lo = (frame.positions - pad).min(axis=0) if len(frame.positions) else np.zeros(3)
        hi = (frame.positions + pad).max(axis=0) if len(frame.positions) else np.ones(3)
        if frame.dim == 2:
            lo[2], hi[2] = -0.5, 0.5
        rows = "\n".join(f"{a:.17g} {b:.17g}" for a, b in zip(lo, hi))
        return f"ITEM: BOX BOUNDS ff ff {'pp' if frame.dim == 2 else 'ff'}\n{rows}\n"
    a = as3(frame.cell)
    if frame.dim == 2:
        a = np.vstack([a, [0.0, 0.0, 1.0]])
    if a[0, 1] != 0 or a[0, 2] != 0 or a[1, 2] != 0:
        raise SceneError(f"{where}: cell: not LAMMPS's restricted triclinic form (a1 along x, a2 in the xy plane): "
                         "export --format vtp or xyz, which take any cell")
    xy, xz, yz = a[1, 0], a[2, 0], a[2, 1]
    lo = np.array([min(0.0, xy, xz, xy + xz), min(0.0, yz), 0.0 if frame.dim == 3 else -0.5])
    hi = np.array([a[0, 0] + max(0.0, xy, xz, xy + xz), a[1, 1] + max(0.0, yz), a[2, 2] if frame.dim == 3 else 0.5])
    rows = [f"{lo[0]:.17g} {hi[0]:.17g} {xy:.17g}", f"{lo[1]:.17g} {hi[1]:.17g} {xz:.17g}",
            f"{lo[2]:.17g} {hi[2]:.17g} {yz:.17g}"]
    return "ITEM: BOX BOUNDS xy xz yz pp pp pp\n" + "\n".join(rows) + "\n"


#: vector fields whose components LAMMPS names itself (OVITO maps these to its Orientation and Aspherical Shape)
COMPONENT_NAMES = {"orientation": ["quati", "quatj", "quatk", "quatw"], "aspherical_shape": ["shapex", "shapey", "shapez"]}
#: ... and writes in other units: LAMMPS (since 2020) dumps an ellipsoid's shapex..z as diameters, and OVITO halves them
COMPONENT_SCALE = {"aspherical_shape": 2.0}


def numeric_columns(fields: dict) -> tuple[list[str], np.ndarray]:
    """The numeric fields as dump columns: names (vectors as NAME[1..3], or LAMMPS's own component names) and the
    (n, k) table as text."""
    names, parts = [], []
    for name, values in fields.items():
        values = np.asarray(values)
        if values.dtype.kind not in "fiu":
            continue
        flat = values.reshape(len(values), -1) * COMPONENT_SCALE.get(name, 1)
        names += ([name] if values.ndim == 1 else
                  COMPONENT_NAMES.get(name, [f"{name}[{i + 1}]" for i in range(flat.shape[1])]))
        fmt = "{:.17g}" if values.dtype.kind == "f" else "{:d}"
        parts.append(np.vectorize(fmt.format, otypes=[str])(flat) if flat.size else flat.astype(str))
    return names, np.concatenate(parts, axis=1) if parts else np.zeros((0, 0), dtype=str)


def rows(table: np.ndarray) -> str:
    return "".join(" ".join(r) + "\n" for r in table)


def atoms_block(frame: FrameFields, step: int, where: str) -> str:
    n = len(frame.positions)
    ids = np.c_[np.arange(1, n + 1), np.ones(n, dtype=np.int64)]
    fields = {"x": frame.positions[:, 0], "y": frame.positions[:, 1], "z": frame.positions[:, 2], **frame.particles}
    names, table = numeric_columns(fields)
    table = np.concatenate([ids.astype(str), table], axis=1) if n else table
    return (f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ATOMS\n{n}\n{box(frame, where)}"
            f"ITEM: ATOMS id type {' '.join(names)}\n{rows(table)}")


def local_block(frame: FrameFields, step: int, where: str) -> str:
    contacts = dict(frame.contacts)
    contacts["p"], contacts["q"] = contacts["p"] + 1, contacts["q"] + 1        # atom ids
    names, table = numeric_columns(contacts)
    return (f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ENTRIES\n{len(frame.ends)}\n{box(frame, where)}"
            f"ITEM: ENTRIES {' '.join(names)}\n{rows(table)}")


def write(frames: list[FrameFields], out: Path, stem: str) -> list[Path]:
    """NAME.atoms.dump and NAME.local.dump, a block a frame, TIMESTEP = the frame's number (its index where the
    frames' times are not integers)."""
    atoms, local = out / f"{stem}.atoms.dump", out / f"{stem}.local.dump"
    integer = all(float(f.time).is_integer() for f in frames)
    with atoms.open("w", encoding="utf-8") as fa, local.open("w", encoding="utf-8") as fl:
        for i, frame in enumerate(frames):
            step = int(frame.time) if integer else i
            fa.write(atoms_block(frame, step, str(atoms)))
            fl.write(local_block(frame, step, str(local)))
    return [atoms, local]
