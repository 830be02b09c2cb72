"""The sparse path: the lowest eigenpairs of sym(𝓗^i) for large clusters (10⁴-10⁵ particles, 2D and 3D).

Nothing of size n_dof × n_dof is ever formed. In the scaled dofs of rigid.py (Ũ = [du, L dθ]):

  sym(𝓗^i) = P Hs^i P,   Hs^i = sym(H̃_el) + ½ Σ_{sliding} (a sᵀ + s aᵀ)   (eq:newstiffnesses, eq:ContactF)

with P = I - Q Qᵀ (Q: orthonormal basis of the rigid rotations C̃, eq:Pnrr; P is the orthogonal projector because
C⁺ = (CᵀC)⁻¹Cᵀ). Rigid translations T̂ and rotations Q are exact null vectors of P Hs P and span an invariant
subspace, so the non-trivial spectrum is that of the DEFLATED operator

  B = P Hs P + s (Q Qᵀ + T̂ T̂ᵀ) = Hs + U K Uᵀ,     U = [Q, Y, T̂, a_on, s_on],  Y = Hs Q,  rank ≤ 2r + d + 2Ms

(the rigid modes are moved to s, an upper bound of ‖Hs‖). B is a sparse matrix plus a rank-≤(2r+d+2Ms)
correction; it is applied as a LinearOperator. Its lowest eigenpairs come from one of two solvers:

* shift-invert (default in 2D and for 3D up to LU_MAX_DOF_3D dofs): the lowest eigenpairs of B around σ slightly
  below 0, with (B - σI)⁻¹ applied by ONE factorisation of Hs - σI in a geometric nested-dissection order and the
  Woodbury identity; the same factorisation serves every loading branch (the branches differ only in the low-rank
  part). The factorisation is multifrontal.py's block elimination Hs - σI = L̂ S L̂ᵀ (a Cholesky per front where it
  is positive definite, else an eigendecomposition of the front): a congruence, so by Sylvester's law of inertia
  the number of -1 in S is the number of eigenvalues of Hs below σ, and Haynsworth's inertia formula for the
  low-rank update gives the number ν of eigenvalues of B below σ,
      ν(B - σI) = ν(Hs - σI) + ν(-K⁻¹ - UᵀM⁻¹U) - ν(-K⁻¹).
  Where every front is positive definite its factors also do the solves, in blocks (_block_near: block
  shift-invert Krylov, BLAS-3, with a float32 copy of the factor as its preconditioner: residuals in float64); otherwise SuperLU's LU does them and ARPACK (eigsh) finds the pairs.
  When every eigenvalue below σ was found (always the case when ν = 0) the k returned eigenvalues are provably the
  lowest k; otherwise (or when more than 4k + 20 lie below σ: a floppy chain has thousands, clustered, on which
  Lanczos stalled) σ is moved by bisection on the inertia count, one factorisation a step (spectrum slicing, `_slice`), until
  between k and 4k + 20 eigenvalues lie below it, and exactly those are computed: the most negative eigenvalues
  of (B - σI)⁻¹. A Lanczos estimate of λ_min is the fallback where no count is available. `Modes.verified`
  says whether that check passed. Memory: the factor's fill, ~n log n in 2D and ~n^{4/3} in 3D (`info["lu_nnz"]`).
* LOBPCG (default for larger 3D scenes): scipy.sparse.linalg.lobpcg on B with the rigid modes as constraints and
  the `TwoLevel` preconditioner (smoothed aggregation of per-aggregate rigid motions over the elastic Hm + τI,
  block-Jacobi smoothing, a small coarse LU): memory O(contacts), 30-100 iterations, not inertia-verified; one
  that does not converge is redone by shift-invert (up to LU_MAX_DOF_FALLBACK dofs).

Eigenvalues are Rayleigh quotients of the exact operator, and residuals ‖Bv - λv‖/‖Hs‖ are reported per pair.

Public API::

    sp = sparse_problem(scene)                     # assembly (vectorised), scaling, rigid bases: set up once
    modes = lowest_modes(sp, k=6, mask=None)       # lowest k non-rigid eigenpairs of sym(𝓗^mask)
    analyze(scene, method="sparse", k=6)           # the same inside granstab.analyze (Analysis, verdicts);
                                                   # method="auto" (default) uses it above DENSE_MAX_DOF dofs
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from ..mechanics.accuracy import resolved_sign, vector_bounds
from ..mechanics.branches import RIGID, Branch, Problem, canonical_signs, search_eigenspaces, test_codes
from .assembled import (
    SparseParts,
    SparseProblem,
    contact_chunks,
    identity_errors,
    norm_estimate,
    sparse_parts,
    sparse_problem,
)
from .krylov import Krylov, TwoLevel, _block_near, _eigsh_near, _lobpcg, _norms
from .multifrontal import Factor, dissection_order, factor

SMALL_DENSE = 48   # up to this many dofs lowest_modes uses a dense eigh of the operator (exact, instant)
SIGMA_REL = 1e-6   # default shift σ = -SIGMA_REL · s (s = upper bound of ‖Hs‖): just below 0, above round-off


# ------------------------------------------------------------------------------------------------ assembly

# ------------------------------------------------------------------------------------------ the operator

def _lowrank(sp_: SparseProblem, on: np.ndarray, shift: float):
    """U (n, m) and K (m, m) with B = Hs + U K Uᵀ for the branch whose sliding contacts are `on` (bool, Ms)."""
    Q = sp_.Q
    r = Q.shape[1]
    A, S = sp_.A[:, on], sp_.S[:, on]
    Y = sp_.Hs @ Q + 0.5 * (A @ (S.T @ Q) + S @ (A.T @ Q))
    G = Q.T @ Y
    G = 0.5 * (G + G.T)
    T = sp_.R[:, :sp_.scene.dim]
    d, m = T.shape[1], A.shape[1]
    U = np.concatenate([Q, Y, T, A, S], axis=1)
    K = np.zeros((2 * r + d + 2 * m,) * 2)
    I_r = np.eye(r)
    K[:r, :r] = G + shift * I_r
    K[:r, r:2 * r] = K[r:2 * r, :r] = -I_r
    K[2 * r:2 * r + d, 2 * r:2 * r + d] = shift * np.eye(d)
    o = 2 * r + d
    K[o:o + m, o + m:] = K[o + m:, o:o + m] = 0.5 * np.eye(m)
    return U, K


@dataclass(eq=False)
class Shifted:
    """(B - σI)⁻¹ for one branch from the LU of Hs - σI and the Woodbury identity; the inertia of B - σI."""

    lu: object
    U: np.ndarray
    K: np.ndarray
    sigma: float
    n_neg_M: int | None
    Z: np.ndarray = None
    cap: object = None
    n_below: int | None = None
    rhs: np.ndarray | None = None      # more columns to solve with U's, in the same pass over the factor: rhs_solved
    rhs_solved: np.ndarray | None = None

    def __post_init__(self):
        if self.Z is None:                                             # given: (Hs - σI)⁻¹U known (ritz.py)
            u = self.U.shape[1]
            both = self.U if self.rhs is None else np.concatenate([self.U, self.rhs], axis=1)
            solved = self.lu.solve(both) if both.shape[1] else both
            self.Z, self.rhs_solved = solved[:, :u], None if self.rhs is None else solved[:, u:]
        Kinv = np.linalg.inv(self.K) if self.K.size else self.K
        Cap = Kinv + self.U.T @ self.Z
        Cap = 0.5 * (Cap + Cap.T)
        self.cap = sla.lu_factor(Cap) if Cap.size else None
        if self.n_neg_M is not None:
            pos_cap = int(np.sum(np.linalg.eigvalsh(Cap) > 0)) if Cap.size else 0
            pos_K = int(np.sum(np.linalg.eigvalsh(self.K) > 0)) if self.K.size else 0
            self.n_below = self.n_neg_M + pos_cap - pos_K

    def solve(self, b: np.ndarray, single: bool = False) -> np.ndarray:
        """(B - σI)⁻¹ b; `single`: the factor's float32 solve (Factor.solve), an approximation for preconditioning."""
        y = self.lu.solve(b, single)
        if self.cap is None:
            return y
        return y - self.Z @ sla.lu_solve(self.cap, self.U.T @ y)


@dataclass(eq=False)
class Modes:
    """Lowest non-rigid eigenpairs of sym(𝓗^mask) from the sparse path.

    eigenvalues (k,) ascending, in force/length (scaled dofs); vectors (n, k) unit columns in scaled dofs
    (physical motion U = scale · Ũ); residuals (k,) ‖B v - λ v‖ / ‖Hs‖ with the exact operator; verified: the
    inertia check proved these are the k lowest; n_below: eigenvalues found below σ (None if not counted).
    """

    eigenvalues: np.ndarray
    vectors: np.ndarray
    residuals: np.ndarray
    mask: np.ndarray
    sigma: float
    verified: bool
    n_below: int | None
    method: str
    info: dict


def operator(sp_: SparseProblem, mask=None, shift: float | None = None) -> spla.LinearOperator:
    """B = P Hs^i P + s R Rᵀ as a LinearOperator (never a dense matrix)."""
    on = _on(sp_, mask)
    U, K = _lowrank(sp_, on, sp_.norm if shift is None else shift)
    Hs = sp_.Hs

    def mv(x):
        return Hs @ x + U @ (K @ (U.T @ x))

    return spla.LinearOperator(Hs.shape, matvec=mv, matmat=mv, rmatvec=mv, dtype=float)


def _on(sp_: SparseProblem, mask) -> np.ndarray:
    Ms = len(sp_.sliding)
    if mask is None:
        return np.zeros(Ms, bool)
    mask = np.asarray(mask)
    if mask.shape != (sp_.scene.n_contacts,):
        raise ValueError(f"mask must have {sp_.scene.n_contacts} entries")
    return mask[sp_.sliding] == 1


OWN_FACTOR_COLUMNS = 64   # a branch whose sliding contacts add more low-rank columns than this gets its own factor
BLOCK_MAX_WANTED = 32     # _block_near for at most this many eigenpairs (k + ν), ARPACK above: its basis (5 blocks of
                          # 2kk + 1) costs more than it saves there (2,000 disks, 5,904 dofs: kk = 61 2.2 s against
                          # ARPACK's 0.8 s, kk = 74 7.3 s against 4.5; kk = 16 0.24 against 0.19, kk = 28 2.9 against
                          # 3.5: CPU seconds, BENCHMARKS track_lammps)
LU_MAX_DOF_FALLBACK = 300000   # a LOBPCG that does not converge is redone by shift-invert up to this size
LU_MAX_DOF_3D = 30000   # method="auto": shift-invert (sparse LU) in 2D and up to this many dofs in 3D, else LOBPCG


def lowest_modes(problem, k: int = 6, mask=None, *, sigma: float | None = None, tol: float = 0.0,
                 method: str = "auto", maxiter: int | None = None, factorization=None,
                 seed: int = 0, rhs: np.ndarray | None = None) -> Modes:
    """The k lowest eigenpairs of sym(𝓗^mask) off the rigid modes (see the module docstring).

    problem: a SparseProblem or a Scene. mask: +1 sliding per contact (default: all elastic). sigma: shift (default
    -1e-6 ‖Hs‖). tol: eigsh/lobpcg relative tolerance (0 = machine precision). method: "shift-invert" (ARPACK + sparse
    LU, inertia-verified; the LU fill grows like n log n in 2D and n^{4/3} in 3D), "lobpcg" (LOBPCG with the TwoLevel
    preconditioner: memory O(contacts), not verified; tol is then the residual tolerance relative to ‖Hs‖, default
    1e-8, which gives eigenvalues to ~1e-16 ‖Hs‖) or "auto" (shift-invert in 2D and up to LU_MAX_DOF_3D dofs in 3D,
    LOBPCG above). factorization: (sigma, lu, n_neg) from an earlier call, reused across branches (not by one with its
    own, branch_problem). rhs (n, c): solved with the first block solve (info["shifted"].rhs_solved, None if σ moved;
    ritz.py). Returns Modes; info has the timings, the LU fill and, by shift-invert, "shifted" (the branch's Shifted).
    """
    sp_ = problem if isinstance(problem, SparseProblem) else sparse_problem(problem)
    n = sp_.n
    k = int(max(0, min(k, n - sp_.n_rigid)))
    mask_arr = np.zeros(sp_.scene.n_contacts, dtype=np.int8) if mask is None else np.asarray(mask, dtype=np.int8)
    on = _on(sp_, mask)
    shift = sp_.norm
    info: dict = {}
    if k <= 0:
        return Modes(np.zeros(0), np.zeros((n, 0)), np.zeros(0), mask_arr, 0.0, True, 0, method, info)
    if method == "auto":
        method = "shift-invert" if sp_.scene.dim == 2 or n <= LU_MAX_DOF_3D else "lobpcg"
    if method == "shift-invert" and 2 * on.sum() > OWN_FACTOR_COLUMNS and rhs is None:     # branch_problem
        return _own_factor(sp_, on, mask_arr, k, sigma=sigma, tol=tol, maxiter=maxiter, seed=seed)
    rng = np.random.default_rng(seed)
    v0 = rng.standard_normal(n)
    v0 -= sp_.R @ (sp_.R.T @ v0)
    Bop = operator(sp_, mask, shift)
    if n <= SMALL_DENSE or k >= n - sp_.n_rigid - 1:
        return _dense_small(sp_, Bop, n, k, mask_arr, info)
    if method == "lobpcg":
        t = time.perf_counter()
        lam, V = _lobpcg(sp_, Bop, k, tol, maxiter, rng, info)
        info["solve"] = time.perf_counter() - t - info["setup"]
        if info["converged"] or n > LU_MAX_DOF_FALLBACK:
            return _finish(sp_, Bop, lam, V, mask_arr, np.nan, False, None, method, info)
        info["fallback"] = "LOBPCG did not converge: shift-invert"      # then continue below
        method = "shift-invert"
    if method != "shift-invert":
        raise ValueError(f"method must be 'auto', 'shift-invert' or 'lobpcg', got {method!r}")
    U, K = _lowrank(sp_, on, shift)
    sig = -SIGMA_REL * sp_.norm if sigma is None else float(sigma)
    t = time.perf_counter()
    if factorization is not None and factorization.sigma == sig:
        fac = factorization
    else:
        fac = factor(sp_, sig)
    info.update(factor=time.perf_counter() - t, lu_nnz=fac.nnz, factorization=fac)
    shifted = Shifted(fac, U, K, sig, fac.n_neg, rhs=rhs)
    nu = shifted.n_below
    t = time.perf_counter()
    verified = False
    if nu is not None and nu <= 4 * k + 20:
        block = fac.lu is None and tol == 0 and k + nu <= BLOCK_MAX_WANTED
        found = _block_near(shifted, Bop, sp_, k + nu, rng) if block else None
        if found is not None:
            lam, V, info["krylov"] = found
        else:
            lam, V = _eigsh_near(shifted, Bop, n, k + nu, tol, maxiter, v0)
        verified = int(np.sum(lam < sig)) >= nu
    else:
        lam = np.array([sig])
    if not verified and nu is not None and 0 < nu <= 4 * k + 20:
        # a few lie below σ but the solve nearest σ missed some (far below, past closer ones above): they are
        # exactly the ν most negative values of (B - σI)⁻¹, and the lowest above σ are among those found
        below, V_below = _eigsh_near(shifted, Bop, n, nu, tol, maxiter, v0, which="SA")
        above = lam >= sig
        lam, V = np.r_[below, lam[above]], np.hstack([V_below, V[:, above]])
        order = np.argsort(lam, kind="stable")
        lam, V = lam[order], V[:, order]
        verified = int(np.sum(below < sig)) == nu
    if not verified:
        shifted, lam, V, sig, nu, verified = _sliced(sp_, Bop, U, K, shifted, lam, k, n, tol, maxiter, v0, info)
    info["solve"] = time.perf_counter() - t
    info["shifted"] = shifted                                          # (Hs - σI)⁻¹U of this branch (ritz.py)
    return _finish(sp_, Bop, lam[:k], V[:, :k], mask_arr, sig, verified, nu, method, info)


def branch_problem(sp_: SparseProblem, on: np.ndarray) -> SparseProblem:
    """The branch whose sliding contacts are `on` as a problem without sliding contacts: its sparse matrix
    Hs^i = Hs + ½ Σ_on (a sᵀ + s aᵀ) (eq:ContactF; a and s live on the contact's two particles, so Hs^i has Hs's
    pattern), the same deflation and norm bound. B is the same operator, so its eigenpairs and inertia are the
    branch's; its own factor replaces the Woodbury correction of 2·|on| columns, whose (Hs - σI)⁻¹U solve and
    per-solve products cost more than a factorisation once |on| is large (639 sliding contacts of 2,000 disks:
    1,278 columns, half of the branch's time)."""
    A, S = sps.csc_matrix(sp_.A[:, on]), sps.csc_matrix(sp_.S[:, on])
    AS = A @ S.T
    none = np.zeros((sp_.n, 0))
    return replace(sp_, Hs=(sp_.Hs + 0.5 * (AS + AS.T)).tocsr(), A=none, S=none, sliding=np.zeros(0, np.intp))


def _own_factor(sp_: SparseProblem, on: np.ndarray, mask_arr: np.ndarray, k: int, **options) -> Modes:
    """lowest_modes of the branch_problem of `on`, the branch's mask and "own_factor" in its info."""
    modes = lowest_modes(branch_problem(sp_, on), k, None, method="shift-invert", **options)
    modes.mask, modes.info["own_factor"] = mask_arr, True
    return modes


def _dense_small(sp_: SparseProblem, Bop, n: int, k: int, mask_arr, info: dict) -> Modes:
    """A handful of dofs: ARPACK needs k < n - 1, and a dense eigh of B is exact and instant here."""
    t = time.perf_counter()
    B = Bop.matmat(np.eye(n))
    lam, V = np.linalg.eigh(0.5 * (B + B.T))
    lam, V = _drop_rigid(sp_, lam, V)
    info["solve"] = time.perf_counter() - t
    return _finish(sp_, Bop, lam[:k], V[:, :k], mask_arr, np.nan, True, None, "dense", info)


def _sliced(sp_: SparseProblem, Bop, U, K, shifted: Shifted, lam, k: int, n: int, tol, maxiter, v0, info: dict):
    """Too many lie below σ (a floppy structure's thousands of clustered negative eigenvalues, on which Lanczos
    stalls), or the ν below were not all reached: slice the spectrum by inertia counts; (shifted, λ, V, σ, ν,
    verified)."""
    t2 = time.perf_counter()
    nu = shifted.n_below
    shifted = _slice(sp_, U, K, shifted, k, 4 * k + 20) if nu is not None else None
    if shifted is None:
        shifted = _below_lanczos(sp_, Bop, U, K, lam, v0, n)
    info["factor"] += time.perf_counter() - t2
    fac = shifted.lu
    sig, nu = shifted.sigma, shifted.n_below
    info["factorization"] = fac
    info["lu_nnz"] = fac.nnz
    if nu is not None and nu >= k:       # exactly ν below σ: the most negative values of (B - σI)⁻¹ are they
        lam, V = _eigsh_near(shifted, Bop, n, nu, tol, maxiter, v0, which="SA")
    else:
        lam, V = _eigsh_near(shifted, Bop, n, k + (nu or 0), tol, maxiter, v0)
    verified = nu is not None and int(np.sum(lam < sig)) >= nu
    return shifted, lam, V, sig, nu, verified


SLICE_STEPS = 60   # inertia counts (one sparse LU each) allowed to find a shift with few eigenvalues below it


def _slice(sp_: SparseProblem, U, K, above: Shifted, least: int, target: int) -> Shifted | None:
    """A shift σ with least <= ν(σ) <= target eigenvalues of B below it (or, where a cluster makes ν jump past that
    window, the highest σ found with fewer), by bisection on σ between -1.01 s (no eigenvalue of B lies below
    -‖Hs‖ >= -s) and `above` (ν > target), each step one LU of Hs - σI and its inertia (Sylvester, Haynsworth: the
    module docstring), geometric in |σ| (the eigenvalues of a floppy structure crowd near 0): spectrum slicing,
    O(steps · LU) whatever the clustering. Then the ν eigenvalues below σ are exactly the ν most negative of
    (B - σI)⁻¹ (`lowest_modes`). None where the counts are unknown or s is not above ‖Hs‖."""
    lo, hi = None, above
    for _ in range(SLICE_STEPS + 1):
        if lo is None:
            mid = -1.01 * sp_.norm
        else:
            mid = 0.5 * (lo.sigma + hi.sigma) if hi.sigma >= 0 else -np.sqrt(lo.sigma * hi.sigma)
        fac = factor(sp_, mid)
        if fac.n_neg is None:
            return None
        cut = Shifted(fac, U, K, mid, fac.n_neg)
        if lo is None and cut.n_below != 0:
            return None
        if lo is not None and least <= cut.n_below <= target:
            return cut
        if cut.n_below < least:
            lo = cut
        else:
            hi = cut
        if hi.sigma - lo.sigma <= 1e-12 * sp_.norm:
            break
    return lo


def _below_lanczos(sp_: SparseProblem, Bop, U, K, lam, v0, n) -> Shifted:
    """A shift below a Lanczos estimate of λ_min (where no inertia count is available)."""
    try:
        est = spla.eigsh(Bop, k=1, which="SA", tol=1e-3, v0=v0, return_eigenvectors=False,
                         maxiter=max(1000, 20 * n))[0]
    except spla.ArpackNoConvergence as exc:                     # fall back on the crude bound -‖Hs‖
        est = float(np.min(exc.eigenvalues)) if len(exc.eigenvalues) else -sp_.norm
    sig = min(lam.min(), est) - 0.05 * abs(min(lam.min(), est)) - SIGMA_REL * sp_.norm
    fac = factor(sp_, sig)
    return Shifted(fac, U, K, sig, fac.n_neg)


def _drop_rigid(sp_: SparseProblem, lam, V):
    """Remove the n_rigid eigenpairs of B that lie in the rigid span (eigenvalue s) from a full spectrum."""
    rigid_weight = np.linalg.norm(sp_.R.T @ V, axis=0)
    keep = np.argsort(rigid_weight, kind="stable")[:V.shape[1] - sp_.n_rigid]
    keep = np.sort(keep)
    return lam[keep], V[:, keep]


def _finish(sp_, Bop, lam, V, mask, sig, verified, nu, method, info) -> Modes:
    V = V - sp_.R @ (sp_.R.T @ V)                                      # drop round-off along the rigid modes
    V /= _norms(V)
    BV = Bop.matmat(V)
    lam = np.einsum("ij,ij->j", V, BV)                                 # Rayleigh quotients with the exact B
    res = _norms(BV - V * lam) / sp_.norm
    order = np.argsort(lam)
    return Modes(eigenvalues=lam[order], vectors=V[:, order], residuals=res[order], mask=mask, sigma=sig,
                 verified=bool(verified), n_below=nu, method=method, info=info)


# ------------------------------------------------------------------------------------------ branches

def sparse_branch(problem: Problem, spb, modes, mask, k: int):
    """A branches.Branch from the k+1 lowest modes: rigid modes first in the basis, per-eigenvalue accuracy bounds
    (accuracy.py, with the branch's `rigid_leakage`), consistency codes, the subspace search of Appendix D on
    repeated and non-rigid zero eigenvalues (branches.search_eigenspaces, as the dense path) and the negative count
    of sym(𝓗^i) (`negative_count`: count, total = whether every negative eigenvalue is among the computed ones,
    below = the shift σ of the inertia count)."""
    n = spb.n
    lam_k, V_k = modes.eigenvalues, modes.vectors
    res_k = modes.residuals * spb.norm                                  # absolute residual norms
    formation = problem.formation_error + rigid_leakage(spb, _on(spb, mask))
    bounds_k = vector_bounds(lam_k, res_k, spb.norm, formation, n)
    cut = len(lam_k) > k and k > 0 and lam_k[k] - lam_k[k - 1] <= bounds_k[k] + bounds_k[k - 1]
    top = (lam_k[k], bounds_k[k]) if len(lam_k) > k else (np.inf, 0.0)
    lam_k, V_k, bounds_k = lam_k[:k], V_k[:, :k], bounds_k[:k]
    n_rigid = spb.n_rigid
    lam = np.r_[np.zeros(n_rigid), lam_k]
    bounds = np.r_[np.full(n_rigid, formation), bounds_k]
    V = np.concatenate([spb.R, canonical_signs(V_k)], axis=1)          # the signs of branches.column_signs
    order = np.argsort(lam, kind="stable")
    lam, V, bounds = lam[order], V[:, order], bounds[order]
    rigid = order < n_rigid
    codes, hinges = test_codes(problem, np.asarray(mask)[None], V[None])
    codes, hinges = codes[0].copy(), hinges[0].copy()
    codes[rigid] = RIGID
    hinges[rigid] = False
    zero = np.abs(lam) <= bounds
    extra = np.flatnonzero(zero & ~rigid)
    search_eigenspaces(problem, mask, lam, bounds, V, codes, hinges, extra, V[:, extra])
    signs = resolved_sign(lam_k, bounds_k)
    # every negative eigenvalue is among the computed ones when the next one (k+1) is resolved positive, or when
    # the inertia count below σ is covered and nothing between σ and the bound is left uncomputed
    total = bool(top[0] > top[1]) or k >= n - n_rigid
    if modes.n_below is None and not modes.verified and k < n - n_rigid:
        total = False          # no inertia count (LOBPCG: no factorisation): nothing excludes an eigenvalue below
    count = int(np.sum(signs < 0))
    if modes.n_below is not None and modes.verified:
        count = max(count, int(modes.n_below))
    res = float(modes.residuals[:k].max(initial=0.0)) if k else 0.0
    b = Branch(mask=np.asarray(mask), stability_eigenvalues=lam, stability_vectors=V, codes=codes, hinges=hinges,
               n_zero=int(zero.sum()), zero_tol=float(bounds.max(initial=0.0)),
               uniqueness_eigenvalues=np.zeros(0, complex), uniqueness_n_zero=-1, type2=[],
               residual_stability=res, residual_uniqueness=0.0, bounds=bounds,
               negative_count={"count": count, "total": total,
                               "below": float(modes.sigma) if np.isfinite(modes.sigma) else None})
    return b, bool(cut)


def rigid_leakage(sp_: SparseProblem, on: np.ndarray) -> float:
    """‖sym(𝓗^i) R‖_F = ‖P Hs^i P R‖_F for the branch whose sliding contacts are `on` (bool, Ms): the rigid leakage
    that remains (zero in exact arithmetic), added to every bound as the dense path's `dense.formation` does, from
    sparse-times-thin products (R is (n, d + r); nothing n × n is formed)."""
    Q = sp_.Q
    X = sp_.R - Q @ (Q.T @ sp_.R)
    A, S = sp_.A[:, on], sp_.S[:, on]
    Y = sp_.Hs @ X + 0.5 * (A @ (S.T @ X) + S @ (A.T @ X))
    return float(np.linalg.norm(Y - Q @ (Q.T @ Y)))


# ------------------------------------------------------------------------------------------------ errors

# ------------------------------------------------------------------------------------------- analyze()

DENSE_MAX_DOF = 2000   # analyze(method="auto") uses the dense path up to this many dofs, the sparse one above


__all__ = ["DENSE_MAX_DOF", "LU_MAX_DOF_3D", "Factor", "Krylov", "Modes", "SparseParts", "SparseProblem", "TwoLevel",
           "contact_chunks", "dissection_order", "factor", "identity_errors", "lowest_modes", "norm_estimate",
           "operator", "rigid_leakage", "sparse_branch", "sparse_parts", "sparse_problem"]
