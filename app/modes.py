"""Eigenmodes for people: what each motion does at the contacts, and poses to animate it (no viser).

A motion U = [du^p, dθ^p]_p (physical dofs, `Analysis.motion`) deforms contact c by δu_def (eq:dudef) and
δθ_def (eq:dtdef), taken from the core's kinematic rows (granstab.mechanics.stiffness.kinematics). Split
δu_def into its normal part (indentation) and tangential part (shearing, or sliding where the branch has the
contact sliding), and weigh δθ_def by the rotation length L (rolling). The label is the largest of the three
summed squares; a rolling motion whose particle centres stay put (after the rigid part is removed) and that turns
three or more particles is a gear mode (Fig. gears). Motions in the rigid span are "rigid"; non-rigid motions
that deform no contact (a particle with no contacts) are "free".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from granstab.mechanics.rigid import rotations, translations
from granstab.mechanics.stiffness import kinematics
from granstab.model.vec import rot_dim

# Relative thresholds, all dimensionless: shares of the summed squares of one unit motion.
NO_DEFORMATION = 1e-10   # summed contact deformation below this × |U|² counts as none
GEAR_TRANSLATION = 0.05  # non-rigid centre motion below this share of the rotation (in L units) counts as still


@dataclass(frozen=True)
class ModeLabel:
    label: str
    shares: dict           # {"indentation", "tangential", "rolling"}: fractions of the contact deformation


def contact_deformation(scene, U: np.ndarray):
    """δu_def (M, d, …) and δθ_def (M, r, …) of every contact for motions U (n_dof, …) (eq:dudef, eq:dtdef)."""
    d, r = scene.dim, rot_dim(scene.dim)
    per = d + r
    local = np.arange(per)
    index = np.concatenate([scene.p[:, None] * per + local, scene.q[:, None] * per + local], axis=1)
    Bu, Bt = kinematics(scene)
    Ul = U[index]                                                   # (M, n_loc, …)
    return np.einsum("mdn,mn...->md...", Bu, Ul), np.einsum("mrn,mn...->mr...", Bt, Ul)


def non_rigid(scene, U: np.ndarray, length: float) -> np.ndarray:
    """U (n_dof, …) minus its least-squares rigid part (translations and rotations about the centroid, metric
    [du, L dθ]); U itself where particles are fixed (a scene held by supports has no rigid motion)."""
    if scene.fixed is not None:
        return U
    D = np.tile(np.r_[np.ones(scene.dim), np.full(rot_dim(scene.dim), length)], scene.n_particles)
    D = D.reshape(-1, *([1] * (U.ndim - 1)))
    R = np.concatenate([translations(scene), rotations(scene, length)], axis=1)   # scaled dofs
    Q, _ = np.linalg.qr(R)
    Us = U * D
    return (Us - Q @ (Q.T @ Us)) / D


def label_mode(scene, U: np.ndarray, mask, length: float, rigid: bool = False) -> ModeLabel:
    """Label a physical motion U of branch `mask` (+1 = sliding contact): see module docstring."""
    return label_modes(scene, np.asarray(U, float)[:, None], mask, length, np.array([rigid]))[0]


def label_modes(scene, U: np.ndarray, mask, length: float, rigid: np.ndarray) -> list[ModeLabel]:
    """Label the physical motions U (n_dof, K) of branch `mask` at once (one contact deformation for all: a
    143-disk frame's 429 modes one at a time took 0.3 s of the server's Python); `rigid` (K,): the core's RIGID code."""
    K = U.shape[1]
    size = np.einsum("nk,nk->k", U, U)
    if scene.n_contacts == 0:
        return [ModeLabel("rigid" if rigid[k] else "free", {}) for k in range(K)]
    du, dth = contact_deformation(scene, U)                                 # (M, d, K), (M, r, K)
    un = np.einsum("mdk,md->mk", du, scene.normal)
    ut = du - un[:, None, :] * scene.normal[:, :, None]
    ut2 = np.sum(ut ** 2, axis=1)                                           # (M, K)
    parts = np.stack([np.sum(un ** 2, axis=0), ut2.sum(axis=0), length ** 2 * np.sum(dth ** 2, axis=(0, 1))])
    total = parts.sum(axis=0)
    which = np.argmax(parts, axis=0)
    still = total <= NO_DEFORMATION * size
    need = (still | (which == 2)) & ~rigid                                 # the rigid part removed: only these
    moving = np.zeros_like(U)
    if need.any():
        moving[:, need] = non_rigid(scene, U[:, need], length)
    moved2 = np.einsum("nk,nk->k", moving, moving)
    per = moving.reshape(scene.n_particles, -1, K)
    d = scene.dim
    trans = np.sum(per[:, :d] ** 2, axis=(0, 1))
    rot = per[:, d:]
    turning = np.sum(np.linalg.norm(rot, axis=1) * length > 0.1 * np.sqrt(size), axis=0)
    gear = (trans <= GEAR_TRANSLATION * length ** 2 * np.sum(rot ** 2, axis=(0, 1))) & (turning >= 3)
    sliding = np.zeros(K, bool) if mask is None else np.asarray(mask)[np.argmax(ut2, axis=0)] == 1
    out = []
    for k in range(K):
        if rigid[k] or (still[k] and moved2[k] <= NO_DEFORMATION * size[k]):
            out.append(ModeLabel("rigid", {}))
        elif still[k]:
            out.append(ModeLabel("free", {}))
        else:
            label = ("indentation", "sliding" if sliding[k] else "shearing", "gear" if gear[k] else "rolling")
            shares = dict(zip(("indentation", "tangential", "rolling"), (parts[:, k] / total[k]).round(3).tolist()))
            out.append(ModeLabel(label[which[k]], shares))
    return out


def mode_offsets(scene, U: np.ndarray, size: float):
    """Per-particle (du (N, d), dθ (N, r)) of U scaled so the largest particle motion (|du| or |dθ|·size) is 1·size."""
    d = scene.dim
    per = U.reshape(scene.n_particles, -1)
    du, dth = per[:, :d], per[:, d:]
    biggest = max(float(np.linalg.norm(du, axis=1).max()), float(np.linalg.norm(dth, axis=1).max()) * size, 1e-300)
    scale = size / biggest
    return du * scale, dth * scale


def rotation_matrix(dim: int, dth: np.ndarray) -> np.ndarray:
    """Rotation by the small-rotation vector dθ (2D: scalar about e3), exactly (Rodrigues)."""
    if dim == 2:
        a = float(np.asarray(dth).reshape(-1)[0])
        return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    v = np.asarray(dth, float)
    a = float(np.linalg.norm(v))
    if a == 0:
        return np.eye(3)
    k = v / a
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
