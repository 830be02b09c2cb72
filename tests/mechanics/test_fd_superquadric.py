"""granstab's H of small superquadric clusters against the derivative of EXACT nonlinear statics.

Pairs and a chain of three blocky, elongated superquadrics (n1 = n2 = ν from 3 to 6, aspect ratio 2, LIGGGHTS's
surface) pressed to an overlap δ = f/k from 1e-4 to 1e-2 (lengths ~1), with tangential forces. The scene is made
as the LIGGGHTS reader makes it: contact point c and normal n, curvatures from model/surface.py's
`contact_curvature` at c (foot points, parallel surfaces). The exact model (tests/exact_geometry.py) moves the
contact on both surfaces: the common normal maximises d·n − h_p(n) − h_q(n) with the superquadric support function
h (the dual q-norm, q = ν/(ν − 1)), P and Q are the support points and c their midpoint; H_exact = ∂[b, w]/∂[u, θ]
by the complex step. Tolerances as in test_fd_exact.py: ‖H − H_exact‖ ≤ 1e-12 ‖H‖, geometric part ≤ 1e-8 ‖Hg‖
(round-off eps/(f/k) of ‖Hg‖ plus the foot-point solve's 1e-13 of a length).
"""
from dataclasses import replace
from functools import cache

import numpy as np
import pytest
from exact_geometry import Cluster, contact_state, stiffness_exact
from scipy.spatial.transform import Rotation

import granstab
from granstab.model import surface
from granstab.model.scene import build_scene

LEVELS = (1e-4, 1e-3, 1e-2)
K, ALPHA, MU = 1.0, 0.7, 0.5
CLUSTERS = {   # axes (N, 3), ν (N,), centres (N, 3), rotation vectors (N, 3), pairs
    "pair": (np.array([[1.0, 0.6, 0.5], [0.9, 0.5, 0.45]]), np.array([4.0, 3.0]),
             np.array([[0.0, 0.0, 0.0], [1.2, 0.5, 0.3]]), np.array([[0.3, -0.2, 0.5], [-0.4, 0.1, 0.9]]),
             [(0, 1)]),
    "chain": (np.array([[1.0, 0.6, 0.5], [0.9, 0.5, 0.45], [0.8, 0.5, 0.4]]), np.array([4.0, 6.0, 3.0]),
              np.array([[0.0, 0.0, 0.0], [1.2, 0.5, 0.3], [2.0, 1.3, 0.1]]),
              np.array([[0.3, -0.2, 0.5], [-0.4, 0.1, 0.9], [0.7, 0.4, -0.2]]), [(0, 1), (1, 2)]),
}


def _cluster(axes, nu, x, R, pairs, n0):
    p, q = (np.array(v) for v in zip(*pairs))
    M = len(p)
    return Cluster(x0=x, R0=R, axes=axes, p=p, q=q, k=np.full(M, K), alpha=np.full(M, ALPHA), k_r=np.zeros(M),
                   a_p0=np.zeros((M, 3)), a_q0=np.zeros((M, 3)), n0=n0, blockiness=nu)


def pressed(name, level):
    """The cluster with every pair overlapping by `level` (each grain moved along its contact's normal in turn),
    its exact state (n, δ, c)."""
    axes, nu, x, rv, pairs = CLUSTERS[name]
    x = x.copy()
    R = Rotation.from_rotvec(rv).as_matrix()
    n0 = x[[q for _, q in pairs]] - x[[p for p, _ in pairs]]
    n0 /= np.linalg.norm(n0, axis=1)[:, None]
    cl = _cluster(axes, nu, x, R, pairs, n0)
    for _ in range(60):
        n, delta, c = contact_state_converged(cl)
        for k, (_, q) in enumerate(pairs):       # a chain: moving q along n fixes pair k, then the next
            x[q:] += (delta[k] - level) * n[k]
        cl.n0 = n
        if np.abs(delta - level).max() <= 1e-15:
            break
    return cl, contact_state_converged(cl)


def contact_state_converged(cl):
    """The exact (real) contact state, Newton iterated from the stored normals until they settle."""
    for _ in range(30):
        n, delta, c = contact_state(cl, cl.x0, cl.R0)
        if np.abs(n - cl.n0).max() <= 1e-15:
            break
        cl.n0 = n
    return n, delta, c


@cache
def case(name, level):
    cl, (n, delta, c) = pressed(name, level)
    M = len(cl.p)
    K_p, _, depth_p = surface.contact_curvature(c, cl.x0[cl.p], cl.R0[cl.p], cl.axes[cl.p],
                                                np.repeat(cl.blockiness[cl.p, None], 2, axis=1), n)
    K_q, _, depth_q = surface.contact_curvature(c, cl.x0[cl.q], cl.R0[cl.q], cl.axes[cl.q],
                                                np.repeat(cl.blockiness[cl.q, None], 2, axis=1), -n)
    t = np.cross(n, [0.3, 0.5, 0.8])
    t /= np.linalg.norm(t, axis=1)[:, None]
    force = -K * delta[:, None] * n + 0.3 * K * delta[:, None] * t
    s = 0.3 * K * delta[:, None] * t / (ALPHA * K)
    cl.a_p0, cl.a_q0 = c - s / 2, c + s / 2
    arrays = {"p": cl.p, "q": cl.q, "point": c, "normal": n, "curvature_p": K_p, "curvature_q": K_q,
              "force": force, "moment": np.zeros((M, 3)), "k": cl.k, "alpha": cl.alpha, "mu": np.full(M, MU),
              "rolling": np.zeros((M, 3, 3)), "state": ("auto",) * M}
    scene = build_scene(3, [str(i) for i in range(len(cl.x0))], cl.x0, arrays)
    return scene, granstab.stiffness(scene), stiffness_exact(cl), (depth_p, depth_q, delta)


@pytest.mark.parametrize("name", CLUSTERS)
@pytest.mark.parametrize("level", LEVELS)
def test_superquadric_stiffness_matches_exact_derivative(name, level):
    scene, st, H_exact, (depth_p, depth_q, delta) = case(name, level)
    # the contact point is the midpoint: half the overlap deep in each grain (the kernel's foot points agree)
    np.testing.assert_allclose(depth_p, delta / 2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(depth_q, delta / 2, rtol=0, atol=1e-12)
    Hg = st.Hg1 + st.Hg2 + st.Hg3
    assert np.linalg.norm(st.H - H_exact) <= 1e-12 * np.linalg.norm(st.H)
    assert np.linalg.norm(H_exact - st.Hm - Hg) <= 1e-8 * np.linalg.norm(Hg)
    assert 0.1 * level <= np.linalg.norm(Hg) / np.linalg.norm(st.Hm) <= 10 * level


def test_surface_curvature_instead_would_fail():
    """Fed the curvature of the surfaces (depth 0) instead of the parallel surfaces, the geometric part is off by
    order f/k: the test above can tell the convention."""
    scene, st, H_exact, _ = case("pair", 1e-2)
    cl, (n, delta, c) = pressed("pair", 1e-2)
    Kp0, _, _ = surface.contact_curvature(c - delta[:, None] / 2 * n, cl.x0[cl.p], cl.R0[cl.p], cl.axes[cl.p],
                                          np.repeat(cl.blockiness[cl.p, None], 2, axis=1), n)
    wrong = replace(scene, curvature_p=Kp0, curvature_sum=Kp0 + scene.curvature_q)
    st_w = granstab.stiffness(wrong)
    Hg = st_w.Hg1 + st_w.Hg2 + st_w.Hg3
    assert np.linalg.norm(H_exact - st_w.Hm - Hg) >= 1e-3 * np.linalg.norm(Hg)
