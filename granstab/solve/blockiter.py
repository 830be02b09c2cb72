"""The whole packing's lowest modes on the backend's device (issue 41, `--device gpu`): the sparse products and a
preconditioned block iteration (LOBPCG) run where the arrays live — CuPy (cupyx.scipy.sparse) on a GPU, numpy/scipy
on the CPU — and only the k eigenpairs come back.

The operator is the sparse path's deflated B = Hs + U K Uᵀ of the branch (sparse.py: the rigid rotations moved to
s ≥ ‖Hs‖, the translations kept out as LOBPCG's constraints Y), applied as one sparse product and two thin ones on
the device. The preconditioner is block Jacobi on the particle blocks of the elastic Hm + τI (krylov.particle_blocks:
Hm = Bᵀ F B is positive semi-definite with the rigid motions as null space, so it stays SPD whatever the prestress
does), inverted once on the host and applied as one batched product of per × per blocks on the device — no
factorisation, O(contacts) memory, as a 3D packing of 10⁶ spheres needs (its factor would not fit).

Accuracy: the eigenvalues are Rayleigh quotients and the residuals ‖Bv − λv‖/‖Hs‖ are recomputed on the host with
the exact operator in float64 (sparse._finish), so the bounds (sparse.sparse_branch: residual and formation error)
are the CPU's whatever the device did. Not available here: the inertia counts (no factorisation: `verified` is
False and the count below σ is not proven; the CPU's shift-invert path proves it where its factor fits)."""
from __future__ import annotations

import time

import numpy as np

from .device import backend
from .krylov import particle_blocks
from .sparse import Modes, _finish, _lowrank, _on, operator

TOL = 1e-9          # LOBPCG's residual tolerance relative to ‖Hs‖ (eigenvalues then to ~1e-16‖Hs‖: quadratic)
MAXITER = 2000      # iterations: block Jacobi is a weak preconditioner on a whole packing's low end
TAU_REL = 1e-6      # the preconditioner's shift, relative to ‖Hs‖


def _sparse_lib(be):
    """(sparse matrix module, linalg module) of the backend: scipy's or cupyx's."""
    if be.name == "gpu":
        import cupyx.scipy.sparse as xsp
        import cupyx.scipy.sparse.linalg as xla
    else:
        import scipy.sparse as xsp
        import scipy.sparse.linalg as xla
    return xsp, xla


def jacobi_blocks(sp_, tau_rel: float = TAU_REL) -> np.ndarray:
    """The inverses (N, per, per) of the particle blocks of sym(Hm) + τI (|eigenvalues| floored: SPD)."""
    Hm = 0.5 * (sp_.Hm + sp_.Hm.T)
    blocks = particle_blocks(Hm.tocsr(), sp_.scene.dof_per_particle)
    blocks = blocks + tau_rel * sp_.norm * np.eye(blocks.shape[1])
    lam, V = np.linalg.eigh(blocks)
    floor = 1e-6 * max(float(np.abs(lam).max()), 1e-300)
    return (V / np.maximum(np.abs(lam), floor)[:, None, :]) @ np.swapaxes(V, 1, 2)


def device_lowest(sp_, k: int = 6, mask=None, device: str = "cpu", tol: float = TOL, maxiter: int = MAXITER,
                  seed: int = 0) -> Modes:
    """The k lowest non-rigid eigenpairs of sym(𝓗^mask) by preconditioned LOBPCG on `device` (module docstring);
    Modes with method "lobpcg-<device>" and info: iterations, seconds, device, converged."""
    be = backend(device)
    xsp, xla = _sparse_lib(be)
    t = time.perf_counter()
    U, K = _lowrank(sp_, _on(sp_, mask), sp_.norm)
    T = sp_.R[:, :sp_.scene.dim]                                   # translations: constraints (K puts them at s too)
    Hs, Ud, Kd = xsp.csr_matrix(sp_.Hs), be.asarray(U), be.asarray(K)
    Dinv = be.asarray(jacobi_blocks(sp_))
    N, per = Dinv.shape[:2]

    def apply_b(x):
        return Hs @ x + Ud @ (Kd @ (Ud.T @ x))

    def apply_m(x):
        return (Dinv @ x.reshape(N, per, -1)).reshape(x.shape)

    n = sp_.n
    B = xla.LinearOperator((n, n), matvec=apply_b, matmat=apply_b, dtype=np.float64)
    M = xla.LinearOperator((n, n), matvec=apply_m, matmat=apply_m, dtype=np.float64)
    m = min(k + max(4, k // 2), n - sp_.n_rigid - 1)
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, m))
    X -= sp_.R @ (sp_.R.T @ X)
    setup = time.perf_counter() - t
    lam, V = xla.lobpcg(B, be.asarray(X), M=M, Y=be.asarray(T), largest=False, tol=tol * sp_.norm,
                        maxiter=maxiter)
    lam, V = be.to_host(lam), be.to_host(V)
    order = np.argsort(lam)[:k]
    info = {"device": be.name, "setup": setup, "solve": time.perf_counter() - t - setup}
    mask8 = np.zeros(sp_.scene.n_contacts, np.int8) if mask is None else np.asarray(mask, np.int8)
    modes = _finish(sp_, operator(sp_, mask, sp_.norm), lam[order], V[:, order], mask8, np.nan, False, None,
                    f"lobpcg-{be.name}", info)
    info["converged"] = bool(modes.residuals.max(initial=0.0) <= 10 * tol)
    return modes
