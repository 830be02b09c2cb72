"""Why a cluster is unstable (issue 25): the second-order work of a consistent negative mode split by part, its
share on the rim, and the mechanism label from these and two control solves.

The work of a motion U on branch i, Uᵀ H^i U (eq:newinner), is a sum over contacts of U_cᵀ X_c U_c, X_c the
contact's block of each part of H = Hg1 + Hg2 + Hg3 + Hm (eq:final1, stiffness.contact_blocks). Five parts
(`PARTS`): Hm of the contacts that are elastic on the branch, Hm of those that slide on it (their elastic block plus
the rank-one a ⊗ s, eq:ContactF), Hg1, Hg2, and Hg3 (the corotation of the loads, eq:Hg3). With U = D P v for the
eigenvector v, unit in the verdict's metric (metric.py: Ũ = D⁻¹ U) and P the no-rigid-rotation projection
(eq:Pnrr, identity for held clusters), the five parts sum to vᵀ sym(𝓗^i) v = λ: the row's lambda_min when v is
the lowest consistent negative mode. One kernel (`contact_work`) serves one scene (analysis.attribute) and a
stack of clusters (scan/batch.py).

Mechanism rule (`mechanism`, first that holds):
  frictional: Hm of the sliding contacts is negative and the all-elastic control is stable;
  geometric:  Hg1 + Hg2 is negative and both controls (all elastic; rim held) are still unstable — the rolling
              instability of sharp contacts (Sec. 4.1);
  boundary:   Hg3 is negative or the rim carries the mode (rim_share > RIM_CARRIES), and the rim-held control is
              stable — the dead loads at the cut, not the packing;
  mixed:      unstable, none of the above.
"""
from __future__ import annotations

import numpy as np

PARTS = ("Hm_elastic", "Hm_sliding", "Hg1", "Hg2", "Hg3")
MECHANISMS = ("frictional", "geometric", "boundary", "mixed")
RIM_CARRIES = 0.5       # rim_share above which the rim carries the mode (more of its metric norm there than inside)


def contact_work(blocks, contacts: np.ndarray, U: np.ndarray, sliding: np.ndarray) -> np.ndarray:
    """Per entry e the work U[e]ᵀ X U[e] of each part (P, 5), in `PARTS` order.

    blocks: stiffness.ContactBlocks; contacts (P,): the contact of each entry; U (P, n): the physical motion on the
    contact's local dofs [du^p, dθ^p, du^q, dθ^q] (zero on held dofs); sliding (P,) bool: the contact slides on
    the branch (adds a ⊗ s to its Hm, eq:ContactF)."""
    def quad(name):
        return np.einsum("pi,pij,pj->p", U, blocks.blocks[name][contacts], U)

    hm = quad("Hm")
    rank_one = (np.einsum("pi,pi->p", U, blocks.slide_left[contacts])
                * np.einsum("pi,pi->p", U, blocks.slide_right[contacts]))
    out = np.zeros((len(contacts), len(PARTS)))
    out[:, 0] = np.where(sliding, 0.0, hm)
    out[:, 1] = np.where(sliding, hm + rank_one, 0.0)
    for j, name in enumerate(("Hg1", "Hg2", "Hg3"), start=2):
        out[:, j] = quad(name)
    return out


def rim_share(weights: np.ndarray, rim: np.ndarray, inside: np.ndarray | None = None) -> np.ndarray:
    """Share of a mode's squared metric norm on the rim particles among the cluster's: weights (..., N) per particle
    (Σ over its dofs of ṽ²), rim, inside (N,) or (..., N) bool (inside: the cluster's particles; default all)."""
    inside = np.ones(weights.shape, dtype=bool) if inside is None else inside
    total = np.sum(weights * inside, axis=-1)
    return np.divide(np.sum(weights * (rim & inside), axis=-1), total, out=np.full(total.shape, np.nan),
                     where=total > 0)


def mechanism(parts: np.ndarray, share: np.ndarray, elastic: np.ndarray, fixed: np.ndarray,
              unstable: np.ndarray) -> np.ndarray:
    """The label of each row (the module docstring's rule): parts (G, 5), share (G,), the controls' verdict strings
    (G,) and whether the row is unstable (G,); '' for rows that are not."""
    parts = np.atleast_2d(np.asarray(parts, dtype=float))
    elastic, fixed = np.asarray(elastic, dtype=object), np.asarray(fixed, dtype=object)
    frictional = (parts[:, 1] < 0) & (elastic == "stable")
    geometric = (parts[:, 2] + parts[:, 3] < 0) & (elastic == "unstable") & (fixed == "unstable")
    boundary = ((parts[:, 4] < 0) | (np.asarray(share) > RIM_CARRIES)) & (fixed == "stable")
    label = np.select([frictional, geometric, boundary], MECHANISMS[:3], default="mixed").astype(object)
    return np.where(np.asarray(unstable, dtype=bool), label, "").astype(object)
