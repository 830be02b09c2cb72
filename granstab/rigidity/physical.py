"""The physical model: the rank and null space of the compatibility matrix at the actual geometry.

C (mechanics/compatibility.py) is split into the connected components of its body graph (bodies joined by a
contact). A block of up to DENSE_MAX columns: one dense SVD, rank tolerance (numpy's matrix_rank rule)
σ > max(K, n)·ε·σ_max. A larger block: the sparse path, the lowest eigenpairs of CᵀC by block inverse iteration
(one sparse LU of CᵀC + δI, δ = 1e-14·σ_max²) on as many vectors as the pebble game's floppy count plus 16 (the physical nullity is never below the
generic one: rank can only drop at special geometry), doubled until
the last is clearly non-zero; tolerance σ² ≤ max(K, n)·ε·σ_max² (CᵀC squares the conditioning, so the sparse
path resolves σ down to √(max(K, n)ε)·σ_max, about 1e-6 of it). Either way the gap σ_rank / σ_rank+1 says how
clearly the rank is resolved. The null vectors are the floppy modes (trivial ones included); the self-stresses
are counted, K - rank.

Rigid clusters. Bodies p and q move rigidly together in a velocity Ũ = [du, L dθ] when du^q - du^p - dθ^p × b^pq = 0
and dθ^q - dθ^p = 0 (b^pq the branch vector to q's copy). Every allowed velocity is a combination of the null
vectors N, so p and q are rigidly together iff the (d + r) × f "strain" E_pq N of the contact vanishes: its norm,
relative to (1 + |b|/L), below `RIGID_RTOL`. Rigid contacts link their bodies; the clusters are the connected
components of that graph (the relation is transitive: rigid with p and with q makes rigid with both).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from ..mechanics.compatibility import compatibility_matrix
from ..model.vec import rotate_matrix
from ..solve.threads import blas_threads
from .frame import Frame
from .pebble import pebble_game

DENSE_MAX = 600      # columns of a block solved by dense SVD; larger ones take the sparse path
RIGID_RTOL = 1e-7     # strain of a contact counted as zero: sqrt(ε)-level, well above an SVD's ε·κ null vectors


@dataclass(frozen=True, eq=False)
class Physical:
    """rank, nullity, self_stresses; null: per connected block (its columns, its orthonormal null vectors); gap (smallest over the blocks of
    σ_rank / σ_rank+1, inf when a block has full rank); tolerance (largest rank tolerance used); strain (M,) each
    contact's relative strain; rigid_contact (M,) bool; component (N_b,) cluster label (-1 none); seconds."""

    rank: int
    nullity: int
    self_stresses: int
    null: list
    gap: float
    tolerance: float
    strain: np.ndarray
    rigid_contact: np.ndarray
    component: np.ndarray
    strain_gap: dict


def physical(frame: Frame, length: float) -> Physical:
    """Rank, null space, self-stress count and rigid clusters of a frame; `length` L of the scaled dofs."""
    C, row_contact = compatibility_matrix(frame.p, frame.q, frame.r_pq, frame.r_qp, frame.normal, frame.sliding,
                                frame.rolling, frame.n_bodies, length)
    per = frame.per
    n_comp, body_comp = connected_components(
        sp.coo_matrix((np.ones(len(frame.p)), (frame.p, frame.q)), shape=(frame.n_bodies,) * 2), directed=False)
    col_comp = np.repeat(body_comp, per)
    row_comp = body_comp[frame.p][row_contact]
    contact_comp = body_comp[frame.p]
    generic = _generic_nullity(frame, body_comp, n_comp)
    blocks, rank, gap, tol = [], 0, np.inf, 0.0
    strain = np.zeros(len(frame.p))
    for c in range(n_comp):
        cols = np.flatnonzero(col_comp == c)
        block = C[np.flatnonzero(row_comp == c)][:, cols]
        with blas_threads(len(cols)):
            r, g, t, V = _null_block(block.toarray()) if len(cols) <= DENSE_MAX else _null_sparse(block, generic[c])
        rank, gap, tol = rank + r, min(gap, g), max(tol, t)
        blocks.append((cols, V))
        mine = np.flatnonzero(contact_comp == c)
        where = np.full(C.shape[1], -1)
        where[cols] = np.arange(len(cols))
        strain[mine] = contact_strain(frame, mine, V, where, length)
    rigid = strain <= RIGID_RTOL
    component = _clusters(frame, rigid)
    counted = strain[rigid]
    moving = strain[~rigid]
    strain_gap = {"largest_counted_rigid": float(counted.max()) if counted.size else None,
                  "smallest_counted_moving": float(moving.min()) if moving.size else None, "rtol": RIGID_RTOL}
    return Physical(rank, C.shape[1] - rank, C.shape[0] - rank, blocks, gap, tol, strain, rigid, component,
                    strain_gap)


def _generic_nullity(frame: Frame, body_comp: np.ndarray, n_comp: int) -> np.ndarray:
    """The pebble game's floppy count of every connected block (near-linear; the sparse path's start)."""
    bars = frame.bars
    order = np.repeat(np.arange(len(bars)), bars)
    game = pebble_game(frame.n_bodies, frame.p[order], frame.q[order], frame.per, components=False)
    return np.bincount(body_comp, weights=game.free_per_body, minlength=n_comp).astype(int)


def _null_block(block: np.ndarray):
    """rank, gap σ_rank/σ_rank+1, tolerance and the null vectors (n, n - rank) of one dense block, by SVD."""
    K, n = block.shape
    if K == 0:
        return 0, np.inf, 0.0, np.eye(n)
    _, s, Vt = la.svd(block, full_matrices=True, lapack_driver="gesdd")
    tol = max(K, n) * np.finfo(float).eps * s[0]
    rank = int(np.sum(s > tol))
    gap = np.inf if rank == len(s) and rank == n else (s[rank - 1] / s[rank] if rank < len(s) and s[rank] > 0
                                                       else np.inf)
    null = Vt[rank:].T
    return rank, float(gap), float(tol), _canonical(null)


def _null_sparse(block: sp.csr_matrix, start: int):
    """rank, gap, tolerance (on σ) and null vectors of a large block: block inverse iteration on CᵀC + δI (one
    sparse LU) from `start` + 16 vectors (the pebble game's count, a lower bound of the nullity), then
    Rayleigh–Ritz. A null direction grows by 1/δ a step, a mode with σ² = λ by 1/(λ + δ): for
    σ above 1e-5·σ_max three steps damp it below 1e-12."""
    K, n = block.shape
    A = (block.T @ block).tocsc()
    top = float(abs(A).sum(axis=0).max())                  # ‖CᵀC‖₁ >= σ_max²
    tol = max(K, n) * np.finfo(float).eps * top
    lu = spla.splu((A + 1e-14 * top * sp.identity(n, format="csc")).tocsc())
    k = min(n, start + 16)
    while True:
        X = np.random.default_rng(0).standard_normal((n, k))
        for _ in range(3):
            X = lu.solve(X)
            X /= np.linalg.norm(X, axis=0)
        X, _ = np.linalg.qr(X)
        lam, W = la.eigh(X.T @ (A @ X))
        zero = int(np.sum(lam <= tol))
        if zero < k or k == n:
            break
        k = min(n, 2 * k)
    floor = np.finfo(float).eps * top                       # the Ritz values' own round-off
    gap = float(np.sqrt(lam[zero] / max(lam[zero - 1], floor))) if 0 < zero < k else np.inf
    return n - zero, gap, float(np.sqrt(tol)), _canonical(X @ W[:, :zero])


def _canonical(V: np.ndarray) -> np.ndarray:
    """Each vector's sign fixed by its largest entry (positive), so results do not depend on LAPACK's choice."""
    if V.size == 0:
        return V
    idx = np.argmax(np.abs(V), axis=0)
    return V * np.sign(V[idx, np.arange(V.shape[1])])


def pair_strain_matrix(frame: Frame, length: float):
    """E (M, d + r, 2(d + r)): the rigid-pair residual [du^q - du^p - dθ^p × b, L(dθ^q - dθ^p)] in scaled dofs."""
    d, per, M = frame.dim, frame.per, len(frame.p)
    r = per - d
    E = np.zeros((M, per, 2 * per))
    E[:, :d, :d] = -np.eye(d)
    E[:, :d, d:per] = -rotate_matrix(frame.branch) / length
    E[:, :d, per:per + d] = np.eye(d)
    E[:, d:, d:per] = -np.eye(r)
    E[:, d:, per + d:] = np.eye(r)
    return E


def contact_strain(frame: Frame, contacts: np.ndarray, null: np.ndarray, where: np.ndarray, length: float):
    """Per contact |E_pq N|_F / (1 + |b|/L): how far the floppy modes move its two bodies relative to each other;
    null (n_block, f) the block's null vectors, where[dof] the dof's row in it."""
    per = frame.per
    E = pair_strain_matrix(frame, length)[contacts]
    p, q = frame.p[contacts], frame.q[contacts]
    idx = np.c_[p[:, None] * per + np.arange(per), q[:, None] * per + np.arange(per)]
    local = null[where[idx]]                                  # (m, 2 per, f)
    res = np.einsum("mij,mjf->mif", E, local)
    return np.sqrt(np.sum(res ** 2, axis=(1, 2))) / (1 + np.linalg.norm(frame.branch[contacts], axis=1) / length)


def _clusters(frame: Frame, rigid: np.ndarray) -> np.ndarray:
    """Cluster label per body: the connected components of the rigid contacts with >= 2 bodies, -1 otherwise."""
    n = frame.n_bodies
    graph = sp.coo_matrix((np.ones(int(rigid.sum())), (frame.p[rigid], frame.q[rigid])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label, minlength=n)
    return np.where(size[label] >= 2, label, -1)
