"""Drawing geometry of shapes, from the same kernel as their contacts (granstab.model.shapes): numpy only.

`tip_ellipse(r, rho)`: the ellipse a contact-level grain is drawn as — semi-axis r along its line of centres and
b = √(ρ r) across, so that the radius of curvature at its tip, b²/a, is ρ exactly (the pair of Sec. 4.1 at its
ρ/r). `support_outline(S, n)`: surface points of a convex shape with shape tensor S (shapes.shape_tensor) at outward
normals n, x = S n / h(n) with h(n) = √(nᵀ S n) the support function (the point whose normal is n).
"""
from __future__ import annotations

import numpy as np


def tip_ellipse(r: float, rho: float) -> tuple[float, float]:
    """Semi-axes (a, b) = (r, √(ρ r)) of the ellipse whose tip, at distance r from its centre, has radius of
    curvature ρ (b²/a = ρ): sharp tips for ρ < r, a circle at ρ = r, flat sides for ρ > r."""
    if r <= 0 or rho <= 0:
        raise ValueError(f"tip_ellipse: r and rho must be > 0, got r = {r!r}, rho = {rho!r}")
    return float(r), float(np.sqrt(rho * r))


def support_outline(S: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Points (…, d) of the surface with outward unit normals n (…, d) of the shape with tensor S (d, d):
    x = S n / √(nᵀ S n) (the gradient of the support function h(n) = √(nᵀ S n))."""
    n = np.asarray(n, float)
    Sn = n @ np.asarray(S, float).T
    return Sn / np.sqrt(np.sum(n * Sn, axis=-1))[..., None]


def rounded_polygon(vertices: np.ndarray, radius: float, per_corner: int = 8) -> np.ndarray:
    """Counter-clockwise outline (V·per_corner, 2) of a rounded polygon (LAMMPS `body rounded/polygon`): the convex
    polygon `vertices` (V, 2, in order around it, either way) swept by a disk of `radius`. Each vertex contributes
    an arc of that radius from the outward normal of its incoming side to that of its outgoing side; the straight
    sides join consecutive arcs."""
    v = np.asarray(vertices, float)
    x, y = v[:, 0], v[:, 1]
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:           # clockwise: reverse
        v = v[::-1]
    side = np.roll(v, -1, axis=0) - v                                  # side i: vertex i → i + 1
    out = np.arctan2(-side[:, 0], side[:, 1])                          # its outward normal's angle
    start = np.roll(out, 1)                                            # the incoming side of vertex i
    turn = np.mod(out - start, 2 * np.pi)
    turn = np.where(turn > np.pi, 0.0, turn)                           # a reflex vertex: no arc
    t = np.linspace(0.0, 1.0, per_corner)
    angle = start[:, None] + turn[:, None] * t[None, :]
    arcs = v[:, None, :] + radius * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    return arcs.reshape(-1, 2)
