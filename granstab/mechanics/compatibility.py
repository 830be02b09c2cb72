"""The compatibility matrix of a body-bar frame: what each contact forbids of the two bodies' velocities.

Each contact constrains the relative velocity of its two contact points, δu_def = du^q - du^p + dθ^q × r^qp -
dθ^p × r^pq (eq:dudef, the map `stiffness.relative_motion`): a sticking contact forbids all of it (d rows: n and
the tangent basis t), a sliding (fully mobilised) one only its normal part n·δu_def (1 row), as RigidLibrary's
pebble game counts them; rolling stiffness (eq:rolling) adds the relative rotation δθ_def (r rows). Rotations are
non-dimensionalised by a length L (the scaled dofs Ũ = [du, L dθ] of metric.py), so that every row and column
has units of length and the singular values are comparable.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..model.vec import rot_dim, tangent_basis
from .stiffness import relative_motion


def constraint_rows(normal: np.ndarray, sliding: np.ndarray, rolling: np.ndarray):
    """Per contact the rows it contributes, as (K, ...) arrays: `contact` (K,) its index, `kind` (K,) 0 normal,
    1 tangential, 2 rolling, and `frame` (K, d) the direction (zero for rolling rows) and `axis` (K,) the rotation
    component of a rolling row (-1 otherwise). Order: contact by contact, normal, tangents, rotations."""
    M, d = normal.shape
    r = rot_dim(d)
    T = tangent_basis(normal)                                      # (M, d, d-1)
    dirs = np.concatenate([normal[:, :, None], T], axis=2)         # (M, d, d): n, t...
    use = np.ones((M, d + r), bool)
    use[:, 1:d] = ~sliding[:, None]
    use[:, d:] = rolling[:, None]
    frame = np.zeros((M, d + r, d))
    frame[:, :d] = np.swapaxes(dirs, 1, 2)
    kind = np.broadcast_to(np.r_[0, np.ones(d - 1, int), np.full(r, 2)], (M, d + r))
    axis = np.broadcast_to(np.r_[np.full(d, -1), np.arange(r)], (M, d + r))
    contact = np.broadcast_to(np.arange(M)[:, None], (M, d + r))
    return contact[use], kind[use], frame[use], axis[use]


def compatibility_matrix(p, q, r_pq, r_qp, normal, sliding, rolling, n_bodies: int, length: float):
    """The sparse compatibility matrix C (K rows, n_bodies·(d + r) columns) in the scaled dofs [du, L dθ], and the
    contact of each row (K,). C Ũ = 0 is the velocity every contact allows (rigidity's null space)."""
    M, d = normal.shape
    r = rot_dim(d)
    per = d + r
    contact, kind, frame, axis = constraint_rows(normal, np.asarray(sliding, bool), np.asarray(rolling, bool))
    Bu, Bt = relative_motion(r_pq, r_qp)                           # (M, d, n), (M, r, n)
    rows = np.einsum("kd,kdn->kn", frame, Bu[contact])
    roll = kind == 2
    rows[roll] = length * Bt[contact[roll], axis[roll]]             # a relative rotation, in length units
    scale = np.ones(2 * per)
    scale[d:per] = scale[per + d:] = 1.0 / length                  # dθ = (L dθ) / L
    rows *= scale
    local = np.r_[np.arange(per), per + np.arange(per)]
    cols = np.where(local < per, p[contact, None] * per + local, q[contact, None] * per + local - per)
    K = len(contact)
    C = sp.csr_matrix((rows.ravel(), (np.repeat(np.arange(K), 2 * per), cols.ravel())), shape=(K, n_bodies * per))
    return C, contact
