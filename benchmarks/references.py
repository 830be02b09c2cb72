"""The dense reference for the sparse path: dense sym(𝓗) of the elastic branch and numpy's eigh (n × n)."""
from __future__ import annotations

import numpy as np

from granstab.analysis import build_problem
from granstab.mechanics.branches import branch_matrices
from granstab.mechanics.rigid import rotation_length, rotations, translations
from granstab.mechanics.stiffness import contact_blocks


def dense_sym_calH(scene):
    """REFERENCE: dense sym(𝓗) of the elastic branch from the dense core pieces (n × n)."""
    problem, _ = build_problem(scene, contact_blocks(scene), rotation_length(scene))
    masks = np.zeros((1, scene.n_contacts), dtype=np.int8)
    return branch_matrices(problem, masks)[2][0]


def nonrigid(lam, V, scene, C) -> np.ndarray:
    """The eigenvalues of (lam, V) outside the rigid span [translations, C], in ascending order: the rigid ones
    are the eigenvectors of largest weight in that span."""
    R = np.linalg.qr(np.concatenate([translations(scene), C], axis=1))[0]
    w = np.linalg.norm(R.T @ V, axis=0)
    return lam[np.sort(np.argsort(w, kind="stable")[:len(lam) - R.shape[1]])]


def dense_lowest(scene, k):
    """Dense eigh of sym(𝓗) and its lowest k non-rigid eigenvalues."""
    lam, V = np.linalg.eigh(dense_sym_calH(scene))
    return nonrigid(lam, V, scene, rotations(scene, rotation_length(scene)))[:k]
