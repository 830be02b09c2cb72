"""The full per-branch path: every eigenpair of every branch's sym(𝓗^i) and ℍ^i (eq:newstiffnesses), stacked in
chunks (LAPACK eigh, eig, SVD), with the subspace search of Appendix D where an eigenvalue is repeated or a zero
is not rigid, and Type-2 null vectors of ℍ^i (Sec. 3.1)."""
from __future__ import annotations

import numpy as np

from ..mechanics.accuracy import eigen_bounds, gamma, tightened
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


def solve_branches(problem: Problem, masks: np.ndarray, chunk: int | None = None, on_branch=None,
                   uniqueness: bool = True) -> list[Branch]:
    """Spectra and consistent modes of every branch in `masks`, stacked in chunks; `on_branch(b)` streams results.
    uniqueness=False leaves out ℍ^i (its eig and SVDs, Type-2: uniqueness eigenvalues empty, uniqueness_n_zero -1);
    the stability results (sym(𝓗^i) spectra, codes, bounds) are the same.

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
            mu, W = np.linalg.eig(HH) if uniqueness else (None, None)
            codes, hinges = test_codes(problem, part, V)
            batch = _batched(problem, Hsym, HH, lam, V, mu, W)
        for i, mask in enumerate(part):
            eig = None if mu is None else (mu[i], W[i])
            if batch["special"][i]:
                b = _branch(problem, mask, Hsym[i], HH[i], lam[i], V[i], codes[i], hinges[i], eig,
                            svd=batch["svd"].get(i))
            else:
                b = _plain_branch(problem, mask, batch, i, lam[i], V[i], codes[i], hinges[i], eig)
            out.append(b)
            if on_branch is not None:
                on_branch(b)
    return out


def _batched(problem, Hsym, HH, lam, V, mu, W) -> dict:
    """Per-chunk arrays of `_branch` for L branches at once: zero tolerances, which branches need the per-branch
    subspace search ("special"), the ℍ null-space counts and both eigen-residuals (mu None: no ℍ, `_uniqueness`).

    The rigid motions are exact null vectors of sym(𝓗^i) and ℍ^i, so a branch whose zero count equals the number
    of rigid motions has nothing else in its null space; only branches with more zeros are examined further
    (singular vectors are computed for those alone)."""
    L, n = lam.shape
    R = problem.rigid
    n_rigid = R.shape[1]
    norm = np.maximum(np.abs(lam).max(axis=1), 1e-300)
    bounds, resid = eigen_bounds(Hsym, lam, V, formation(problem, Hsym))   # accuracy.py: |λ - λ̂| <= bound
    bounds = tighten(problem, Hsym, lam, V, bounds, resid)
    tol = bounds.max(axis=1) if n else np.zeros(L)
    zero = np.abs(lam) <= bounds
    close = np.diff(lam, axis=1) <= bounds[:, :-1] + bounds[:, 1:]   # adjacent eigenvalues in one group
    repeated = np.any(close & ~zero[:, :-1] & ~zero[:, 1:], axis=1) | np.any(close & (zero[:, :-1] ^ zero[:, 1:]),
                                                                             axis=1)
    extra_z = np.zeros(L, dtype=int)
    more = np.flatnonzero(zero.sum(axis=1) > n_rigid)
    if more.size:
        extra_z[more] = _count_nonrigid(R, V[more] * zero[more][:, None, :])
    u = _uniqueness(problem, HH, mu, W) if mu is not None else \
        {"n_null": np.full(L, -1), "extra": np.zeros(L, dtype=int), "res_u": np.zeros(L), "svd": {}}
    res_s = resid.max(axis=1) / norm if n else np.zeros(L)
    return {"tol": tol, "bounds": bounds, "zero": zero, "special": repeated | (extra_z > 0) | (u["extra"] > 0),
            "n_null": u["n_null"], "res_s": res_s, "res_u": u["res_u"], "svd": u["svd"]}


def _uniqueness(problem, HH, mu, W) -> dict:
    """The ℍ^i part of `_batched`: null-space counts (SVD), how many null vectors are not rigid, the singular
    vectors of the branches that have some (for `_branch`), and the residuals of eig."""
    L, n = mu.shape
    R = problem.rigid
    sv = np.linalg.svd(HH, compute_uv=False)
    norm_u = np.maximum(sv.max(axis=1), 1e-300)
    tol_u = problem.tol.zero_factor * max(n, 1) * EPS * norm_u
    null = sv <= tol_u[:, None]
    extra_u = np.zeros(L, dtype=int)
    more = np.flatnonzero(null.sum(axis=1) > R.shape[1])
    svd = {}
    if more.size:
        _, sv_m, Vt_m = np.linalg.svd(HH[more])
        null_m = sv_m <= tol_u[more, None]
        extra_u[more] = _count_nonrigid(R, np.swapaxes(Vt_m, 1, 2) * null_m[:, None, :])
        svd = {int(i): (sv_m[j], Vt_m[j]) for j, i in enumerate(more)}
    res_u = np.linalg.norm(HH @ W - W * mu[:, None, :], axis=1).max(axis=1) / norm_u if n else np.zeros(L)
    return {"n_null": null.sum(axis=1), "extra": extra_u, "res_u": res_u, "svd": svd}


def formation(problem, Hsym: np.ndarray):
    """The formation bound of each branch (..., 1): the problem's (accuracy.formation_error) plus the rigid leakage
    ‖sym(𝓗^i) R‖_F that remains (zero in exact arithmetic: R is the rigid basis), so that a rigid motion leaking
    into the spectrum can never pass for a resolved eigenvalue (issue 26)."""
    leak = np.linalg.norm(Hsym @ problem.rigid, axis=(-2, -1)) if problem.rigid.size else np.zeros(Hsym.shape[:-2])
    return problem.formation_error + np.asarray(leak)[..., None]


def tighten(problem, Hsym: np.ndarray, lam: np.ndarray, V: np.ndarray, bounds: np.ndarray, resid: np.ndarray) -> \
        np.ndarray:
    """`bounds` (..., n) tightened by accuracy.tightened where that is smaller: where the formation error is mostly
    the curvature sum's (near-conforming contacts), an eigenvalue away from the others' intervals is bounded by
    |u|ᵀE|u| + ρ²/gap instead of ‖E‖ (docs/bounds.md). The residual's rounding is taken per vector,
    γ_{n+2}(‖|A||u|‖ + |λ|), instead of γ_{n+2}(‖|A|‖∞ + |λ|)."""
    n = lam.shape[-1]
    if not tightenable(problem) or n == 0:
        return bounds
    idx = np.arange(n)
    r_bar = resid + gamma(n + 2) * (np.linalg.norm(np.abs(Hsym) @ np.abs(V), axis=-2) + np.abs(lam))
    return tightened(lam, bounds, idx, V, r_bar, problem.curvature_entrywise, problem.curvature_bound,
                     formation_rest(problem, formation(problem, Hsym)), projection_defect(problem, V))


def tightenable(problem) -> bool:
    """Whether the problem's formation error has an entrywise part to tighten with (accuracy.tightened)."""
    e_K = problem.curvature_bound
    return problem.curvature_entrywise is not None and bool(np.isfinite(e_K)) and e_K > 0


def formation_rest(problem, form):
    """The formation bound less its curvature part e_K (the 2-norm rest of accuracy.tightened), rounded up."""
    return form - problem.curvature_bound + 2 * EPS * form


def projection_defect(problem, U: np.ndarray) -> np.ndarray:
    """A bound of ‖(I - P)u‖ per column of U (..., n, c): ‖C C⁺ u‖ as computed plus its rounding, 2γ_n κ(C̃) (the
    projection's term of accuracy.formation_error)."""
    C, Cplus = problem.projection.C, problem.projection.Cplus
    if not C.size:
        return np.zeros(U.shape[:-2] + U.shape[-1:])
    kappa = float(np.linalg.norm(C) * np.linalg.norm(Cplus))
    return np.linalg.norm(C @ (Cplus @ U), axis=-2) + 2 * gamma(C.shape[0]) * kappa


def _count_nonrigid(R: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Stacked version of `non_rigid_part(...).shape[1]`: singular values > 0.5 of (I - R Rᵀ) W, W (L, n, k)."""
    if W.shape[2] == 0:
        return np.zeros(W.shape[0], dtype=int)
    Wp = W - R @ (R.T @ W)
    return np.sum(np.linalg.svd(Wp, compute_uv=False) > 0.5, axis=1)


def _sorted(eig) -> np.ndarray:
    """The eigenvalues of ℍ^i by real part (eig: (mu, W) or None where ℍ^i is left out: empty)."""
    return np.zeros(0, complex) if eig is None else eig[0][np.argsort(eig[0].real, kind="stable")]


def _plain_branch(problem, mask, batch, i, lam, V, codes, hinges, eig) -> Branch:
    """`_branch` for a branch without repeated non-zero eigenvalues, non-rigid zeros or Type-2 null vectors:
    the zero eigenvalues are the rigid motions and nothing needs a subspace search."""
    zero = batch["zero"][i]
    codes = codes.copy()
    hinges = hinges.copy()
    codes[zero] = RIGID
    hinges[zero] = False
    return Branch(mask=mask, stability_eigenvalues=lam, stability_vectors=V.copy(), codes=codes, hinges=hinges,
                  n_zero=int(zero.sum()), zero_tol=float(batch["tol"][i]), uniqueness_eigenvalues=_sorted(eig),
                  uniqueness_n_zero=int(batch["n_null"][i]), type2=[],
                  residual_stability=float(batch["res_s"][i]), residual_uniqueness=float(batch["res_u"][i]),
                  bounds=batch["bounds"][i])


def _branch(problem, mask, Hsym, HH, lam, V, codes, hinges, eig, svd=None) -> Branch:
    """One branch with the subspace search of Appendix D; eig: ℍ^i's (mu, W), or None to leave ℍ^i out."""
    n = len(lam)
    norm = max(np.abs(lam).max(), 1e-300)
    bounds, resid = eigen_bounds(Hsym, lam, V, formation(problem, Hsym))
    bounds = tighten(problem, Hsym, lam, V, bounds, resid)
    tol = float(bounds.max()) if n else 0.0
    V = V.copy()
    codes = codes.copy()
    hinges = hinges.copy()
    zero = np.flatnonzero(np.abs(lam) <= bounds)
    extra = non_rigid_part(problem, V[:, zero]) if zero.size else V[:, :0]   # the non-rigid null space, last
    codes[zero] = RIGID
    hinges[zero] = False
    search_eigenspaces(problem, mask, lam, bounds, V, codes, hinges, zero[len(zero) - extra.shape[1]:], extra)
    res_cols = np.linalg.norm(Hsym @ V - V * lam, axis=0)
    res_s = float(res_cols.max(initial=0.0) / norm)
    n_null, type2, res_u = -1, [], 0.0
    if eig is not None:
        sv, Vt = svd if svd is not None else np.linalg.svd(HH)[1:]
        norm_u = max(sv.max(), 1e-300)
        null = Vt[sv <= problem.tol.zero_tol(norm_u, n)].T
        n_null, type2 = int(null.shape[1]), _type2(problem, mask, null)
        res_u = float(np.linalg.norm(HH @ eig[1] - eig[1] * eig[0], axis=0).max() / norm_u) if n else 0.0
    return Branch(mask=mask, stability_eigenvalues=lam, stability_vectors=V, codes=codes, hinges=hinges,
                  n_zero=int(zero.size), zero_tol=tol, uniqueness_eigenvalues=_sorted(eig),
                  uniqueness_n_zero=n_null, type2=type2, residual_stability=res_s, residual_uniqueness=res_u,
                  bounds=bounds)


def _type2(problem, mask, null) -> list:
    """Consistent non-rigid null vectors of ℍ^i (nullity from the SVD): Type-2 non-uniqueness (Sec. 3.1)."""
    extra = non_rigid_part(problem, null) if null.shape[1] else null
    if extra.shape[1] == 0:
        return []
    found = search_subspace(problem, mask, extra)
    return [] if found is None else [{"vector": found[0], "vector_sign": found[1], "hinges": found[2],
                                      "dimension": int(extra.shape[1])}]
