"""Periodic scenes: the cell (lattice vectors a_i as rows) and the images of q, and their checks.

A contact's `image` (d integers) names the copy of q it touches, x^q + Σ_i image_i a_i = x^q + image @ cell
(`image_offset`, the one formula for it). The checks raise one-line `SceneError`s naming the entry and field.
"""
from __future__ import annotations

import itertools

import numpy as np

from .errors import SceneError, describe, first, row_problem, value_problem
from .tolerances import DEFAULT, Tolerances

EXACT_INTEGER = 2.0 ** 53   # |image| up to here is an exact float64 integer


def image_offset(image: np.ndarray, cell: np.ndarray | None) -> np.ndarray:
    """image @ cell, (M, d): where a contact's copy of q sits relative to x^q (zeros without a cell)."""
    image = np.asarray(image)
    return np.zeros(image.shape) if cell is None else image @ np.asarray(cell, float)


def minimum_image(delta: np.ndarray, lattice: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The minimum image of separations `delta` (M, d) in the lattice (rows a_i; a NaN row: an open axis) and the
    integer shifts s (M, d) used: the image is delta − s @ lattice (so q's copy across the seam is image −s). A
    lower-triangular lattice (Lees–Edwards, LAMMPS tilt) or one with an open axis is reduced last axis first; any
    other full cell by rounding the fractional coordinates (the same shifts for a lower-triangular one: separations
    far shorter than the cell). Without a lattice: delta and zero shifts."""
    shifts = np.zeros(delta.shape, dtype=np.int64)
    if lattice is None:
        return delta, shifts
    if not np.isnan(lattice).any() and np.any(np.triu(lattice, 1) != 0):
        shifts = np.round(np.linalg.solve(lattice.T, delta.T).T).astype(np.int64)
        return delta - shifts @ lattice, shifts
    for i in range(delta.shape[1] - 1, -1, -1):
        if np.isnan(lattice[i, i]):
            continue
        s = np.round(delta[:, i] / lattice[i, i]).astype(np.int64)
        delta = delta - s[:, None] * lattice[i][None, :]
        shifts[:, i] = s
    return delta, shifts


def neighbour_shifts(cell: np.ndarray) -> np.ndarray:
    """e @ cell for the 3^d - 1 integer vectors e ∈ {-1, 0, 1}^d \\ {0}: the neighbouring copies, (3^d - 1, d)."""
    d = cell.shape[0]
    e = np.array([v for v in itertools.product((-1, 0, 1), repeat=d) if any(v)], float)
    return e @ cell


def check_cell(cell, dim: int, source: str, tol: Tolerances = DEFAULT) -> np.ndarray | None:
    """The cell as a (dim, dim) float array (None: not periodic): finite, and its rows a_i right-handed with a
    positive volume, det > input_rtol · Π|a_i|."""
    if cell is None:
        return None
    given = cell.tolist() if isinstance(cell, np.ndarray) else cell
    problem = value_problem(given, (dim, dim))
    if problem is None:
        arr = np.array(given, float)
        bad = row_problem(arr)
        problem = None if bad is None else bad[1]
    if problem is not None:
        raise SceneError(f"{source}: scene: cell: {problem} (the {dim} lattice vectors as rows)")
    det = float(np.linalg.det(arr))
    scale = float(np.prod(np.linalg.norm(arr, axis=1)))
    if not det > tol.input_rtol * scale:
        what = "left-handed (det < 0): swap two rows" if det < -tol.input_rtol * scale else "degenerate"
        raise SceneError(f"{source}: scene: cell: the lattice vectors (rows) span no positive volume, "
                         f"det = {det:.6g} ({what})")
    return arr


def check_images(image, M: int, dim: int, cell, source: str, contact_name) -> np.ndarray:
    """The images as an (M, dim) int64 array (zeros when None): integer-valued, and zero without a cell."""
    if image is None:
        return np.zeros((M, dim), dtype=np.int64)
    arr = np.asarray(image)
    if arr.dtype.kind not in "fiu" or arr.shape != (M, dim):
        raise SceneError(f"{source}: contacts: image: must be {M}x{dim} integers, got {arr.dtype} {arr.shape}")
    flat = arr.astype(float).reshape(M, dim)
    bad = row_problem(flat)
    if bad is not None:
        raise SceneError(f"{source}: {contact_name(bad[0])}: image: {bad[1]}")
    wrong = np.any((flat != np.round(flat)) | (np.abs(flat) > EXACT_INTEGER), axis=1)
    if wrong.any():
        c = first(wrong)
        raise SceneError(f"{source}: {contact_name(c)}: image: must be {dim} integers, got {describe(flat[c].tolist())}")
    out = flat.astype(np.int64)
    if cell is None and np.any(out):
        c = first(np.any(out != 0, axis=1))
        raise SceneError(f"{source}: {contact_name(c)}: image: {out[c].tolist()} is not zero but the scene has no "
                         "cell (give `cell`, the lattice vectors as rows)")
    return out


def check_points(scene, contact_name) -> None:
    """In a periodic scene every contact point must lie between x^p and q's copy x^q + image @ cell: the contact
    plane separates them, n·r^pq >= 0 >= n·r^qp, and no neighbouring copy of p or q is nearer the point than
    the two its image names (minimum image), each within input_rtol·|b^pq|. A wrong image fails one of these."""
    if scene.cell is None or scene.n_contacts == 0:
        return
    r_pq, r_qp, n = scene.r_pq, scene.r_qp, scene.normal
    slack = scene.tol.input_rtol * np.linalg.norm(scene.branch, axis=1)
    out_p, out_q = np.sum(n * r_pq, axis=1), -np.sum(n * r_qp, axis=1)
    bad = (out_p < -slack) | (out_q < -slack)
    if bad.any():
        c = first(bad)
        raise SceneError(f"{scene.source}: {contact_name(c)}: point: not between x^p and q's copy x^q + image·cell "
                         f"(image {scene.image[c].tolist()}): n·(point - x^p) = {out_p[c]:.6g} and "
                         f"n·(x^q' - point) = {out_q[c]:.6g} must both be >= 0")
    shifts = neighbour_shifts(scene.cell)
    for side, r in (("p", r_pq), ("q", r_qp)):
        other = np.linalg.norm(r[:, None, :] - shifts[None], axis=2)        # (M, 3^d - 1)
        nearer = other.min(axis=1) < np.linalg.norm(r, axis=1) - slack
        if nearer.any():
            c = first(nearer)
            raise SceneError(f"{scene.source}: {contact_name(c)}: point: nearer another copy of {side} than the one "
                             f"image {scene.image[c].tolist()} names ({other[c].min():.6g} < "
                             f"{np.linalg.norm(r[c]):.6g}): check the image")


def tile(scene, reps) -> object:
    """The periodic `scene` repeated reps_i times along each lattice vector (a supercell with rows reps_i a_i):
    particle p of copy t sits at x^p + t @ cell, and a contact (p, q, image e) of copy t touches q's copy
    t + e, folded into the supercell with the image floor((t + e) / reps). The same packing, N·Π reps particles."""
    from dataclasses import replace

    if scene.cell is None:
        raise ValueError(f"{scene.source}: tile needs a periodic scene (a cell)")
    d = scene.dim
    reps = np.broadcast_to(np.asarray(reps, dtype=np.int64), (d,))
    copies = np.array(list(itertools.product(*(range(r) for r in reps))), dtype=np.int64)   # (T, d)
    T, N, M = len(copies), scene.n_particles, scene.n_contacts
    flat = lambda t: np.ravel_multi_index(tuple(t.T), tuple(reps))                          # noqa: E731
    shift = copies @ scene.cell                                                              # (T, d)
    target = copies[:, None, :] + scene.image[None]                                          # (T, M, d)
    new_image, where = np.divmod(target, reps)
    contact = {key: np.tile(getattr(scene, key), (T,) + (1,) * (getattr(scene, key).ndim - 1))
               for key in ("normal", "curvature_p", "curvature_q", "curvature_sum", "force", "moment", "k", "alpha", "mu",
                           "rolling")}
    names = tuple(f"{name}@{'.'.join(map(str, t))}" for t in copies for name in scene.names)
    per_particle = lambda a: None if a is None else np.tile(a, (T,) + (1,) * (a.ndim - 1))  # noqa: E731
    return replace(scene, names=names, x=(scene.x[None] + shift[:, None]).reshape(T * N, d),
                   p=(flat(copies)[:, None] * N + scene.p[None]).ravel(),
                   q=(flat(where.reshape(-1, d)).reshape(T, M) * N + scene.q[None]).ravel(),
                   point=(scene.point[None] + shift[:, None]).reshape(T * M, d), image=new_image.reshape(T * M, d),
                   state=tuple(scene.state) * T, load=per_particle(scene.load),
                   load_moment=per_particle(scene.load_moment), mass=per_particle(scene.mass),
                   inertia=per_particle(scene.inertia), fixed=per_particle(scene.fixed),
                   cell=reps[:, None] * scene.cell, title=f"{scene.title} tiled {'x'.join(map(str, reps))}",
                   **contact)
