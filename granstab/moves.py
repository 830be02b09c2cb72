"""Moving a scene's positions within a position band (issue 42): the model of mechanics/nonaffine.py made concrete,
and the first-order direction that moves a mode's work most, for the counter-example search of
granstab.uncertainty (a position set within the band that gives the other verdict, re-analysed by `analyze`).

A move gives every particle centre and contact point a displacement (within the band: each at most LEN); each
normal turns with its centre line (the smallest rotation taking b^pq to the moved b^pq: round particles), and the
curvature tensors (and their sum) turn with it; the radii of curvature stay as measured (a move within the band:
the model lets them move by up to 2·LEN, the search does not use that).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .mechanics.stiffness import contact_blocks, geometric
from .model.scene import Scene
from .model.vec import cross_matrix


def _rotations(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M, d, d): the smallest rotation taking each unit a to the unit b (2D: by the angle between; 3D: Rodrigues
    about a × b; antiparallel pairs are not expected within a band below |b|/2)."""
    if a.shape[1] == 2:
        t = np.arctan2(b[:, 1], b[:, 0]) - np.arctan2(a[:, 1], a[:, 0])
        c, s = np.cos(t), np.sin(t)
        return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    K = cross_matrix(np.cross(a, b))
    c = np.sum(a * b, axis=1)
    return np.eye(3) + K + (K @ K) / (1.0 + c)[:, None, None]


def moved_positions(scene: Scene, x: np.ndarray, point: np.ndarray) -> Scene:
    """The scene with centres x (N, d) and contact points `point` (M, d), each normal and curvature tensor turned
    with its centre line (module docstring); forces and loads as given."""
    out = replace(scene, x=x, point=point)
    b0, b1 = scene.branch, out.branch
    R = _rotations(b0 / np.linalg.norm(b0, axis=1, keepdims=True), b1 / np.linalg.norm(b1, axis=1, keepdims=True))
    Rt = np.swapaxes(R, 1, 2)
    turned = {k: R @ getattr(scene, k) @ Rt for k in ("curvature_p", "curvature_q", "curvature_sum")}
    return replace(out, normal=np.einsum("mij,mj->mi", R, scene.normal), **turned)


def work_gradient_positions(scene: Scene, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(∂W/∂x (N, d), ∂W/∂point (M, d)) of W = Σ_c U_cᵀ sym(X_c) U_c (X_c = Hg1 + Hg2 + Hg3 + Hm_el, U (M, n) the
    motion over each contact's dofs), by central differences with every contact on its own copies of its particles
    (so one move per axis and side gives every contact's derivative), normals turning with the centre lines."""
    M, d = scene.n_contacts, scene.dim
    h = 1e-7 * np.linalg.norm(scene.branch, axis=1)
    own = replace(scene, names=tuple(f"c{i}" for i in range(2 * M)), x=np.concatenate([scene.x[scene.p],
                  scene.q_copy]), p=np.arange(M), q=M + np.arange(M), image=np.zeros((M, d), dtype=np.int64),
                  cell=None, load=np.zeros((2 * M, d)), load_moment=np.zeros((2 * M, scene.load_moment.shape[1])),
                  mass=None, inertia=None, fixed=None)

    def work(s):
        b = contact_blocks(s).blocks
        return np.einsum("ma,mab,mb->m", U, geometric(b) + b["Hm"], U)

    grads = {}
    for what in ("point", "p", "q"):
        g = np.zeros((M, d))
        for j in range(d):
            step = np.zeros((M, d))
            step[:, j] = h
            sides = []
            for sign in (1, -1):
                dx = np.zeros((2 * M, d))
                dp = np.zeros((M, d))
                if what == "point":
                    dp = sign * step
                else:
                    dx[(slice(0, M) if what == "p" else slice(M, 2 * M))] = sign * step
                sides.append(work(moved_positions(own, own.x + dx, own.point + dp)))
            g[:, j] = (sides[0] - sides[1]) / (2 * h)
        grads[what] = g
    gx = np.zeros((scene.n_particles, d))
    np.add.at(gx, scene.p, grads["p"])
    np.add.at(gx, scene.q, grads["q"])
    return gx, grads["point"]
