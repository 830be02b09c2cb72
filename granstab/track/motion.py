"""Between two frames, particles matched by name: the non-affine displacement D²min (Falk & Langer, PRE 57, 7192,
1998) and the contacts made, broken and slid.

D²min of particle i from frame t to t + W: its neighbours j are the particles within `radius` of i at t (through
the cell's images in a periodic frame), Δr_ij(s) the vector from i to j at frame s, and

    D²min_i = min_X Σ_j |Δr_ij(t+W) − X Δr_ij(t)|²,   X = B A⁻¹,  A = Σ_j Δr(t) Δr(t)ᵀ,  B = Σ_j Δr(t+W) Δr(t)ᵀ,

not normalised (length² units). In a periodic frame Δr_ij(t) is the minimum image in the cell of t, and Δr_ij(t+W)
the image of j at t+W nearest to Δr_ij(t) in the cell of t+W (which may differ: Lees–Edwards shear, a flipped
tilt), so that a pair that crosses the seam keeps its vector; this assumes that no pair moves by half a cell
relative to each other within a window. NaN: i absent at t+W, or its neighbours present at both frames span less
than d dimensions.
"""
from __future__ import annotations

import numpy as np

from ..model.periodic import minimum_image


def pair_vectors(x: np.ndarray, i: np.ndarray, j: np.ndarray, cell: np.ndarray | None,
                 near: np.ndarray | None = None) -> np.ndarray:
    """x[j] − x[i] (P, d); with a cell: the image nearest to `near` (P, d), or the minimum image without it."""
    raw = x[j] - x[i]
    if near is None:
        return minimum_image(raw, cell)[0]
    return near + minimum_image(raw - near, cell)[0]


def neighbours(x: np.ndarray, radius: float, cell: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j), i ≠ j, with |Δr_ij| ≤ radius (through the images of a cell), each ordered pair once."""
    from scipy.spatial import cKDTree
    N, d = x.shape
    if cell is None:
        pairs = cKDTree(x).query_pairs(radius, output_type="ndarray")
    else:                                     # the cell's images in {−1, 0, 1}^d: a radius under half the cell
        shifts = np.stack(np.meshgrid(*[[-1, 0, 1]] * d, indexing="ij"), axis=-1).reshape(-1, d) @ cell
        images = (x[None] + shifts[:, None]).reshape(-1, d)
        found = cKDTree(images).query_ball_point(x, radius, return_sorted=False)
        sizes = np.array([len(f) for f in found])
        pairs = np.stack([np.repeat(np.arange(N), sizes), np.concatenate(found).astype(np.int64) % N], axis=1) \
            if sizes.sum() else np.zeros((0, 2), np.int64)
        pairs = np.unique(pairs[pairs[:, 0] < pairs[:, 1]], axis=0)
    both = np.concatenate([pairs, pairs[:, ::-1]])
    return both[:, 0], both[:, 1]


def d2min(x0: np.ndarray, x1: np.ndarray, present: np.ndarray, radius: float, cell0=None, cell1=None) -> np.ndarray:
    """D²min (N,) of each particle from positions x0 (frame t) to x1 (frame t + W, the same particle in the same
    row; rows with present False are absent at t + W), neighbours within `radius` at t (module docstring)."""
    N, d = x0.shape
    i, j = neighbours(x0, radius, cell0)
    keep = present[i] & present[j]
    i, j = i[keep], j[keep]
    r0 = pair_vectors(x0, i, j, cell0)
    r1 = pair_vectors(x1, i, j, cell1, near=r0)
    A = np.zeros((N, d, d))
    B = np.zeros((N, d, d))
    np.add.at(A, i, r0[:, :, None] * r0[:, None, :])
    np.add.at(B, i, r1[:, :, None] * r0[:, None, :])
    scale = np.trace(A, axis1=1, axis2=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        spans = (np.abs(np.linalg.det(A)) > 1e-10 * (scale / d) ** d) & (scale > 0)
    X = np.full((N, d, d), np.nan)
    X[spans] = np.linalg.solve(A[spans], np.swapaxes(B[spans], 1, 2)).swapaxes(1, 2)   # B A⁻¹, A symmetric
    residual = r1 - np.einsum("pab,pb->pa", X[i], r0)
    out = np.bincount(i, weights=np.sum(residual * residual, axis=1), minlength=N)
    out[~spans | ~present] = np.nan
    return out


def contact_keys(names: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """One string key a contact, the same whichever particle is p: 'a|b' with a < b."""
    a, b = names[p].astype(str), names[q].astype(str)
    low, high = np.where(a < b, a, b), np.where(a < b, b, a)
    return np.char.add(np.char.add(low, "|"), high)


def contact_changes(names: np.ndarray, before: dict, after: list) -> dict:
    """Per particle of frame t (`names`): contacts made and broken from t to t + W, and contacts of t still there at
    t + W that were at yield (sliding) in any frame of (t, t + W]. before, after[k]: {"key": contact_keys,
    "a", "b": the two names, "sliding": bool} of frame t and of the frames t+1 … t+W."""
    end = after[-1]
    broken = ~np.isin(before["key"], end["key"])
    made = ~np.isin(end["key"], before["key"])
    slid_keys = np.unique(np.concatenate([f["key"][f["sliding"]] for f in after]))
    slid = ~broken & np.isin(before["key"], slid_keys)
    order = np.argsort(names)

    def per_particle(a, b, mask):
        ends = np.concatenate([a[mask], b[mask]])
        where = np.searchsorted(names[order], ends)
        hit = (where < len(names)) & (names[order][np.minimum(where, len(names) - 1)] == ends)
        return np.bincount(order[where[hit]], minlength=len(names)).astype(float)

    made_n, broken_n = per_particle(end["a"], end["b"], made), per_particle(before["a"], before["b"], broken)
    return {"contacts_made": made_n, "contacts_broken": broken_n, "contacts_changed": made_n + broken_n,
            "contacts_slid": per_particle(before["a"], before["b"], slid),
            "counts": {"made": int(made.sum()), "broken": int(broken.sum()), "slid": int(slid.sum())}}
