"""granstab's H against the derivative of EXACT nonlinear rigid-body statics (tests/exact_geometry.py).

Clusters of rigid ellipses (2D) and ellipsoids (3D) pressed together to an overlap δ = f/k (lengths in units
of the particle size, ~1) from 1e-4 to 1e-1, with tangential forces (0.3 |f_n|) and, in one 3D cluster, a
rolling stiffness. granstab.stiffness(scene) is fed the contact data of granstab.model.shapes (parallel-curve
curvature, docs/errata.md); the reference H_exact = ∂[b, w]/∂[u, θ] is a complex-step derivative (exact to round-off).

Tolerances (why): H_exact and H both carry round-off of a few eps·‖H‖ (measured ≤ 6e-16 relative), so
‖H - H_exact‖ ≤ 1e-12 ‖H‖. The geometric part Hg = Hg1 + Hg2 + Hg3 is only ~(f/k)‖H‖, so the same absolute
round-off is eps/(f/k) relative to it — ≤ 1e-11 at f/k = 1e-4 (measured ≤ 5e-12); we require 1e-9 ‖Hg‖.
"""
from functools import cache

import numpy as np
import pytest
from exact_geometry import (
    central_difference,
    cluster_from_scene,
    press,
    reference_loads,
    stiffness_exact,
)
from scipy.spatial.transform import Rotation

import granstab
from granstab.model import shapes as S
from granstab.model.scene import build_scene
from granstab.model.vec import cross_matrix

EPS = np.finfo(float).eps
LEVELS = (1e-4, 1e-3, 1e-2, 1e-1)
LAW = dict(k=1.0, alpha=0.7, mu=0.5, mobilised=0.6)      # |f_t| = 0.3 |f_n|, elastic (Q < 0)
H_RTOL = 1e-12
HG_RTOL = 1e-9


def R3(v):
    return Rotation.from_rotvec(v).as_matrix()


CLUSTERS = {
    "pair2d": ([("a", S.Ellipse(1.0, 0.5), ((0, 0), 0.3)), ("b", S.Ellipse(0.8, 0.4), ((1.5, 0.6), -0.5))],
               [(0, 1)], 0.0),
    "chain2d": ([("a", S.Ellipse(1.0, 0.6), ((0, 0), 0.2)), ("b", S.Ellipse(0.7, 0.4), ((1.5, 0.2), 1.0)),
                 ("c", S.Disk(0.6), ((2.6, -0.3), 0.0)), ("d", S.Ellipse(0.9, 0.5), ((3.6, 0.6), -0.4))],
                [(0, 1), (1, 2), (2, 3)], 0.0),
    "triangle2d": ([("a", S.Ellipse(1.0, 0.6), ((0, 0), 0.2)), ("b", S.Ellipse(0.8, 0.5), ((1.6, 0.1), 1.0)),
                    ("c", S.Ellipse(0.9, 0.45), ((0.8, 1.2), -0.4))],
                   [(0, 1), (0, 2), (1, 2)], 0.0),
    "pair3d": ([("a", S.Ellipsoid(1.0, 0.7, 0.5), ((0, 0, 0), R3([0.3, -0.2, 0.5]))),
                ("b", S.Ellipsoid(0.9, 0.6, 0.5), ((1.3, 0.5, 0.4), R3([-0.4, 0.1, 0.9])))],
               [(0, 1)], 0.0),
    "tetra3d": ([("a", S.Ellipsoid(1.0, 0.7, 0.6), ((0, 0, 0), R3([0.3, -0.2, 0.5]))),
                 ("b", S.Ellipsoid(0.9, 0.6, 0.5), ((1.5, 0.2, 0.1), R3([-0.4, 0.1, 0.9]))),
                 ("c", S.Ellipsoid(0.8, 0.7, 0.5), ((0.7, 1.3, 0.0), R3([0.2, 0.6, -0.3]))),
                 ("d", S.Sphere(0.6), ((0.7, 0.5, 1.1), None))],
                [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)], 0.05),
}
CASES = [(name, level) for name in CLUSTERS for level in LEVELS]


@cache
def case(name, level):
    """(particles, scene, exact cluster, granstab Stiffness, H_exact) for a cluster pressed to δ = level."""
    parts, pairs, k_r = CLUSTERS[name]
    parts = press(parts, pairs, level)
    dim = len(parts[0][2][0])
    scene = S.scene_from_shapes(dim, parts, rolling_stiffness=k_r, **LAW)
    assert [(int(p), int(q)) for p, q in zip(scene.p, scene.q)] == pairs
    np.testing.assert_allclose(np.hypot.reduce(scene.force, axis=1), level * np.hypot(1, 0.3), rtol=0, atol=64 * EPS)
    cluster = cluster_from_scene(scene, parts, k_r=k_r)
    return parts, scene, cluster, granstab.stiffness(scene), stiffness_exact(cluster)


def geometric(st):
    return st.Hg1 + st.Hg2 + st.Hg3


def rel_geometric_error(st, H_exact):
    """‖(H_exact - Hm) - Hg‖ / ‖Hg‖."""
    Hg = geometric(st)
    return np.linalg.norm(H_exact - st.Hm - Hg) / np.linalg.norm(Hg)


@pytest.mark.parametrize("name, level", CASES)
def test_reference_loads_are_the_scene_loads(name, level):
    """The exact model in its reference configuration reproduces the scene's equilibrium loads (eq:equil1):
    the normal, contact point and overlap of granstab.model.shapes agree with the independent solver. Overlaps are
    differences of O(1) lengths, so the loads carry an absolute round-off ~ k·eps·L: tolerance 100 eps."""
    _, scene, cluster, _, _ = case(name, level)
    L = np.concatenate([scene.load, scene.load_moment], axis=1)
    np.testing.assert_allclose(reference_loads(cluster), L, rtol=0, atol=100 * EPS)


@pytest.mark.parametrize("name, level", CASES)
def test_stiffness_matches_exact_derivative(name, level):
    _, _, _, st, H_exact = case(name, level)
    Hg = geometric(st)
    assert np.linalg.norm(st.H - H_exact) <= H_RTOL * np.linalg.norm(st.H)
    assert rel_geometric_error(st, H_exact) <= HG_RTOL
    # the geometric part is resolved, not negligible: ‖Hg‖/‖Hm‖ is of order f/k
    assert 0.1 * level <= np.linalg.norm(Hg) / np.linalg.norm(st.Hm) <= 10 * level


@pytest.mark.parametrize("name", ["pair2d", "tetra3d"])
def test_complex_step_matches_central_differences(name):
    """Validates the complex-step machinery (no hidden conjugation) against Richardson-extrapolated central
    differences, h = 1e-3: truncation O(h⁶) ~ 1e-18, round-off ~ eps/h ~ 1e-13 relative."""
    _, _, cluster, st, H_exact = case(name, 1e-1)
    assert np.linalg.norm(central_difference(cluster) - H_exact) <= 1e-10 * np.linalg.norm(H_exact)


@pytest.mark.parametrize("name", ["pair2d", "triangle2d", "pair3d", "tetra3d"])
def test_surface_curvature_leaves_an_error_of_order_f_over_k(name):
    """Feeding the SURFACE curvature at the touching points P, Q (radius ρ instead of ρ - δ/2) leaves a relative
    error in Hg of order f/k (docs/errata.md: ~1.4 f/k for 2D ellipses, ~3.4 f/k for 3D ellipsoids; the factor depends
    on the shapes) that shrinks linearly with f/k."""
    ratios = []
    for level in LEVELS[:3]:
        parts, scene, _, _, H_exact = case(name, level)
        ratios.append(rel_geometric_error(granstab.stiffness(surface_curvature_scene(parts, scene)), H_exact) / level)
    ratios = np.array(ratios)
    assert np.all((0.1 <= ratios) & (ratios <= 10)), ratios
    assert np.ptp(ratios) <= 0.05 * ratios.mean(), ratios        # error / (f/k) constant: linear in f/k


def surface_curvature_scene(parts, scene):
    """The scene with curvature_p/q replaced by the surface curvature at the touching points P, Q."""
    Kp, Kq = [], []
    for i, j in zip(scene.p, scene.q):
        geo = S.contact_geometry(parts[i][1], parts[i][2], parts[j][1], parts[j][2])
        Kp.append(S.surface_curvature_at(parts[i][1], parts[i][2], geo.point_p))
        Kq.append(S.surface_curvature_at(parts[j][1], parts[j][2], geo.point_q))
    arrays = {f: getattr(scene, f) for f in ("p", "q", "point", "normal", "force", "moment", "k", "alpha", "mu",
                                             "rolling", "state")}
    return build_scene(scene.dim, scene.names, scene.x, {**arrays, "curvature_p": np.array(Kp),
                                                         "curvature_q": np.array(Kq)})


def erratum1_difference(scene):
    """H(printed eq:A3) - H(corrected): the printed qp-row twirl term -½(δθ_def·n^qp) f^qp × n^qp has the
    opposite sign of the corrected one, so δf^qp changes by (δθ_def·n)(f × n): -that in db^q, -r^qp × that
    in dw^q."""
    d, per = 3, 6
    D = np.zeros((scene.n_dof, scene.n_dof))
    for c in range(scene.n_contacts):
        p, q, n = scene.p[c], scene.q[c], scene.normal[c]
        fxn = np.cross(scene.force[c], n)
        rows = np.concatenate([-fxn, -cross_matrix(scene.r_qp[c]) @ fxn])
        D[q * per:(q + 1) * per, q * per + d:(q + 1) * per] += np.outer(rows, n)
        D[q * per:(q + 1) * per, p * per + d:(p + 1) * per] -= np.outer(rows, n)
    return D


@pytest.mark.parametrize("name", ["pair3d", "tetra3d"])
@pytest.mark.parametrize("level", LEVELS)
def test_printed_twirl_sign_would_fail(name, level):
    """erratum 1, docs/errata.md: with tangential forces the twirl terms matter. The printed qp-row sign would be off by
    ≥ 5% of Hg, seven orders above the tolerance, and would break Σ_p db^p = 0 for a relative twist."""
    _, scene, _, st, H_exact = case(name, level)
    D = erratum1_difference(scene)
    printed_error = np.linalg.norm(st.H + D - H_exact) / np.linalg.norm(geometric(st))
    assert printed_error >= 0.05
    d, per = 3, 6
    force_rows = np.concatenate([np.arange(i * per, i * per + d) for i in range(scene.n_particles)])
    net = (st.H + D)[force_rows].reshape(scene.n_particles, d, -1).sum(axis=0)
    assert np.abs(net).max() >= 0.5 * 0.3 * level                 # ~ |f_t| = 0.3 f per unit relative twist
    # the exact loads balance for every motion; entries of H are O(k) = O(1), so 100 eps is round-off
    assert np.abs(H_exact[force_rows].reshape(scene.n_particles, d, -1).sum(axis=0)).max() <= 100 * EPS
    assert np.abs(st.H[force_rows].reshape(scene.n_particles, d, -1).sum(axis=0)).max() <= 100 * EPS
