"""The moduli's solve above the dense limit (moduli.py): H X = B on the kept dofs (the translations grounded) by GMRES
(gmres.py) preconditioned by the multifrontal Cholesky factor of sym(H) (multifrontal.py, nested-dissection order);
that factor's inertia is the fixed-cell check, and a second elimination of sym(H) - τI proves ‖H⁻¹‖₂ ≤ 1/τ
(xᵀHx = xᵀ sym(H) x ≥ τ‖x‖², so ‖Hx‖ ≥ τ‖x‖) for the moduli's error bounds (moduli.py's docstring).

One factor of the symmetric part replaces SuperLU's LU of both triangles of the non-symmetric H (about twice the
fill): what lets 10⁶ disks fit (BENCHMARKS.md `million`)."""
from __future__ import annotations

import multiprocessing
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .gmres import gmres
from .multifrontal import SINGULAR_RTOL, Multifrontal, dissection_order

GMRES_TOL = 1e-14     # GMRES stops at ‖R‖ ≤ this·‖B‖ per column (the bound carries whatever residual is reached)
FLOOR_BLOCK = 4       # columns of the inverse iteration that estimates λ_min(sym H) …
FLOOR_STEPS = 3       # … its steps, …
FLOOR_MARGIN = 8.0    # … and τ = θ_min / this, proven by the inertia of sym(H) - τI (then τ / FLOOR_MARGIN² once)
PARALLEL_MIN = 200_000   # kept dofs from which that proof runs in a forked process beside GMRES (the second core)

HOW = ("inertia of sym(H) of the elastic branch without the translations, by sparse block elimination "
       "(solve/multifrontal.py; granstab analyze: every branch, consistency and error bounds)")


@dataclass(eq=False)
class SymmetricFactor:
    """sym(H) - shift·I on the kept dofs in a nested-dissection order `perm` (kept-dof numbers), eliminated (`mf`)."""

    mf: Multifrontal
    perm: np.ndarray

    def solve(self, V: np.ndarray) -> np.ndarray:
        out = np.empty_like(V)
        out[self.perm] = self.mf.solve(V[self.perm])
        return out


def symmetric_factor(scene, H: sp.csr_matrix, keep: np.ndarray, shift: float = 0.0,
                     factors: bool = True) -> SymmetricFactor:
    """sym(H) - shift·I (H on the kept dofs `keep`) eliminated in the particles' nested-dissection order
    (multifrontal.dissection_order, the kept dofs of each node together); `factors` False: its inertia only; else
the factors kept in float32 (Multifrontal.to_single: a preconditioner, half the memory and solve time)."""
    per = scene.dof_per_particle
    order, sizes = dissection_order(scene.x, scene.p, scene.q, nodes=True)
    position = np.full(scene.n_dof, -1)
    position[keep] = np.arange(len(keep))
    dofs = position[(order[:, None] * per + np.arange(per)).reshape(-1)]
    node = np.repeat(np.arange(len(sizes)), sizes * per)[dofs >= 0]   # the node of each kept dof, in that order
    perm = dofs[dofs >= 0]
    Hs = (0.5 * (H + H.T)).tocsr()
    if shift:
        Hs = (Hs - shift * sp.identity(Hs.shape[0], format="csr")).tocsr()
    Hs = Hs[perm][:, perm]
    mf = Multifrontal(Hs, np.r_[0, np.cumsum(np.bincount(node, minlength=len(sizes)))], keep=factors)
    if factors and mf.definite:
        mf.to_single()
    return SymmetricFactor(mf=mf, perm=perm)


def held(mf: Multifrontal) -> dict:
    """The fixed-cell check from the inertia of sym(H) (moduli._held above the dense limit)."""
    if not mf.ok:
        return {"verdict": "not determined", "min_eigenvalue": None, "negative_count": None,
                "tolerance": SINGULAR_RTOL, "note": f"an eigenvalue within {SINGULAR_RTOL:g}·‖H‖ of zero: neutral "
                                                    f"or unresolved; {HOW}"}
    return {"verdict": "unstable" if mf.negative else "stable", "min_eigenvalue": None,
            "negative_count": int(mf.negative), "tolerance": SINGULAR_RTOL, "note": HOW}


def _prove(scene, H, keep, theta: float):
    """τ = θ / FLOOR_MARGIN (then / FLOOR_MARGIN³) where the inertia of sym(H) - τI proves λ_min(sym H) ≥ τ; None."""
    for tau in (theta / FLOOR_MARGIN, theta / FLOOR_MARGIN ** 3):
        if tau > 0:
            count = symmetric_factor(scene, H, keep, tau, factors=False).mf
            if count.ok and count.negative == 0:
                return tau
    return None


class Floor:
    """τ > 0 with λ_min(sym H) ≥ τ proven (`_prove`), or None, from the estimate θ of a block inverse iteration with
    sym(H)'s factor; from PARALLEL_MIN kept dofs the elimination runs in a forked process (the second core) while
    the caller solves, and `tau()` waits for it. The answer is the same either way (an inertia count)."""

    def __init__(self, scene, H: sp.csr_matrix, keep: np.ndarray, factor: SymmetricFactor, seed: int = 0):
        X = np.random.default_rng(seed).standard_normal((H.shape[0], FLOOR_BLOCK))
        for _ in range(FLOOR_STEPS):
            X, _ = np.linalg.qr(factor.solve(X))
        self.theta = float(np.linalg.eigvalsh(X.T @ (0.5 * (H @ X + H.T @ X)))[0])   # ≥ λ_min: a Rayleigh quotient
        self._value, self._child = None, None
        if len(keep) >= PARALLEL_MIN and "fork" in multiprocessing.get_all_start_methods():
            ours, theirs = multiprocessing.get_context("fork").Pipe(duplex=False)
            self._child = multiprocessing.get_context("fork").Process(
                target=lambda: theirs.send(_prove(scene, H, keep, self.theta)), daemon=True)
            self._child.start()
            self._pipe = ours
        else:
            self._value = _prove(scene, H, keep, self.theta)

    def tau(self) -> float | None:
        if self._child is not None:
            self._value = self._pipe.recv()
            self._child.join()
            self._child = None
        return self._value


def iterative(H: sp.csr_matrix, factor: SymmetricFactor, info: dict):
    """B ↦ X ≈ H⁻¹B by GMRES preconditioned by `factor`; each call adds its preconditioned products to info."""
    def solve(B: np.ndarray) -> np.ndarray:
        X, _, steps = gmres(lambda V: H @ V, factor.solve, B, GMRES_TOL)
        info["gmres_steps"] = info.get("gmres_steps", 0) + steps
        return X
    return solve
