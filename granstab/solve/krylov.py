"""The sparse path's iterations (sparse.py): a block Krylov solve near the shift with a guard of extra Ritz vectors,
ARPACK in shift-invert mode with its fallbacks, and LOBPCG with a two-level preconditioner (particle blocks and a
coarse space of rigid motions); orthonormal extension of a basis (`extend`) for the Ritz updates (ritz.py)."""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..model.vec import rot_dim, rotate_matrix

if TYPE_CHECKING:
    from .assembled import SparseProblem


DENSE_FALLBACK_MAX_DOF = 4000   # ARPACK failures below this size are solved densely instead


DENSE_FALLBACK_PATIENCE = 300   # ARPACK restarts allowed where the dense fallback exists (tightly clustered spectra,
                                # e.g. a compressed chain in the L/10 metric, took > 3 min for 1,200 dofs otherwise)


NARROW_PATIENCE = 30            # ARPACK restarts of the first, narrow Krylov space (2k + 1) before the wide one: a
                                # cluster wider than it never converges there (a 3D superquadric packing's branches
                                # at yield: 300 restarts, 0.7 s of 372 dofs, then 0.02 s with the wide space)


def _sym(M):
    return 0.5 * (M + M.swapaxes(-1, -2))


def _norms(B: np.ndarray) -> np.ndarray:
    """The column norms of a tall B (n, m) without a temporary (np.linalg.norm squares B first: 4× slower)."""
    return np.sqrt(np.einsum("ij,ij->j", B, B))


REORTH_DROP = 0.2   # extend: one pass suffices where every column kept at least this share of its norm …


REORTH_COND = 0.1   # … and the projected block's Gram matrix has no eigenvalue below this × its largest


def extend(X: np.ndarray, B: np.ndarray, cut: float = 1e-10) -> np.ndarray:
    """Orthonormal columns spanning the part of span(B) outside span(X) (X orthonormal; n × m, n ≫ m): B is projected
    off X (block classical Gram-Schmidt), its columns rescaled and orthonormalised from their Gram matrix (BLAS-3
    only, no Householder QR of n × m); directions below `cut` are dropped. A second pass follows where the first
    can have lost orthogonality: the projection's rounding (~eps of a column's old norm) grows by 1/REORTH_DROP at
    most relative to the new norm, and the orthonormalisation by 1/√REORTH_COND at most, so a single pass leaves
    |XᵀQ| and |QᵀQ - I| within ~15·√m·eps (measured ≤ 3e-14 on 3·10⁴ disks, against ~1e-16 after two passes);
    otherwise (a block mostly inside span(X), as shift-invert makes after a restart, or nearly dependent
    columns) it is projected and orthonormalised twice ("twice is enough")."""
    for _ in range(2):
        C = X.T @ B
        B = B - X @ C
        after = _norms(B)
        before = np.sqrt(after ** 2 + np.einsum("ij,ij->j", C, C))     # ‖B‖² = ‖XᵀB‖² + ‖B - XXᵀB‖²
        B = B / np.maximum(after, 1e-300)
        s, U = np.linalg.eigh(_sym(B.T @ B))
        keep = s > cut * max(s[-1], 1e-300)
        B = B @ (U[:, keep] / np.sqrt(s[keep]))
        if keep.all() and np.all(after >= REORTH_DROP * before) and s[0] >= REORTH_COND * s[-1]:
            break
    return B


@dataclass(frozen=True, eq=False)
class Krylov:
    """_block_near's basis: X (n, m) orthonormal and rigid-free, and G = Xᵀ B X (m, m) with the operator B it was
    built with, as the iteration maintained it (equal to Xᵀ B X to round-off)."""

    X: np.ndarray
    G: np.ndarray


BLOCK_GUARD = 1   # _block_near: Ritz vectors beyond those wanted whose residuals start a cycle …


BLOCK_STEPS = 3   # … block solves per cycle …


BLOCK_CYCLES = 8  # … and restarts before ARPACK takes over


BLOCK_RTOL = 1e-13   # … converged: every residual ‖Bv - θv‖ below this · ‖Hs‖ (ARPACK's tol=0 reaches ~1e-15)


CLUSTER = 0.1   # _block_near: Ritz values within this relative distance (from σ) of the kk-th converge with it


def _cluster_end(theta: np.ndarray, kk: int, sigma: float) -> int:
    """kk, or more where the Ritz values after the kk-th continue its cluster (each within CLUSTER·(θ - σ) of the one
    before, at most 2kk in all): a cluster cut in two converges slowly, as a whole fast."""
    end = min(kk, len(theta))
    while 0 < end < min(2 * kk, len(theta)) and theta[end] - theta[end - 1] <= CLUSTER * (theta[end - 1] - sigma):
        end += 1
    return end


def _block_near(shifted, Bop, sp_: SparseProblem, kk: int, rng) -> tuple | None:
    """The kk lowest eigenpairs of B by restarted block shift-invert Krylov: a cycle starts from the residuals
    Bv - θv of the kk + BLOCK_GUARD lowest Ritz vectors not yet converged, applies (B - σI)⁻¹ to that block BLOCK_STEPS
    times (one block solve each, BLAS-3 on the multifrontal factor, where ARPACK makes one single-vector solve per
    step), then Rayleigh-Ritz on the exact B and a thick restart. With exact solves span{V, (B - σ)⁻¹R} =
    span{V, (B - σ)⁻¹V}. The solves are the factor's float32 ones (Factor.solve(single=True)): a cycle's first
    block, (B - σ)⁻¹ of the residuals, has an error relative to those residuals, so the iteration converges to
    float64 round-off (applied to the Ritz vectors themselves they would stall at ~1e-8), and every eigenvalue and
    residual is computed with the exact B in float64. None if not converged to BLOCK_RTOL after BLOCK_CYCLES (the
    caller then runs ARPACK). Ritz values are upper bounds of the eigenvalues (Cauchy interlacing), each within its
    residual of one; which eigenvalues they are is settled by the caller's inertia count. Also returns the whole
    orthonormal basis and its Rayleigh quotient Xᵀ B X (Krylov: SparseRitz starts from them)."""
    R, n = sp_.R, sp_.n
    w = 2 * kk + BLOCK_GUARD                                          # the widest block (_cluster_end: ≤ 2kk)
    d, cap = R.shape[1], w * (BLOCK_STEPS + 2)                       # the widest basis: kept + new blocks
    X, BV = np.empty((n, d + cap), order="F"), np.empty((n, cap), order="F")   # [R, basis], B·basis: in place,
                                                                      # column slices contiguous (BLAS, no copy)
    X[:, :d] = R
    block = rng.standard_normal((n, kk + BLOCK_GUARD))
    block = extend(R, block - R @ (R.T @ block))
    G, m = _append(X, BV, np.zeros((0, 0)), 0, block, Bop)          # G = basisᵀ B basis, m basis columns
    for _ in range(BLOCK_CYCLES):
        for _ in range(BLOCK_STEPS):
            block = extend(X[:, :d + m], shifted.solve(block, single=True))
            if not block.shape[1] or m + block.shape[1] > cap:
                break
            G, m = _append(X, BV, G, m, block, Bop)
        theta, Y = np.linalg.eigh(_sym(G))
        want = _cluster_end(theta, kk, shifted.sigma)
        top = min(want + BLOCK_GUARD, m)
        keep = min(2 * w, m)                                          # Ritz vectors kept at a restart
        V = X[:, d:d + m] @ Y[:, :top]
        resid = BV[:, :m] @ Y[:, :top] - V * theta[:top]
        res = _norms(resid)
        if res[:want].max(initial=0.0) <= BLOCK_RTOL * sp_.norm:
            return theta[:kk], V[:, :kk], Krylov(X[:, d:d + m], _sym(G))
        rotate(X[:, d:d + m], Y[:, :keep])                            # thick restart on the lowest Ritz vectors,
        rotate(BV[:, :m], Y[:, :keep])                                # in place (no n × keep temporaries)
        m, G = keep, np.diag(theta[:keep])
        active = res > BLOCK_RTOL * sp_.norm
        block = resid[:, active] / res[active]
    return None


ROTATE_ROWS = 65536   # rotate: rows a pass (temporaries of ROTATE_ROWS × keep, ~15 MB)


def rotate(A: np.ndarray, Y: np.ndarray) -> None:
    """A[:, :c] ← A Y (Y: m × c, c ≤ m) in place, ROTATE_ROWS rows at a time: the restart's Ritz vectors without the
    two n × c copies a whole product makes (1.4 GB on 10⁶ disks)."""
    c = Y.shape[1]
    for s in range(0, A.shape[0], ROTATE_ROWS):
        A[s:s + ROTATE_ROWS, :c] = A[s:s + ROTATE_ROWS] @ Y


def _append(X, BV, G, m, block, Bop):
    """Put `block` after the m basis columns of X (after R's d) and B·block in BV (B is applied once per vector;
    restarts rotate it); G grows by the block's rows and columns (B symmetric). Returns (G, m)."""
    b, d = block.shape[1], X.shape[1] - BV.shape[1]
    X[:, d + m:d + m + b], BV[:, m:m + b] = block, Bop.matmat(block)
    C = X[:, d:d + m + b].T @ BV[:, m:m + b]
    return np.block([[G, C[:m]], [C[:m].T, _sym(C[m:])]]), m + b


def _eigsh_near(shifted, Bop, n, kk, tol, maxiter, v0, which: str = "LM"):
    """The kk eigenpairs of B nearest σ by shift-invert ARPACK (which="SA": the kk nearest below σ). If ARPACK
    does not converge in NARROW_PATIENCE restarts (clustered eigenvalues at σ), retry with a larger Krylov space and a round-off tolerance; small problems (at most
    DENSE_FALLBACK_MAX_DOF dofs, where ARPACK gets DENSE_FALLBACK_PATIENCE restarts) then fall back on a dense eigh
    of B, large ones raise a RuntimeError that says so."""
    kk = int(min(kk, n - 2))
    if n <= DENSE_FALLBACK_MAX_DOF:         # a dense eigh of B costs seconds at most: do not wait longer for ARPACK
        maxiter = min(maxiter or 10 * n, DENSE_FALLBACK_PATIENCE)
    OPinv = spla.LinearOperator((n, n), matvec=shifted.solve, dtype=float)
    wide = min(n - 1, max(4 * kk + 1, 40))
    first = min(maxiter or 10 * n, NARROW_PATIENCE)
    attempts = [dict(tol=tol, maxiter=first), dict(tol=tol, ncv=wide, maxiter=maxiter),
                dict(tol=max(tol, 1e-12), ncv=wide, maxiter=maxiter)]
    for options in attempts:
        try:
            lam, V = spla.eigsh(Bop, k=kk, sigma=shifted.sigma, which=which, OPinv=OPinv, v0=v0, **options)
            break
        except spla.ArpackNoConvergence:
            continue
    else:
        if n > DENSE_FALLBACK_MAX_DOF:
            raise RuntimeError(f"shift-invert ARPACK did not converge for {kk} eigenpairs near σ = "
                               f"{shifted.sigma:.3g} ({n} dofs); try method='lobpcg'")
        B = Bop.matmat(np.eye(n))
        lam, V = np.linalg.eigh(0.5 * (B + B.T))
        dist = np.abs(lam - shifted.sigma) if which == "LM" else np.where(lam < shifted.sigma, shifted.sigma - lam,
                                                                           np.inf)
        near = np.sort(np.argsort(dist, kind="stable")[:kk])
        lam, V = lam[near], V[:, near]
    order = np.argsort(lam)
    return lam[order], V[:, order]


def particle_blocks(A: sp.csr_matrix, per: int) -> np.ndarray:
    """The per×per diagonal blocks (N, per, per) of a matrix over particle dofs."""
    N = A.shape[0] // per
    coo = A.tocoo()
    same = coo.row // per == coo.col // per
    blk = np.zeros((N, per, per))
    np.add.at(blk, (coo.row[same] // per, coo.row[same] % per, coo.col[same] % per), coo.data[same])
    return blk


class TwoLevel:
    """Smoothed-aggregation two-level preconditioner ≈ (Hs + τI)⁻¹ for LOBPCG, memory O(contacts).

    Aggregates: particles binned into boxes of about `aggregate` particles. Coarse space: the d + r rigid motions
    of each aggregate (in scaled dofs, about its centroid), smoothed once by damped block-Jacobi
    (P = (I - ω D⁻¹A) P₀, ω = 4/(3ρ(D⁻¹A))); coarse matrix PᵀAP factorised by SuperLU. Smoother: damped
    block-Jacobi on the particle blocks (|eigenvalues| floored, so it is positive definite). One symmetric V-cycle:
    pre-smooth, coarse correction, post-smooth.
    """

    def __init__(self, sp_: SparseProblem, aggregate: int = 16, tau_rel: float = 1e-6):
        scene = sp_.scene
        d, r, N = scene.dim, rot_dim(scene.dim), scene.n_particles
        per = d + r
        n = sp_.n
        # the elastic mechanical stiffness Hm = Bᵀ F B (eq:Hm) is positive semi-definite with the rigid motions
        # as null space, so Hm + τI is SPD whatever the geometric terms do: the preconditioner stays SPD even for
        # an unstable (indefinite) sym(𝓗)
        A = (0.5 * (sp_.Hm + sp_.Hm.T) + tau_rel * sp_.norm * sp.identity(n, format="csr")).tocsr()
        blk = particle_blocks(A, per)
        lam_b, V_b = np.linalg.eigh(blk)
        floor = 1e-6 * max(float(np.abs(lam_b).max()), 1e-300)
        self.Dinv = (V_b / np.maximum(np.abs(lam_b), floor)[:, None, :]) @ np.swapaxes(V_b, 1, 2)
        # aggregates: boxes of side h with ~aggregate particles each
        x = scene.x
        lo, hi = x.min(axis=0), x.max(axis=0)
        h = max(float(np.prod(hi - lo + 1e-12) * aggregate / max(N, 1)) ** (1.0 / d), 1e-300)
        cell = np.floor((x - lo) / h).astype(np.int64)
        _, agg = np.unique(cell, axis=0, return_inverse=True)
        agg = agg.reshape(-1)
        n_agg = int(agg.max()) + 1
        centre = np.zeros((n_agg, d))
        np.add.at(centre, agg, x)
        centre /= np.bincount(agg, minlength=n_agg)[:, None]
        # tentative prolongator: rigid motions of each aggregate, rows (particle dofs), cols (aggregate modes)
        loc = np.zeros((N, per, per))
        loc[:, :d, :d] = np.eye(d)
        loc[:, :d, d:] = rotate_matrix(x - centre[agg])
        loc[:, d:, d:] = np.eye(r)
        loc = np.linalg.solve(sp_.metric.blocks, loc)                  # D⁻¹: the metric's dofs
        rows = np.broadcast_to((np.arange(N) * per)[:, None, None] + np.arange(per)[None, :, None], loc.shape)
        cols = np.broadcast_to((agg * per)[:, None, None] + np.arange(per)[None, None, :], loc.shape)
        P0 = sp.csr_matrix((loc.reshape(-1), (rows.reshape(-1), cols.reshape(-1))), shape=(n, n_agg * per))
        # damped block-Jacobi smoothing of the prolongator; ρ(D⁻¹A) by power iteration
        rng = np.random.default_rng(0)
        v = rng.standard_normal(n)
        rho = 1.0
        for _ in range(15):
            w = self._jacobi(A @ v)
            rho = float(np.linalg.norm(w) / np.linalg.norm(v))
            v = w / np.linalg.norm(w)
        self.omega = 1.0 / rho
        AP0 = (A @ P0).tocsr()
        P = P0 - (4.0 / (3.0 * rho)) * self._jacobi_sparse(AP0, per)
        self.P = P.tocsr()
        Ac = (self.P.T @ (A @ self.P)).tocsc()
        self.coarse = spla.splu(Ac)
        self.A = A
        self.n_coarse = Ac.shape[0]
        self.nnz = int(A.nnz + self.P.nnz + self.coarse.nnz)

    def _jacobi(self, b):
        N, per = self.Dinv.shape[:2]
        return (self.Dinv @ b.reshape(N, per, -1)).reshape(b.shape)

    def _jacobi_sparse(self, S: sp.csr_matrix, per: int) -> sp.csr_matrix:
        """D⁻¹ S for a sparse S: block-diagonal D⁻¹ as a BSR matrix times S."""
        N = self.Dinv.shape[0]
        Dinv = sp.bsr_matrix((self.Dinv, np.arange(N), np.arange(N + 1)), shape=(N * per, N * per))
        return (Dinv @ S).tocsr()

    def apply(self, b: np.ndarray) -> np.ndarray:
        w = self.omega
        x = w * self._jacobi(b)
        res = b - self.A @ x
        x = x + self.P @ self.coarse.solve(np.asarray(self.P.T @ res))
        res = b - self.A @ x
        return x + w * self._jacobi(res)


def _lobpcg(sp_: SparseProblem, Bop, k, tol, maxiter, rng, info):
    """LOBPCG on B with the rigid modes as constraints, preconditioned by TwoLevel: O(contacts) memory."""
    import warnings as _w

    t = time.perf_counter()
    pre = TwoLevel(sp_)
    info["setup"] = time.perf_counter() - t
    info["coarse_dofs"] = pre.n_coarse
    info["lu_nnz"] = pre.nnz
    m = min(k + max(4, k // 2), sp_.n - sp_.n_rigid - 1)
    X = rng.standard_normal((sp_.n, m))
    X -= sp_.R @ (sp_.R.T @ X)
    Mop = spla.LinearOperator(sp_.Hs.shape, matvec=pre.apply, matmat=pre.apply, dtype=float)
    with _w.catch_warnings(record=True) as caught:
        _w.simplefilter("always")
        lam, V, hist = spla.lobpcg(Bop, X, M=Mop, Y=sp_.R, largest=False, tol=(tol or 1e-8) * sp_.norm,
                                   maxiter=maxiter or 500, verbosityLevel=0, retLambdaHistory=True)
    info["iterations"] = len(hist)
    info["warnings"] = [str(c.message).split("\n")[0] for c in caught]
    order = np.argsort(lam)[:k]
    V = V[:, order]
    res = np.linalg.norm(Bop.matmat(V) - V * lam[order], axis=0).max(initial=0.0)
    info["converged"] = bool(res <= 10 * (tol or 1e-8) * sp_.norm)
    return lam[order], V
