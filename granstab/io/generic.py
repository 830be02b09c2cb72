"""Generic tables for every other code: one particle table and one contact table (CSV or whitespace, a header
line naming the columns after any `#` comment lines), optionally many frames (a `frame` column in both).

    particles: id x y [z] radius       (or r, or diameter; 3D when there is a z column)
               [angle | quatw quati quatj quatk]    the orientation, where known (2D angle about e3, radians)
    contacts:  id1 id2 fx fy [fz]      (force on id1 by id2; or fnx … + ftx …; or fn ft in 2D with
               [nx ny [nz]] [m | mx my mz] [mobilised]      f = −f_n n + f_t t, t = e3 × n)

`columns` renames the contact table's columns in order (names as in granstab.io.columns.CONTACT_NAMES). A pair
listed in both orders is one contact; the two rows must agree with Newton's third law (reported).

A periodic cell: a comment line `# cell: a11 a12 a21 a22` (2D; 3D: nine numbers, the rows a_i; or d numbers, an
orthogonal box) before the header of either table, or the `cell` option (`--cell`). Contacts then take the
minimum image (build.py); the scene is periodic unless `--no-periodic`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from . import columns as cols
from .build import Snapshot, branch_vectors
from .lines import line_of, pick_frame, read_table
from .registry import Format, register
from .unwrap import parse_cell

SUFFIXES = (".csv", ".tsv", ".txt", ".dat")
PARTICLE_NAMES = {"id", "x", "y", "z", "radius", "r", "diameter", "frame", *cols.ORIENTATION_NAMES}


def header(path: Path):
    """(column names, delimiter, header line number): the first line that is neither blank nor a # comment."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for number, line in enumerate(fh, 1):
                text = line.split("#", 1)[0].strip()
                if text:
                    delimiter = "," if "," in text else ("\t" if "\t" in text else None)
                    return [c.strip() for c in text.split(delimiter)], delimiter, number
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    raise SceneError(f"{path}: line 1: header: empty file")


def cell_comment(path: Path):
    """(the text after `cell:`, its line number) of a `# cell: ...` comment before the header, or None."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            text = line.strip()
            if text and not text.startswith("#"):
                return None
            words = text.lstrip("#").strip()
            if words.lower().startswith("cell") and words[4:].lstrip()[:1] in (":", "="):
                return words[4:].lstrip()[1:].strip(), number
    return None


def table_cell(paths: list[Path], dim: int, given=None):
    """The cell of `# cell:` comments (both tables may give one: then the same) or of `given` (--cell), or None."""
    cells = []
    for path in paths:
        found = cell_comment(path)
        if found is not None:
            cells.append((parse_cell(found[0], dim, f"{path}: line {found[1]}"), path, found[1]))
    for cell, path, line in cells[1:]:
        if not np.array_equal(cell, cells[0][0]):
            raise SceneError(f"{path}: line {line}: cell: differs from the cell of {cells[0][1].name} line "
                             f"{cells[0][2]}")
    if given is not None and cells:
        raise SceneError(f"--cell: {cells[0][1]} line {cells[0][2]} gives the cell already; leave --cell out")
    return parse_cell(given, dim, "--cell") if given is not None else cells[0][0] if cells else None


def table_names(path: Path) -> list | None:
    """The column names of a table file (one of SUFFIXES, with a header), or None: the sniffs' shared look."""
    if path.suffix.lower() not in SUFFIXES or not path.is_file():
        return None
    try:
        return header(path)[0]
    except SceneError:
        return None


def is_table(path: Path) -> bool:
    names = table_names(path)
    return names is not None and ({"id1", "id2"} <= set(names) or {"id", "x", "y"} <= set(names))


def _two_tables(paths: list[Path]):
    """The particle table, the contact table and each one's header (names, delimiter, line)."""
    kinds = {p: header(p) for p in paths}
    particle_files = [p for p, h in kinds.items() if {"id", "x", "y"} <= set(h[0])]
    contact_files = [p for p in paths if p not in particle_files]
    if len(contact_files) != 1 or len(particle_files) != 1:
        raise SceneError(f"{paths[0]}: need one particle table (header id x y [z] radius) and one contact table "
                         f"(header id1 id2 ...), got {len(particle_files)} and {len(contact_files)}")
    return particle_files[0], contact_files[0], kinds


def read_tables(paths: list[Path], frame=None, columns: str | None = None, progress=None, cell=None) -> Snapshot:
    """The snapshot of one frame; `progress`: a progress.ReadProgress (bytes parsed); `cell`: --cell."""
    update = None if progress is None else progress.update
    ppath, cpath, kinds = _two_tables(paths)
    pnames, pdelim, pline = kinds[ppath]
    cnames, cdelim, cline = kinds[cpath]
    unknown = [c for c in pnames if c not in PARTICLE_NAMES]
    if unknown:
        raise SceneError(f"{ppath}: line {pline}: {unknown[0]}: unknown column (known: {', '.join(sorted(PARTICLE_NAMES))})")
    header_names = cnames
    if columns:
        cnames = cols.columns_option(columns, len(cnames), str(cpath), " ".join(cnames))
    elif any(c not in cols.CONTACT_NAMES for c in cnames):
        bad = next(c for c in cnames if c not in cols.CONTACT_NAMES)
        raise SceneError(f"{cpath}: line {cline}: {bad}: unknown column: name the columns with --columns")
    for need, names, path, line in (("id", pnames, ppath, pline), ("x", pnames, ppath, pline),
                                    ("y", pnames, ppath, pline), ("id1", cnames, cpath, cline),
                                    ("id2", cnames, cpath, cline)):
        if need not in names:
            raise SceneError(f"{path}: line {line}: {need}: missing column")
    if not {"radius", "r", "diameter"} & set(pnames):
        raise SceneError(f"{ppath}: line {pline}: radius: missing column (radius, r or diameter)")
    if progress is not None:
        progress.stage("parse")
    P = held_table(ppath, pnames, delimiter=pdelim, skiprows=pline, min_rows=1, progress=update)
    C = held_table(cpath, cnames, delimiter=cdelim, skiprows=cline, progress=update)
    pcol = {n: P[:, k] for k, n in enumerate(pnames)}
    ccol = {n: C[:, k] for k, n in enumerate(cnames) if n != "-"}
    prow, crow, frames, which = _frame_rows(ppath, cpath, pcol, ccol, frame)
    pcol = {n: v[prow] for n, v in pcol.items()}
    ccol = {n: v[crow] for n, v in ccol.items()}
    pline_of = lambda r: f"{ppath}: line {line_of(ppath, prow[r], skiprows=pline)}"  # noqa: E731
    cline_of = lambda r: f"{cpath}: line {line_of(cpath, crow[r], skiprows=cline)}"  # noqa: E731
    ids = pcol["id"]
    cols.unique_ids(ids, pline_of, "in one frame")
    dim = 3 if "z" in pcol else 2
    x = np.stack([pcol[a] for a in "xyz"[:dim]], axis=1)
    radius = pcol.get("radius", pcol.get("r", pcol.get("diameter", np.zeros(0)) / 2))
    orientation = cols.particle_orientation(pcol, dim, pline_of, str(ppath))
    what = "not in the particle table" + ("" if which is None else f" at frame {which:g}")
    wall = ccol["id2"] < 0
    p = cols.to_indices(ids, ccol["id1"], "id1", cline_of, what)
    q = np.where(wall, p, cols.to_indices(ids, np.where(wall, ids[0], ccol["id2"]), "id2", cline_of, what))
    lattice = table_cell([ppath, cpath], dim, cell)
    branch = branch_vectors(x, p, q, lattice)[0]           # minimum image in a cell (wall rows: p = q, unused)
    normal = None
    if "nx" in ccol:
        normal = np.stack([ccol[f"n{a}"] for a in "xyz"[:dim]], axis=1)
    elif "fn" in ccol and dim == 2:
        with np.errstate(invalid="ignore", divide="ignore"):
            normal = branch / np.linalg.norm(branch, axis=1)[:, None]
    force, how = cols.contact_forces(str(cpath), ccol, dim, normal)
    if normal is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            normal = normal / np.linalg.norm(normal, axis=1)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):     # f_r columns: R_eff f_r × n (wall rows: unused)
        moment = cols.contact_moments(ccol, dim, branch / np.linalg.norm(branch, axis=1)[:, None],
                                 radius[p] * radius[q] / (radius[p] + radius[q]))
    force_err, err_from = cols.force_uncertainty(ccol, cline_of)
    wall_load, walls = _walls(wall, p, force, len(ids), ccol["id2"])
    rows = np.flatnonzero(~wall)
    law = _law(ccol, rows, cpath)
    p, q, force, normal, moment, mobilised, keep, duplicates = _one_row_per_pair(
        p[rows], q[rows], force[rows], None if normal is None else normal[rows],
        None if moment is None else moment[rows], None if "mobilised" not in ccol else ccol["mobilised"][rows])
    law = {k: (v[keep], where) for k, (v, where) in law.items()}
    keep = rows[keep]
    return Snapshot(source=f"{ppath} + {cpath}", format="table", dim=dim, ids=ids.astype(np.int64)
                    if np.all(ids == np.round(ids)) else ids, x=x, radius=radius, p=p, q=q, force=force,
                    normal=normal, moment=moment, mobilised=mobilised, wall_load=wall_load, law=law,
                    orientation=orientation,
                    lattice=lattice, force_uncertainty=None if force_err is None else (force_err[keep], err_from),
                    frame=None if which is None else float(which), frames=frames,
                    notes={"duplicates": duplicates, "forces_from": how, "walls": walls,
                           "columns": cols.column_note(cpath, header_names, cnames, bool(columns))},
                    particle_line=pline_of, contact_line=lambda c: cline_of(keep[c]))


HELD_TABLES = 2      # the particle and the contact table of one sequence
_held: dict = {}     # path → ((size, mtime, options), rows): the sequences' tables read in this process


def held_table(path: Path, fields, **options) -> np.ndarray:
    """`read_table`, kept in this process for a table with a frame column: a sequence is read once, not once for
    each of its frames (`track` loads every frame; the whole table was parsed each time, a cost growing with the
    square of the run's length), and read again when the file changes (its size or modification time). At most
    HELD_TABLES tables are kept; the rows are read-only (frames are selected by copying)."""
    if "frame" not in fields:
        return read_table(path, fields, **options)
    try:
        stat = path.stat()
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    key = str(path.resolve())
    stamp = (stat.st_size, stat.st_mtime_ns, tuple(fields), tuple(sorted((k, v) for k, v in options.items()
                                                                          if k != "progress")))
    if key not in _held or _held[key][0] != stamp:
        _held.pop(key, None)
        while len(_held) >= HELD_TABLES:
            _held.pop(next(iter(_held)))
        rows = read_table(path, fields, **options)
        rows.flags.writeable = False
        _held[key] = (stamp, rows)
    return _held[key][1]


def _frame_rows(ppath, cpath, pcol, ccol, frame):
    if "frame" not in pcol and "frame" not in ccol:
        if frame is not None:
            raise SceneError(f"{ppath}: frame {frame}: frame: the tables have no frame column")
        return np.arange(len(pcol["id"])), np.arange(len(ccol["id1"])), None, None
    if "frame" not in pcol or "frame" not in ccol:
        path = cpath if "frame" not in ccol else ppath
        raise SceneError(f"{path}: frame: missing column (the other table has one)")
    which, frames = pick_frame(pcol["frame"], frame, ppath)
    extra = np.setdiff1d(np.unique(ccol["frame"]), frames)
    if extra.size:
        raise SceneError(f"{cpath}: frame {extra[0]:g}: frame: not in {ppath.name} (mismatched files)")
    return (np.flatnonzero(pcol["frame"] == which), np.flatnonzero(ccol["frame"] == which),
            [float(f) for f in frames], which)


def _walls(wall, p, force, n, id2):
    """Rows with a negative id2 are forces on id1 by a wall: summed per particle, they are external loads."""
    if not np.any(wall):
        return None, "none in the file"
    load = np.zeros((n, force.shape[1]))
    np.add.at(load, p[wall], force[wall])
    return load, {"wall_contacts": int(wall.sum()), "walls": int(np.unique(id2[wall]).size),
                  "particles_touching": int(np.unique(p[wall]).size),
                  "treatment": "wall forces become external loads on their particles (with the rest of the "
                               "imbalance, b = −Σf over particle contacts)"}


def _law(col, rows, path):
    """k = kn, α = kt/kn, μ per contact where the table has those columns."""
    law = {}
    if "kn" in col:
        law["k"] = (col["kn"][rows], f"{path.name} column kn")
        if "kt" in col:
            law["alpha"] = (col["kt"][rows] / col["kn"][rows], f"{path.name} columns kt/kn")
    if "mu" in col:
        law["mu"] = (col["mu"][rows], f"{path.name} column mu")
    return law




def _one_row_per_pair(p, q, force, normal, moment, mobilised):
    """Pairs listed in both orders: keep the first row, check the second against Newton's third law."""
    lo, hi = np.minimum(p, q), np.maximum(p, q)
    key = lo.astype(np.int64) * (max(int(hi.max(initial=0)), 0) + 1) + hi
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    keep = np.sort(first)
    report = {"pairs_listed_twice": int(np.sum(counts == 2)), "pairs_listed_more": int(np.sum(counts > 2))}
    if np.any(counts > 1):
        order = np.argsort(key, kind="stable")
        sorted_key = key[order]
        second = order[1:][sorted_key[1:] == sorted_key[:-1]]
        partner = order[:-1][sorted_key[1:] == sorted_key[:-1]]
        sign = np.where(p[second] == p[partner], 1.0, -1.0)[:, None]
        diff = np.linalg.norm(force[second] - sign * force[partner], axis=1)
        scale = np.maximum(np.linalg.norm(force[partner], axis=1), 1e-300)
        report.update({"newton_third_law_largest_relative_misfit": float((diff / scale).max()),
                       "kept": "the first row of each pair"})
    pick = lambda a: None if a is None else a[keep]  # noqa: E731
    mob = None if mobilised is None else mobilised[keep] != 0
    return p[keep], q[keep], force[keep], pick(normal), pick(moment), mob, keep, report


register(Format("table", sniff=lambda paths: all(is_table(p) for p in paths), columns=True,
                read=lambda paths, request, progress: read_tables(paths, request.frame, request.columns, progress,
                                                                  request.cell)))
