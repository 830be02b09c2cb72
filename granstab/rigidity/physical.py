"""The physical model: the rank and null space of the compatibility matrix at the actual geometry.

C (mechanics/compatibility.py) is split into the connected components of its body graph (bodies joined by a
contact); a body without contacts is d + r free dofs with no linear algebra. σ_max of C is bounded by
‖C‖₂ ≤ √(‖C‖₁‖C‖_∞) (`norm_bound`, cheap, at most √K above it) and every rank tolerance is relative to it, the
same rule on both paths: σ counted zero when σ ≤ TOL_RULE·max(K, n)·ε·σ̄ (numpy's matrix_rank rule times 10).
- A block of up to DENSE_MAX columns: one dense SVD. All dense work runs on one BLAS thread (solve/threads.py: a
  two-thread pool on a busy machine waits for a core at every call).
- A larger block, the sparse path (`_null_sparse`): block inverse iteration with one sparse LU of CᵀC + δI
  (δ = SHIFT·σ̄², minimum-degree ordering, symmetric mode), STEPS steps from `start` + MARGIN vectors (the pebble
  game's floppy count where it was played, the physical nullity never being below the generic one, else
  Maxwell's n - K; plus the free spins, which the game counts constrained), then PROJECTIONS steps of the projection
  X - (CᵀC + δI)⁻¹Cᵀ(CX) (which removes the √ε error of working with CᵀC), then a thin SVD of C X: its singular
  values are C's on that subspace with absolute error ~ε·σ̄, not the √ε·σ̄ of CᵀC's Ritz values. The vectors
  are doubled (and the iteration restarted) until the subspace holds MARGIN/2 clearly non-zero σ.
Either way the gap σ_rank / σ_rank+1 (the smallest non-zero over the largest zero) says how clearly the rank is
resolved. The null vectors are the floppy modes (trivial ones included); the self-stresses are K - rank.

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
from .bodybar import BodyBar

DENSE_MAX = 600      # columns of a block solved by dense SVD; larger ones take the sparse path
TOL_RULE = 10.0      # rank tolerance TOL_RULE·max(K, n)·ε·σ̄: numpy's rule with a margin for σ̄ being a bound
SHIFT = 1e-12        # δ = SHIFT·σ̄²: σ above 1e-5·σ̄ is damped ≥ 100x a step against the null space
MARGIN = 16          # vectors beyond the expected nullity in the sparse path
PROJECTIONS = 2      # projection steps X - (CᵀC + δI)⁻¹Cᵀ(CX), each computed from C
STEPS = 2            # inverse iteration steps before the projection: the margin's modes (σ_k+1² >> δ) are damped
                     # by δ/σ_k+1² a step, the projection damps them once more, and the SVD of C X decides
NEAR_RTOL = 1e-6     # σ in (tolerance, NEAR_RTOL·σ̄]: counted non-zero, but floppy to a data file's precision
RIGID_RTOL = 1e-7    # strain of a contact counted as zero: sqrt(ε)-level, far above an accurate null vector's


@dataclass(frozen=True, eq=False)
class Physical:
    """rank, nullity, self_stresses; null: per connected block (its columns, its orthonormal null vectors); gap (smallest
    over the blocks of σ_rank / σ_rank+1, inf when no block has both); tolerance (largest rank tolerance used);
    sigma_max_bound; strain (M,) each contact's relative strain; rigid_contact (M,) bool; component (N_b,)
    cluster label (-1 none); strain_gap; paths: blocks by the dense and the sparse path; nearly_floppy: σ counted
    non-zero but below NEAR_RTOL·σ̄ (a lower bound on the sparse path: only its subspace's σ are seen)."""

    rank: int
    nullity: int
    self_stresses: int
    null: list
    gap: float
    tolerance: float
    sigma_max_bound: float
    strain: np.ndarray
    rigid_contact: np.ndarray
    component: np.ndarray
    strain_gap: dict
    paths: dict
    nearly_floppy: int


def norm_bound(C: sp.spmatrix) -> float:
    """σ̄ = √(‖C‖₁‖C‖_∞) ≥ ‖C‖₂ (Hölder)."""
    if C.nnz == 0:
        return 0.0
    A = abs(C)
    return float(np.sqrt(A.sum(axis=0).max() * A.sum(axis=1).max()))


def physical(bodybar: BodyBar, length: float, free_per_body: np.ndarray | None = None) -> Physical:
    """Rank, null space, self-stress count and rigid clusters of a body-bar frame; `length` L of the scaled dofs;
    `free_per_body` the pebble game's free pebbles (the sparse path's start, else Maxwell's count n - K; the free
    spins added)."""
    C, row_contact = compatibility_matrix(bodybar.p, bodybar.q, bodybar.r_pq, bodybar.r_qp, bodybar.normal, bodybar.sliding,
                                          bodybar.rolling, bodybar.n_bodies, length)
    per, nb = bodybar.per, bodybar.n_bodies
    _, body_comp = connected_components(sp.coo_matrix((np.ones(len(bodybar.p)), (bodybar.p, bodybar.q)), shape=(nb, nb)),
                                        directed=False)
    body_comp = np.where(np.bincount(bodybar.p, minlength=nb) + np.bincount(bodybar.q, minlength=nb) > 0, body_comp, -1)
    sigma = norm_bound(C)
    spins = free_spins(bodybar)
    cols_of = _groups(np.repeat(body_comp, per))
    rows_of = _groups(body_comp[bodybar.p][row_contact])
    contacts_of = _groups(body_comp[bodybar.p])
    E = pair_strain_operator(bodybar, length)
    blocks, rank, gap, tol, near = [], 0, np.inf, 0.0, 0
    strain = np.zeros(len(bodybar.p))
    paths = {"dense": 0, "sparse": 0, "free_bodies": int(np.sum(body_comp < 0))}
    if -1 in cols_of:
        blocks.append((cols_of[-1], np.eye(len(cols_of[-1]))))
    for c, cols in cols_of.items():
        if c < 0:
            continue
        block = C[rows_of[c]][:, cols]
        mine_b = body_comp == c
        start = (free_per_body[mine_b].sum() if free_per_body is not None else
                 max(len(cols) - len(rows_of[c]), per)) + spins[mine_b].sum()
        with blas_threads(1):
            r, g, t, V, nf = _null_dense(block.toarray(), sigma) if len(cols) <= DENSE_MAX else \
                _null_sparse(block, sigma, int(start))
        paths["dense" if len(cols) <= DENSE_MAX else "sparse"] += 1
        rank, gap, tol, near = rank + r, min(gap, g), max(tol, t), near + nf
        blocks.append((cols, V))
        mine = contacts_of[c]
        strain[mine] = contact_strain(E, mine, cols, V, per) / (1 + np.linalg.norm(bodybar.branch[mine], axis=1) / length)
    rigid = strain <= RIGID_RTOL
    counted, moving = strain[rigid], strain[~rigid]
    strain_gap = {"largest_counted_rigid": float(counted.max()) if counted.size else None,
                  "smallest_counted_moving": float(moving.min()) if moving.size else None, "rtol": RIGID_RTOL}
    return Physical(rank, C.shape[1] - rank, C.shape[0] - rank, blocks, gap, tol, sigma, strain, rigid,
                    _clusters(bodybar, rigid), strain_gap, paths, near)


def free_spins(bodybar: BodyBar, rtol: float = 1e-9) -> np.ndarray:
    """(N_b,) rotations each body can make in place (r where every contact of it slides, has no rolling
    stiffness and a normal through its reference point, |r × n| <= rtol·|r|; else 0): the sparse path adds them
    to its start, since a pebble game counts them constrained."""
    def through(r):
        cross = np.cross(r, bodybar.normal) if bodybar.dim == 3 else r[:, 0] * bodybar.normal[:, 1] - r[:, 1] * bodybar.normal[:, 0]
        return np.abs(cross).reshape(len(r), -1).max(axis=1) <= rtol * np.linalg.norm(r, axis=1)

    free = bodybar.sliding & ~bodybar.rolling
    blocked = np.zeros(bodybar.n_bodies, bool)
    blocked[bodybar.p[~(free & through(bodybar.r_pq))]] = True
    blocked[bodybar.q[~(free & through(bodybar.r_qp))]] = True
    return np.where(blocked, 0, bodybar.per - bodybar.dim)


def _groups(labels: np.ndarray) -> dict:
    """{label: the indices with that label, ascending}, in one sort."""
    order = np.argsort(labels, kind="stable")
    found, start = np.unique(labels[order], return_index=True)
    return {int(c): ix for c, ix in zip(found, np.split(order, start[1:]))}


def _resolved(s: np.ndarray, tol: float, n: int, sigma: float):
    """rank, gap σ_rank/σ_rank+1 (inf when all or none are zero) and the nearly floppy count of singular values s
    (descending) of n columns; the columns beyond len(s) are zero."""
    rank = int(np.sum(s > tol))
    near = int(np.sum((s > tol) & (s <= NEAR_RTOL * sigma)))
    if rank == 0 or rank == n:
        return rank, np.inf, near
    below = s[rank] if rank < len(s) else 0.0
    return rank, float(s[rank - 1] / below) if below > 0 else np.inf, near


def _null_dense(block: np.ndarray, sigma: float):
    """rank, gap, tolerance and the null vectors (n, n - rank) of one dense block, by SVD."""
    K, n = block.shape
    tol = TOL_RULE * max(K, n) * np.finfo(float).eps * sigma
    _, s, Vt = la.svd(block, full_matrices=True, lapack_driver="gesdd")
    rank, gap, near = _resolved(s, tol, n, sigma)
    return rank, gap, float(tol), _canonical(Vt[rank:].T), near


def _null_sparse(block: sp.csr_matrix, sigma: float, start: int):
    """rank, gap, tolerance and null vectors of a large block (the module's sparse path)."""
    K, n = block.shape
    tol = TOL_RULE * max(K, n) * np.finfo(float).eps * sigma
    A = (block.T @ block).tocsc()
    lu = spla.splu((A + SHIFT * sigma ** 2 * sp.identity(n, format="csc")).tocsc(), permc_spec="MMD_AT_PLUS_A",
                   diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    k = min(n, start + MARGIN)
    rng = np.random.default_rng(0)
    while True:
        X = np.asfortranarray(rng.standard_normal((n, k)))          # SuperLU solves column by column
        for _ in range(STEPS):
            X = lu.solve(X)
            X /= np.linalg.norm(X, axis=0)
        for _ in range(PROJECTIONS):
            X -= lu.solve(np.asfortranarray(block.T @ (block @ X)))
        X, _ = np.linalg.qr(X)
        _, s, Wt = la.svd(np.asarray(block @ X), full_matrices=False)
        zero = int(np.sum(s <= tol))
        if k - zero >= MARGIN // 2 or k == n:
            break
        k = min(n, 2 * k)
    rank, gap, near = _resolved(np.r_[np.full(n - k, np.inf), s], tol, n, sigma)
    return rank, gap, float(tol), _canonical(X @ Wt[k - zero:].T), near


def _canonical(V: np.ndarray) -> np.ndarray:
    """Each vector's sign fixed by its largest entry (positive), so results do not depend on LAPACK's choice."""
    if V.size == 0:
        return V
    idx = np.argmax(np.abs(V), axis=0)
    return V * np.sign(V[idx, np.arange(V.shape[1])])


def pair_strain_matrix(bodybar: BodyBar, length: float):
    """E (M, d + r, 2(d + r)): the rigid-pair residual [du^q - du^p - dθ^p × b, L(dθ^q - dθ^p)] in scaled dofs."""
    d, per, M = bodybar.dim, bodybar.per, len(bodybar.p)
    r = per - d
    E = np.zeros((M, per, 2 * per))
    E[:, :d, :d] = -np.eye(d)
    E[:, :d, d:per] = -rotate_matrix(bodybar.branch) / length
    E[:, :d, per:per + d] = np.eye(d)
    E[:, d:, d:per] = -np.eye(r)
    E[:, d:, per + d:] = np.eye(r)
    return E


def pair_strain_operator(bodybar: BodyBar, length: float) -> sp.csr_matrix:
    """The E of every contact as one sparse (M·(d + r), N_b·(d + r)) matrix, contact by contact."""
    per, M = bodybar.per, len(bodybar.p)
    E = pair_strain_matrix(bodybar, length)
    local = np.concatenate([bodybar.p[:, None] * per + np.arange(per), bodybar.q[:, None] * per + np.arange(per)], axis=1)
    cols = np.broadcast_to(local[:, None, :], E.shape)
    rows = np.broadcast_to(np.arange(M * per).reshape(M, per, 1), E.shape)
    return sp.csr_matrix((E.ravel(), (rows.ravel(), cols.ravel())), shape=(M * per, bodybar.n_bodies * per))


def contact_strain(E: sp.csr_matrix, contacts: np.ndarray, cols: np.ndarray, null: np.ndarray, per: int,
                   chunk: int = 256) -> np.ndarray:
    """Per contact |E_pq N|_F: how far the floppy modes (null (len(cols), f), on the block's columns `cols`) move
    its two bodies relative to each other, in chunks of modes."""
    rows = (contacts[:, None] * per + np.arange(per)).ravel()
    Eb = E[rows][:, cols]
    total = np.zeros(len(rows))
    for j in range(0, null.shape[1], chunk):
        total += np.sum(np.asarray(Eb @ null[:, j:j + chunk]) ** 2, axis=1)
    return np.sqrt(total.reshape(-1, per).sum(axis=1))


def _clusters(bodybar: BodyBar, rigid: np.ndarray) -> np.ndarray:
    """Cluster label per body: the connected components of the rigid contacts with >= 2 bodies, -1 otherwise."""
    n = bodybar.n_bodies
    graph = sp.coo_matrix((np.ones(int(rigid.sum())), (bodybar.p[rigid], bodybar.q[rigid])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label, minlength=n)
    return np.where(size[label] >= 2, label, -1)
