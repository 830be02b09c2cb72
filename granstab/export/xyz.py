"""Extended XYZ, as OVITO and ASE read it: NAME.xyz holds one block a frame — the particle count, the header line
(`Lattice=` for a periodic scene, `Properties=` naming every column with its type and width, `pbc=`, the frame's
scalars, `Time=`) and one row a particle; NAME.contacts.xyz the same with one row a contact, at its contact point.

Numbers are written with 17 significant digits, so a reader gets back the exact float64 (ASE's own writer rounds
every real to 8 decimals, `%16.8f`). A 2D cell gets the third lattice vector (0, 0, h), h = twice the largest
radius (or 1), since the format's Lattice is 3×3; pbc says the third direction is not periodic.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from .fields import FrameFields, as3

TYPES = {"f": "R", "i": "I", "u": "I", "U": "S", "S": "S"}


def lattice(frame: FrameFields) -> np.ndarray:
    """The 3×3 lattice of a periodic frame (module docstring for 2D)."""
    cell = as3(frame.cell)
    if frame.dim == 2:
        radius = frame.particles.get("radius", np.zeros(0))
        finite = radius[np.isfinite(radius)]
        cell = np.vstack([cell, [0.0, 0.0, 2.0 * finite.max() if len(finite) else 1.0]])
    return cell


def header(frame: FrameFields, columns: dict, where: str) -> str:
    """The comment line: Lattice, Properties, pbc, the scalars of the frame and its time."""
    props = []
    for name, values in columns.items():
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise SceneError(f"{where}: {name}: not a property name extended XYZ can hold")
        width = 1 if values.ndim == 1 else values.shape[1]
        props.append(f"{name}:{TYPES[values.dtype.kind]}:{width}")
    words = []
    if frame.cell is not None:
        words.append('Lattice="' + " ".join(f"{v:.17g}" for v in lattice(frame).ravel()) + '"')
    words.append("Properties=" + ":".join(props))
    for key, value in frame.info.items():
        words.append(f"{key}={value:.17g}" if isinstance(value, float) else f'{key}="{value}"')
    words.append(f"Time={float(frame.time):.17g}")
    periodic = "T T F" if frame.dim == 2 else "T T T"
    words.append(f'pbc="{periodic if frame.cell is not None else "F F F"}"')
    return " ".join(words)


def text_column(values: np.ndarray, where: str, name: str) -> np.ndarray:
    """One column (or a vector's components) as text: reals at 17 significant digits, integers, names (no
    blanks: a name with one would shift the columns; a one-line error)."""
    if values.dtype.kind in "US":
        bad = [v for v in values if not v or re.search(r"\s|\"", str(v))]
        if bad:
            raise SceneError(f"{where}: {name}: {bad[0]!r} holds a blank or a quote, which extended XYZ cannot hold")
        return values.astype(str)[:, None]
    flat = values.reshape(len(values), -1)
    fmt = "{:.17g}" if values.dtype.kind == "f" else "{:d}"
    return np.vectorize(fmt.format, otypes=[str])(flat) if flat.size else flat.astype(str)


def block(frame: FrameFields, positions: np.ndarray, columns: dict, where: str) -> str:
    """One frame's block: count, header, rows (species X: OVITO and ASE need a species; these are grains)."""
    columns = {"species": np.full(len(positions), "X"), "pos": positions, **columns}
    parts = [text_column(np.asarray(v), where, k) for k, v in columns.items()]
    rows = np.concatenate(parts, axis=1) if len(positions) else np.zeros((0, 0), dtype=str)
    body = "".join(" ".join(r) + "\n" for r in rows)
    return f"{len(positions)}\n{header(frame, columns, where)}\n{body}"


def write(frames: list[FrameFields], out: Path, stem: str) -> list[Path]:
    """NAME.xyz and NAME.contacts.xyz, every frame a block (a sequence: a trajectory in one file)."""
    particles, contacts = out / f"{stem}.xyz", out / f"{stem}.contacts.xyz"
    with particles.open("w", encoding="utf-8") as fp, contacts.open("w", encoding="utf-8") as fc:
        for frame in frames:
            fp.write(block(frame, frame.positions, frame.particles, str(particles)))
            rest = {k: v for k, v in frame.contacts.items() if k != "point"}
            fc.write(block(frame, frame.contacts["point"], rest, str(contacts)))
    return [particles, contacts]
