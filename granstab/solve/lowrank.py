"""All 2^Ms loading branches as low-rank updates of the elastic problem, stacked on a backend (numpy or CuPy).

Branch i has sym(𝓗^i) = P sym(H^i) P with H^i = H_el + Σ_{on} a_j s_jᵀ (eq:ContactF, eq:newstiffnesses). The
rigid motions R (translations and rotations, orthonormal) are exact null vectors of every sym(𝓗^i) (Σ db^p = 0,
s·T = 0, P C = 0), so in the orthonormal complement N of R (Nᵀ P = Nᵀ) every branch is the k × k matrix

    M_i = Nᵀ sym(H^i) N = M_0 + ½ (a diag(on_i) sᵀ + s diag(on_i) aᵀ),   M_0 = Nᵀ sym(H_el) N, a = NᵀA, s = NᵀS,

the elastic matrix plus a symmetric update of rank ≤ 2·(#loading contacts). The elastic part and the projected
factors are computed once; each chunk of branches is one batched product and one stacked `eigh` on the backend.

What is exact and what is bounded, per branch and eigenvalue (reported as `Branch.bounds`, accuracy.py's meaning):
* The reduction is exact up to round-off: in the basis [N, R] the full matrix is [[M_i, E_iᵀ], [E_i, G_i]] with
  E_i = Rᵀ sym(𝓗^i) N (the rigid leakage, zero in exact arithmetic); by Weyl, dropping it moves no eigenvalue by
  more than ‖E_i‖₂ ≤ ‖E_i‖_F, which is computed per branch (also a low-rank update of E_0).
* Each computed pair (λ, w) has residual r = ‖M_i w − λ w‖; the eigenvalues match one to one within √2 r
  (accuracy.py, Kahan), plus the rounding of r itself and the formation error of the problem. The bound per
  eigenvalue is that of accuracy.vector_bounds plus ‖E_i‖_F, whatever the backend's solver (LAPACK or Jacobi).
* Eigenvalues whose bound keeps them off zero have a proven sign, so their counts are exact (Sylvester).
* ℍ^i = H^i P has no non-rigid null vector when σ_min(H^i N) > its zero tolerance; σ_min(H^i N) ≥ λ_min(M_i)
  (wᵀ M_i w = wᵀ NᵀH^iN w ≤ |w|·‖H^iN w‖), so a positive definite branch needs no SVD; the others get a lower bound
  of σ_min² from the Gram matrix's eigenvalues less its rounding error.
Branches with a repeated eigenvalue, a non-rigid zero or a possibly singular ℍ^i (which need the eigenspace search
of Appendix D, or Type-2) are handed to `dense.solve_branches`, the full per-branch path, unchanged.

What is kept per branch: eigenvalues, codes, hinges and error bounds (O(n)); the eigenvectors are recomputed on
demand (`LazyVectors`), so memory does not grow with 2^Ms × n². ℍ^i spectra are not computed on this path (only
its nullity), which is what makes it fast; the full path (`dense.solve_branches`) gives them.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..mechanics.accuracy import abs_norm_inf, gamma, resolved_sign, tightened, values_backward_error, vector_bounds
from ..mechanics.branches import RIGID, Branch, Problem, column_signs, consistency, needs_search
from ..mechanics.rigid import on_complement, rigid_basis
from ..mechanics.verdicts import CONSISTENT, merge_tallies, tally
from ..model.tolerances import EPS
from .dense import formation_rest, projection_defect, solve_branches, tightenable
from .device import backend, residual_norms
from .threads import blas_threads, cores

MIN_BRANCHES = 1024   # analyze() takes this path from 2^10 branches on (below it the full path costs < 1 s) …
MIN_WORK = 5e8        # … or from branches · n³ >= this: the full path's eig + SVD of n×n then costs > ~1 s a core
                      # (measured: n = 879, eig 1.5 s, SVD 0.27 s, eigh 0.16 s on one core), this path's eigh a fifth
GPU_THREADS = 8       # chunks in flight on a GPU (each takes its share of the device memory, backend.chunk)


@dataclass(frozen=True, eq=False)
class Reduced:
    """The branch-independent pieces in the rigid-free basis N (n, k): M0 (k, k), a, s (k, Ms); leakage pieces
    E0 (r, k), alpha, beta (r, Ms) with E_i = E0 + ½(alpha on sᵀ + beta on aᵀ); ℍ pieces HN = H_el N (n, k) and
    the per-contact norms |A_j| |s_j| for an upper bound of ‖H^i N‖."""

    N: np.ndarray
    M0: np.ndarray
    a: np.ndarray
    s: np.ndarray
    E0: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    HN: np.ndarray
    HN_norm: float
    AS_norm: np.ndarray
    n: int

    @property
    def k(self) -> int:
        return self.N.shape[1]


def reduce(problem: Problem) -> Reduced:
    """M0, a, s and the leakage pieces of the module docstring, once per cluster."""
    R = problem.rigid
    _, N = rigid_basis(R, complement=True)
    M0, a, s = on_complement(N, problem.H_el, problem.A, problem.S)
    Hsym = 0.5 * (problem.H_el + problem.H_el.T)
    PR = problem.projection.apply(R)
    HN = problem.H_el @ N
    AS_norm = np.linalg.norm(problem.A, axis=0) * np.linalg.norm(s, axis=0)
    return Reduced(N=N, M0=M0, a=a, s=s, E0=PR.T @ Hsym @ N, alpha=PR.T @ problem.A, beta=PR.T @ problem.S, HN=HN,
                   HN_norm=spectral_upper(HN), AS_norm=AS_norm, n=R.shape[0])


def spectral_upper(X: np.ndarray) -> float:
    """An upper bound of ‖X‖₂ without an SVD: √(‖X‖₁ ‖X‖∞) (Hölder; an SVD of a 900-dof cluster's H N took
    longer than all its branches)."""
    if X.size == 0:
        return 0.0
    return float(np.sqrt(np.abs(X).sum(axis=0).max() * np.abs(X).sum(axis=1).max()))


def use_lowrank(n_branches: int, n: int, uniqueness: bool = True) -> bool:
    """Whether `DenseMethod` takes this path by default (on a CPU): from MIN_BRANCHES branches, or when the full
    path's per-branch eig + SVD would cost more than MIN_WORK (a rule on sizes, not on the machine, so that the
    result's contents do not depend on load). Without ℍ^i (uniqueness False) the full path does no eig or SVD: a
    few large branches cost it one eigh each, as here, without this path's set-up."""
    return n_branches >= MIN_BRANCHES or (uniqueness and n_branches * float(n) ** 3 >= MIN_WORK)


def sym_updates(a: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Per sliding contact j the flattened ½(a_j s_jᵀ + s_j a_jᵀ), (Ms, k·k): a branch's update is then the row
    `on @ updates` (one GEMM for a whole stack)."""
    m = 0.5 * (np.einsum("im,jm->mij", a, s) + np.einsum("im,jm->mij", s, a))
    return m.reshape(a.shape[1], a.shape[0] * s.shape[0])


def _updates(red: Reduced) -> tuple[np.ndarray, np.ndarray]:
    """The updates of M (sym_updates(a, s)) and of E (½(alpha_j s_jᵀ + beta_j a_jᵀ), (Ms, r·k))."""
    e = 0.5 * (np.einsum("im,jm->mij", red.alpha, red.s) + np.einsum("im,jm->mij", red.beta, red.a))
    return sym_updates(red.a, red.s), e.reshape(len(e), red.E0.size)


def stack(xp, M0, updates, on):
    """M0 + (on @ updates) reshaped: (L, k, k) on the backend `xp`."""
    k = M0.shape[0]
    return xp.asarray(M0)[None] + xp.matmul(on, xp.asarray(updates)).reshape(-1, k, k)


def branch_stack(xp, red: Reduced, on, updates=None):
    """M_i (L, k, k) for on (L, Ms) ∈ {0, 1} on the backend `xp`: M0 + sym(a diag(on) sᵀ)."""
    return stack(xp, red.M0, updates if updates is not None else _updates(red)[0], on)


def leakage(xp, red: Reduced, on, updates=None):
    """‖E_i‖_F (L,): the rigid leakage of each branch (module docstring)."""
    dE = xp.asarray(updates if updates is not None else _updates(red)[1])
    E = xp.asarray(red.E0.reshape(-1))[None] + xp.matmul(on, dE)
    return xp.sqrt(xp.sum(E * E, axis=1))


def solve_branches_lowrank(problem: Problem, masks: np.ndarray, device: str = "cpu", chunk: int | None = None,
                           on_branch=None, keep_all: bool = True, uniqueness: bool = True):
    """Every branch in `masks` (L, M): a list of `branches.Branch` in mask order, and info (device, unit round-off,
    how many branches took the full path, the largest leakage and backward error relative to ‖M_i‖, the largest
    residual_stability).

    Plain branches come from the stacked reduced problems; the others from `solve_branches` (module docstring).
    keep_all=False: only the branches a verdict rests on are returned — those with a consistent eigenpair of sign
    ≤ 0 (resolved or not) or Type-2, and the branch with the lowest non-rigid eigenvalue — and info["tally"] holds
    the counts over all L branches (verdicts.tally): memory no longer grows with 2^Ms. uniqueness=False: no ℍ^i
    nullity test (`_special`), uniqueness_n_zero -1, and the full path without ℍ^i (dense.solve_branches).
    """
    be = backend(device)
    xp = be.xp
    red = reduce(problem)
    n, k = red.n, red.k
    L = len(masks)
    info = {"device": be.name, "eps": be.eps, "full_path": 0, "leakage": 0.0, "backward_error": 0.0}
    if k == 0 or L == 0:
        out = solve_branches(problem, masks, on_branch=on_branch, uniqueness=uniqueness)
        info["full_path"] = len(out)
        return out, info
    workers = cores() if be.name == "cpu" else min(GPU_THREADS, cores())
    size = chunk or min(be.chunk(8.0 * (5 * k * k + 2 * n * k) * workers, L), -(-L // (2 * workers)))
    dM, dE = (be.asarray(u) for u in _updates(red))
    N = be.asarray(red.N)
    s_t = be.asarray(red.s.T)

    def solve(start):
        """The stacked arithmetic of one chunk, in a thread pool: numpy releases the GIL, so CPU chunks run on every
        core; on a GPU one chunk's host work overlaps the next chunk's device work."""
        part = masks[start:start + size]
        on_h = (part[:, problem.sliding] == 1).astype(float)
        on = be.asarray(on_h)
        M = branch_stack(xp, red, on, dM)
        lam, W = xp.linalg.eigh(M)
        W = W * full_signs(xp, N, W)[:, None, :]
        Sv = xp.matmul(s_t[None], W)
        m = be.asarray(part[:, problem.sliding])[:, :, None]
        codes, hinges = consistency(m, Sv, problem.s_tol, problem.s_floor, xp)
        got = {"lam": lam, "res": residual_norms(xp, M, lam, W), "leak": leakage(xp, red, on, dE),
               "scale": abs_norm_inf(M, xp), "codes": codes, "hinges": hinges,
               **fingerprint(xp, Sv)}
        host = {key: be.to_host(v) for key, v in got.items()}          # O(L·k): the S values stay on the device
        host["bounds"] = vector_bounds(host["lam"], host["res"], host["scale"][:, None],
                                       problem.formation_error, k) + host["leak"][:, None]
        host["bounds"] = tighten_unresolved(problem, red, host, W, be)
        special = _special(problem, red, host, on_h, be, uniqueness)
        return part, host, special, _plain_arrays(problem, host, uniqueness)

    kept = Kept(keep_all)
    info["residual_stability"] = 0.0
    with (be.threads(k) if workers == 1 else blas_threads(1)), ThreadPoolExecutor(workers) as pool:
        for start, (part, host, special, plain) in zip(range(0, L, size), pool.map(solve, range(0, L, size))):
            with be.threads(n if workers == 1 else 1):
                full = dict(zip(np.flatnonzero(special),
                                solve_branches(problem, part[special], uniqueness=uniqueness) if special.any()
                                else []))
            info["full_path"] += len(full)
            norm = np.maximum(np.abs(host["lam"]).max(axis=1), 1e-300)
            info["leakage"] = max(info["leakage"], float((host["leak"] / norm).max()))
            info["backward_error"] = max(info["backward_error"], float((host["res"].max(axis=1) / norm).max()))
            info["residual_stability"] = max([info["residual_stability"], float(plain["res"][~special].max(initial=0)),
                                              *(b.residual_stability for b in full.values())])

            def branch(i, full=full, part=part, plain=plain):
                return full.get(i) or _plain(problem, red, part[i], {key: v[i] for key, v in plain.items()})

            if keep_all or on_branch is not None:
                for i in range(len(part)):
                    b = branch(i)
                    kept.add(start + i, b, plain, i, special[i])
                    if on_branch is not None:
                        on_branch(b)
            else:
                kept.add_chunk(start, branch, plain, special, full)
    out = kept.branches()
    if not keep_all:
        info["tally"], info["n_branches"] = kept.tally, L
    return out, info


def tighten_unresolved(problem: Problem, red: Reduced, h: dict, W, be) -> np.ndarray:
    """h["bounds"] with those of unresolved eigenvalues (|λ| <= bound: where a verdict's `sufficient` may depend on
    it) tightened by accuracy.tightened, as on the full path (dense.tighten), on their full vectors u = N w. The
    rigid motions count among the others (exact zeros, bound ‖E_i‖ + F), and u's residual for the whole branch
    matrix is that of w for M_i plus the leakage ‖E_i‖ (in the basis [N, R], sym(𝓗^i) u = N M_i w + R E_i w)."""
    lam, bounds = h["lam"], h["bounds"]
    todo = np.abs(lam) <= bounds
    if not tightenable(problem) or not todo.any():
        return bounds
    out, r, k = bounds.copy(), problem.rigid.shape[1], red.k
    rest = formation_rest(problem, problem.formation_error)
    for i in np.flatnonzero(todo.any(axis=1)):
        idx = np.flatnonzero(todo[i])
        U = red.N @ be.to_host(W[i][:, idx])
        lam_all = np.concatenate([np.zeros(r), lam[i]])
        bounds_all = np.concatenate([np.full(r, h["leak"][i] + problem.formation_error), bounds[i]])
        r_bar = h["res"][i, idx] + gamma(k + 2) * (h["scale"][i] + np.abs(lam[i, idx])) + h["leak"][i]
        out[i, idx] = tightened(lam_all, bounds_all, idx + r, U, r_bar, problem.curvature_entrywise,
                                problem.curvature_bound, rest, projection_defect(problem, U))
    return out


class Kept:
    """The branches `solve_branches_lowrank` returns: all of them, or (keep_all False) those a verdict rests on and
    the one with the lowest non-rigid eigenvalue, with the running `verdicts.tally` of every branch."""

    def __init__(self, keep_all: bool):
        self.keep_all, self.tally = keep_all, None
        self.chosen: dict = {}
        self.lowest = (np.inf, None)

    def add(self, index: int, b: Branch, plain: dict, i: int, special: bool) -> None:
        """One branch (every branch is made: keep_all, or a caller streaming them)."""
        if self.keep_all:
            self.chosen[index] = b
            return
        self._count([b.stability_eigenvalues], [b.accuracy], [b.codes], [b.hinges])
        low = _lowest(b.stability_eigenvalues, b.codes)
        if _worth(b.stability_eigenvalues, b.accuracy, b.codes) or b.type2:
            self.chosen[index] = b
        if low < self.lowest[0]:
            self.lowest = (low, (index, b))

    def add_chunk(self, start: int, branch, plain: dict, special: np.ndarray, full: dict) -> None:
        """A chunk without making a Branch for the rows nobody keeps (vectorised over its plain rows)."""
        rows = ~special
        self._count([plain["lam"][rows].ravel()] + [b.stability_eigenvalues for b in full.values()],
                    [plain["err"][rows].ravel()] + [b.accuracy for b in full.values()],
                    [plain["codes"][rows].ravel()] + [b.codes for b in full.values()],
                    [plain["hinges"][rows].ravel()] + [b.hinges for b in full.values()])
        worth = _worth(plain["lam"], plain["err"], plain["codes"]) & rows
        lows = _lowest(plain["lam"], plain["codes"])
        for i, b in full.items():
            worth[i] = _worth(b.stability_eigenvalues, b.accuracy, b.codes) or bool(b.type2)
            lows[i] = _lowest(b.stability_eigenvalues, b.codes)
        for i in np.flatnonzero(worth):
            self.chosen[start + int(i)] = branch(int(i))
        i = int(np.argmin(lows))
        if lows[i] < self.lowest[0]:
            self.lowest = (float(lows[i]), (start + i, self.chosen.get(start + i) or branch(i)))

    def _count(self, lam, acc, codes, hinges) -> None:
        lam, acc, codes, hinges = (np.concatenate(a) for a in (lam, acc, codes, hinges))
        one = tally(lam, acc, codes, hinges.astype(bool), np.zeros(len(lam), dtype=np.int64), 1)
        self.tally = merge_tallies(self.tally, {key: value[0] for key, value in one.items()})

    def branches(self) -> list:
        if self.lowest[1] is not None:
            self.chosen.setdefault(*self.lowest[1])
        return [self.chosen[i] for i in sorted(self.chosen)]


def _worth(lam, acc, codes):
    """A branch (row) with a consistent eigenpair of sign ≤ 0 within accuracy: what instability or neutrality rests
    on (eq:instab, eq:neutral)."""
    return np.any(np.isin(codes, CONSISTENT) & (resolved_sign(lam, acc) <= 0), axis=-1)


def _lowest(lam, codes):
    """The lowest non-rigid eigenvalue of a branch (row); inf if it has none."""
    return np.min(np.where(codes != RIGID, lam, np.inf), axis=-1, initial=np.inf)


def full_signs(xp, N, W):
    """±1 per column (L, k): branches.column_signs of the full eigenvector N w, so that both paths report the same
    vector_sign."""
    return column_signs(xp.matmul(N[None], W), xp)[:, 0, :]


def _special(problem: Problem, red: Reduced, h: dict, on: np.ndarray, be, uniqueness: bool = True) -> np.ndarray:
    """Branches that need the full path: a non-rigid zero or a repeated eigenvalue within the accuracy bounds
    (branches.needs_search), or (uniqueness) an ℍ^i whose smallest singular value on N is not proven above its zero
    tolerance."""
    lam, bounds = h["lam"], h["bounds"]
    n = red.n
    search = needs_search(lam, bounds)
    if not uniqueness:
        return search
    upper = red.HN_norm + on @ red.AS_norm                            # ≥ ‖H^i N‖₂ = ‖ℍ^i‖₂
    tol_u = problem.tol.zero_tol(1.0, n) * upper
    lower = lam[:, 0] - bounds[:, 0]                                  # ≤ λ_min(M_i) ≤ σ_min(H^i N)
    unsure = np.flatnonzero(~search & (lower <= tol_u))
    singular = np.zeros(len(lam), bool)
    if unsure.size:
        smin2, gmax = gram_floor(be, problem.A, red, on[unsure])
        tol_g = problem.tol.zero_tol(1.0, n) * np.sqrt(np.maximum(gmax, 0.0))
        singular[unsure] = smin2 <= tol_g ** 2
        again = unsure[singular[unsure]]
        if again.size and be.name == "cpu":
            singular[again] = svd_floor(problem, red, on[again]) <= 0.0
    return search | singular


def svd_floor(problem: Problem, red: Reduced, on: np.ndarray) -> np.ndarray:
    """σ_min(H^i N) less its zero tolerance, proven from below, per branch, where `gram_floor` cannot tell: squaring
    X = H^i N into the Gram matrix loses what lies below √(nε)‖X‖ (an unstable branch at L/10 of a 300-disk packing,
    σ_min/σ_max ~ 1e-6, went to the full path for it). The singular values (LAPACK gesdd, no vectors: 0.3 s at 900
    dofs against the full path's eig + SVD + search, seconds) are backward stable, those of X + E with
    ‖E‖₂ <= γ_{n²}‖X‖₂ (accuracy.values_backward_error, the a-priori bound taken for every eigenvalue computed
    without vectors), and ‖X‖₂ <= spectral_upper(X); the tolerance is that of the Gram test and of the full path
    (zero_tol of σ_max)."""
    n = red.n
    out = np.empty(len(on))
    for i, X in enumerate(hinge_stack(backend("cpu"), problem.A, red, on)):
        sv = np.linalg.svd(X, compute_uv=False)
        upper = spectral_upper(X)
        out[i] = sv[-1] - values_backward_error(upper, n) - problem.tol.zero_tol(1.0, n) * upper
    return out


def hinge_stack(be, A: np.ndarray, red: Reduced, on: np.ndarray):
    """H^i N (L, n, k) per branch on the backend: H_el N + A diag(on) sᵀ (eq:newstiffnesses; ℍ^i in the basis N)."""
    return be.asarray(red.HN)[None] + be.asarray(A)[None] * be.asarray(on)[:, None, :] @ be.asarray(red.s.T)


def gram_floor(be, A: np.ndarray, red: Reduced, on: np.ndarray):
    """A lower bound of σ_min(H^i N)² and the largest eigenvalue of G = (H^i N)ᵀ(H^i N) per branch, on the backend.

    G is formed to within 4nε‖H^i N‖_F² (γ_n per entry). Its smallest eigenvalue: on the CPU LAPACK's eigvalsh,
    backward stable, whose error that term also covers; on a GPU (Jacobi, ~1e-14 relative) nothing is assumed of
    the solver: eigh's own residual gives the bound (accuracy.vector_bounds, Kahan), as for every other eigenvalue.
    """
    xp, n = be.xp, red.n
    X = hinge_stack(be, A, red, on)
    G = xp.swapaxes(X, 1, 2) @ X
    fro2 = be.to_host(xp.sum(X * X, axis=(1, 2)))
    if be.name == "cpu":
        g = np.linalg.eigvalsh(G)
        return g[:, 0] - 4 * n * EPS * fro2, g[:, -1]
    g, Z = xp.linalg.eigh(G)
    res = be.to_host(residual_norms(xp, G, g, Z)[:, 0])
    scale = be.to_host(abs_norm_inf(G, xp))
    g0, gmax = be.to_host(g[:, 0]), be.to_host(g[:, -1])
    return g0 - vector_bounds(g0, res, scale, 0.0, G.shape[-1]) - 4 * n * EPS * fro2, gmax


def fingerprint(xp, S) -> dict:
    """Per reduced column (L, k) the sliding contact with the largest |S| and that S's sign: what `LazyVectors` needs
    to give a recomputed eigenvector the sign its consistency code was computed with."""
    if S.shape[1] == 0:
        return {"finger": xp.zeros(S.shape[::2], dtype=xp.int64), "sign": xp.ones(S.shape[::2])}
    finger = xp.argmax(xp.abs(S), axis=1)
    return {"finger": finger, "sign": xp.sign(xp.take_along_axis(S, finger[:, None, :], axis=1)[:, 0, :])}


def _plain_arrays(problem: Problem, h: dict, uniqueness: bool = True) -> dict:
    """Per-chunk arrays of the plain branches' Branch fields: the rigid motions as exact zeros (code RIGID, error
    bound ‖E_i‖_F) sorted in with the reduced eigenvalues; ℍ^i's nullity (the rigid motions, proven by `_special`;
    -1 without uniqueness: not evaluated)."""
    L = h["lam"].shape[0]
    r = problem.rigid.shape[1]
    lam = np.concatenate([np.zeros((L, r)), h["lam"]], axis=1)
    order = np.argsort(lam, axis=1, kind="stable")
    err = np.concatenate([np.broadcast_to(h["leak"][:, None] + problem.formation_error, (L, r)), h["bounds"]],
                         axis=1)
    codes = np.concatenate([np.full((L, r), RIGID, np.int8), h["codes"]], axis=1)
    hinges = np.concatenate([np.zeros((L, r), bool), h["hinges"]], axis=1)
    norm = np.maximum(np.abs(lam).max(axis=1), 1e-300)
    res = (np.sqrt(2.0) * h["res"].max(axis=1, initial=0.0) + h["leak"]) / norm
    take = lambda a: np.take_along_axis(a, order, axis=1)              # noqa: E731
    return {"lam": take(lam), "err": take(err), "codes": take(codes), "hinges": take(hinges), "order": order,
            "tol": err.max(axis=1), "res": res, "finger": h["finger"], "sign": h["sign"],
            "n_null": np.full(L, r if uniqueness else -1)}


def _plain(problem: Problem, red: Reduced, mask, p: dict) -> Branch:
    """A Branch from one row of `_plain_arrays`, eigenvectors recomputed on demand."""
    r = problem.rigid.shape[1]
    return Branch(mask=mask, stability_eigenvalues=p["lam"], stability_vectors=LazyVectors(
                      problem, red, mask, p["order"], p["finger"], p["sign"]), codes=p["codes"], hinges=p["hinges"],
                  n_zero=r, zero_tol=float(p["tol"]), uniqueness_eigenvalues=np.zeros(0, complex),
                  uniqueness_n_zero=int(p["n_null"]), type2=[], residual_stability=float(p["res"]),
                  residual_uniqueness=0.0, bounds=p["err"])


class LazyVectors:
    """The eigenvectors of a plain branch (n, n), computed when indexed: the branch's reduced matrix is solved
    again (one k × k eigh) and each column's sign is set to the one its consistency code was computed with (the
    sign of its largest S value: `finger` and `sign` per reduced column); the rigid columns are the orthonormal
    rigid basis; `order` sorts the columns like the branch's eigenvalues."""

    def __init__(self, problem, red, mask, order, finger, sign):
        self.problem, self.red, self.mask = problem, red, mask
        self.order, self.finger, self.sign = order, finger, sign

    @property
    def shape(self):
        return (self.red.n, self.red.n)

    def array(self, columns=None) -> np.ndarray:
        """The vectors (n, n), or only the sorted `columns` (an index array): then only the reduced eigenvectors
        between the lowest and the highest of them are computed (scipy's eigh with subset_by_index: the reduction
        to tridiagonal form and a few vectors, a fifth of a full eigh at 900 dofs; attribution asks for the few
        negative modes of a branch)."""
        cols = np.arange(len(self.order)) if columns is None else np.atleast_1d(np.asarray(columns))
        cols = np.flatnonzero(cols) if cols.dtype == bool else cols
        r = self.problem.rigid.shape[1]
        picked = self.order[cols]
        reduced = picked[picked >= r] - r
        V = np.zeros((self.red.n, len(cols)))
        V[:, picked < r] = self.problem.rigid[:, picked[picked < r]]
        if reduced.size:
            lo, hi = int(reduced.min()), int(reduced.max())
            on = (self.mask[None, self.problem.sliding] == 1).astype(float)
            with backend("cpu").threads(self.red.k):
                M = branch_stack(np, self.red, on)[0]
                W = np.linalg.eigh(M)[1] if hi - lo + 1 == self.red.k else \
                    scipy.linalg.eigh(M, subset_by_index=[lo, hi])[1]
            W = W[:, reduced - lo]
            if self.red.s.size:
                finger = self.finger[reduced]
                flip = np.sign((self.red.s.T @ W)[finger, np.arange(W.shape[1])]) * self.sign[reduced]
                W = W * np.where(flip == 0, 1.0, flip)[None, :]
            V[:, picked >= r] = self.red.N @ W
        return V

    def __array__(self, dtype=None, copy=None):
        V = self.array()
        return V if dtype is None else V.astype(dtype)

    def __getitem__(self, index):
        """V[index]; V[:, j] (j an int or an index array) computes only the columns asked for (`array`)."""
        if isinstance(index, tuple) and len(index) == 2 and index[0] == slice(None) and \
                isinstance(index[1], (int, np.integer, list, np.ndarray)):
            one = np.ndim(index[1]) == 0
            V = self.array(index[1])
            return V[:, 0] if one else V
        return self.array()[index]
