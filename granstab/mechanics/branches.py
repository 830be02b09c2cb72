"""Loading branches of the sliding contacts and their consistent eigenmodes (Sec. 3, Appendix D).

With Ms potentially sliding contacts there are 2^Ms branches; a mask has +1 (loading, sliding), -1 (unloading,
elastic) for each of them and 0 for contacts not at yield (`sign_patterns`: the branches of one cluster or of a
stack of clusters). Branch i has H^i = H_el + Σ_{mask=+1} a ⊗ s (rank-one sliding terms, eq:ContactF),
ℍ^i = H^i P^nrr and 𝓗^i = Pᵀ H^i P (eq:newstiffnesses), in the scaled dofs of rigid.py. The eigen solvers are in
solve/ (dense.py, lowrank.py, sparse.py) and the scan's batch (scan/batch.py); what decides consistency is here,
written once for all of them.

Consistency (Appendix D): the test vector of a motion v is sign(S) per potentially sliding contact with
S = g·δu_def (eq:flow) and |S| <= s_tol counted as 0; v is consistent if mask·test is all >= 0, -v if all <= 0,
both if all 0. A repeated eigenvalue (or the non-rigid part of the zero eigenspace) has no preferred basis:
there the whole eigenspace is searched for a consistent vector with a small linear program.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from ..model.tolerances import EPS

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
    free_spins: int = 0             # rotation dofs no contact feels (rigid.untouched_dofs), set aside with the rigid ones
    curvature_entrywise: object = None  # sym. entrywise bound (n, n, sparse) of H̃'s error from K^p + K^q, or None
    curvature_bound: float = np.inf    # its 2-norm bound e_K, part of formation_error (accuracy.tightened)

    @property
    def s_tol(self) -> float:
        """|S| <= s_tol counts as zero (`s_limits`)."""
        return s_limits(self.S, self.tol)[0]

    @property
    def s_floor(self) -> float:
        """Round-off level of S (`s_limits`)."""
        return s_limits(self.S, self.tol)[1]


def s_limits(S: np.ndarray, tol):
    """(s_tol, s_floor) of the sliding factors S (..., n, Ms), per matrix of a stack: |S| <= s_tol counts as zero,
    s_rtol times the largest ‖s_c‖ (the scale of S for a unit motion); below s_floor (1e3 ε of that scale) an S is a
    structural zero, above it (and <= s_tol) a verdict 'hinges'."""
    scale = np.linalg.norm(S, axis=-2).max(axis=-1, initial=0.0)
    return tol.s_rtol * scale, 1e3 * EPS * scale


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


def sign_patterns(n_sliding: np.ndarray, width: int):
    """The branches of a stack of clusters, cluster c with n_sliding[c] = Ms_c potentially sliding contacts: the
    owner (B,) and the signs (B, width) of all 2^Ms_c branches of every cluster, ±1 on its first Ms_c columns and 0
    after them; per cluster branch 0 is all loading (+1) and bit j of the branch number unloads column Ms_c - 1 - j."""
    n_sliding = np.asarray(n_sliding)
    owner = np.repeat(np.arange(len(n_sliding)), 2 ** n_sliding)
    signs = np.zeros((len(owner), width), dtype=np.int8)
    first = np.r_[0, np.cumsum(2 ** n_sliding)[:-1]]
    for k in np.unique(n_sliding):
        rows = (first[n_sliding == k][:, None] + np.arange(2 ** k)).ravel()
        bits = (np.arange(2 ** k)[:, None] >> np.arange(k)[::-1]) & 1
        signs[rows, :k] = np.tile(1 - 2 * bits, (int(np.sum(n_sliding == k)), 1))
    return owner, signs


def enumerate_masks(sliding: np.ndarray, n_contacts: int) -> np.ndarray:
    """All 2^Ms masks (L, M) of one scene: ±1 on the potentially sliding contacts (`sign_patterns`: branch 0 all
    +1), 0 elsewhere."""
    _, signs = sign_patterns([len(sliding)], len(sliding))
    masks = np.zeros((len(signs), n_contacts), dtype=np.int8)
    masks[:, sliding] = signs
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


def needs_search(lam: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Per branch (rows of sorted eigenvalues lam (..., n) with their bounds) whether Appendix D needs the
    eigenspace search: a repeated eigenvalue (neighbours whose error intervals touch, `eigen_groups`) or a zero
    within its bound; on the solved dofs of the rigid-free paths any zero is a non-rigid one."""
    return (np.any(np.diff(lam, axis=-1) <= bounds[..., :-1] + bounds[..., 1:], axis=-1)
            | np.any(np.abs(lam) <= bounds, axis=-1))


def search_subspace(problem: Problem, mask: np.ndarray, W: np.ndarray):
    """A consistent unit vector in span(W) (n, k), or None: (vector, code, hinges).

    Maximises the smallest mask_j·S_j over the box |c| <= 1 (a linear program); if that is not positive, a vector
    with every S_j = 0 (consistent both ways) or with all mask_j·S_j >= 0 and some > 0 is looked for.
    """
    m = mask[problem.sliding].astype(float)
    A = (problem.S.T @ W)[m != 0] * m[m != 0][:, None]               # rows m_j S_j(c)
    k = W.shape[1]
    if A.shape[0] == 0:
        return canonical(_unit(W[:, 0])), BOTH, False
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


def search_eigenspaces(problem: Problem, mask: np.ndarray, lam: np.ndarray, bounds: np.ndarray, V: np.ndarray,
                       codes: np.ndarray, hinges: np.ndarray, null_slots=(), null_basis=None) -> None:
    """Appendix D where eigenpairs cannot be tested one by one, in place on V (n, n_eig), codes and hinges: each run
    of eigenvalues within each other's bounds (`eigen_groups`) without a zero is one eigenspace, searched for a
    consistent vector (`search_subspace`: the run's first column gets it, the others are INCONSISTENT); then likewise
    the non-rigid null space, whose orthonormal basis `null_basis` (n, k) is put in the columns `null_slots` (k,)."""
    zero = np.abs(lam) <= bounds
    for group in eigen_groups(lam, bounds):
        if len(group) > 1 and not zero[group].any():
            _take_consistent(problem, mask, V, codes, hinges, group, V[:, group])
    if len(null_slots):
        V[:, null_slots] = null_basis
        _take_consistent(problem, mask, V, codes, hinges, null_slots, null_basis)


def _take_consistent(problem, mask, V, codes, hinges, slots, W) -> None:
    """The columns `slots` of V span(W): INCONSISTENT, unless `search_subspace` finds a consistent vector, which
    then takes the first slot."""
    codes[slots] = INCONSISTENT
    found = search_subspace(problem, mask, W)
    if found is not None:
        V[:, slots[0]], codes[slots[0]], hinges[slots[0]] = found


def _unit(v):
    return v / np.linalg.norm(v)


def _finish(problem, mask, v):
    v = canonical(_unit(v))
    codes, hinges = test_codes(problem, mask[None], v[None, :, None])
    code = int(codes[0, 0])
    if code == INCONSISTENT:
        return None
    return v, code, bool(hinges[0, 0])


SIGN_TIE = 1e-6   # entries within this relative distance of a column's largest magnitude count as tied for it
# (1e-6, not 1e-8: an eigenvector's entries move by ~ε‖H‖/gap between BLAS builds, far above ε when gaps are small)


def column_signs(V, xp=np):
    """±1 per eigenvector column of V (..., n, k): THE sign rule of every reported vector (the dense, low-rank and
    sparse paths, the eigenspace search's vectors, the paper's tables). The first entry, in dof order, whose
    magnitude is within SIGN_TIE (relative) of the column's largest is made positive. LAPACK's sign choice varies
    between builds, CPU kernels (OpenBLAS Haswell/SkylakeX) and BLAS thread counts, and so does which of two
    entries equal by symmetry comes out larger at round-off (four_disk: 0.60150096 twice, 5.5e-16 apart); the
    reported vector_sign (±v consistent) must not."""
    mag = xp.abs(V)
    tied = mag >= (1 - SIGN_TIE) * mag.max(axis=-2, keepdims=True)
    idx = xp.argmax(tied, axis=-2)[..., None, :]
    return xp.where(xp.take_along_axis(V, idx, axis=-2) < 0, -1.0, 1.0)


def canonical_signs(V: np.ndarray) -> np.ndarray:
    """Eigenvectors (..., n, k) in the sign convention of `column_signs`."""
    return V * column_signs(V)


def canonical(v: np.ndarray) -> np.ndarray:
    """One vector (n,) in the sign convention of `column_signs`."""
    return v * column_signs(v[:, None])[0, 0]


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
