"""Loading branches of the sliding contacts and their consistent eigenmodes (Sec. 3, Appendix D).

With Ms potentially sliding contacts there are 2^Ms branches; a mask has +1 (loading, sliding), -1 (unloading,
elastic) for each of them and 0 for contacts not at yield. Branch i has H^i = H_el + Σ_{mask=+1} a ⊗ s (rank-one
sliding terms, eq:ContactF), ℍ^i = H^i P^nrr and 𝓗^i = Pᵀ H^i P (eq:newstiffnesses). All branches are handled
as one stacked array (in chunks), in the scaled dofs of rigid.py; from lowrank.MIN_BRANCHES branches on (or on a
GPU) analyze() uses lowrank.py, which solves them as low-rank updates of the elastic problem and hands only the
branches that need the per-branch code below (repeated eigenvalues, non-rigid zeros, Type-2) to solve_branches.

Consistency (Appendix D): the test vector of a motion v is sign(S) per potentially sliding contact with
S = g·δu_def (eq:flow) and |S| <= s_tol counted as 0; v is consistent if mask·test is all >= 0, -v if all <= 0,
both if all 0. A repeated eigenvalue (or the non-rigid part of the zero eigenspace) has no preferred basis:
there the whole eigenspace is searched for a consistent vector with a small linear program.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from .accuracy import eigen_bounds
from .threads import sized
from .tolerances import EPS

# codes of an eigenpair's consistency: vector_sign +1 / -1 / 0 (both), not consistent, rigid (trivial)
PLUS, MINUS, BOTH, INCONSISTENT, RIGID = 1, -1, 0, 2, 3


@dataclass(frozen=True, eq=False)
class Problem:
    """Everything a branch needs, in scaled dofs: H_el (n, n), sliding factors A, S (n, Ms), projection, rigid basis."""

    H_el: np.ndarray
    A: np.ndarray
    S: np.ndarray
    projection: object
    rigid: np.ndarray          # (n, n_rigid) orthonormal basis of all rigid motions
    sliding: np.ndarray        # (Ms,) indices of the potentially sliding contacts
    n_contacts: int
    tol: object
    formation_error: float = 0.0   # bound of ‖sym(𝓗) computed − exact‖₂ from forming it (accuracy.formation_error)
    free: np.ndarray | None = None  # the scene's dofs these n are (Scene.free_dofs), None: all of them

    @property
    def s_tol(self) -> float:
        """|S| <= s_tol counts as zero: s_rtol times the largest |s_c|, the scale of S for a unit motion."""
        scale = np.linalg.norm(self.S, axis=0).max() if self.S.size else 0.0
        return self.tol.s_rtol * scale

    @property
    def s_floor(self) -> float:
        """Round-off level of S: below it an S is a structural zero, above it (and <= s_tol) a verdict 'hinges'."""
        scale = np.linalg.norm(self.S, axis=0).max() if self.S.size else 0.0
        return 1e3 * EPS * scale


@dataclass(eq=False)
class Branch:
    """One loading branch: spectra of sym(𝓗^i) (stability) and ℍ^i (uniqueness), with consistency codes.

    stability_vectors are unit columns in scaled dofs Ũ (physical motion U = D Ũ); codes[j] is the consistency of
    eigenpair j (PLUS, MINUS, BOTH, INCONSISTENT, RIGID); hinges[j] is True where the verdict depends on an S
    inside the tolerance band; type2 lists consistent non-rigid null vectors of ℍ^i (Type-2 non-uniqueness).
    """

    mask: np.ndarray
    stability_eigenvalues: np.ndarray
    stability_vectors: np.ndarray
    codes: np.ndarray
    hinges: np.ndarray
    n_zero: int
    zero_tol: float
    uniqueness_eigenvalues: np.ndarray
    uniqueness_n_zero: int
    type2: list = field(default_factory=list)
    residual_stability: float = 0.0
    residual_uniqueness: float = 0.0
    bounds: np.ndarray | None = None   # per stability eigenvalue: |λ_exact - λ| <= bounds[j] (accuracy.py)
    negative_count: dict | None = None  # sparse path: negatives of sym(𝓗^i) (count, total?, inertia shift)

    @property
    def accuracy(self) -> np.ndarray:
        """Per-eigenvalue error bounds (zero_tol for every eigenvalue where none were computed)."""
        lam = self.stability_eigenvalues
        return np.full(lam.shape, self.zero_tol) if self.bounds is None else self.bounds

    def consistent(self) -> list[dict]:
        """Consistent non-trivial eigenpairs: eigenvalue, vector_sign (+1, -1, 0 = both), hinges."""
        out = []
        for j in np.flatnonzero(np.isin(self.codes, (PLUS, MINUS, BOTH))):
            out.append({"eigenvalue": float(self.stability_eigenvalues[j]), "vector_sign": int(self.codes[j]),
                        "hinges_on_tolerance": bool(self.hinges[j]), "index": int(j)})
        return out


def enumerate_masks(sliding: np.ndarray, n_contacts: int) -> np.ndarray:
    """All 2^Ms masks (L, M): ±1 on the potentially sliding contacts (branch 0 all +1), 0 elsewhere."""
    Ms = len(sliding)
    bits = (np.arange(2 ** Ms)[:, None] >> np.arange(Ms)[::-1]) & 1
    masks = np.zeros((2 ** Ms, n_contacts), dtype=np.int8)
    masks[:, sliding] = 1 - 2 * bits
    return masks


def branch_matrices(problem: Problem, masks: np.ndarray):
    """Stacked H^i, ℍ^i and sym(𝓗^i) for masks (L, M): three (L, n, n) arrays."""
    on = (masks[:, problem.sliding] == 1).astype(float)               # (L, Ms)
    H = problem.H_el[None] + np.einsum("nm,lm,km->lnk", problem.A, on, problem.S)
    HH = problem.projection.right(H)
    HS = problem.projection.both(HH)
    return H, HH, 0.5 * (HS + np.swapaxes(HS, 1, 2))


def sample_masks(sliding: np.ndarray, n_contacts: int, n_sample: int, seed: int = 0) -> np.ndarray:
    """The all-loading and all-unloading masks, then up to n_sample distinct seeded random ones (L, M), for Ms too
    large to enumerate the 2^Ms branches."""
    Ms = len(sliding)
    rng = np.random.default_rng(seed)
    signs = np.vstack([np.ones(Ms), -np.ones(Ms), rng.choice([-1.0, 1.0], size=(n_sample, Ms))]).astype(np.int8)
    _, first = np.unique(signs, axis=0, return_index=True)
    masks = np.zeros((len(first), n_contacts), dtype=np.int8)
    masks[:, sliding] = signs[np.sort(first)]
    return masks


def test_codes(problem: Problem, masks: np.ndarray, V: np.ndarray):
    """Appendix-D test of every column of V (L, n, k) against its branch mask: codes (L, k) and hinges (L, k)."""
    return codes_from_s(problem, masks, np.einsum("nm,lnk->lmk", problem.S, V))


def codes_from_s(problem: Problem, masks: np.ndarray, Svals: np.ndarray):
    """`test_codes` from the S values (L, Ms, k) of the columns (S = g·δu_def of each sliding contact, eq:flow)."""
    return consistency(masks[:, problem.sliding][:, :, None].astype(float), Svals, problem.s_tol, problem.s_floor)


def consistency(m, Svals, s_tol, s_floor, xp=np):
    """Appendix-D codes (L, k) and hinges (L, k) of columns with S values Svals (L, Ms, k) against branch masks m
    (L, Ms, 1) (0 for contacts not at yield); s_tol, s_floor: scalars or per branch (L, 1, 1); xp: numpy or CuPy."""
    test = xp.where(xp.abs(Svals) <= s_tol, 0.0, xp.sign(Svals))
    prod = m * test
    plus = xp.all(prod >= 0, axis=1)
    minus = xp.all(prod <= 0, axis=1)
    codes = xp.where(plus & minus, BOTH, xp.where(plus, PLUS, xp.where(minus, MINUS, INCONSISTENT)))
    band = (xp.abs(Svals) <= s_tol) & (xp.abs(Svals) > s_floor) & (m != 0)
    return codes.astype(np.int8), xp.any(band, axis=1)


def search_subspace(problem: Problem, mask: np.ndarray, W: np.ndarray):
    """A consistent unit vector in span(W) (n, k), or None: (vector, code, hinges).

    Maximises the smallest mask_j·S_j over the box |c| <= 1 (a linear program); if that is not positive, a vector
    with every S_j = 0 (consistent both ways) or with all mask_j·S_j >= 0 and some > 0 is looked for.
    """
    m = mask[problem.sliding].astype(float)
    A = (problem.S.T @ W)[m != 0] * m[m != 0][:, None]               # rows m_j S_j(c)
    k = W.shape[1]
    if A.shape[0] == 0:
        return _unit(W[:, 0]), BOTH, False
    res = linprog(np.r_[np.zeros(k), -1.0], A_ub=np.c_[-A, np.ones(len(A))], b_ub=np.zeros(len(A)),
                  bounds=[(-1, 1)] * k + [(None, 1)], method="highs")
    if res.status == 0 and -res.fun > problem.s_tol:
        return _finish(problem, mask, W @ res.x[:k])
    _, sv, Vt = np.linalg.svd(A, full_matrices=True)
    rank = int(np.sum(sv > problem.s_tol))
    if rank < k:
        return _finish(problem, mask, W @ Vt[rank])
    res = linprog(-A.sum(axis=0), A_ub=-A, b_ub=np.zeros(len(A)), bounds=[(-1, 1)] * k, method="highs")
    if res.status == 0 and -res.fun > problem.s_tol:
        return _finish(problem, mask, W @ res.x)
    return None


def _unit(v):
    return v / np.linalg.norm(v)


def _finish(problem, mask, v):
    v = _unit(v)
    codes, hinges = test_codes(problem, mask[None], v[None, :, None])
    code = int(codes[0, 0])
    if code == INCONSISTENT:
        return None
    return v, code, bool(hinges[0, 0])


def canonical_signs(V: np.ndarray) -> np.ndarray:
    """Eigenvectors (..., n, k) with each column's largest-magnitude entry positive: LAPACK's sign choice varies
    between builds, and the reported vector_sign (±v consistent) must not."""
    idx = np.argmax(np.abs(V), axis=-2)[..., None, :]
    return V * np.where(np.take_along_axis(V, idx, axis=-2) < 0, -1.0, 1.0)


def eigen_groups(lam: np.ndarray, tol) -> list[np.ndarray]:
    """Indices of runs of sorted eigenvalues closer than tol (repeated eigenvalues), including singletons; tol a
    number or per-eigenvalue bounds (neighbours whose error intervals touch are one group)."""
    tol = np.asarray(tol, dtype=float)
    gap_tol = tol[:-1] + tol[1:] if tol.ndim else tol
    breaks = np.flatnonzero(np.diff(lam) > gap_tol) + 1
    return np.split(np.arange(len(lam)), breaks)


def non_rigid_part(problem: Problem, W: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the part of span(W) outside the rigid motions."""
    R = problem.rigid
    Wp = W - R @ (R.T @ W)
    U, sv, _ = np.linalg.svd(Wp, full_matrices=False)
    return U[:, sv > 0.5]


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
    bounds, resid = eigen_bounds(Hsym, lam, V, problem.formation_error)   # accuracy.py: |λ - λ̂| <= bound
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
    bounds, _ = eigen_bounds(Hsym, lam, V, problem.formation_error)
    tol = float(bounds.max()) if n else 0.0
    V = V.copy()
    codes = codes.copy()
    hinges = hinges.copy()
    zero = np.flatnonzero(np.abs(lam) <= bounds)
    for group in eigen_groups(lam, bounds):
        if group[0] in zero or len(group) == 1:
            continue
        found = search_subspace(problem, mask, V[:, group])
        codes[group] = INCONSISTENT
        if found is not None:
            V[:, group[0]], codes[group[0]], hinges[group[0]] = found
    if zero.size:
        extra = non_rigid_part(problem, V[:, zero])
        n_extra = extra.shape[1]
        codes[zero] = RIGID
        hinges[zero] = False
        if n_extra:
            slots = zero[len(zero) - n_extra:]
            V[:, slots] = extra
            codes[slots] = INCONSISTENT
            found = search_subspace(problem, mask, extra)
            if found is not None:
                V[:, slots[0]], codes[slots[0]], hinges[slots[0]] = found
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
