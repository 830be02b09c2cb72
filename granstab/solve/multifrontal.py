"""Inertia of a sparse symmetric matrix by multifrontal block elimination (a congruence), for the sparse path's
count of eigenvalues below the shift σ (`Factor`, below).

Sylvester's law of inertia holds for congruences A = L D Lᵀ with L invertible; a sparse LU with diagonal pivots
is one only in exact arithmetic and without pivoting, and reading its pivots from scipy's SuperLU copies (and
keeps) both factors. Here A (already in a fill-reducing order, e.g. `dissection_order`, below) is eliminated node by
node, a node being a contiguous range of its dofs (a leaf or a separator of the dissection). For a node X with
front rows [X, struct(X)] (struct: the later rows its columns and its children's updates reach) the front

    F = [[F11, F21ᵀ], [F21, F22]]     (F11 = the current Schur complement on X)

is split as F11 = G⁻¹ S G⁻ᵀ with S = diag(±1): G⁻¹ = L11 (Cholesky, S = I) where F11 is positive definite, else
G⁻¹ = V|Λ|^{1/2} from F11 = VΛVᵀ (S = sign Λ). Then F = [[G⁻¹, 0], [W, I]] diag(S, F22 - W S Wᵀ) [[G⁻ᵀ, Wᵀ], [0, I]]
with W = F21 Gᵀ S, and the update F22 - W S Wᵀ is added to the parent's front (the node of struct(X)'s first row).
Each step is a congruence (Haynsworth: In(A) = In(F11) + In(A/F11)), so the number of negative eigenvalues of A is
the number of -1 in all the S. In floating point each front is a backward-stable dense factorisation (Cholesky;
the symmetric eigendecomposition) of a front that carries the rounding of the updates before it: the count is the
inertia of A + E with ‖E‖ ≲ c·f·eps·‖A‖·g (f the largest front, g the growth of the updates over ‖A‖, 1 while every
front is positive definite). The count is refused (None) where a front's |λ| falls below SINGULAR_RTOL·‖A‖ (an
eigenvalue too close to σ to count) or the growth exceeds GROWTH_MAX; the caller then moves σ.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg.blas import dsyrk, dtrmm
from scipy.linalg.lapack import dpotrf, dtrtri

from .threads import blas_threads

if TYPE_CHECKING:
    from .assembled import SparseProblem

SINGULAR_RTOL = 1e-13   # |λ| of a front's F11 below this · ‖A‖: too close to σ to count
GROWTH_MAX = 1e8        # an update larger than this · ‖A‖: the elimination is not trusted
SINGLE_MAX = 3e8        # float32 copies of the factors only up to this many entries (1.2 GB): a 10⁶-disk factor
                        # (~7·10⁸ entries) solves its preconditioning blocks in float64 instead of holding 2.8 GB more


def _fronts(A: sp.csc_matrix, bounds: np.ndarray):
    """Symbolic step: for each node (dofs bounds[i]:bounds[i+1]) its struct (sorted later rows) and parent (-1 at
    a root), from the lower triangle of its columns and its children's structs."""
    n_nodes = len(bounds) - 1
    node_of = np.repeat(np.arange(n_nodes), np.diff(bounds))
    structs, parents = [None] * n_nodes, np.full(n_nodes, -1)
    pending = {}
    for i in range(n_nodes):
        s, e = bounds[i], bounds[i + 1]
        rows = A.indices[A.indptr[s]:A.indptr[e]]
        parts = [rows[rows >= e]] + pending.pop(i, [])
        st = np.unique(np.concatenate(parts))
        st = st[st >= e]
        structs[i] = st
        if st.size:
            parents[i] = node_of[st[0]]
            pending.setdefault(parents[i], []).append(st)
    return structs, parents


class Multifrontal:
    """The block elimination of the symmetric A (n × n, in its own order) with nodes `bounds` (increasing dof offsets
    from 0 to n): A = L̂ S L̂ᵀ (module docstring). `negative`: the number of negative eigenvalues of A (None where
    refused, and then `ok` is False and nothing can be solved); `nnz`: the stored factor entries; `solve(b)`:
    A⁻¹ b for b (n,) or (n, m). `keep` False: the count only, each front's factor dropped once eliminated (memory:
    the fronts and pending updates, not the factor)."""

    def __init__(self, A: sp.spmatrix, bounds: np.ndarray, keep: bool = True):
        A = sp.csc_matrix(A)
        A.sum_duplicates()
        A.sort_indices()
        self.n, self.bounds = A.shape[0], np.asarray(bounds, dtype=np.intp)
        scale = max(float(abs(A).sum(axis=0).max()) if A.nnz else 0.0, 1e-300)
        self.structs, parents = _fronts(A, self.bounds)
        self.factors = []
        loc = np.empty(self.n, dtype=np.intp)
        updates: dict[int, list] = {}
        self.negative = 0
        with blas_threads(1):        # thousands of small fronts: a BLAS pool costs more than it gains (threads.py)
            for i in range(len(self.bounds) - 1):
                out = _eliminate(A, i, int(self.bounds[i]), int(self.bounds[i + 1]), self.structs[i],
                                 int(parents[i]), loc, updates, scale)
                if out is None:
                    self.negative, self.factors = None, []
                    break
                self.factors.append(out if keep else (None, None, *out[2:]))
                self.negative += int(np.sum(out[2] < 0))
        self.ok = self.negative is not None
        self.definite = self.ok and all(chol for *_, chol in self.factors)      # Cholesky in every front
        self.nnz = int(sum(G.size + W.size for G, W, *_ in self.factors if G is not None))
        self.plans = {}                                                # per dtype: the fronts as the solve reads them
        self.single = False                                            # factors held in float32 only (`to_single`)

    def to_single(self) -> None:
        """Hold the factors in float32 only, front by front (half the memory and of each solve's traffic): for a
        preconditioner whose caller computes its residuals in float64 (cellsolve.py); every later solve is then in
        float32 (relative error ~cond·1e-7)."""
        for i, (G, W, *rest) in enumerate(self.factors):
            self.factors[i] = (G.astype(np.float32), W.astype(np.float32), *rest)
        self.plans, self.single = {}, True

    def _plan(self, dtype) -> list:
        """(s, e, G, W, struct, has W) per front in `dtype` (float32: copies made at the first such solve, half the
        memory traffic, where the factor has at most SINGLE_MAX entries; float64: the factors themselves), so that
        the solve's loop does no lookups or conversions."""
        if dtype == np.float32 and self.nnz > SINGLE_MAX and not self.single:
            dtype = np.float64
        if dtype not in self.plans:
            b, structs = self.bounds.tolist(), self.structs
            self.plans[dtype] = [(b[i], b[i + 1], G.astype(dtype, copy=False), W.astype(dtype, copy=False),
                                  structs[i], W.shape[0] > 0) for i, (G, W, *_) in enumerate(self.factors)]
        return self.plans[dtype]

    def solve(self, b: np.ndarray, single: bool = False) -> np.ndarray:
        """x = A⁻¹ b where every front is Cholesky (`definite`; G = L11⁻¹ lower triangular with a zero upper triangle,
        S = I): L̂ z = b (nodes in order), L̂ᵀ x = z (nodes in reverse order), each front two small products (numpy's
        matmul: BLAS gemm, no conversions; the solve is bound by reading the factor once per pass, not by the loop).
        `single`: in float32 with float32 copies of the factors (made at the first such call, half the memory
        traffic), x then has a relative error ~cond(A)·1e-7: only for preconditioning, where the caller computes its
        residuals in float64 (sparse._block_near); returned in float64. Above SINGLE_MAX factor entries there is no
        copy and `single` solves in float64 (the copy would cost a third of the factor's memory again)."""
        if not self.definite or (self.factors and self.factors[0][0] is None):
            raise ValueError("Multifrontal.solve needs every front positive definite (definite) and kept")
        plan = self._plan(np.float32 if single or self.single else np.float64)
        x = np.array(b, dtype=plan[0][2].dtype if plan else float, copy=True)
        X = x.reshape(self.n, -1)
        with blas_threads(1):                                          # small blocks: one thread (threads.py)
            for s, e, G, W, st, has_w in plan:
                y = G @ X[s:e]
                X[s:e] = y
                if has_w:
                    X[st] -= W @ y
            for s, e, G, W, st, has_w in reversed(plan):
                X[s:e] = G.T @ (X[s:e] - W.T @ X[st] if has_w else X[s:e])
        return x.astype(float, copy=False)


def _eliminate(A, node: int, s: int, e: int, st: np.ndarray, parent: int, loc: np.ndarray, updates: dict,
               scale: float):
    """One node's front: assemble (A's lower columns s:e and the children's updates), split F11 = G⁻¹ S G⁻ᵀ, pass
    the update F22 - W S Wᵀ (W = F21 Gᵀ) to `parent`; (G, W, S), or None where refused (module docstring). Fronts
    and updates hold their lower triangles only (rows are in increasing order, so a child's lower triangle lands in
    its parent's): W by dtrmm and the update by dsyrk where F11 is Cholesky, half a full product's flops each."""
    k = e - s
    rows = np.concatenate([np.arange(s, e), st])
    loc[rows] = np.arange(len(rows))
    F = np.zeros((len(rows), len(rows)))
    lo, hi = A.indptr[s], A.indptr[e]
    r, c = A.indices[lo:hi], np.repeat(np.arange(k), np.diff(A.indptr[s:e + 1]))
    keep = r >= s + c                                                 # the lower triangle
    F[loc[r[keep]], c[keep]] = A.data[lo:hi][keep]
    for child_rows, U in updates.pop(node, []):
        _extend_add(F, loc[child_rows], U)
    F11 = F[:k, :k]
    L, info = dpotrf(F11, lower=1, clean=1, overwrite_a=0)
    chol = info == 0
    if chol:                                                         # positive definite: G = L11⁻¹, S = I
        G, info = dtrtri(L, lower=1)
        signs = np.ones(k)
        chol = info == 0
    if not chol:
        lam, V = np.linalg.eigh(F11, UPLO="L")
        if np.abs(lam).min() <= SINGULAR_RTOL * scale:
            return None
        signs = np.sign(lam)
        G = (V / np.sqrt(np.abs(lam))).T
    W = dtrmm(1.0, G, F[k:, :k], side=1, lower=1, trans_a=1) if chol else F[k:, :k] @ G.T
    if st.size:
        U = (dsyrk(-1.0, W, beta=1.0, c=F[k:, k:], lower=1) if chol
             else np.tril(F[k:, k:] - (W * signs) @ W.T))
        if max(U.max(initial=0.0), -U.min(initial=0.0)) > GROWTH_MAX * scale:      # max |U|, no temporary
            return None
        updates.setdefault(parent, []).append((st, U))
    return G, W, signs, chol


RUNS_MAX = 16   # _extend_add: slice by slice up to this many contiguous runs of rows, one fancy index above …
SLICE_MIN = 64  # … and below this many rows (a loop of slices costs more than it saves there)


def _extend_add(F: np.ndarray, li: np.ndarray, U: np.ndarray) -> None:
    """F[li, li] += U on the lower triangle (li increasing): a child's update is mostly a few contiguous runs of the
    parent's rows (90% of the entries within ≤ 10 runs on a 2D dissection), each pair of runs added as a slice; the
    upper triangle, which no front reads, is left out."""
    cut = np.flatnonzero(np.diff(li) != 1) + 1
    if len(cut) >= RUNS_MAX or len(li) < SLICE_MIN:
        F[np.ix_(li, li)] += U
        return
    bounds = [0, *cut.tolist(), len(li)]
    for a in range(len(bounds) - 1):
        sa, ea = bounds[a], bounds[a + 1]
        fa = int(li[sa])
        for b in range(a + 1):
            sb, eb = bounds[b], bounds[b + 1]
            fb = int(li[sb])
            F[fa:fa + ea - sa, fb:fb + eb - sb] += U[sa:ea, sb:eb]


__all__ = ["GROWTH_MAX", "SINGULAR_RTOL", "Multifrontal"]


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
