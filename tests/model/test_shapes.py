"""Exact contact geometry of disks, ellipses, spheres and ellipsoids (granstab.model.shapes) and the shape format.

Tolerances are relative to the particle size L ~ 1 (lengths) or to 1/ρ (curvatures): the overlap δ is a
difference of O(L) lengths, so its absolute round-off is a few eps·L; everything else is at eps level.
"""
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import granstab
from granstab import SceneError
from granstab.io.shapefile import shape_scene_from_dict, shape_scene_to_dict
from granstab.model.shapes import (
    Disk,
    Ellipse,
    Ellipsoid,
    Sphere,
    contact_geometry,
    rotation_matrix,
    scene_from_shapes,
    shape_tensor,
    surface_curvature_at,
)

EPS = np.finfo(float).eps
TOL = 64 * EPS   # lengths (L ~ 1) and unit vectors; curvatures are compared relative to their scale


def rot3(v):
    return Rotation.from_rotvec(v).as_matrix()


def rot2(a):
    return rotation_matrix(2, a)


PAIRS_2D = [
    (Ellipse(1.0, 0.5), ((0.0, 0.0), 0.3), Ellipse(0.8, 0.4), ((1.24, 0.56), -0.5)),
    (Ellipse(1.2, 0.3), ((0.1, -0.2), 1.1), Disk(0.5), ((0.29, 1.2), 0.0)),
]
PAIRS_3D = [
    (Ellipsoid(1.0, 0.7, 0.5), ((0.0, 0.0, 0.0), rot3([0.3, -0.2, 0.5])),
     Ellipsoid(0.9, 0.6, 0.5), ((1.44, 0.58, 0.46), rot3([-0.4, 0.1, 0.9]))),
    (Ellipsoid(1.1, 0.8, 0.4), ((0.2, 0.1, -0.3), rot3([1.0, 0.4, -0.2])),
     Sphere(0.6), ((0.6, 0.77, 0.77), None)),
]
ALL_PAIRS = PAIRS_2D + PAIRS_3D


def inside_value(shape, pose, y):
    """(y - x)ᵀ R A⁻² Rᵀ (y - x): 1 on the surface (the implicit equation, independent of support functions)."""
    R = rotation_matrix(shape.dim, pose[1])
    z = R.T @ (y - np.asarray(pose[0], float))
    return float(np.sum(z**2 / np.square(shape.semi_axes)))


def implicit_normal(shape, pose, y):
    R = rotation_matrix(shape.dim, pose[1])
    m = R @ ((R.T @ (y - np.asarray(pose[0], float))) / np.square(shape.semi_axes))
    return m / np.linalg.norm(m)


def tangent_radii(K, n):
    """Eigenvalues of K on the tangent plane of n (ascending)."""
    lam, V = np.linalg.eigh(K)
    keep = np.abs(V.T @ n) < 0.5
    return lam[keep]


# -------------------------------------------------------------------------------------------- closed forms

def test_disk_disk_closed_form():
    r1, r2, x2 = 1.0, 0.5, np.array([1.2, 0.6])
    c = contact_geometry(Disk(r1), ((0.0, 0.0), 0.0), Disk(r2), (x2, 0.7))
    dist = np.linalg.norm(x2)
    n = x2 / dist
    delta = r1 + r2 - dist
    assert c.overlap == pytest.approx(delta, abs=TOL)
    np.testing.assert_allclose(c.normal, n, atol=TOL)
    np.testing.assert_allclose(c.point_p, r1 * n, atol=TOL)
    np.testing.assert_allclose(c.point_q, x2 - r2 * n, atol=TOL)
    np.testing.assert_allclose(c.point, (r1 - delta / 2) * n, atol=TOL)
    t = np.array([-n[1], n[0]])                     # e3 × n
    np.testing.assert_allclose(c.curvature_p, -np.outer(t, t) / (r1 - delta / 2), atol=TOL)
    np.testing.assert_allclose(c.curvature_q, -np.outer(t, t) / (r2 - delta / 2), atol=4 * TOL)


def test_sphere_sphere_closed_form():
    r1, r2, x2 = 0.8, 0.6, np.array([0.5, -0.9, 0.7])
    c = contact_geometry(Sphere(r1), ((0.0, 0.0, 0.0), None), Sphere(r2), (x2, rot3([0.1, 0.2, 0.3])))
    dist = np.linalg.norm(x2)
    n = x2 / dist
    delta = r1 + r2 - dist
    P = np.eye(3) - np.outer(n, n)
    assert c.overlap == pytest.approx(delta, abs=TOL)
    np.testing.assert_allclose(c.point, (r1 - delta / 2) * n, atol=TOL)
    np.testing.assert_allclose(c.curvature_p, -P / (r1 - delta / 2), atol=4 * TOL)
    np.testing.assert_allclose(c.curvature_q, -P / (r2 - delta / 2), atol=4 * TOL)


@pytest.mark.parametrize("phi", [0.0, 0.7, -2.1])
def test_ellipse_tips_parallel_radius(phi):
    """Tip to tip along the major axes: tip radius b²/a, parallel curve through the midpoint b²/a - δ/2."""
    (a1, b1), (a2, b2), delta = (1.0, 0.5), (0.8, 0.6), 0.05
    e = np.array([np.cos(phi), np.sin(phi)])
    c = contact_geometry(Ellipse(a1, b1), ((0.0, 0.0), phi), Ellipse(a2, b2), ((a1 + a2 - delta) * e, phi))
    assert c.overlap == pytest.approx(delta, abs=TOL)
    np.testing.assert_allclose(c.normal, e, atol=TOL)
    np.testing.assert_allclose(c.point, (a1 - delta / 2) * e, atol=TOL)
    t = np.array([-e[1], e[0]])
    assert t @ c.curvature_p @ t == pytest.approx(-1 / (b1**2 / a1 - delta / 2), rel=TOL)
    assert t @ c.curvature_q @ t == pytest.approx(-1 / (b2**2 / a2 - delta / 2), rel=TOL)
    # the touching points keep the surface curvature: -a/b²
    assert t @ surface_curvature_at(Ellipse(a1, b1), ((0, 0), phi), c.point_p) @ t == pytest.approx(-a1 / b1**2,
                                                                                                     rel=TOL)


def test_ellipsoid_tips_principal_radii():
    """Tips along body e1: principal radii b²/a (along e2) and c²/a (along e3), each minus δ/2."""
    a, b, c_, delta = 1.0, 0.7, 0.5, 0.02
    R = rot3([0.4, -0.3, 0.8])
    x2 = R @ np.array([2 * a - delta, 0.0, 0.0])
    g = contact_geometry(Ellipsoid(a, b, c_), ((0, 0, 0), R), Ellipsoid(a, b, c_), (x2, R))
    assert g.overlap == pytest.approx(delta, abs=TOL)
    np.testing.assert_allclose(g.normal, R[:, 0], atol=TOL)
    for K in (g.curvature_p, g.curvature_q):
        assert R[:, 1] @ K @ R[:, 1] == pytest.approx(-1 / (b**2 / a - delta / 2), rel=TOL)
        assert R[:, 2] @ K @ R[:, 2] == pytest.approx(-1 / (c_**2 / a - delta / 2), rel=TOL)
        assert abs(R[:, 1] @ K @ R[:, 2]) < TOL * np.abs(K).max()


# ------------------------------------------------------------------------------------------ general pairs

@pytest.mark.parametrize("sp, pp, sq, pq", ALL_PAIRS)
def test_common_normal_pair_on_both_surfaces(sp, pp, sq, pq):
    """P and Q satisfy the implicit surface equations, their implicit normals are ±n, Q - P = -δ n, and n
    maximises the gap g(n) = d·n - h_p(n) - h_q(-n) over a dense set of directions (minimum penetration)."""
    c = contact_geometry(sp, pp, sq, pq)
    assert 0.01 < c.overlap < 0.3
    assert inside_value(sp, pp, c.point_p) == pytest.approx(1.0, abs=TOL)
    assert inside_value(sq, pq, c.point_q) == pytest.approx(1.0, abs=TOL)
    np.testing.assert_allclose(implicit_normal(sp, pp, c.point_p), c.normal, atol=TOL)
    np.testing.assert_allclose(implicit_normal(sq, pq, c.point_q), -c.normal, atol=TOL)
    np.testing.assert_allclose(c.point_q - c.point_p, -c.overlap * c.normal, atol=TOL)
    dim = sp.dim
    dirs = np.random.default_rng(0).normal(size=(20000, dim))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    Sp, Sq = shape_tensor(sp, pp[1]), shape_tensor(sq, pq[1])
    d = np.asarray(pq[0], float) - np.asarray(pp[0], float)
    gaps = (dirs @ d - np.sqrt(np.einsum("ki,ij,kj->k", dirs, Sp, dirs))
            - np.sqrt(np.einsum("ki,ij,kj->k", dirs, Sq, dirs)))
    assert -c.overlap >= gaps.max() - TOL


@pytest.mark.parametrize("sp, pp, sq, pq", ALL_PAIRS)
def test_curvature_tensors(sp, pp, sq, pq):
    """Symmetric, tangent (K·n = 0), convex (negative), and the parallel surface of the touching point's
    surface curvature: radii ρ_i - δ/2 with the same principal directions."""
    c = contact_geometry(sp, pp, sq, pq)
    for shape, pose, K, point in ((sp, pp, c.curvature_p, c.point_p), (sq, pq, c.curvature_q, c.point_q)):
        scale = np.abs(K).max()
        np.testing.assert_allclose(K, K.T, atol=TOL * scale)
        np.testing.assert_allclose(K @ c.normal, 0.0, atol=TOL * scale)
        assert np.all(tangent_radii(K, c.normal) < 0)
        Ks = surface_curvature_at(shape, pose, point)
        np.testing.assert_allclose(surface_curvature_at(shape, pose, point, c.overlap / 2), K, atol=TOL * scale)
        rs = np.sort(-1 / tangent_radii(Ks, c.normal))
        rk = np.sort(-1 / tangent_radii(K, c.normal))
        np.testing.assert_allclose(rk, rs - c.overlap / 2, rtol=TOL)


@pytest.mark.parametrize("sp, pp, sq, pq", ALL_PAIRS)
def test_swap_p_and_q(sp, pp, sq, pq):
    c = contact_geometry(sp, pp, sq, pq)
    s = contact_geometry(sq, pq, sp, pp)
    assert s.overlap == pytest.approx(c.overlap, abs=TOL)
    np.testing.assert_allclose(s.normal, -c.normal, atol=TOL)
    np.testing.assert_allclose(s.point, c.point, atol=TOL)
    np.testing.assert_allclose(s.point_p, c.point_q, atol=TOL)
    np.testing.assert_allclose(s.curvature_p, c.curvature_q, atol=TOL * np.abs(c.curvature_q).max())
    np.testing.assert_allclose(s.curvature_q, c.curvature_p, atol=TOL * np.abs(c.curvature_p).max())


@pytest.mark.parametrize("sp, pp, sq, pq", ALL_PAIRS)
def test_objectivity_under_rigid_motion(sp, pp, sq, pq):
    """Rotating and translating both bodies rigidly rotates n, the points and K; δ is unchanged."""
    dim = sp.dim
    if dim == 2:
        angle, G, shift = 0.9, rot2(0.9), np.array([0.3, -1.7])
        def move(pose):
            return (G @ np.asarray(pose[0], float) + shift, pose[1] + angle)
    else:
        G, shift = rot3([0.7, -1.1, 0.4]), np.array([0.3, -1.7, 2.2])
        def move(pose):
            return (G @ np.asarray(pose[0], float) + shift, G @ rotation_matrix(3, pose[1]))
    c = contact_geometry(sp, pp, sq, pq)
    m = contact_geometry(sp, move(pp), sq, move(pq))
    assert m.overlap == pytest.approx(c.overlap, abs=TOL)
    np.testing.assert_allclose(m.normal, G @ c.normal, atol=TOL)
    np.testing.assert_allclose(m.point, G @ c.point + shift, atol=TOL)
    for K, Km in ((c.curvature_p, m.curvature_p), (c.curvature_q, m.curvature_q)):
        np.testing.assert_allclose(Km, G @ K @ G.T, atol=TOL * np.abs(K).max())


def test_separated_touching_and_near_touching():
    e1, e2 = Ellipse(1.0, 0.5), Ellipse(0.8, 0.6)
    phi = 0.4
    e = np.array([np.cos(phi), np.sin(phi)])
    assert contact_geometry(e1, ((0, 0), phi), e2, (1.8 * e + 1e-9 * e, phi)) is None
    assert contact_geometry(Disk(1.0), ((0, 0), 0), Disk(1.0), ((2.0 + 1e-12, 0.0), 0)) is None
    touch = contact_geometry(Disk(1.0), ((0, 0), 0), Disk(1.0), ((2.0, 0.0), 0))
    assert touch.overlap == 0.0 and touch.curvature_p[1, 1] == -1.0
    for delta in (1e-6, 1e-10, 1e-13):
        c = contact_geometry(e1, ((0, 0), phi), e2, ((1.8 - delta) * e, phi))
        assert c.overlap == pytest.approx(delta, abs=8 * EPS)
        np.testing.assert_allclose(c.normal, e, atol=TOL)
    s1, s2 = Ellipsoid(1.0, 0.7, 0.5), Ellipsoid(0.6, 0.5, 0.4)
    R = rot3([0.2, 0.5, -0.3])
    assert contact_geometry(s1, ((0, 0, 0), R), s2, (R @ [1.6 + 1e-9, 0, 0], R)) is None
    c = contact_geometry(s1, ((0, 0, 0), R), s2, (R @ [1.6 - 1e-11, 0, 0], R))
    assert c.overlap == pytest.approx(1e-11, abs=8 * EPS)


def test_elongated_side_by_side():
    """Needles side by side: the line of centres is far from the common normal; the sampled start finds the
    global maximum of the gap (checked against 200000 directions: sampling error ~ R·Δφ² ≈ 3e-9)."""
    sp, pp, sq, pq = Ellipse(3.0, 0.2), ((0, 0), 0.0), Ellipse(3.0, 0.2), ((2.0, 0.39), 0.05)
    c = contact_geometry(sp, pp, sq, pq)
    assert abs(c.normal[1]) > 0.99
    phi = np.linspace(0, 2 * np.pi, 200000, endpoint=False)
    dirs = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    Sp, Sq = shape_tensor(sp, pp[1]), shape_tensor(sq, pq[1])
    gaps = dirs @ np.array(pq[0]) - np.sqrt(np.einsum("ki,ij,kj->k", dirs, Sp, dirs)) - np.sqrt(
        np.einsum("ki,ij,kj->k", dirs, Sq, dirs))
    assert gaps.max() - TOL <= -c.overlap <= gaps.max() + 1e-8
    assert inside_value(sp, pp, c.point_p) == pytest.approx(1.0, abs=TOL)


# ----------------------------------------------------------------------------------------------- scenes

def test_scene_from_shapes_2d_forces_and_states():
    parts = [("a", Disk(1.0), ((0.0, 0.0), 0.0)), ("b", Ellipse(1.0, 0.6), ((1.95, 0.1), 0.2)),
             ("c", Disk(0.5), ((0.2, 1.45), 0.0)), ("far", Disk(0.5), ((9.0, 9.0), 0.0))]
    k, mu, mob = 2.0, 0.4, 0.5
    sc = scene_from_shapes(2, parts, k=k, mu=mu, mobilised=mob, alpha=0.8)
    assert [(int(p), int(q)) for p, q in zip(sc.p, sc.q)] == [(0, 1), (0, 2)]
    for c, (i, j) in enumerate(zip(sc.p, sc.q)):
        g = contact_geometry(parts[i][1], parts[i][2], parts[j][1], parts[j][2])
        n = g.normal
        t = np.array([-n[1], n[0]])
        np.testing.assert_allclose(sc.force[c], -k * g.overlap * n + mob * mu * k * g.overlap * t, atol=TOL)
        np.testing.assert_allclose(sc.curvature_p[c], g.curvature_p, atol=TOL * np.abs(g.curvature_p).max())
    assert sc.state == ("auto", "auto")
    assert np.all(sc.yield_function() < 0)
    np.testing.assert_allclose(sc.load.sum(axis=0), 0.0, atol=TOL)
    slide = scene_from_shapes(2, parts, k=k, mu=mu, mobilised=1.0)
    assert slide.state == ("sliding", "sliding") and slide.at_yield().all()


def test_scene_from_shapes_3d_shear_direction():
    parts = [("a", Ellipsoid(1.0, 0.7, 0.5), ((0, 0, 0), rot3([0.3, -0.2, 0.5]))),
             ("b", Sphere(0.6), ((1.2, 0.4, 0.5), None)), ("c", Sphere(0.6), ((0.0, 0.0, 1.05), None))]
    sc = scene_from_shapes(3, parts, mu=0.5, mobilised=0.6, rolling_stiffness=0.1)
    assert sc.n_contacts == 2
    for c in range(sc.n_contacts):
        n, f = sc.normal[c], sc.force[c]
        fn = -(f @ n)
        ft = f + fn * n
        t = np.array([1.0, 0, 0]) - n[0] * n
        np.testing.assert_allclose(ft, 0.3 * fn * t / np.linalg.norm(t), atol=TOL)
        np.testing.assert_allclose(sc.rolling[c], 0.1 * np.eye(3))
    # along e1 the projection of e1 vanishes: fallback to tangent_basis
    axial = scene_from_shapes(3, [("a", Sphere(1.0), ((0, 0, 0), None)), ("b", Sphere(1.0), ((1.9, 0, 0), None))],
                              mobilised=0.5)
    assert abs(axial.force[0] @ axial.normal[0]) == pytest.approx(0.1, rel=TOL)
    assert np.linalg.norm(axial.tangential_force()[0]) == pytest.approx(0.025, rel=TOL)


def test_shape_file_roundtrip_and_hook(tmp_path):
    """to_dict → JSON → from_dict gives the same arrays; load_scene dispatches shape files (scene.py hook)."""
    parts = [("a", Ellipse(1.0, 0.5), ((0.0, 0.0), 0.3)), ("b", Ellipse(0.8, 0.4), ((1.24, 0.56), -0.5)),
             ("c", Disk(0.5), ((0.2, 0.8), 0.0))]
    kw = dict(k=3.0, alpha=0.7, mu=0.4, mobilised=0.25, rolling_stiffness=0.05, title="three")
    direct = scene_from_shapes(2, parts, **kw)
    data = json.loads(json.dumps(shape_scene_to_dict(2, parts, **kw)))
    back = shape_scene_from_dict(data, source="x.json")
    assert back.n_contacts == direct.n_contacts == 3 and back.title == "three"
    for field in ("p", "q", "point", "normal", "curvature_p", "curvature_q", "force", "k", "alpha", "mu",
                  "rolling", "load", "load_moment"):
        np.testing.assert_array_equal(getattr(back, field), getattr(direct, field), err_msg=field)
    parts3 = [("a", Ellipsoid(1.0, 0.7, 0.5), ((0, 0, 0), rot3([0.3, -0.2, 0.5]))),
              ("b", Sphere(0.6), ((1.2, 0.4, 0.5), None))]
    d3 = json.loads(json.dumps(shape_scene_to_dict(3, parts3, mobilised=0.5, shear=[0, 1, 0])))
    np.testing.assert_array_equal(shape_scene_from_dict(d3).force,
                                  scene_from_shapes(3, parts3, mobilised=0.5, shear=[0, 1, 0]).force)
    path = tmp_path / "three.json"
    path.write_text(json.dumps(data))
    via_core = granstab.load_scene(path)
    np.testing.assert_array_equal(via_core.force, direct.force)


BASE_2D = {"dim": 2, "particles": [{"name": "a", "x": [0.0, 0.0], "shape": {"kind": "disk", "radius": 1.0}},
                                   {"name": "b", "x": [1.9, 0.0], "shape": {"kind": "ellipse", "a": 1.0, "b": 0.5},
                                    "angle": 0.1}]}


def _with(path, value, base=BASE_2D):
    data = json.loads(json.dumps(base))
    target = data
    for key in path[:-1]:
        target = target[key]
    if value is KeyError:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return data


@pytest.mark.parametrize("path, value, expect", [
    (("particles", 0, "shape", "kind"), "cube", "f.toml: particles[0] ('a'): shape: kind: must be one of disk"),
    (("particles", 0, "shape", "kind"), "sphere",
     "f.toml: particles[0] ('a'): shape: kind: must be one of disk, ellipse in 2D"),
    (("particles", 0, "shape", "radius"), -1.0, "f.toml: particles[0] ('a'): shape: radius: must be > 0"),
    (("particles", 0, "shape", "radius"), "big", "f.toml: particles[0] ('a'): shape: radius: must be a number"),
    (("particles", 1, "shape", "b"), KeyError, "f.toml: particles[1] ('b'): shape: b: missing"),
    (("particles", 1, "shape", "c"), 1.0, "f.toml: particles[1] ('b'): shape: c: unknown key (allowed: a, b, kind)"),
    (("particles", 1, "shape"), KeyError, "f.toml: particles[1] ('b'): shape: missing"),
    (("particles", 1, "shape"), "disk", "f.toml: particles[1] ('b'): shape: must be a table"),
    (("particles", 1, "rotation"), [[1, 0], [0, 1]], "f.toml: particles[1]: rotation: unknown key"),
    (("particles", 1, "angle"), "0.1", "f.toml: particles[1] ('b'): angle: must be a number"),
    (("particles", 1, "name"), "a", "f.toml: particles[1] ('a'): name: duplicate particle name"),
    (("particles", 1, "x"), [0.0, 0.0], "f.toml: particles: coincident centres"),
    (("defaults",), {"mobilised": 1.5}, "f.toml: defaults: mobilised: must be in [0, 1]"),
    (("defaults",), {"shear": [1.0, 0.0]}, "f.toml: defaults: shear: only for 3D"),
    (("defaults",), {"k": -1.0}, "f.toml: defaults: k: must be > 0"),
    (("contacts_extra",), 1, "f.toml: scene: contacts_extra: unknown key"),
])
def test_shape_file_errors_are_one_line(path, value, expect):
    data = _with(path, value)
    if path[-1] == "x":                                  # coincident disks need two round bodies
        data["particles"][1]["shape"] = {"kind": "disk", "radius": 1.0}
    with pytest.raises(SceneError) as info:
        shape_scene_from_dict(data, source="f.toml")
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(expect), msg


def test_shape_file_3d_rotation_errors():
    base = {"dim": 3, "particles": [{"name": "a", "x": [0, 0, 0], "shape": {"kind": "sphere", "radius": 1.0}},
                                    {"name": "b", "x": [1.9, 0, 0], "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                                     "shape": {"kind": "ellipsoid", "a": 1.0, "b": 0.5, "c": 0.4}}]}
    assert shape_scene_from_dict(base).n_contacts == 1
    for rot, expect in (([[1, 0, 0], [0, 1, 0], [0, 0, -1]], "proper rotation"),
                        ([[1, 0.1, 0], [0, 1, 0], [0, 0, 1]], "proper rotation"),
                        ([[1, 0], [0, 1]], "3x3 numbers")):
        data = _with(("particles", 1, "rotation"), rot, base)
        with pytest.raises(SceneError, match=expect) as info:
            shape_scene_from_dict(data, source="g.json")
        assert str(info.value).startswith("g.json: particles[1] ('b'): rotation: ")
    with pytest.raises(SceneError, match=r"^g.json: particles\[1\]: angle: unknown key"):
        shape_scene_from_dict(_with(("particles", 1, "angle"), 0.2, base), source="g.json")
