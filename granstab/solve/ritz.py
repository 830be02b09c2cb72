"""The lowest eigenpairs of every branch of a large cluster from ONE elastic sparse solve (`SparseRitz`): the sparse
path's counterpart of lowrank.py, a Rayleigh-Ritz problem per branch on a basis built once, verified by inertia
(sparse.py) and refined, or redone by shift-invert, where that fails."""
from __future__ import annotations

from functools import cached_property

import numpy as np

from .device import backend
from .krylov import _norms, _sym, extend
from .lowrank import stack, sym_updates
from .multifrontal import factor
from .sparse import Modes, Shifted, _finish, _lowrank, lowest_modes, operator

GUARD = 6            # extra Ritz vectors carried by the refinement (faster convergence of the kk lowest)
TAYLOR = 6           # powers (B_0 - σ)⁻ʲ[A, S] in the basis: each a block solve of 2·d·Ms columns; 2 powers left
                     # residuals ~5e-9‖Hs‖ on 10⁴-10⁵ disks (two refinements per branch), 6 reach ~4e-13 (none)
STEPS = 4            # refinements of a branch's Ritz vectors before shift-invert redoes it


class SparseRitz:
    """The lowest eigenpairs of every branch of a large cluster from ONE elastic solve (granstab.solve.sparse).

    Branch i's deflated operator is B_i = B_0 + U_i K_i U_iᵀ with U_i in span[A, S] (and the rigid modes). An
    eigenvector of B_i with eigenvalue λ is v = -(B_0 - λ)⁻¹ U_i K_i U_iᵀ v: near the low end it lies in the span of
    the lowest elastic modes and of (B_0 - σ)⁻¹[A, S], (B_0 - σ)⁻²[A, S] (a Taylor expansion of (B_0 - λ)⁻¹ about
    σ). That space W (n × d, d about kk + 48 + 8.5 Ms: budget.ritz_width; orthonormal, rigid-free) is built once
    (on first need: not where every branch goes straight to shift-invert) from the elastic shift-invert
    solve and its sparse LU; every branch is then the d × d Rayleigh-Ritz problem Wᵀ B_i W = Wᵀ Hs W + a low-rank
    update, stacked on the backend like the dense branches.

    Exact: the number ν of eigenvalues below σ per branch (Sylvester/Haynsworth from the shared LU, sparse.Shifted).
    Bounded: every Ritz value θ is an upper bound of its eigenvalue (Cauchy interlacing) and has an eigenvalue
    within its residual ‖B_i v − θ v‖ (exact operator). A branch whose Ritz values below σ are fewer than ν, or whose
    residuals exceed `rtol`·‖Hs‖, is solved again by shift-invert ARPACK with the same LU (sparse.lowest_modes).
    """

    def __init__(self, spb, k: int, tol: float = 0.0, extra: int = 0, rtol: float = 1e-12, device: str = "cpu"):
        self.spb, self.k, self.tol, self.rtol, self.device = spb, k, tol, rtol, device
        Ms = spb.A.shape[1]
        elastic = lowest_modes(spb, k + extra, None, tol=tol, rhs=np.concatenate([spb.A, spb.S], axis=1))
        self.factorization = fac = elastic.info.get("factorization")
        shifted = elastic.info.pop("shifted", None)        # the elastic branch's (Hs - σI)⁻¹U, U = [Q, Hs Q, T]
        self._elastic = (shifted, elastic.info.pop("krylov", None), elastic.vectors)   # for `_basis`, if needed
        self.solved = None
        if fac is not None:                    # (Hs - σI)⁻¹ of every column _lowrank uses: A and S solved with U
            r, d = spb.Q.shape[1], spb.scene.dim
            AS = shifted.rhs_solved
            if AS is None:                                  # σ was moved (spectrum slicing): solved here
                AS = fac.solve(np.concatenate([spb.A, spb.S], axis=1))
            self.solved = dict(zip(("Q", "HQ", "T"), np.split(shifted.Z[:, :2 * r + d], [r, 2 * r], axis=1)),
                               A=AS[:, :Ms], S=AS[:, Ms:])
        self.stats = {"basis": 0, "ritz": 0, "arpack": 0, "direct": 0, "refinements": 0}
        self.steps = STEPS

    @cached_property
    def _basis(self) -> tuple:
        """(W, Wᵀ Hs W, the sliding contacts' updates of it), built once, on first need: not at all where every
        branch goes straight to shift-invert (`modes`). W: the elastic Krylov space (or the elastic vectors) and
        TAYLOR powers of (Hs - σI)⁻¹ on [A, S], orthonormal and rigid-free."""
        spb, (shifted, krylov, vectors) = self.spb, self._elastic
        R, blocks = spb.R, []
        base = extend(R, vectors) if krylov is None else krylov.X   # block Krylov space (sparse._block_near):
        if self.solved is not None:                                 # far more of the low spectrum than k + extra
            Z = np.concatenate([self.solved["A"], self.solved["S"]], axis=1)
            for j in range(TAYLOR if Z.shape[1] else 0):
                Z = Z - R @ (R.T @ Z)                        # (Hs - σI)⁻¹ amplifies the rigid part by ~1/|σ|
                Z /= np.maximum(_norms(Z), 1e-300)
                blocks.append(Z)
                if j + 1 < TAYLOR:
                    Z = self.factorization.solve(Z)
        more = extend(np.concatenate([R, base], axis=1), np.concatenate(blocks, axis=1)) if blocks else base[:, :0]
        M0 = self._rayleigh(krylov, base, more, shifted)
        W = np.concatenate([base, more], axis=1)
        self._elastic, self.stats["basis"] = None, W.shape[1]
        return W, M0, sym_updates(W.T @ spb.A, W.T @ spb.S)

    W = property(lambda self: self._basis[0], doc="The Ritz basis (n × width; `_basis`).")
    M0 = property(lambda self: self._basis[1], doc="Wᵀ Hs W.")
    updates = property(lambda self: self._basis[2], doc="Per sliding contact, its update of Wᵀ Hs W (flattened).")

    def _rayleigh(self, krylov, base: np.ndarray, more: np.ndarray, shifted) -> np.ndarray:
        """Wᵀ Hs W for W = [base, more]: with `krylov` (base = its X) X's block from the iteration's own Xᵀ B X
        (Xᵀ Hs X = G - (UᵀX)ᵀ K UᵀX, B = Hs + U K Uᵀ the elastic operator it ran on) and the rest from one sparse
        product Hs·more (moreᵀ Hs X = (Hs more)ᵀ X: Hs is symmetric); without, directly."""
        Hs = self.spb.Hs
        if krylov is None:
            W = np.concatenate([base, more], axis=1)
            return _sym(W.T @ (Hs @ W))
        U, K = shifted.U, shifted.K
        P = U.T @ krylov.X
        Hmore = Hs @ more
        side, corner = Hmore.T @ krylov.X, more.T @ Hmore
        return _sym(np.block([[krylov.G - P.T @ (K @ P), side.T], [side, corner]]))

    def modes(self, masks: np.ndarray, kk: int):
        """Modes (sparse.Modes) of the kk lowest non-rigid eigenpairs of each branch in `masks`, in order. A branch
        with kk or more eigenvalues below σ (`below`: exact by inertia, known before any Ritz work) cannot be
        accepted here (`_branch`: the Ritz values below σ must be all ν of them and fewer than kk): it goes straight
        to shift-invert, as it did after refinements that could not succeed, and takes no part in the stacked eigh."""
        spb, fac = self.spb, self.factorization
        be = backend(self.device)
        on = (masks[:, spb.sliding] == 1).astype(float)
        nus = [None if fac is None else self.below(on[i] == 1) for i in range(len(masks))]
        hopeful = [i for i, nu in enumerate(nus) if nu is not None and nu < kk]
        self.stats["direct"] = len(masks) - len(hopeful)
        Y, block = {}, 0
        if hopeful:                                        # the basis only where some branch can use it
            block = min(kk + GUARD, self.W.shape[1])
            with be.threads(self.W.shape[1]):
                _, Yh = be.xp.linalg.eigh(stack(be.xp, self.M0, self.updates, be.asarray(on[hopeful])))
                Y = dict(zip(hopeful, be.to_host(Yh[:, :, :block])))
        for i, mask in enumerate(masks):
            if i in Y:
                yield self._branch(mask, on[i] == 1, Y[i], kk, block)
            else:
                self.stats["arpack"] += 1
                yield lowest_modes(spb, kk, mask, factorization=fac, tol=self.tol)

    def below(self, on: np.ndarray) -> int | None:
        """ν: the eigenvalues below σ of the branch whose sliding contacts are `on` (sparse.Shifted's inertia count
        from the shared factor and the solves made once; None where the factor gives no count)."""
        return self._shifted(on).n_below

    def _shifted(self, on: np.ndarray) -> Shifted:
        return branch_shifted(self.spb, self.factorization, self.solved, on)

    def _branch(self, mask, on: np.ndarray, Y: np.ndarray, kk: int, block: int):
        """One branch from its Ritz vectors W·Y: accepted where its Ritz values below σ are all ν of its eigenvalues
        there, fewer than kk, and every residual is within rtol·‖Hs‖; refined up to `steps` times, else redone by
        shift-invert."""
        spb, fac = self.spb, self.factorization
        shifted = self._shifted(on)
        Bop = operator(spb, mask, spb.norm)
        mask8 = np.asarray(mask, np.int8)
        V = self.W @ Y
        for step in range(self.steps + 1):
            modes = _finish(spb, Bop, np.zeros(block), V, mask8, fac.sigma, False, shifted.n_below, "ritz", {})
            nu, found = shifted.n_below, int(np.sum(modes.eigenvalues < fac.sigma))
            if nu is not None and nu == found < kk and modes.residuals[:kk].max() <= self.rtol:
                self.stats["ritz"] += 1
                self.stats["refinements"] += step
                return Modes(modes.eigenvalues[:kk], modes.vectors[:, :kk], modes.residuals[:kk], mask8,
                             fac.sigma, True, nu, "ritz",              # the kk lowest of those _finish made
                             {"factorization": fac, "basis": self.W.shape[1], "refinements": step})
            if step < self.steps:
                V = self._refine(spb, Bop, shifted, modes.vectors)
        self.stats["arpack"] += 1
        return lowest_modes(spb, kk, mask, factorization=fac, tol=self.tol)

    def _refine(self, spb, Bop, shifted, V):
        """Rayleigh-Ritz on span[W, V, (B - σ)⁻¹R, (B - σ)⁻²R] with R the residuals BV - VΘ (block shift-invert with the
        branch's Woodbury operator, as sparse._block_near: float32 solves of the residuals, whose error is relative to
        them, so the refinement converges to float64 round-off): as many of the lowest Ritz vectors as V has columns."""
        BV = Bop.matmat(V)
        R = BV - V * np.einsum("ij,ij->j", V, BV)
        Z1 = shifted.solve(R / np.maximum(_norms(R), 1e-300), single=True)
        Z2 = shifted.solve(Z1 / np.maximum(_norms(Z1), 1e-300), single=True)
        basis = self.W
        for block in (V, Z1, Z2):
            basis = np.concatenate([basis, extend(np.concatenate([spb.R, basis], axis=1), block)], axis=1)
        G = _sym(basis.T @ Bop.matmat(basis))
        _, y = np.linalg.eigh(G)
        return basis @ y[:, :V.shape[1]]


def branch_shifted(spb, fac, solved: dict, on: np.ndarray) -> Shifted:
    """(B - σI)⁻¹ of the branch whose sliding contacts are `on` (sparse.Shifted: its inertia count n_below) from the
    shared factor and the solves made once (`branch_solved`)."""
    U, K = _lowrank(spb, on, spb.norm)
    return Shifted(fac, U, K, fac.sigma, fac.n_neg, Z=branch_solved(spb, solved, on))


def branch_solved(spb, solved: dict, on: np.ndarray) -> np.ndarray:
    """(Hs - σI)⁻¹ U for sparse._lowrank's U = [Q, Y, T, A_on, S_on] of a branch, by linearity from the solves made
    once (`solved`: Q, Hs Q, T, A and S solved; Y = Hs Q + ½(A_on S_onᵀ Q + S_on A_onᵀ Q))."""
    A, S, z = spb.A[:, on], spb.S[:, on], solved
    ZY = z["HQ"] + 0.5 * (z["A"][:, on] @ (S.T @ spb.Q) + z["S"][:, on] @ (A.T @ spb.Q))
    return np.concatenate([z["Q"], ZY, z["T"], z["A"][:, on], z["S"][:, on]], axis=1)


def below_counts(spb, masks: np.ndarray) -> np.ndarray | None:
    """ν of each branch in `masks` (eigenvalues below the run's σ, exact by inertia) without any eigen-solve: the
    factor of Hs - σI and one block solve of [Q, Hs Q, T, A, S], as SparseRitz makes them, then each branch's
    Woodbury capacitance (`SparseRitz.below`). The plan's probe (plan.py): how many branches go to shift-invert and
    with how many pairs. None where the factor gives no count."""
    from .sparse import SIGMA_REL
    fac = factor(spb, -SIGMA_REL * spb.norm)
    if fac.n_neg is None:
        return None
    r, d, Ms = spb.Q.shape[1], spb.scene.dim, spb.A.shape[1]
    Z = fac.solve(np.concatenate([spb.Q, spb.Hs @ spb.Q, spb.R[:, :d], spb.A, spb.S], axis=1))
    solved = dict(zip(("Q", "HQ", "T", "A", "S"), np.split(Z, np.cumsum([r, r, d, Ms]), axis=1)))
    out = [branch_shifted(spb, fac, solved, on).n_below for on in masks[:, spb.sliding] == 1]
    return None if None in out else np.array(out)
