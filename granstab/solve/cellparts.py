"""The periodic cell's extended stiffness [[H, Ξ], [Ξ', B]] (mechanics/cell.py) of the elastic branch, assembled in
chunks of contacts (assembled.contact_chunks: one block kernel, stiffness.contact_blocks, for every size; memory
linear in M with ~10 MB of temporaries per chunk), with entrywise bounds of the error of forming each part from the
scene's data (docs/periodic.md, "How C is solved, and how accurate it is"):

* a contact block K_c = Hm + Hg1 + Hg2 + Hg3 (eq:final1) is rounded relative to its parts' own scales (as
  accuracy.formation_error: 8ε per part), plus the error carried in from rounding K^p + K^q (stiffness's
  curvature_error) and γ_4 of the sum: E_c (n_loc, n_loc);
* Ξ = Σ P_cᵀ K_c G_c, Ξ' and B (cell.cell_parts) carry E_c |G_c| + γ_{n_loc+2} |K_c||G_c| per contact, and every
  scatter sums at most a particle's contacts (γ_64 of the absolute sums, assembled alongside).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..mechanics.accuracy import gamma
from ..mechanics.assembly import Assembly, sliding_factors
from ..mechanics.cell import CellParts, strain_columns
from ..mechanics.stiffness import ContactBlocks, geometric
from ..model.scene import Scene
from ..model.tolerances import EPS
from .assembled import CHUNK, contact_chunks

SUM_TERMS = 64   # γ of a scatter: an entry of H, Ξ, Ξ' or B sums at most this many contact terms (a particle's contacts)


@dataclass(frozen=True, eq=False)
class CellSystem:
    """H (CSR, physical dofs), the sliding factors A, S (n, Ms) of the contacts `sliding`, the cell's parts
    (cell.CellParts) and the formation bounds: `H_error` (CSR, entrywise ≥ |ΔH|), `Xi_error` (n, m),
    `left_error` (m, n), `B_error` (m, m), all entrywise; `sliding_scale` (Ms,) ‖a_c‖‖s_c‖ of each sliding contact
    (its rank-one term rounded to 8ε of it, as accuracy.part_scales)."""

    H: sp.csr_matrix
    A: np.ndarray
    S: np.ndarray
    sliding: np.ndarray
    parts: CellParts
    H_error: sp.csr_matrix
    Xi_error: np.ndarray
    left_error: np.ndarray
    B_error: np.ndarray
    sliding_scale: np.ndarray


def _block_error(cb: ContactBlocks, K: np.ndarray) -> np.ndarray:
    """E_c (mc, n_loc, n_loc): 8ε of each part's largest entry in every entry of the block, the curvature error, and
    γ_4 |K_c| (module docstring)."""
    scale = sum(np.abs(b).max(axis=(1, 2)) for b in cb.blocks.values())
    E = 8 * EPS * scale[:, None, None] + gamma(4) * np.abs(K)
    return E if cb.curvature_error is None else E + cb.curvature_error


def cell_system(scene: Scene, chunk: int = CHUNK) -> CellSystem:
    """The elastic branch's [[H, Ξ], [Ξ', B]], its sliding factors and formation bounds, contact chunk by chunk."""
    per, M, n = scene.dof_per_particle, scene.n_contacts, scene.n_dof
    n_loc = 2 * per
    total, error = np.empty((M, n_loc, n_loc)), np.empty((M, n_loc, n_loc))
    a, s, index = np.empty((M, n_loc)), np.empty((M, n_loc)), np.empty((M, n_loc), dtype=np.intp)
    m = scene.dim * (scene.dim + 1) // 2                              # Mandel components
    Xi, Xi_abs, Xi_err = np.zeros((n, m)), np.zeros((n, m)), np.zeros((n, m))
    left, left_abs, left_err = np.zeros((n, m)), np.zeros((n, m)), np.zeros((n, m))
    B, B_abs, B_err = np.zeros((m, m)), np.zeros((m, m)), np.zeros((m, m))
    branch = scene.branch                                            # once: each access forms every contact's
    for sl, cb in contact_chunks(scene, chunk):
        K = cb.blocks["Hm"] + geometric(cb.blocks)
        E = _block_error(cb, K)
        total[sl], error[sl] = K, E
        a[sl], s[sl], index[sl] = cb.slide_left, cb.slide_right, cb.index
        G = strain_columns(scene, branch[sl])
        Ga, Ka = np.abs(G), np.abs(K)
        right, right_abs = K @ G, Ka @ Ga                             # (mc, n_loc, m)
        lft, lft_abs = np.swapaxes(G, 1, 2) @ K, np.swapaxes(Ga, 1, 2) @ Ka
        rnd = gamma(n_loc + 2)
        for acc, val in ((Xi, right), (Xi_abs, right_abs), (Xi_err, E @ Ga + rnd * right_abs),
                         (left, np.swapaxes(lft, 1, 2)), (left_abs, np.swapaxes(lft_abs, 1, 2)),
                         (left_err, np.swapaxes(np.swapaxes(Ga, 1, 2) @ E + rnd * lft_abs, 1, 2))):
            np.add.at(acc, cb.index, val)
        B += np.einsum("mja,mjb->ab", G, right)
        B_abs += np.einsum("mja,mjb->ab", Ga, right_abs)
        B_err += np.einsum("mja,mjb->ab", Ga, E @ Ga) + gamma(2 * n_loc + 2) * np.einsum("mja,mjb->ab", Ga, right_abs)
    assembly = Assembly(scene.p, scene.q, per, n)
    H = assembly(total)
    del total
    H_error = assembly(error) + gamma(SUM_TERMS) * abs(H)
    del error
    sliding = np.flatnonzero(scene.at_yield())
    local = ContactBlocks(blocks={}, slide_left=a, slide_right=s, index=index, n_dof=n,
                          rolling_undetermined=np.zeros(M, bool))
    A, S = sliding_factors(local, sliding)
    Gs = strain_columns(scene, branch[sliding])
    parts = CellParts(Xi=Xi, Xi_left=left.T.copy(), B=B,
                      A_cell=np.einsum("mja,mj->am", Gs, a[sliding]), S_cell=np.einsum("mja,mj->am", Gs, s[sliding]))
    g = gamma(SUM_TERMS)
    return CellSystem(H=H.tocsr(), A=A, S=S, sliding=sliding, parts=parts, H_error=H_error.tocsr(),
                      Xi_error=Xi_err + g * Xi_abs, left_error=(left_err + g * left_abs).T.copy(),
                      B_error=B_err + g * B_abs,
                      sliding_scale=np.linalg.norm(a[sliding], axis=1) * np.linalg.norm(s[sliding], axis=1))
