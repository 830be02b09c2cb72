"""granstab.model.outline: the drawn tip ellipse has the contact's radius of curvature, checked two ways — the
shape kernel's curvature tensor (shapes.surface_curvature_at) and a circle through three nearby points of the
outline that support_outline draws (finite differences of the exact curve)."""
from __future__ import annotations

import numpy as np
import pytest

from granstab.model import shapes
from granstab.model.outline import support_outline, tip_ellipse


@pytest.mark.parametrize("rho_r", [0.25, 0.5, 1.0, 1.5, 4.0])
def test_the_tip_has_radius_of_curvature_rho(rho_r):
    r = 1.3
    a, b = tip_ellipse(r, rho_r * r)
    ellipse = shapes.Ellipse(a, b)
    K = shapes.surface_curvature_at(ellipse, (np.zeros(2), 0.0), np.array([a, 0.0]))
    assert -1.0 / K[1, 1] == pytest.approx(rho_r * r, rel=1e-12)             # the kernel: κ = -1/ρ across
    S = shapes.shape_tensor(ellipse, 0.0)
    t = 1e-4                                                                  # three normals about the tip
    p = support_outline(S, np.stack([np.cos([-t, 0, t]), np.sin([-t, 0, t])], axis=1))
    assert np.allclose(p[1], [a, 0.0], rtol=0, atol=1e-15)
    A, B, C = p
    circumradius = (np.linalg.norm(A - B) * np.linalg.norm(B - C) * np.linalg.norm(C - A)
                    / (2 * abs((B - A)[0] * (C - A)[1] - (B - A)[1] * (C - A)[0])))
    assert circumradius == pytest.approx(rho_r * r, rel=1e-6)                # O(t²) from the chord's curvature


def test_outline_points_have_the_normals_asked_for_and_bad_sizes_fail():
    S = shapes.shape_tensor(shapes.Ellipse(2.0, 0.5), 0.3)
    n = np.stack([np.cos(np.linspace(0, 2 * np.pi, 7)), np.sin(np.linspace(0, 2 * np.pi, 7))], axis=1)
    x = support_outline(S, n)
    assert np.allclose(np.einsum("ij,jk,ik->i", x, np.linalg.inv(S), x), 1.0, rtol=1e-13)     # on the ellipse
    m = x @ np.linalg.inv(S)                                                   # its normal there ∝ S⁻¹ x
    assert np.allclose(m / np.linalg.norm(m, axis=1)[:, None], n, atol=1e-13)
    with pytest.raises(ValueError, match="rho must be > 0"):
        tip_ellipse(1.0, 0.0)
