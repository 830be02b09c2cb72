"""The shape kernel (granstab/model/surface.py) against independent evaluations.

- Sphere and ellipsoid: the closed forms (sphere: −(I − n⊗n)/(R − depth); ellipsoid: shapes.py's support-function
  curvature, a different formula) at 1e-12 of |K|.
- Superquadrics, the extremes (blocky n up to 10, aspect ratio 2.5, flat faces, tips, mixed n1 ≠ n2, far from the
  origin, tiny and huge length scales): F written afresh in mpmath at 40 digits, its derivatives by mpmath's
  numerical differentiation (not the kernel's analytic formulas), the foot point refined by mpmath's root finder
  on the Lagrange conditions, then W = P ∇∇F P/|∇F| and −P W (I − dW)⁻¹ P; the kernel agrees to 1e-8 of |W|.
- Foot points are the nearest surface points: never farther than the nearest vertex of a fine mesh, for points
  inside and outside.
"""
from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from scipy.spatial import cKDTree

from granstab.model import shapes as gshapes
from granstab.model import surface as sf

RTOL = 1e-8          # vs |W| (the bound for the stored curvature)


def random_rotation(rng):
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q * np.sign(np.linalg.det(Q))


def test_sphere_closed_form():
    rng = np.random.default_rng(1)
    R, depth = 2.5, 0.01
    n = rng.normal(size=(6, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    centres = rng.normal(size=(6, 3)) * 100
    points = centres + (R - depth) * n
    rot = np.array([random_rotation(rng) for _ in range(6)])
    K, nu, d = sf.contact_curvature(points, centres, rot, np.full((6, 3), R), np.full((6, 2), 2.0), n)
    expect = -(np.eye(3) - n[:, :, None] * n[:, None, :]) / (R - depth)
    assert np.abs(K - expect).max() <= 1e-12 / R
    assert np.abs(d - depth).max() <= 1e-12 * 100
    assert np.abs(nu - n).max() <= 1e-12


def test_ellipsoid_equals_support_function_curvature():
    rng = np.random.default_rng(2)
    axes = np.array([3.0, 1.5, 1.0])
    for _ in range(5):
        R = random_rotation(rng)
        x = rng.normal(size=3) * 1e3
        m = rng.normal(size=3)
        m /= np.linalg.norm(m)
        yb = axes**2 * m / np.sqrt(np.sum(axes**2 * m**2))       # the surface point with body normal m
        nb = yb / axes**2
        nb /= np.linalg.norm(nb)
        depth = 0.02
        K, _, d = sf.contact_curvature((x + R @ (yb - depth * nb))[None], x[None], R[None], axes[None],
                                       np.array([[2.0, 2.0]]), (R @ nb)[None])
        ref = gshapes.surface_curvature_at(gshapes.Ellipsoid(*axes), (x, R), x + R @ yb, depth)
        assert abs(d[0] - depth) <= 1e-12 * 1e3
        assert np.abs(K[0] - ref).max() <= 1e-12 * 1e3 * np.abs(ref).max()   # |x| = 1e3 rounds the offset


# ----------------------------------------------------------------------------------------- mpmath truth

def mp_F(y, axes, n1, n2):
    a, b, c = axes
    return (abs(y[0] / a) ** n2 + abs(y[1] / b) ** n2) ** (n1 / n2) + abs(y[2] / c) ** n1


def mp_truth(y, axes, n1, n2, s0, lam0):
    """Foot point, depth and −P W (I − dW)⁻¹ P (body axes) in mpmath, from a start (s0, λ0) near the answer."""
    axes = [mp.mpf(v) for v in axes]
    n1, n2 = mp.mpf(n1), mp.mpf(n2)
    y = [mp.mpf(v) for v in y]

    def grad(s):
        return [mp.diff(lambda t, i=i: mp_F([t if j == i else s[j] for j in range(3)], axes, n1, n2), s[i])
                for i in range(3)]

    def hess(s):
        H = mp.matrix(3, 3)
        for i in range(3):
            for j in range(3):
                order = [0, 0, 0]
                order[i] += 1
                order[j] += 1
                H[i, j] = mp.diff(lambda u, v, w: mp_F([u, v, w], axes, n1, n2), s, tuple(order))
        return H

    def eqs(s0_, s1_, s2_, lam):
        s = [s0_, s1_, s2_]
        g = grad(s)
        return [s[i] + lam * g[i] - y[i] for i in range(3)] + [mp_F(s, axes, n1, n2) - 1]

    sol = mp.findroot(eqs, [mp.mpf(v) for v in s0] + [mp.mpf(lam0)], tol=mp.mpf(10) ** -60)
    s = [sol[i] for i in range(3)]
    g = mp.matrix(grad(s))
    gn = mp.norm(g)
    nu = g / gn
    P = mp.eye(3) - nu * nu.T
    W = P * hess(s) * P / gn
    depth = -sum((y[i] - s[i]) * nu[i] for i in range(3))
    B = mp.eye(3) - depth * W + nu * nu.T
    K = -(W * mp.inverse(B))
    return np.array(K.tolist(), dtype=float), float(depth), np.array([float(v) for v in nu])


CASES = [  # axes, n1, n2, body direction of the surface point, depth/size, length scale, centre offset
    ((1.0, 0.6, 0.4), 3.0, 3.0, (0.3, 0.5, 0.8), 0.01, 1.0, 0.0),
    ((1.0, 0.6, 0.4), 10.0, 10.0, (0.05, 0.02, 1.0), 0.005, 1.0, 0.0),      # a nearly flat face
    ((1.0, 0.6, 0.4), 10.0, 10.0, (1.0, 0.9, 0.8), 0.002, 1.0, 0.0),        # a rounded corner
    ((2.5, 1.0, 1.0), 4.0, 4.0, (1.0, 0.01, 0.02), 0.01, 1.0, 0.0),         # the tip of an elongated grain
    ((1.0, 1.0, 0.5), 3.0, 6.0, (0.6, -0.4, 0.5), 0.01, 1.0, 0.0),          # n1 ≠ n2
    ((1.0, 0.6, 0.4), 6.0, 6.0, (-0.5, 0.7, -0.4), 0.01, 1e-6, 0.0),        # tiny
    ((1.0, 0.6, 0.4), 6.0, 6.0, (-0.5, 0.7, -0.4), 0.01, 1e6, 0.0),         # huge
    ((1.0, 0.6, 0.4), 3.0, 3.0, (0.3, -0.5, 0.8), 0.01, 1.0, 1e5),          # far from the origin
    ((1.0, 0.6, 0.4), 3.0, 3.0, (0.3, 0.5, 0.8), -0.05, 1.0, 0.0),          # a point outside
]


@pytest.mark.parametrize("axes, n1, n2, direction, depth, scale, offset", CASES)
def test_contact_curvature_matches_mpmath(axes, n1, n2, direction, depth, scale, offset):
    mp.mp.dps = 40
    rng = np.random.default_rng(7)
    axes = np.array(axes) * scale
    ray = np.array(direction, float)
    surface = ray / sf.implicit(ray[None], axes, np.array([n1, n2]), order=1)[0][0]
    _, g = sf.implicit(surface[None], axes, np.array([n1, n2]), order=1)
    nu = g[0] / np.linalg.norm(g[0])
    y = surface - depth * scale * nu
    R = random_rotation(rng)
    centre = np.array([offset, -offset, 0.5 * offset]) * scale
    point = centre + R @ y
    K, nu_w, d = sf.contact_curvature(point[None], centre[None], R[None], axes[None], np.array([[n1, n2]]),
                                      (R @ nu)[None])
    yb = R.T @ (point - centre)                       # the body point the kernel saw (rounded like it)
    s_k, _, dist = sf.foot_points(yb[None], axes, np.array([n1, n2]))
    Kb, depth_mp, nu_mp = mp_truth(yb, axes, n1, n2, s_k[0], -dist[0] / np.linalg.norm(g[0]) / scale)
    n_w = R @ nu_mp
    P = np.eye(3) - np.outer(R @ nu, R @ nu)
    expect = P @ (R @ Kb @ R.T) @ P
    W = np.abs(np.linalg.eigvalsh(Kb)).max()
    assert np.abs(K[0] - expect).max() <= RTOL * W
    assert abs(d[0] - depth_mp) <= 1e-10 * scale * (1 + abs(offset))
    assert np.abs(nu_w[0] - n_w).max() <= 1e-10


@pytest.mark.parametrize("n", [2.0, 3.0, 6.0, 10.0])
@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_foot_points_are_nearest(n, scale):
    """Inside and outside points: on the surface, along the normal, and never farther than the nearest of
    ~80 000 mesh vertices (whose spacing bounds how much nearer a missed point could be)."""
    rng = np.random.default_rng(3)
    axes = np.array([1.0, 0.6, 0.4]) * scale
    y = rng.normal(size=(500, 3)) * 0.6 * scale
    s, nu, dist = sf.foot_points(y, axes, np.array([n, n]))
    phi, _ = sf.implicit(s, axes, np.array([n, n]), order=1)
    assert np.abs(phi - 1).max() <= 8e-15                            # on the surface φ = F^(1/n1) = 1
    assert np.abs(np.cross(y - s, nu)).max() <= 1e-13 * scale
    verts, _ = sf.mesh(sf.Superquadric(*axes, n, n), resolution=200)
    nearest, _ = cKDTree(verts).query(y)
    assert np.all(np.abs(dist) <= nearest + 1e-12 * scale)
    assert np.all((dist < 0) == (sf.implicit(y, axes, np.array([n, n]), order=1)[0] < 1))


def test_mesh_is_closed_outward_and_on_the_surface():
    shape = sf.Superquadric(1.0, 0.6, 0.4, 4.0, 3.0)
    V, F = sf.mesh(shape, resolution=24)
    phi, _ = sf.implicit(V[np.linalg.norm(V, axis=1) > 0], np.array(shape.semi_axes), np.array([4.0, 3.0]), 1)
    assert np.abs(phi - 1).max() <= 1e-12
    tri = V[F]
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert volume > 0.8 * 8 * 1.0 * 0.6 * 0.4 * 0.6          # outward winding; a blocky grain fills its box well
    assert sf.mesh(shape, resolution=24)[0] is V               # one shared mesh per shape


def test_outline_of_an_ellipse():
    pts = sf.outline(gshapes.Ellipse(2.0, 1.0), points=32)
    assert np.abs((pts[:, 0] / 2) ** 2 + pts[:, 1] ** 2 - 1).max() <= 1e-14


def test_parallel_surface_degenerate_is_refused():
    """Depth equal to a radius of curvature (1/W): the parallel surface is degenerate."""
    W = np.diag([1.0, 0.5, 0.0])[None]
    nu = np.array([[0.0, 0.0, 1.0]])
    assert np.allclose(sf.parallel_operator(W, nu, np.array([0.5])), np.diag([2.0, 2 / 3, 0.0]), rtol=1e-15)
    with pytest.raises(ValueError, match="radius of curvature"):
        sf.parallel_operator(W, nu, np.array([1.0]))


def test_superquadric_rejects_bad_parameters():
    with pytest.raises(ValueError, match="n1 must be"):
        sf.Superquadric(1.0, 1.0, 1.0, 1.5, 2.0)


def test_ellipse_equals_support_function_curvature():
    """2D: the kernel's superellipse with n = 2 (the app's ellipses) against shapes.py's ellipse curvature."""
    a, b, depth = 2.0, 1.0, 0.05
    for theta, turn in ((0.7, 0.4), (2.0, -1.2), (4.0, 3.0)):
        R = gshapes.rotation_matrix(2, turn)
        x = np.array([3.0, -1.0])
        yb = np.array([a * np.cos(theta), b * np.sin(theta)])
        nb = yb / np.array([a * a, b * b])
        nb /= np.linalg.norm(nb)
        K, _, d = sf.contact_curvature((x + R @ (yb - depth * nb))[None], x[None], R[None], np.array([[a, b]]),
                                       np.array([[2.0, 2.0]]), (R @ nb)[None])
        ref = gshapes.surface_curvature_at(gshapes.Ellipse(a, b), (x, turn), x + R @ yb, depth)
        assert abs(d[0] - depth) <= 1e-14 * 4
        assert np.abs(K[0] - ref).max() <= 1e-13 * np.abs(ref).max()
