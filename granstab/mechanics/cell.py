"""The cell's degrees of freedom of a periodic scene (docs/periodic.md): the extended stiffness [[H, Ξ], [Ξ', B]],
the sliding factors of the cell, the stress, and the Mandel basis of symmetric strains.

A symmetric strain ε = Σ_a ε_a E_a (E_a the orthonormal Mandel basis, `mandel_basis`) deforms the cell affinely,
x → (I + ε) x; in the particles' fluctuation dofs Ũ (the motion beyond the affine one) a contact sees the local
motion [du^p, dθ^p, du^q + ε b^pq, dθ^q]: the affine motion is a rigid translation of the contact (which every
block annihilates, eq:piece) plus ε b^pq on q's copy. So each contact block K_c (eq:final1, the elastic or a
sliding branch, eq:ContactF) acts on [U_c; ε] through Ĝ_c = [I | G_c], G_c e_a = E_a b^pq in q's translation
slot, and the cell's rows are the work-conjugate load Σ_c f^pq ⊗ b^pq : E_a (the virial, V σ):

    Ξ = Σ_c P_cᵀ K_c G_c,    Ξ' = Σ_c G_cᵀ K_c P_c,    B = Σ_c G_cᵀ K_c G_c.

For a conservative law these are the mixed and the strain-strain second derivatives of the energy under
x = (I + ε) X + Ũ, jax-md's `elasticity.athermal_moduli` expansion.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.scene import Scene
from ..model.vec import rot_dim


def mandel_basis(dim: int) -> np.ndarray:
    """E_a (m, d, d), m = d(d+1)/2, orthonormal under A:B: e_i⊗e_i, then (e_i⊗e_j + e_j⊗e_i)/√2 in jax-md's
    Mandel order (2D: xx, yy, xy; 3D: xx, yy, zz, yz, xz, xy)."""
    pairs = [(i, i) for i in range(dim)] + ([(0, 1)] if dim == 2 else [(1, 2), (0, 2), (0, 1)])
    E = np.zeros((len(pairs), dim, dim))
    for a, (i, j) in enumerate(pairs):
        if i == j:
            E[a, i, i] = 1.0
        else:
            E[a, i, j] = E[a, j, i] = np.sqrt(0.5)
    return E


def to_tensor(matrix: np.ndarray) -> np.ndarray:
    """A Mandel matrix (m, m) → the fourth-order tensor C_ijkl = Σ_ab C_ab (E_a)_ij (E_b)_kl, (d, d, d, d)."""
    dim = {3: 2, 6: 3}[matrix.shape[0]]
    E = mandel_basis(dim)
    return np.einsum("ab,aij,bkl->ijkl", matrix, E, E)


def to_mandel(tensor: np.ndarray) -> np.ndarray:
    """The inverse of `to_tensor` for a tensor with the minor symmetries: C_ab = E_a : C : E_b."""
    E = mandel_basis(tensor.shape[0])
    return np.einsum("aij,ijkl,bkl->ab", E, tensor, E)


def stress(scene: Scene, volume: float | None = None) -> np.ndarray:
    """σ = (1/V) Σ_c f^pq ⊗ b^pq (d, d), tension positive: f^pq the force on p by q, b^pq the branch vector to q's
    copy (compressed contacts give a negative trace). Not symmetrised: its skew part is the contacts' net couple.
    V: the cell's (default) or, for a scene without a cell, the `volume` the caller states."""
    return np.einsum("mi,mj->ij", scene.force, scene.branch) / (scene.volume if volume is None else volume)


def strain_columns(scene: Scene, branch: np.ndarray | None = None) -> np.ndarray:
    """G_c (M, n_loc, m): the local motion of each contact under a unit strain E_a, E_a b^pq on q's translation
    (`branch`: the branch vectors of some of the scene's contacts, default all of them)."""
    d, r = scene.dim, rot_dim(scene.dim)
    E = mandel_basis(d)
    branch = scene.branch if branch is None else branch
    G = np.zeros((len(branch), 2 * (d + r), len(E)))
    G[:, d + r:2 * d + r, :] = np.einsum("aij,mj->mia", E, branch)
    return G


@dataclass(frozen=True, eq=False)
class CellParts:
    """The cell rows and columns of the elastic branch and the cell's part of the sliding factors.

    Xi (n, m): Ξ; Xi_left (m, n): Ξ'; B (m, m); A_cell, S_cell (m, Ms): G_cᵀ a_c, G_cᵀ s_c of the potentially
    sliding contacts (S_cell e_a: the S = g·δu_def of eq:flow of a unit strain). A branch adds A_on S_onᵀ to H,
    A_on S_cell,onᵀ to Ξ, A_cell,on S_onᵀ to Ξ' and A_cell,on S_cell,onᵀ to B (eq:ContactF)."""

    Xi: np.ndarray
    Xi_left: np.ndarray
    B: np.ndarray
    A_cell: np.ndarray
    S_cell: np.ndarray


def cell_parts(scene: Scene, blocks, sliding: np.ndarray) -> CellParts:
    """Ξ, Ξ', B of the elastic branch from the contact blocks (stiffness.ContactBlocks), and the cell's sliding
    factors of the contacts `sliding` (Ms,)."""
    G = strain_columns(scene)
    K = sum(blocks.blocks.values())                                   # Hg1 + Hg2 + Hg3 + Hm (eq:final1)
    right = K @ G                                                     # (M, n_loc, m)
    left = np.swapaxes(G, 1, 2) @ K                                   # (M, m, n_loc)
    m, n = G.shape[2], blocks.n_dof
    index = blocks.index.ravel()
    Xi = np.stack([np.bincount(index, right[:, :, a].ravel(), n) for a in range(m)], axis=1)
    Xi_left = np.stack([np.bincount(index, left[:, a, :].ravel(), n) for a in range(m)], axis=0)
    B = np.einsum("mja,mjb->ab", G, right)
    Gs = G[sliding]
    return CellParts(Xi=Xi, Xi_left=Xi_left, B=B,
                     A_cell=np.einsum("mja,mj->am", Gs, blocks.slide_left[sliding]),
                     S_cell=np.einsum("mja,mj->am", Gs, blocks.slide_right[sliding]))


def stress_work(sigma: np.ndarray) -> np.ndarray:
    """Q (m, m): the second-order work of a constant Cauchy stress σ on the cell per unit volume,
    W = V[σ:ε + ½((tr ε)(σ:ε) - σ:(ε ε))] under F = I + ε, as the symmetric matrix of ½ε·Q·ε. At fixed stress
    the stiffness of the cell is C - Q (for σ = -p I: C + p(δ⊗δ - I), the enthalpy U + pV)."""
    s = 0.5 * (sigma + sigma.T)
    E = mandel_basis(len(s))
    tr = np.trace(E, axis1=1, axis2=2)
    se = np.einsum("ij,aij->a", s, E)
    ee = np.einsum("ij,aik,bkj->ab", s, E, E)
    Q = 0.5 * (tr[:, None] * se[None] + se[:, None] * tr[None]) - 0.5 * (ee + ee.T)
    return Q
