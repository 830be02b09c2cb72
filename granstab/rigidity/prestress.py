"""Second-order rigidity: what the prestress does to the physical model's floppy modes.

A floppy mode costs no first-order contact deformation, so its energy is set by the forces the packing carries:
uᵀ H u with the paper's full H (eq:final1, geometric terms eq:Hg1, eq:equilibrium4, eq:Hg3 included). On the
internal floppy space F (the null vectors restricted to the particles, rigid motions of the scene projected out,
orthonormal in the scaled dofs [du, L dθ]) the symmetric Fᵀ sym(H̃) F is diagonalised on the all-loading branch
(every contact at yield slides, mask +1) and the all-unloading one (all stick): positive eigenvalues are floppy
directions the prestress stabilises, negative ones it destabilises. Wall bodies (--walls bodies) carry no H: their
components are dropped and the walls' forces stay dead loads, as in `analyze`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as la

from ..mechanics.rigid import dof_scale, rigid_basis, rotations, translations
from ..mechanics.stiffness import stiffness
from ..model.scene import Scene
from ..solve.threads import blas_threads

MAX_FLOPPY = 4000          # floppy directions beyond this are not evaluated (a dense f x f problem)
ZERO_RTOL = 1e-9           # eigenvalue counted zero below ZERO_RTOL · max|H̃| (H's round-off is ~ε·|H|·√n)


def floppy_space(scene: Scene, blocks: list, length: float) -> np.ndarray:
    """F (n_dof, f): the null vectors on the scene's dofs with the scene's rigid motions projected out."""
    n = scene.n_dof
    cols = [np.zeros((n, 0))]
    for where, V in blocks:
        keep = where < n
        if keep.any():
            W = np.zeros((n, V.shape[1]))
            W[where[keep]] = V[keep]
            cols.append(W)
    N = np.concatenate(cols, axis=1)
    R = np.concatenate([translations(scene), rotations(scene, length)], axis=1)
    Q = rigid_basis(R)[0]
    N = N - Q @ (Q.T @ N)
    if N.shape[1] == 0:
        return N
    U, s, _ = la.svd(N, full_matrices=False)
    return U[:, s > 1e-8 * max(s[0], 1.0)]


def prestress(scene: Scene, blocks: list, length: float) -> dict:
    """Eigenvalues of Fᵀ sym(H̃) F on the all-loading and all-unloading branches, counted by sign."""
    with blas_threads(1):
        return _prestress(scene, blocks, length)


def _prestress(scene: Scene, blocks: list, length: float) -> dict:
    F = floppy_space(scene, blocks, length)
    f = F.shape[1]
    if f == 0 or f > MAX_FLOPPY:
        return {"floppy_directions": f, "evaluated": False,
                "why": "no internal floppy mode" if f == 0 else f"more than {MAX_FLOPPY} floppy directions"}
    D = dof_scale(scene.n_particles, scene.dim, length)
    at_yield = scene.at_yield()
    out = {"floppy_directions": f, "evaluated": True, "units": "force/length (scaled dofs [du, L dθ])",
           "zero_rtol": ZERO_RTOL}
    for name, mask in (("all_loading", at_yield.astype(int)), ("all_unloading", np.zeros(scene.n_contacts, int))):
        H = stiffness(scene, mask, sparse=True).H
        Ht = (H.multiply(D[:, None]).multiply(D[None, :])).tocsr()
        G = F.T @ (Ht @ F)
        lam = la.eigvalsh(0.5 * (G + G.T))
        tol = ZERO_RTOL * max(abs(Ht).max(), 1e-300)
        out[name] = {"stabilised": int(np.sum(lam > tol)), "destabilised": int(np.sum(lam < -tol)),
                     "neutral": int(np.sum(np.abs(lam) <= tol)), "lowest": lam[:5].tolist(),
                     "highest": lam[-5:].tolist(), "tolerance": float(tol)}
    return out
