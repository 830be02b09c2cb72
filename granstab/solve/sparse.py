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
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..mechanics import checks
from ..mechanics.accuracy import resolved_sign, vector_bounds
from ..mechanics.assembly import Assembly, sliding_factors, stack_blocks
from ..mechanics.branches import RIGID, Branch, Problem, canonical_signs, search_eigenspaces, test_codes
from ..mechanics.checks import modified_leakage
from ..mechanics.metric import Metric, default_length, length_metric
from ..mechanics.rigid import Projection, free_spins, rigid_basis, rotations, translations
from ..mechanics.stiffness import ContactBlocks, assembled_error, contact_blocks, geometric
from ..model.scene import CONTACT_FIELDS, Scene
from ..model.vec import rot_dim, rotate_matrix

SMALL_DENSE = 48   # up to this many dofs lowest_modes uses a dense eigh of the operator (exact, instant)
SIGMA_REL = 1e-6   # default shift σ = -SIGMA_REL · s (s = upper bound of ‖Hs‖): just below 0, above round-off


# ------------------------------------------------------------------------------------------------ assembly

CHUNK = 16384   # contacts per chunk of contact_blocks: temporaries stay ~10 MB, so the cost stays linear in M




def contact_chunks(scene: Scene, chunk: int = CHUNK):
    """(slice, ContactBlocks of those contacts) over the scene's contacts in chunks (global dof indices)."""
    import dataclasses

    M = scene.n_contacts
    if M <= chunk:
        yield slice(0, M), contact_blocks(scene)
        return
    for start in range(0, M, chunk):
        sl = slice(start, min(start + chunk, M))
        sub = dataclasses.replace(scene, **{f: getattr(scene, f)[sl] for f in CONTACT_FIELDS},
                                  state=scene.state[sl])
        yield sl, contact_blocks(sub)


@dataclass(frozen=True, eq=False)
class SparseProblem:
    """A scene set up for the sparse path, in scaled dofs Ũ = D⁻¹U (rigid.py). n = n_dof.

    H: CSR scaled elastic H̃ (non-symmetric); Hs: CSR sym(H̃); Hm: CSR scaled elastic mechanical part (for the
    preconditioner); A, S: (n, Ms) sliding factors (scaled, like branches.Problem); C: (n, r) scaled rotations;
    R: (n, d + r) orthonormal basis of all rigid motions (translations first, rigid.rigid_basis) and Q = R[:, d:]
    (n, r) that of the rotations; norm: upper bound of ‖Hs‖₂ (max absolute row sum, plus the sliding terms);
    local: stiffness.ContactBlocks without its (M, n_loc, n_loc) blocks.
    """

    scene: Scene
    length: float | None
    scale: np.ndarray | None
    metric: Metric
    H: sp.csr_matrix
    Hs: sp.csr_matrix
    Hm: sp.csr_matrix
    A: np.ndarray
    S: np.ndarray
    sliding: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    norm: float
    local: ContactBlocks
    timings: dict = field(default_factory=dict)
    free_spins: int = 0       # rotation dofs no contact feels (rigid.untouched_dofs): Hs has 2·norm there, far above

    @property
    def n(self) -> int:
        return self.H.shape[0]

    @property
    def n_rigid(self) -> int:
        return self.R.shape[1]

    @property
    def projection(self) -> Projection:
        return Projection.from_rotations(self.C)


@dataclass(frozen=True, eq=False)
class SparseParts:
    """The metric-independent part of the sparse path (physical dofs): CSR H and Hm, sliding factors A, S (n, Ms),
    the contacts' local data (ContactBlocks without blocks) and the timings of building them."""

    H: sp.csr_matrix
    Hm: sp.csr_matrix
    A: np.ndarray
    S: np.ndarray
    sliding: np.ndarray
    local: ContactBlocks
    timings: dict
    curvature_error: sp.csr_matrix | None = None   # stiffness.assembled_error: H's error from rounding K^p + K^q
    rigid_applied: dict | None = None   # Hg1, Hg2, Hm times the rigid basis (_apply_rigid), for identity_errors


def _rigid_columns(scene: Scene) -> np.ndarray:
    """The translations and unit rotations (physical dofs) that checks.identity_errors applies the parts to."""
    return np.concatenate([translations(scene), rotations(scene, 1.0)], axis=1)


def _apply_rigid(applied: dict, cb: ContactBlocks, rigid: np.ndarray, n_dof: int) -> None:
    """Add the chunk's Hg1, Hg2, Hm blocks times the rigid basis, contact by contact, scattered to `applied`."""
    local = rigid[cb.index]                                          # (m, n_loc, d + r)
    owner = np.zeros(len(cb.index), dtype=np.intp)
    for name, acc in applied.items():
        contrib = cb.blocks[name] @ local
        for j in range(rigid.shape[1]):
            acc[:, j] += stack_blocks(contrib[:, :, j], owner, cb.index, 1, n_dof)[0]


def sparse_parts(scene: Scene, chunk: int = CHUNK) -> SparseParts:
    """H and its mechanical part as CSR from the contact blocks, computed in chunks of contacts and scattered once
    (assembly.Assembly, one pattern for all three), and the sliding factors. Memory O(contacts); no per-part block arrays are kept."""
    t0 = time.perf_counter()
    per = scene.dof_per_particle
    M, n_loc = scene.n_contacts, 2 * per
    total = np.empty((M, n_loc, n_loc))
    mech = np.empty((M, n_loc, n_loc))
    a = np.empty((M, n_loc))
    s = np.empty((M, n_loc))
    index = np.empty((M, n_loc), dtype=np.intp)
    undetermined = np.zeros(M, bool)
    error = np.empty((M, n_loc, n_loc))
    rigid = _rigid_columns(scene)
    applied = {name: np.zeros(rigid.shape) for name in ("Hg1", "Hg2", "Hm")}
    for sl, cb in contact_chunks(scene, chunk):
        b = cb.blocks
        _apply_rigid(applied, cb, rigid, scene.n_dof)
        total[sl] = b["Hm"] + geometric(b)
        mech[sl] = b["Hm"]
        a[sl], s[sl], index[sl] = cb.slide_left, cb.slide_right, cb.index
        undetermined[sl] = cb.rolling_undetermined
        error[sl] = cb.curvature_error
    t1 = time.perf_counter()
    assembly = Assembly(scene.p, scene.q, per, scene.n_dof)          # one pattern for H, Hm and H's error bound
    curvature_error = assembled_error(scene, error, assembly)
    del error
    H = assembly(total)
    del total
    Hm = assembly(mech)
    del mech
    sliding = np.flatnonzero(scene.at_yield())
    local = ContactBlocks(blocks={}, slide_left=a, slide_right=s, index=index, n_dof=scene.n_dof,
                          rolling_undetermined=undetermined)
    A, S = sliding_factors(local, sliding)
    return SparseParts(H=H, Hm=Hm, A=A, S=S, sliding=sliding, local=local, curvature_error=curvature_error,
                       rigid_applied=applied, timings={"blocks": t1 - t0, "assembly": time.perf_counter() - t1})


def sparse_problem(scene: Scene, length: float | None = None, chunk: int = CHUNK, *,
                   metric: Metric | None = None, parts: SparseParts | None = None) -> SparseProblem:
    """The sparse problem in a metric's dofs (metric.py; default the L metric with `length`, itself defaulting to
    the mean contact radius): H̃ = D H D and its mechanical part (sparse congruences, O(nnz)), sym(H̃), the scaled
    sliding factors and the rigid bases. `parts` (sparse_parts) are shared by every metric of a family."""
    if metric is None:
        metric = length_metric(scene, length or default_length(scene), name="L")
    parts = parts or sparse_parts(scene, chunk)
    t1 = time.perf_counter()
    H = metric.sparse_congruence(parts.H)
    Hm = metric.sparse_congruence(parts.Hm)
    Hs = ((H + H.T) * 0.5).tocsr()
    D = metric.matrix()
    A, S = np.asarray(D @ parts.A), np.asarray(D @ parts.S)
    Ms = A.shape[1]
    C = metric.rotations(scene)
    R, _ = rigid_basis(np.concatenate([metric.translations(scene), C], axis=1))
    Q = R[:, scene.dim:]                                                # spans C, which is orthogonal to T
    norm = float(abs(Hs).sum(axis=1).max()) if Hs.nnz else 1.0
    if Ms:
        norm += float(np.sum(np.linalg.norm(A, axis=0) * np.linalg.norm(S, axis=0)))
    spins = free_spins(scene, H, A, S, scale=norm) if scene.fixed is None else np.zeros(0, dtype=np.intp)
    if spins.size:              # free spins (frictionless round particles): exactly decoupled, moved to the top
        Hs = (Hs + sp.csr_matrix((np.full(spins.size, 2.0 * norm), (spins, spins)), shape=Hs.shape)).tocsr()
        norm *= 2.0
    return SparseProblem(scene=scene, length=metric.rotation_length, scale=metric.diagonal, metric=metric, H=H,
                         Hs=Hs, Hm=Hm, A=A, S=S, sliding=parts.sliding, C=C, Q=Q, R=R, norm=max(norm, 1e-300),
                         local=parts.local, timings={**parts.timings, "projection": time.perf_counter() - t1},
                         free_spins=int(spins.size))



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


def dissection_order(x: np.ndarray, p: np.ndarray, q: np.ndarray, leaf: int = 32, nodes: bool = False):
    """Geometric nested dissection of the contact graph: a particle order (N,) with separators last (and, with
    `nodes`, the sizes of its leaves and separators in that order: the nodes of multifrontal.negative_count).

    Each part is split at the median of its longest extent; its separator is the set of particles on the lower
    side with a contact across the cut. Fill of the LU ~ n log n in 2D, n^{4/3} in 3D (SuperLU's minimum degree
    gives about twice as much fill on these graphs). Vectorised per level: O(M log N).
    """
    N = len(x)
    side = np.zeros(N, np.int8)
    order = []
    stack = [(np.arange(N), np.asarray(p), np.asarray(q))]          # LIFO: left part, right part, separator
    while stack:
        item = stack.pop()
        if item[1] is None:                                          # a separator
            order.append(item[0])
            continue
        idx, ep, eq = item
        if len(idx) <= leaf:
            order.append(idx)
            continue
        xs = x[idx]
        axis = int(np.argmax(xs.max(axis=0) - xs.min(axis=0)))
        side[idx] = np.where(xs[:, axis] < np.median(xs[:, axis]), 1, 2)
        if not (np.any(side[idx] == 1) and np.any(side[idx] == 2)):
            side[idx] = 0
            order.append(idx)
            continue
        cut = side[ep] != side[eq]
        sep = np.unique(np.where(side[ep[cut]] == 1, ep[cut], eq[cut]))
        side[sep] = 3
        left, right = idx[side[idx] == 1], idx[side[idx] == 2]
        in_left = (side[ep] == 1) & (side[eq] == 1)
        in_right = (side[ep] == 2) & (side[eq] == 2)
        side[idx] = 0
        stack.append((sep, None, None))
        stack.append((right, ep[in_right], eq[in_right]))
        stack.append((left, ep[in_left], eq[in_left]))
    order = [o for o in order if len(o)]
    perm = np.concatenate(order) if order else np.arange(N)
    return (perm, np.array([len(o) for o in order] or [N], dtype=np.intp)) if nodes else perm


class Factor:
    """Hs - σI factorised in a nested-dissection order (dissection_order).

    n_neg, the number of eigenvalues of Hs below σ, is the inertia of a congruence: the multifrontal block
    elimination of multifrontal.py (a Cholesky or an eigendecomposition per front; Sylvester's law holds for it,
    within its stated rounding), None where that refuses to count (an eigenvalue within ~1e-13‖Hs‖ of σ, or growth).
    Solves use the same factors where every front was positive definite (Cholesky all through: backward stable,
    block solves BLAS-3 on one thread); otherwise SuperLU's LU (diagonal pivots, symmetric mode), whose pivots are
    no longer read (that copied and kept both factors). nnz: stored factor entries."""

    def __init__(self, sp_: SparseProblem, sigma: float):
        from .multifrontal import Multifrontal
        scene = sp_.scene
        per = scene.dof_per_particle
        order, sizes = dissection_order(scene.x, scene.p, scene.q, nodes=True)
        self.perm = (order[:, None] * per + np.arange(per)).reshape(-1)
        self.inv = np.empty_like(self.perm)
        self.inv[self.perm] = np.arange(len(self.perm))
        M = (sp_.Hs - sigma * sp.identity(sp_.n, format="csr"))[self.perm][:, self.perm].tocsc()
        self.mf = Multifrontal(M, np.r_[0, np.cumsum(sizes) * per])
        self.sigma = sigma
        self.n_neg = self.mf.negative
        self.lu = None
        if not (self.mf.ok and self.n_neg == 0 and self.mf.definite):
            self.mf.factors = []                                       # only its count is kept
            self.lu = spla.splu(M, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        self.nnz = int(self.mf.nnz if self.lu is None else self.lu.nnz)
        del M

    def solve(self, b: np.ndarray, single: bool = False) -> np.ndarray:
        """(Hs - σI)⁻¹ b; `single`: in float32 where the multifrontal factors solve (Multifrontal.solve: relative
        error ~cond·1e-7, a preconditioner only; SuperLU's solves are always float64)."""
        if self.lu is not None:
            return self.lu.solve(b[self.perm])[self.inv]
        return self.mf.solve(b[self.perm], single)[self.inv]


def factor(sp_: SparseProblem, sigma: float) -> Factor:
    """Sparse LDLᵀ-like factorisation of Hs - σI (see Factor)."""
    return Factor(sp_, sigma)


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


LU_MAX_DOF_FALLBACK = 300000   # a LOBPCG that does not converge is redone by shift-invert up to this size
LU_MAX_DOF_3D = 30000   # method="auto": shift-invert (sparse LU) in 2D and up to this many dofs in 3D, else LOBPCG


def lowest_modes(problem, k: int = 6, mask=None, *, sigma: float | None = None, tol: float = 0.0,
                 method: str = "auto", maxiter: int | None = None, factorization=None,
                 seed: int = 0, rhs: np.ndarray | None = None) -> Modes:
    """The k lowest eigenpairs of sym(𝓗^mask) off the rigid modes (see the module docstring).

    problem: a SparseProblem or a Scene. mask: +1 sliding per contact (default: all elastic).
    sigma: shift (default -1e-6 ‖Hs‖). tol: eigsh/lobpcg relative tolerance (0 = machine precision).
    method: "shift-invert" (ARPACK + sparse LU, inertia-verified; the LU fill grows like n log n in 2D and
    n^{4/3} in 3D), "lobpcg" (LOBPCG with the TwoLevel preconditioner: memory O(contacts), not verified; tol is
    then the residual tolerance relative to ‖Hs‖, default 1e-8, which gives eigenvalues to ~1e-16 ‖Hs‖) or
    "auto" (shift-invert in 2D and up to LU_MAX_DOF_3D dofs in 3D, LOBPCG above). factorization: (sigma, lu, n_neg) from an earlier call, reused across
    branches. rhs (n, c): solved with the first block solve (info["shifted"].rhs_solved, None if σ moved; ritz.py).
    Returns Modes; info has the timings, the LU fill and, by shift-invert, "shifted" (the branch's Shifted).
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
    rng = np.random.default_rng(seed)
    v0 = rng.standard_normal(n)
    v0 -= sp_.R @ (sp_.R.T @ v0)
    Bop = operator(sp_, mask, shift)
    if n <= SMALL_DENSE or k >= n - sp_.n_rigid - 1:
        # a handful of dofs: ARPACK needs k < n - 1, and a dense eigh of B is exact and instant here
        t = time.perf_counter()
        B = Bop.matmat(np.eye(n))
        lam, V = np.linalg.eigh(0.5 * (B + B.T))
        lam, V = _drop_rigid(sp_, lam, V)
        info["solve"] = time.perf_counter() - t
        return _finish(sp_, Bop, lam[:k], V[:, :k], mask_arr, np.nan, True, None, "dense", info)
    if method == "auto":
        method = "shift-invert" if sp_.scene.dim == 2 or n <= LU_MAX_DOF_3D else "lobpcg"
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
    info["factor"] = time.perf_counter() - t
    info["lu_nnz"] = fac.nnz
    info["factorization"] = fac
    shifted = Shifted(fac, U, K, sig, fac.n_neg, rhs=rhs)
    nu = shifted.n_below
    t = time.perf_counter()
    verified = False
    if nu is not None and nu <= 4 * k + 20:
        found = _block_near(shifted, Bop, sp_, k + nu, rng) if fac.lu is None and tol == 0 else None
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
        # too many lie below σ (a floppy structure's thousands of clustered negative eigenvalues, on which Lanczos
        # stalls), or the ν below were not all reached: slice the spectrum by inertia counts
        t2 = time.perf_counter()
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
    info["solve"] = time.perf_counter() - t
    info["shifted"] = shifted                                          # (Hs - σI)⁻¹U of this branch (ritz.py)
    return _finish(sp_, Bop, lam[:k], V[:, :k], mask_arr, sig, verified, nu, method, info)


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


DENSE_FALLBACK_MAX_DOF = 4000   # ARPACK failures below this size are solved densely instead
DENSE_FALLBACK_PATIENCE = 300   # ARPACK restarts allowed where the dense fallback exists (tightly clustered spectra,
                                # e.g. a compressed chain in the L/10 metric, took > 3 min for 1,200 dofs otherwise)
NARROW_PATIENCE = 30            # ARPACK restarts of the first, narrow Krylov space (2k + 1) before the wide one: a
                                # cluster wider than it never converges there (a 3D superquadric packing's branches
                                # at yield: 300 restarts, 0.7 s of 372 dofs, then 0.02 s with the wide space)


def _drop_rigid(sp_: SparseProblem, lam, V):
    """Remove the n_rigid eigenpairs of B that lie in the rigid span (eigenvalue s) from a full spectrum."""
    rigid_weight = np.linalg.norm(sp_.R.T @ V, axis=0)
    keep = np.argsort(rigid_weight, kind="stable")[:V.shape[1] - sp_.n_rigid]
    keep = np.sort(keep)
    return lam[keep], V[:, keep]


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


def _block_near(shifted: Shifted, Bop, sp_: SparseProblem, kk: int, rng) -> tuple | None:
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
        XY, BVY = X[:, d:d + m] @ Y[:, :keep], BV[:, :m] @ Y[:, :keep]  # (one pass over X and BV each)
        V = XY[:, :top]
        resid = BVY[:, :top] - V * theta[:top]
        res = _norms(resid)
        if res[:want].max(initial=0.0) <= BLOCK_RTOL * sp_.norm:
            return theta[:kk], V[:, :kk], Krylov(X[:, d:d + m], _sym(G))
        X[:, d:d + keep], BV[:, :keep] = XY, BVY                      # thick restart on the lowest Ritz vectors
        m, G = keep, np.diag(theta[:keep])
        active = res > BLOCK_RTOL * sp_.norm
        block = resid[:, active] / res[active]
    return None


def _append(X, BV, G, m, block, Bop):
    """Put `block` after the m basis columns of X (after R's d) and B·block in BV (B is applied once per vector;
    restarts rotate it); G grows by the block's rows and columns (B symmetric). Returns (G, m)."""
    b, d = block.shape[1], X.shape[1] - BV.shape[1]
    X[:, d + m:d + m + b], BV[:, m:m + b] = block, Bop.matmat(block)
    C = X[:, d:d + m + b].T @ BV[:, m:m + b]
    return np.block([[G, C[:m]], [C[:m].T, _sym(C[m:])]]), m + b


def _eigsh_near(shifted: Shifted, Bop, n, kk, tol, maxiter, v0, which: str = "LM"):
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

def norm_estimate(A, iters: int = 30, seed: int = 0) -> float:
    """‖A‖₂ of a sparse matrix (or operator) by power iteration on AᵀA (a lower bound, within a few %)."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(A.shape[1])
    x /= np.linalg.norm(x)
    s = 0.0
    for _ in range(iters):
        y = A.T @ (A @ x)
        s = np.sqrt(np.linalg.norm(y))
        if s == 0:
            return 0.0
        x = y / np.linalg.norm(y)
    return float(s)


class _Applied:
    """A part of H known only through its product with the rigid basis (what checks.identity_errors needs)."""

    def __init__(self, value: np.ndarray):
        self.value = value

    def __matmul__(self, other):
        return self.value


def identity_errors(sp_: SparseProblem, chunk: int = CHUNK, parts: SparseParts | None = None) -> dict:
    """The identities of the dense path (granstab.mechanics.checks; Frobenius norms) without assembling the parts: H in
    physical dofs from the scaled H̃, and Hg1, Hg2, Hm applied to the rigid basis contact by contact (taken from
    `parts`, where sparse_parts made them with the blocks, else chunked again); plus the rigid leakage of ℍ = H̃ P on
    all rigid motions and the projection's own checks."""
    scene = sp_.scene
    H = sp_.metric.sparse_congruence(sp_.H, inverse=True)
    applied = getattr(parts, "rigid_applied", None)
    if applied is None:
        rigid = _rigid_columns(scene)
        applied = {name: np.zeros(rigid.shape) for name in ("Hg1", "Hg2", "Hm")}
        for _, cb in contact_chunks(scene, chunk):
            _apply_rigid(applied, cb, rigid, scene.n_dof)
    errs = checks.identity_errors(scene, {"H": H, **{k: _Applied(v) for k, v in applied.items()}})
    proj = sp_.projection
    errs["rigid_leakage_modified"] = modified_leakage(sp_.H, sp_.R, proj)
    errs.update(proj.errors())
    return errs


# ------------------------------------------------------------------------------------------- analyze()

DENSE_MAX_DOF = 2000   # analyze(method="auto") uses the dense path up to this many dofs, the sparse one above


__all__ = ["DENSE_MAX_DOF", "LU_MAX_DOF_3D", "Factor", "Krylov", "Modes", "SparseParts", "SparseProblem", "TwoLevel",
           "contact_chunks", "dissection_order", "factor", "identity_errors", "lowest_modes", "norm_estimate",
           "operator", "rigid_leakage", "sparse_branch", "sparse_parts", "sparse_problem"]
