"""The full per-branch path: every eigenpair of every branch's sym(𝓗^i) and ℍ^i (eq:newstiffnesses), stacked in
chunks (LAPACK eigh, eig, SVD), with the subspace search of Appendix D where an eigenvalue is repeated or a zero
is not rigid, and Type-2 null vectors of ℍ^i (Sec. 3.1)."""
from __future__ import annotations

import numpy as np

from ..mechanics.accuracy import eigen_bounds
from ..mechanics.branches import (
    RIGID,
    Branch,
    Problem,
    branch_matrices,
    canonical_signs,
    non_rigid_part,
    search_eigenspaces,
    search_subspace,
    test_codes,
)
from ..model.tolerances import EPS
from .threads import sized


def solve_branches(problem: Problem, masks: np.ndarray, chunk: int | None = None, on_branch=None) -> list[Branch]:
    """Spectra and consistent modes of every branch in `masks`, stacked in chunks; `on_branch(b)` streams results.

    Everything that is the same computation on every branch runs batched over the chunk (eigh, eig, SVD,
    residuals, the zero/repeated-eigenvalue tests, the rigid part of the null spaces); only branches with a
    repeated non-zero eigenvalue or a non-rigid zero (which need the subspace search of Appendix D) take the
    per-branch path `_branch`, which gives identical results for the others.
    """
    n = problem.H_el.shape[0]
    chunk = chunk or max(1, int(4e7 // (8 * n * n * 6)))
    out = []
    for start in range(0, len(masks), chunk):
        part = masks[start:start + chunk]
        with sized(n):                                                # threads.py: 1 thread for small stacks
            _, HH, Hsym = branch_matrices(problem, part)
            lam, V = np.linalg.eigh(Hsym)
            V = canonical_signs(V)
            mu, W = np.linalg.eig(HH)
            codes, hinges = test_codes(problem, part, V)
            batch = _batched(problem, Hsym, HH, lam, V, mu, W)
        for i, mask in enumerate(part):
            if batch["special"][i]:
                b = _branch(problem, mask, Hsym[i], HH[i], lam[i], V[i], codes[i], hinges[i], mu[i], W[i],
                            svd=batch["svd"].get(i))
            else:
                b = _plain_branch(problem, mask, batch, i, lam[i], V[i], codes[i], hinges[i], mu[i])
            out.append(b)
            if on_branch is not None:
                on_branch(b)
    return out


def _batched(problem, Hsym, HH, lam, V, mu, W) -> dict:
    """Per-chunk arrays of `_branch` for L branches at once: zero tolerances, which branches need the per-branch
    subspace search ("special"), the ℍ null-space counts and both eigen-residuals.

    The rigid motions are exact null vectors of sym(𝓗^i) and ℍ^i, so a branch whose zero count equals the number
    of rigid motions has nothing else in its null space; only branches with more zeros are examined further
    (singular vectors are computed for those alone)."""
    L, n = lam.shape
    R = problem.rigid
    n_rigid = R.shape[1]
    norm = np.maximum(np.abs(lam).max(axis=1), 1e-300)
    bounds, resid = eigen_bounds(Hsym, lam, V, formation(problem, Hsym))   # accuracy.py: |λ - λ̂| <= bound
    tol = bounds.max(axis=1) if n else np.zeros(L)
    zero = np.abs(lam) <= bounds
    close = np.diff(lam, axis=1) <= bounds[:, :-1] + bounds[:, 1:]   # adjacent eigenvalues in one group
    repeated = np.any(close & ~zero[:, :-1] & ~zero[:, 1:], axis=1) | np.any(close & (zero[:, :-1] ^ zero[:, 1:]),
                                                                             axis=1)
    extra_z = np.zeros(L, dtype=int)
    more = np.flatnonzero(zero.sum(axis=1) > n_rigid)
    if more.size:
        extra_z[more] = _count_nonrigid(R, V[more] * zero[more][:, None, :])
    sv = np.linalg.svd(HH, compute_uv=False)
    norm_u = np.maximum(sv.max(axis=1), 1e-300)
    tol_u = problem.tol.zero_factor * max(n, 1) * EPS * norm_u
    null = sv <= tol_u[:, None]
    extra_u = np.zeros(L, dtype=int)
    more = np.flatnonzero(null.sum(axis=1) > n_rigid)
    svd = {}
    if more.size:
        _, sv_m, Vt_m = np.linalg.svd(HH[more])
        null_m = sv_m <= tol_u[more, None]
        extra_u[more] = _count_nonrigid(R, np.swapaxes(Vt_m, 1, 2) * null_m[:, None, :])
        svd = {int(i): (sv_m[j], Vt_m[j]) for j, i in enumerate(more)}
    res_s = resid.max(axis=1) / norm if n else np.zeros(L)
    res_u = np.linalg.norm(HH @ W - W * mu[:, None, :], axis=1).max(axis=1) / norm_u if n else np.zeros(L)
    return {"tol": tol, "bounds": bounds, "zero": zero, "special": repeated | (extra_z > 0) | (extra_u > 0),
            "n_null": null.sum(axis=1), "res_s": res_s, "res_u": res_u, "svd": svd}


def formation(problem, Hsym: np.ndarray):
    """The formation bound of each branch (..., 1): the problem's (accuracy.formation_error) plus the rigid leakage
    ‖sym(𝓗^i) R‖_F that remains (zero in exact arithmetic: R is the rigid basis), so that a rigid motion leaking
    into the spectrum can never pass for a resolved eigenvalue (issue 26)."""
    leak = np.linalg.norm(Hsym @ problem.rigid, axis=(-2, -1)) if problem.rigid.size else np.zeros(Hsym.shape[:-2])
    return problem.formation_error + np.asarray(leak)[..., None]


def _count_nonrigid(R: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Stacked version of `non_rigid_part(...).shape[1]`: singular values > 0.5 of (I - R Rᵀ) W, W (L, n, k)."""
    if W.shape[2] == 0:
        return np.zeros(W.shape[0], dtype=int)
    Wp = W - R @ (R.T @ W)
    return np.sum(np.linalg.svd(Wp, compute_uv=False) > 0.5, axis=1)


def _plain_branch(problem, mask, batch, i, lam, V, codes, hinges, mu) -> Branch:
    """`_branch` for a branch without repeated non-zero eigenvalues, non-rigid zeros or Type-2 null vectors:
    the zero eigenvalues are the rigid motions and nothing needs a subspace search."""
    zero = batch["zero"][i]
    codes = codes.copy()
    hinges = hinges.copy()
    codes[zero] = RIGID
    hinges[zero] = False
    order = np.argsort(mu.real, kind="stable")
    return Branch(mask=mask, stability_eigenvalues=lam, stability_vectors=V.copy(), codes=codes, hinges=hinges,
                  n_zero=int(zero.sum()), zero_tol=float(batch["tol"][i]), uniqueness_eigenvalues=mu[order],
                  uniqueness_n_zero=int(batch["n_null"][i]), type2=[],
                  residual_stability=float(batch["res_s"][i]), residual_uniqueness=float(batch["res_u"][i]),
                  bounds=batch["bounds"][i])


def _branch(problem, mask, Hsym, HH, lam, V, codes, hinges, mu, W, svd=None) -> Branch:
    n = len(lam)
    norm = max(np.abs(lam).max(), 1e-300)
    bounds, _ = eigen_bounds(Hsym, lam, V, formation(problem, Hsym))
    tol = float(bounds.max()) if n else 0.0
    V = V.copy()
    codes = codes.copy()
    hinges = hinges.copy()
    zero = np.flatnonzero(np.abs(lam) <= bounds)
    extra = non_rigid_part(problem, V[:, zero]) if zero.size else V[:, :0]   # the non-rigid null space, last
    codes[zero] = RIGID
    hinges[zero] = False
    search_eigenspaces(problem, mask, lam, bounds, V, codes, hinges, zero[len(zero) - extra.shape[1]:], extra)
    order = np.argsort(mu.real, kind="stable")
    sv, Vt = svd if svd is not None else np.linalg.svd(HH)[1:]
    norm_u = max(sv.max(), 1e-300)
    tol_u = problem.tol.zero_tol(norm_u, n)
    null = Vt[sv <= tol_u].T
    res_cols = np.linalg.norm(Hsym @ V - V * lam, axis=0)
    res_s = float(res_cols.max(initial=0.0) / norm)
    res_u = float(np.linalg.norm(HH @ W - W * mu, axis=0).max() / norm_u) if n else 0.0
    return Branch(mask=mask, stability_eigenvalues=lam, stability_vectors=V, codes=codes, hinges=hinges,
                  n_zero=int(zero.size), zero_tol=tol, uniqueness_eigenvalues=mu[order],
                  uniqueness_n_zero=int(null.shape[1]), type2=_type2(problem, mask, null),
                  residual_stability=res_s, residual_uniqueness=res_u, bounds=bounds)


def _type2(problem, mask, null) -> list:
    """Consistent non-rigid null vectors of ℍ^i (nullity from the SVD): Type-2 non-uniqueness (Sec. 3.1)."""
    extra = non_rigid_part(problem, null) if null.shape[1] else null
    if extra.shape[1] == 0:
        return []
    found = search_subspace(problem, mask, extra)
    return [] if found is None else [{"vector": found[0], "vector_sign": found[1], "hinges": found[2],
                                      "dimension": int(extra.shape[1])}]
