"""Periodic snapshots in an import (build.py's conventions): the cell the scene keeps (`--cell`, `--no-periodic`,
a region or a cell open along an axis), particles unwrapped along the contact network where it keeps none (contacts
that close a loop around the cell cut, their forces loads), and the report's `periodic` entry."""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from ..model.errors import SceneError
from .lines import is_number


def unwrap(snap, x, shifts, keep_c, scale):
    """Positions unwrapped along a spanning tree of the kept contacts, and the contacts that close a loop around
    the periodic cell (their lattice shift disagrees with the tree's)."""
    cut = np.zeros(len(shifts), bool)
    if snap.lattice is None or not np.any(shifts):
        return x, cut
    N = len(x)
    kept = np.flatnonzero(keep_c)
    key = np.minimum(snap.p[kept], snap.q[kept]).astype(np.int64) * N + np.maximum(snap.p[kept], snap.q[kept])
    c = kept[np.sort(np.unique(key, return_index=True)[1])]   # one edge a pair (rigid bodies touch at several points)
    p, q = snap.p[c], snap.q[c]
    contacts = coo_matrix((np.ones(len(c)), (p, q)), shape=(N, N))
    _, label = connected_components(contacts, directed=False)
    roots = np.unique(label, return_index=True)[1]
    # a virtual root N joined to one particle of each component: one BFS gives a spanning forest
    rows = np.concatenate([p, q, np.full(len(roots), N)])
    cols = np.concatenate([q, p, roots])
    data = np.concatenate([c + 1, -(c + 1), np.zeros(len(roots), np.int64)]).astype(np.int64)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(N + 1, N + 1)).tocsr()
    code = coo_matrix((data, (rows, cols)), shape=(N + 1, N + 1)).tocsr()
    _, pred = breadth_first_order(graph, N, directed=True, return_predecessors=True)
    pred = pred[:N]
    pred = np.where(pred < 0, N, pred)
    link = np.asarray(code[pred, np.arange(N)]).ravel()
    step = np.zeros((N + 1, snap.dim), np.int64)
    has = link != 0
    step[:N][has] = np.sign(link[has])[:, None] * shifts[np.abs(link[has]) - 1]
    # pointer jumping: the sum of steps along the path to the root in log(depth) vectorised passes
    total, up = step.copy(), np.append(pred, N)
    while np.any(up[:N] != N):
        total = total + np.where((up != N)[:, None], total[up], 0)
        up = up[up]
    image = total[:N]
    lattice = np.nan_to_num(snap.lattice) * scale
    unwrapped = x - image @ lattice
    cut[kept] = np.any(image[snap.q[kept]] - image[snap.p[kept]] != shifts[kept], axis=1)
    return unwrapped, cut


def cell_of(snap, opts, scale: float):
    """(the scene's cell (d, d) in scene units, None) when the scene is periodic, else (None, why the seam
    contacts are cut; None without a cell)."""
    if snap.lattice is None:
        return None, None
    if not opts.periodic:
        return None, "--no-periodic"
    if np.isnan(snap.lattice).any():
        return None, "the cell is open along an axis (a periodic scene needs a full cell)"
    if opts.region is not None:
        return None, "a region was selected (the scene is a cluster, not the cell)"
    return snap.lattice * scale, None


def parse_cell(value, dim: int, where: str) -> np.ndarray:
    """The cell's rows a_i from d·d numbers (a_1 then a_2 …) or d (an orthogonal box), as text (commas or blanks)
    or numbers; a one-line error naming `where` (e.g. "<file>: line 2") and the field `cell`."""
    words = value.replace(",", " ").split() if isinstance(value, str) else list(np.ravel(value))
    try:
        numbers = np.array([float(w) for w in words])
    except ValueError:
        bad = next(w for w in words if not is_number(w))
        raise SceneError(f"{where}: cell: not a number ({str(bad)[:40]!r})") from None
    if numbers.size == dim:
        numbers = np.diag(numbers).ravel()
    if numbers.size != dim * dim:
        raise SceneError(f"{where}: cell: expected {dim * dim} numbers (the rows a_1 … a_{dim} of the {dim}D cell) "
                         f"or {dim} (an orthogonal box), got {numbers.size}")
    cell = numbers.reshape(dim, dim)
    if not np.all(np.isfinite(cell)):
        raise SceneError(f"{where}: cell: not finite ({', '.join(f'{v:g}' for v in numbers)})")
    det, scale = float(np.linalg.det(cell)), float(np.prod(np.linalg.norm(cell, axis=1)))
    if not det > 1e-12 * scale:                  # as the scene's check (model/periodic.py), here with the line
        what = " (left-handed: swap two rows)" if det < -1e-12 * scale else ""
        raise SceneError(f"{where}: cell: the lattice vectors (rows) span no positive volume, det = {det:.6g}{what}")
    return cell


def periodic_report(snap, cut, pair, cell, why_cut, shifts, kept):
    """The cell and what became of the seam contacts: kept with their images (periodic) or cut (and why)."""
    if snap.lattice is None:
        return None
    seam = np.zeros(len(shifts), bool)
    seam[kept] = True
    seam = (seam | cut) & np.any(shifts != 0, axis=1)
    report = {"lattice": np.nan_to_num(snap.lattice, nan=0.0).tolist(), **snap.notes.get("periodic", {}),
              "periodic": cell is not None, "cell": None if cell is None else cell.tolist(),
              "seam_contacts": int(seam.sum()), "seam_names": [str(v) for v in pair[seam]],
              "contacts_cut": int(cut.sum()), "cut_names": [str(v) for v in pair[cut]]}
    if cell is not None:
        report["treatment"] = ("periodic scene: the cell kept, each contact with q's image (seam contacts: a nonzero "
                               "image); --no-periodic cuts them instead")
    else:
        report["treatment"] = (f"not periodic ({why_cut}): minimum-image branch vectors; particles unwrapped along "
                               "the contacts; contacts closing a loop around the cell are cut and their forces "
                               "become loads on both particles")
    return report
