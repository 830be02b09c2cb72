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
