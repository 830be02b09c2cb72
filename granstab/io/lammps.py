"""LAMMPS (and LIGGGHTS) text dumps: a per-atom dump plus a local contact dump, optionally the input script.

    dump atoms all custom N atoms.dump id type x y z radius            (x/xu/xs..., radius or diameter)
    compute ends all property/local patom1 patom2
    compute pair all pair/local fx fy fz p10 p11 p12                   (LIGGGHTS: compute pg all pair/gran/local
    dump contacts all local N contacts.dump c_ends[1] c_ends[2] c_pair[1] c_pair[2] c_pair[3]    id force ...)

Local dumps name their columns c_ID[k]; what each is comes from `columns` (one name a column: id1, id2, fx, fy,
fz, delx, dely, delz, cx, cy, cz, ftx, fty, ftz, delta, or - to ignore), from canonical header names, or from the
input script's compute lines when the script is one of the inputs. The forces are those on id1 by id2
(pair/local fx fy fz: the force on the first atom). pair/local also lists neighbour pairs that do not touch: they
are dropped by overlap (R_1 + R_2 − d ≤ 0), not by force, and counted. Periodic boxes (pp) use minimum-image
branch vectors (triclinic tilt: a sheared lattice); the scene is periodic (the box is its cell, each contact keeps
its image) when every axis of the dimension is periodic (build.py). 2D when the script says `dimension 2`, or when every z is
equal and fz = 0. The contact law comes from the script's pair_style/pair_coeff (granular hooke/hertz with
linear_history or mindlin tangential, gran/hooke/history, gran/hertz/history) where it has one:
Hookean k = k_n, α = k_t/k_n; Hertz k = dF/dδ = 1.5 k_n a with a = √(R_eff δ) (tangent stiffness at the
current overlap), mindlin scales k_t by a (LAMMPS pair_granular documentation); LIGGGHTS `pair_style gran model
hooke/stiffness tangential history` with kn, kt, coefficientFriction from `fix property/global`. pair/gran/local
(LIGGGHTS) gives the force on id1 and lists touching pairs only (checked against Debian's liggghts 3.8.0).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from ..model.vec import norms
from .build import Snapshot, branch_vectors
from .columns import (
    CONTACT_NAMES,
    ORIENTATION_NAMES,
    column_note,
    columns_option,
    contact_forces,
    contact_moments,
    force_uncertainty,
    particle_orientation,
    to_indices,
    unique_ids,
)
from .lammps_script import compute_columns, contact_law, read_script
from .lines import read_window
from .registry import Format, register

CHUNK = 1 << 23          # bytes per step of the scan for timesteps

ATOM_ALIASES = {"xu": "x", "yu": "y", "zu": "z", "xs": "xs", "ys": "ys", "zs": "zs"}


def is_dump(path: Path) -> bool:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.readline().startswith("ITEM: TIMESTEP")
    except OSError:
        return False


def has_shape_columns(path: Path) -> bool:
    """A dump whose first ITEM: ATOMS line names shapex and blockiness1: LIGGGHTS superquadrics (their own reader,
    liggghts_superquadric.py)."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            head = [line for _, line in zip(range(12), fh)]
    except OSError:
        return False
    atoms = next((line.split() for line in head if line.startswith("ITEM: ATOMS")), [])
    return bool(head) and head[0].startswith("ITEM: TIMESTEP") and "shapex" in atoms and "blockiness1" in atoms


@dataclass
class Block:
    """One timestep of a dump: header values and where its rows are (bytes [start, end), from file line
    `first_line`)."""

    timestep: int
    count: int
    bounds: np.ndarray | None   # (3, 2) box bounds as dumped (triclinic: *_bound values)
    tilt: np.ndarray            # (3,) xy, xz, yz
    periodic: tuple
    columns: list
    kind: str                   # "ATOMS" or "ENTRIES"
    start: int
    end: int
    first_line: int


MARK = b"ITEM: TIMESTEP"
HEADER_LINES = 25               # a timestep's header is read up to this many lines


def index_dump(path: Path, progress=None) -> tuple[list[Block], str | None]:
    """Split a dump into timesteps: one pass over its bytes in chunks (C-speed searches for the ITEM: TIMESTEP
    lines, newlines counted for line numbers; memory O(chunk), not the file), then each timestep's header. Rows
    are parsed later, for the chosen timestep only (`rows`). `progress(n_bytes)` is called as bytes are read.
    A last timestep cut short (its header, or fewer rows than it says: a run still writing, or killed) is left
    out: the blocks before it and the line that says so."""
    try:
        with open(path, "rb") as fh:
            starts, lines, size, newlines = _marks(fh, progress)
            if not starts:
                raise SceneError(f"{path}: line 1: ITEM: TIMESTEP: missing (not a LAMMPS dump)")
            ends = starts[1:] + [size]
            blocks = [_header(path, fh, start, end, line)
                      for start, end, line in zip(starts[:-1], ends[:-1], lines[:-1])]
            try:
                last = _header(path, fh, starts[-1], size, lines[-1])
            except SceneError as exc:
                return blocks, (f"{path}: the last timestep (line {lines[-1]}) is cut short and left out "
                                f"({str(exc).removeprefix(f'{path}: ')})")
            rows = _complete_rows(fh, last, size, newlines)
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    if rows < last.count:
        return blocks, (f"{path}: timestep {last.timestep}: cut short ({rows} of {last.count} rows, from line "
                        f"{last.first_line}): the last timestep is left out")
    return blocks + [last], None


def _complete_rows(fh, block: Block, size: int, newlines: int) -> int:
    """The rows of the file's last block: its newline-terminated lines, and a last line without a newline when it
    is as wide as the header says (a file cut mid-row ends in a short line)."""
    rows = newlines - block.first_line + 1
    fh.seek(max(block.start, size - 65536))
    last = fh.read().rsplit(b"\n", 1)[-1]
    return rows + int(bool(last.strip()) and len(last.split()) >= len(block.columns))


def _marks(fh, progress=None):
    """Byte offsets and 1-based line numbers of the lines that start with ITEM: TIMESTEP, the file size and its
    number of newlines."""
    pattern = b"\n" + MARK
    starts, lines = ([0], [1]) if fh.read(len(MARK)) == MARK else ([], [])
    fh.seek(0)
    tail, size, newlines = b"", 0, 0   # the last bytes read (a mark may straddle two chunks), bytes and "\n" so far
    while chunk := fh.read(CHUNK):
        if progress is not None:
            progress(len(chunk))
        buf = tail + chunk
        base, before, counted = size - len(tail), newlines - tail.count(b"\n"), 0
        i = buf.find(pattern)
        while i >= 0:
            before += buf.count(b"\n", counted, i + 1)
            counted = i + 1
            starts.append(base + i + 1)
            lines.append(before + 1)
            i = buf.find(pattern, i + 1)
        size += len(chunk)
        newlines += chunk.count(b"\n")
        tail = buf[-(len(pattern) - 1):]
    return starts, lines, size, newlines


def _header(path: Path, fh, start: int, end: int, line: int) -> Block:
    fh.seek(start)
    lines, after, pos = [], [], start            # the header's lines (as str.split would give) and their ends
    while len(lines) < HEADER_LINES and pos < end:
        raw = fh.readline(end - pos)
        pos += len(raw)
        lines.append(raw.decode("utf-8", "replace").rstrip("\r\n"))
        after.append(pos)
        if pos == end and raw.endswith(b"\n") and len(lines) < HEADER_LINES:
            lines.append("")
            after.append(pos)
    values = {"tilt": np.zeros(3), "bounds": None, "periodic": (False, False, False)}
    i = 0

    def fail(field, what, at=0):
        raise SceneError(f"{path}: line {line + i + at}: {field}: {what}")

    def number(kind, text, field, at=1):
        try:
            return kind(text)
        except ValueError:
            fail(field, f"not a number ({text.strip()[:40]!r})", at)

    while i < len(lines):
        item = lines[i].strip()
        if not item.startswith("ITEM:"):
            fail("ITEM", f"expected a header line, got {item[:40]!r} (truncated or garbled dump?)")
        word = item[5:].strip()
        if word.startswith("ATOMS") or word.startswith("ENTRIES"):
            kind, _, cols = word.partition(" ")
            if "timestep" not in values or "count" not in values:
                fail(kind, "header incomplete (TIMESTEP and NUMBER OF ... must come first)")
            return Block(values["timestep"], values["count"], values["bounds"], values["tilt"], values["periodic"],
                         cols.split(), kind, after[i], end, line + i + 1)
        if i + 1 >= len(lines):
            fail(word.split()[0] if word else "ITEM", "file ends inside the header (truncated?)")
        if word == "TIMESTEP":
            values["timestep"] = number(int, lines[i + 1], "timestep")
            i += 2
        elif word.startswith("NUMBER OF"):
            values["count"] = number(int, lines[i + 1], "number of rows")
            i += 2
        elif word.startswith("BOX BOUNDS"):
            flags = word.split()[2:]
            triclinic = flags[:3] == ["xy", "xz", "yz"]
            flags = flags[3:] if triclinic else flags
            if len(lines) < i + 4:
                fail("box bounds", "file ends inside the header (truncated?)")
            rows = []
            for k in range(3):
                cells = lines[i + 1 + k].split()
                if len(cells) != (3 if triclinic else 2):
                    fail("box bounds", f"expected {3 if triclinic else 2} numbers, got {len(cells)}", 1 + k)
                rows.append([number(float, c, "box bounds", 1 + k) for c in cells])
            rows = np.array(rows)
            values["bounds"] = rows[:, :2]
            values["tilt"] = rows[:, 2] if triclinic else np.zeros(3)
            values["periodic"] = tuple(f.startswith("p") for f in flags) if len(flags) == 3 else (False,) * 3
            i += 4
        else:  # ITEM: TIME, UNITS, ...: one value line
            i += 2
    fail("ATOMS", "no ITEM: ATOMS / ENTRIES line (truncated?)")


def lattice_of(block: Block, dim: int) -> np.ndarray | None:
    """Periodic lattice vectors (rows, lower-triangular; NaN row for an open axis) from a dump's box."""
    if block.bounds is None or not any(block.periodic[:dim]):
        return None
    xy, xz, yz = block.tilt
    lo, hi = block.bounds[:, 0].copy(), block.bounds[:, 1].copy()
    lo[0] -= min(0.0, xy, xz, xy + xz)
    hi[0] -= max(0.0, xy, xz, xy + xz)
    lo[1] -= min(0.0, yz)
    hi[1] -= max(0.0, yz)
    full = np.array([[hi[0] - lo[0], 0, 0], [xy, hi[1] - lo[1], 0], [xz, yz, hi[2] - lo[2]]])
    lattice = full[:dim, :dim].copy()
    for axis in range(dim):
        if not block.periodic[axis]:
            lattice[axis] = np.nan
    return lattice


# ------------------------------------------------------------------------------------------------ script

# ------------------------------------------------------------------------------------------------ reading

@dataclass
class DumpIndex:
    """A LAMMPS run's dumps indexed once (`index_lammps`): each timestep's header and byte offsets in the atom and
    the local dump, the timesteps both have (`frames`), what was left out (`warnings`) and the input script."""

    atoms: Path
    local: Path
    script: dict | None
    atom_blocks: dict             # timestep → Block
    local_blocks: dict
    frames: list
    warnings: list

    def read(self, frame, request, progress=None) -> Snapshot:
        """One timestep (default the last both dumps have): its rows only (registry.Format.index)."""
        return read_step(self, frame, request.columns, progress)

    def spans(self, frames=None) -> dict:
        """{path: [(timestep, first byte, end)]} of `frames` (default all) in each dump: a frame's bytes from the end
        of the frame before it (its header included) to its own end (what a resume hashes: scan/resume.py)."""
        wanted = set(self.frames if frames is None else frames)
        out = {}
        for path, blocks in ((self.atoms, self.atom_blocks), (self.local, self.local_blocks)):
            ordered = sorted(blocks.values(), key=lambda b: b.end)
            out[path] = [(b.timestep, lo, b.end) for lo, b in zip([0] + [b.end for b in ordered], ordered)
                         if b.timestep in wanted]
        return out


def index_lammps(paths: list[Path], progress=None) -> DumpIndex:
    """One pass over each dump (`index_dump`) and the script: the timesteps both dumps have. Timesteps that one
    dump has and the other lacks are named in one warning line, a truncated last timestep in another; dumps of
    two different runs (no timestep in common, or a different box at the same timestep) are refused."""
    update = None if progress is None else progress.update
    dumps = [p for p in paths if is_dump(p)]
    scripts = [p for p in paths if p not in dumps]
    if len(scripts) > 1:
        raise SceneError(f"{scripts[1]}: not a LAMMPS dump, and {scripts[0].name} is already the input script")
    script = read_script(scripts[0]) if scripts else None
    if script is not None:
        _refuse_uncurved(script)
    indexed = [(p, *index_dump(p, update)) for p in dumps]
    frames, warnings = account(sorted(indexed, key=lambda e: bool(e[1]) and e[1][0].kind != "ATOMS"))
    atoms = [(p, b) for p, b, _ in indexed if b[0].kind == "ATOMS"]
    local = [(p, b) for p, b, _ in indexed if b[0].kind == "ENTRIES"]
    if len(atoms) != 1 or len(local) != 1:
        raise SceneError(f"{paths[0]}: need one per-atom dump (ITEM: ATOMS) and one local dump (ITEM: ENTRIES), "
                         f"got {len(atoms)} and {len(local)}")
    (apath, ablocks), (cpath, cblocks) = atoms[0], local[0]
    by_a, by_c = {b.timestep: b for b in ablocks}, {b.timestep: b for b in cblocks}
    return DumpIndex(apath, cpath, script, by_a, by_c, frames, warnings)


def account(indexed: list) -> tuple[list, list]:
    """The timesteps that every dump of `indexed` [(path, blocks, cut line or None)] has, and the warning lines:
    a truncated last timestep (`index_dump`'s cut line), the timesteps in some dumps only, named in one line. Dumps
    of different runs (no timestep in common, or a box differing from the first dump's at the same timestep) are
    refused (issue 38: every reader of several dumps accounts for its frames so)."""
    for path, blocks, cut in indexed:
        if not blocks:
            raise SceneError(cut or f"{path}: no timestep")
    by = [{b.timestep: b for b in blocks} for _, blocks, _ in indexed]
    common = set(by[0]) if by else set()
    for k, ((path, _, _), mine) in enumerate(zip(indexed, by)):
        if not common & set(mine):
            raise SceneError(f"{path}: timestep: none in common with {', '.join(p.name for p, _, _ in indexed[:k])} "
                             f"({_steps(sorted(mine))} against {_steps(sorted(common))}): dumps of two different runs?")
        common &= set(mine)
    frames = sorted(common)
    for (path, _, _), mine in zip(indexed[1:], by[1:]):
        _same_box(indexed[0][0], path, by[0], mine, frames)
    warnings = [cut for _, _, cut in indexed if cut]
    # past a dump's cut, the other's timesteps are said by the cut's line
    known = min([b[-1].timestep for _, b, cut in indexed if cut], default=np.inf)
    alone = [(path.name, sorted(t for t in set(mine) - common if t <= known)) for (path, _, _), mine in zip(indexed, by)]
    if any(steps for _, steps in alone):
        warnings.append(f"timesteps in {'one dump' if len(indexed) == 2 else 'some dumps'} only, left out: "
                        + "; ".join(f"{len(steps)} in {name} only ({_steps(steps)})" for name, steps in alone if steps)
                        + f"; {len(frames)} timesteps in {'both' if len(indexed) == 2 else 'all'}")
    return frames, warnings


def _steps(steps: list) -> str:
    return ", ".join(map(str, steps[:5])) + (f", … {steps[-1]}" if len(steps) > 5 else "")


def _same_box(apath: Path, cpath: Path, by_a: dict, by_c: dict, frames: list) -> None:
    """The two dumps' boxes agree at every common timestep (to 1e-9 of the box size: the same run writes the same
    numbers); else a one-line refusal."""
    for step in frames:
        a, c = by_a[step], by_c[step]
        if a.bounds is None or c.bounds is None:
            continue
        box_a, box_c = np.r_[a.bounds.ravel(), a.tilt], np.r_[c.bounds.ravel(), c.tilt]
        if np.abs(box_a - box_c).max() > 1e-9 * max(np.abs(box_a).max(), 1e-300):
            raise SceneError(f"{cpath}: timestep {step}: box bounds: differ from {apath.name}'s at the same timestep "
                             f"({' '.join(f'{v:g}' for v in box_c)} against {' '.join(f'{v:g}' for v in box_a)}): "
                             "dumps of two different runs?")


def read_lammps(paths: list[Path], timestep=None, columns: str | None = None, progress=None) -> Snapshot:
    """The snapshot of one timestep; `progress`: a progress.ReadProgress (bytes scanned, then the rows parsed)."""
    return read_step(index_lammps(paths, progress), timestep, columns, progress)


def read_step(index: DumpIndex, timestep=None, columns: str | None = None, progress=None) -> Snapshot:
    """One timestep of indexed dumps (default the last both have): its atom and local rows only."""
    update = None if progress is None else progress.update
    apath, cpath, script = index.atoms, index.local, index.script
    step = index.frames[-1] if timestep is None else timestep
    for path, blocks in ((apath, index.atom_blocks), (cpath, index.local_blocks)):
        if step not in blocks:
            raise SceneError(f"{path}: timestep {step}: timestep: not in the file (it has {_steps(sorted(blocks))})"
                             + "".join(f"; {w}" for w in index.warnings))
    ablock, cblock = index.atom_blocks[step], index.local_blocks[step]
    if progress is not None:
        progress.stage("parse", total=ablock.end - ablock.start + cblock.end - cblock.start)
    ids, x, radius, mass, dim_hint, turns = _atoms(apath, ablock, update)
    names = _contact_columns(cpath, cblock, columns, script)
    data = read_window(cpath, cblock.start, cblock.end, cblock.first_line, names, cblock.count, "entries", update)
    col = {name: data[:, k] for k, name in enumerate(names) if name != "-"}
    dim = script["dimension"] if script and script["dimension"] else dim_hint
    orientation = particle_orientation(turns, dim, lambda row: f"{apath}: line {ablock.first_line + row}",
                                       f"{apath}: timestep {step}")
    for need in ("id1", "id2"):
        if need not in col:
            raise SceneError(f"{cpath}: timestep {step}: {need}: no column (name the columns with --columns)")
    force, how = contact_forces(f"{cpath}: timestep {step}", col, dim)
    if any(f"fr{a}" in col for a in "xyz"[:dim]) and not all(f"fr{a}" in col for a in "xyz"[:dim]):
        missing = next(f"fr{a}" for a in "xyz"[:dim] if f"fr{a}" not in col)
        raise SceneError(f"{cpath}: timestep {step}: {missing}: no column ({dim}D rolling resistance needs "
                         f"{', '.join('fr' + a for a in 'xyz'[:dim])})")
    line = lambda row: f"{cpath}: line {cblock.first_line + row}"  # noqa: E731
    what = f"not in {apath.name} at timestep {step}: dumps of two different runs?"
    p, q = (to_indices(ids, col[name], name, line, what) for name in ("id1", "id2"))
    lattice = lattice_of(ablock, dim)
    branch = branch_vectors(x[:, :dim], p, q, lattice)[0]
    d = norms(branch)
    delta = radius[p] + radius[q] - d
    touching = delta > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        moment = contact_moments(col, dim, branch / d[:, None], radius[p] * radius[q] / (radius[p] + radius[q]))
    apart = ~touching
    dropped = {"count": int(apart.sum()), "with_force": int(np.sum(apart & np.any(force != 0, axis=1))),
               "rule": "dropped: R_1 + R_2 − d ≤ 0 (pair/local lists neighbours that do not touch)"}
    law, notes = contact_law(script, radius[p[touching]], radius[q[touching]], delta[touching])
    rows = np.flatnonzero(touching)
    err, err_from = force_uncertainty(col, line)          # f_err, or fn_err and ft_err (issue 42), where named
    return Snapshot(
        source=f"{apath} + {cpath}", format="lammps", dim=dim, ids=ids, x=x[:, :dim], radius=radius, mass=mass,
        orientation=orientation,
        p=p[touching], q=q[touching], force=force[touching], lattice=lattice, law=law, frame=int(step),
        moment=None if moment is None else moment[touching],
        force_uncertainty=None if err is None else (err[touching], err_from),
        frames=list(index.frames),
        notes={"non_touching_pairs": dropped, "law_notes": notes, "dimension": dim, "forces_from": how,
               **({} if lattice is None else {"periodic": {"kind": "LAMMPS " + (
                   f"triclinic box (tilt xy xz yz {' '.join(f'{t:g}' for t in ablock.tilt)})"
                   if np.any(ablock.tilt) else "orthogonal box")}}),
               "moments_from": "none" if moment is None else "mx my mz (m)" if "frx" not in col else
               "rolling resistance f_r (pair/local p5 p6 p7): m = R_eff f_r × n on id1",
               "columns": column_note(cpath, cblock.columns, names, bool(columns), script is not None)},
        particle_line=lambda i: f"{apath}: line {ablock.first_line + i}",
        contact_line=lambda c: f"{cpath}: line {cblock.first_line + rows[c]}")


def _atoms(path: Path, block: Block, progress=None):
    names = [ATOM_ALIASES.get(c, c) for c in block.columns]
    for need in ("id",):
        if need not in names:
            raise SceneError(f"{path}: timestep {block.timestep}: {need}: no column in ITEM: ATOMS")
    if "radius" not in names and "diameter" not in names:
        raise SceneError(f"{path}: timestep {block.timestep}: radius: no radius or diameter column in ITEM: ATOMS")
    data = read_window(path, block.start, block.end, block.first_line, names, block.count, "atoms", progress)
    col = {name: data[:, k] for k, name in enumerate(names)}
    ids = col["id"].astype(np.int64)
    if np.any(ids != col["id"]):
        row = int(np.flatnonzero(ids != col["id"])[0])
        raise SceneError(f"{path}: line {block.first_line + row}: id: not an integer ({col['id'][row]})")
    unique_ids(ids, lambda row: f"{path}: line {block.first_line + row}", f"in timestep {block.timestep}")
    radius = col["radius"] if "radius" in col else col["diameter"] / 2
    if "x" in col:
        x = np.stack([col["x"], col["y"], col.get("z", np.zeros(len(ids)))], axis=1)
    elif "xs" in col and block.bounds is not None:
        lat = lattice_of(Block(0, 0, block.bounds, block.tilt, (True,) * 3, [], "", 0, 0, 0), 3)
        lo = block.bounds[:, 0] - np.array([min(0.0, *block.tilt[:2], block.tilt[0] + block.tilt[1]),
                                            min(0.0, block.tilt[2]), 0.0])
        x = lo + np.stack([col["xs"], col["ys"], col.get("zs", np.zeros(len(ids)))], axis=1) @ lat
    else:
        raise SceneError(f"{path}: timestep {block.timestep}: x: no x/xu/xs column in ITEM: ATOMS")
    flat = np.ptp(x[:, 2]) == 0 if len(x) else True
    turns = {n: col[n] for n in ORIENTATION_NAMES if n in col}
    return ids, x, radius, col.get("mass"), 2 if flat else 3, turns


def _contact_columns(path: Path, block: Block, columns: str | None, script) -> list:
    width = len(block.columns)
    if columns:
        return columns_option(columns, width, str(path), " ".join(block.columns))
    known = compute_columns(script["computes"], (script["pair"] or [None])[0]) if script else {}
    names = [c if c in CONTACT_NAMES else known.get(c, known.get(re.sub(r"\[\d+\]$", "[*]", c)))
             for c in block.columns]
    if "index" in block.columns:
        names[block.columns.index("index")] = "-"
    if None in names:
        unknown = block.columns[names.index(None)]
        raise SceneError(f"{path}: line {block.first_line - 1}: {unknown}: ambiguous column: name the columns with "
                         "--columns id1,id2,fx,fy,fz,... or give the input script as well")
    return names


# shapes without a rounding radius or a smooth surface: no curvature at a sharp vertex or edge (issue 37)
UNCURVED = {"tri": "triangles (a mesh)", "line": "line segments (a mesh)",
            "body nparticle": "rigid bodies of point sub-particles"}
POLYHEDRA = ("3D rounded polyhedra: not read yet (LAMMPS dumps none of their contacts: pair body/rounded/polyhedron "
             "has no single(), so no pair/local, and granstab does not reproduce its edge-face and edge-edge contact "
             "model as it does body rounded/polygon's; docs/formats.md)")


def _refuse_uncurved(script: dict) -> None:
    """One line for an atom style whose grains granstab cannot give a curvature (UNCURVED)."""
    words, number = script.get("atom_style") or ([], 0)
    key = " ".join(words[:2]) if words[:1] == ["body"] else " ".join(words[:1])
    if key == "body rounded/polyhedron":
        raise SceneError(f"{script['source']}: line {number}: atom_style: {' '.join(words)}: {POLYHEDRA}")
    if key in UNCURVED:
        raise SceneError(f"{script['source']}: line {number}: atom_style: {' '.join(words)}: {UNCURVED[key]}: no "
                         "curvature at a sharp vertex or edge (granstab needs rounded or smooth grains: spheres, "
                         "clumps, body rounded/polygon)")


register(Format("lammps", sniff=lambda paths: any(is_dump(p) for p in paths) and not any(map(has_shape_columns, paths))
                and not multisphere_script(paths) and not body_script(paths),
                columns=True,
                read=lambda paths, request, progress: read_lammps(paths, request.frame, request.columns, progress),
                index=lambda paths, request, progress: index_lammps(paths, progress)))


def _script_says(paths: list[Path], pattern: str) -> bool:
    """Whether one of the paths (not a dump, under 1 MB) has a line matching `pattern`."""
    for path in paths:
        if path.is_file() and not is_dump(path) and path.stat().st_size < 1 << 20:
            if re.search(pattern, path.read_text(encoding="utf-8", errors="replace"), re.MULTILINE):
                return True
    return False


def multisphere_script(paths: list[Path]) -> bool:
    """Whether one of the paths is a LIGGGHTS input script with `fix ID group multisphere` (multisphere.py reads
    its dumps as clumps)."""
    return _script_says(paths, r"^\s*fix\s+\S+\s+\S+\s+multisphere(/nointegration)?(\s|$)")


def body_script(paths: list[Path]) -> bool:
    """Whether one of the paths is an input script with `atom_style body rounded/polygon` (polygons.py)."""
    return _script_says(paths, r"^\s*atom_style\s+body\s+rounded/polygon(\s|$)")
