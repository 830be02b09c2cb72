"""The vertex certificate in 3D (issue 42, granstab/vertices.py, docs/uncertainty.md): a contact's force band is a
ball (normal and both tangential components), covered by the simplices of an icosahedron's (or octahedron's)
geodesic grid scaled to circumscribe it.

Two spheres (r = 1, principal radii of curvature ρ = 1.2, k = α = 1, a twisting stiffness n⊗n so that twist is
not a zero mode, the paper's metric L = 1) pressed by a normal force f: in each tangential plane the pair is the
paper's two-particle cluster of Sec. 4.1, so the non-rigid spectrum is {2k, 2k_t, λ⁽⁵⁾, λ⁽⁵⁾, λ⁽⁶⁾, λ⁽⁶⁾} with
λ⁽⁵⁾ = 4 − f(4 − 3ρ)/(2ρ) changing sign at f* = 8ρ/(4 − 3ρ) = 24 and λ⁽⁶⁾ = f(ρ − r) at f = 0
(paper.two_particle): stable for 0 < f < f*, unstable above."""
import json

import numpy as np
import pytest

import granstab
from granstab.cli import main
from granstab.mechanics.branches import RIGID
from granstab.mechanics.uncertainty import Band
from granstab.paper.two_particle import lambda5, lambda6
from granstab.uncertainty import data_robustness, perturbed
from granstab.vertices import COVERS, covering_factor, first_cover, split

RHO = 1.2
F_STAR = 8 * RHO / (4 - 3 * RHO)
CURVATURE = (-np.diag([0.0, 1.0, 1.0]) / RHO).tolist()       # spheres: -(I - n⊗n)/ρ, n = e1


def pair(f: float):
    contact = {"p": "p", "q": "q", "point": [1.0, 0.0, 0.0], "normal": [1.0, 0.0, 0.0], "curvature_p": CURVATURE,
               "curvature_q": CURVATURE, "force": [-f, 0.0, 0.0], "k": 1.0, "alpha": 1.0, "state": "elastic",
               "rolling_stiffness": np.diag([1.0, 0.0, 0.0]).tolist()}
    return granstab.scene_from_dict({"dim": 3, "particles": [{"name": "p", "x": [0.0, 0.0, 0.0]},
                                                             {"name": "q", "x": [2.0, 0.0, 0.0]}],
                                     "contacts": [contact]})


def robust(f, radius):
    return data_robustness(pair(f), Band(abs=radius), metric="L", rotation_length=1.0)


def lowest(force_vector, f):
    res = granstab.analyze(perturbed(pair(f), np.array([force_vector])), metric="L", rotation_length=1,
                           attribution=False, keep="all")
    b = res.branches[0]
    return res, float(np.min((b.stability_eigenvalues - b.accuracy)[b.codes != RIGID]))


@pytest.mark.parametrize("f", [5.0, 20.0, 30.0])
def test_the_3d_pair_is_the_closed_form(f):
    """The non-rigid spectrum is the closed form's, each tangential plane the paper's pair (1e-9 of the largest)."""
    res = granstab.analyze(pair(f), metric="L", rotation_length=1, keep="all")
    b = res.branches[0]
    got = np.sort(b.stability_eigenvalues[b.codes != RIGID])
    l5, l6 = float(lambda5(1, 1, 1, RHO, f)), float(lambda6(1, RHO, f))
    assert np.allclose(got, np.sort([2.0, 2.0, l5, l5, l6, l6]), rtol=0, atol=1e-9 * max(2.0, abs(l5), l6))
    assert res.verdict.verdict == ("stable" if f < F_STAR else "unstable") and res.verdict.sufficient


@pytest.mark.parametrize("f", [5.0, 20.0])
def test_3d_certificate_is_exact_at_the_closed_form_threshold(f, tmp_path, capsys):
    """A ball of 0.99 of the distance to the nearest threshold (f = 0 of λ⁽⁶⁾ or f* of λ⁽⁵⁾): holds, proven at the
    vertices (the bound alone proves < 0.2× the band here; ≤ 64 analyses); its lowest vertex value is a lower bound
    of the closed-form λ_min over the ball's normal diameter, min(λ⁽⁵⁾(f + R), λ⁽⁶⁾(f − R)). At 1.01: depends, the
    counter-example lies in the ball and `granstab analyze` of a scene file with its forces proves it unstable."""
    distance = min(f, F_STAR - f)
    R = 0.99 * distance
    below = robust(f, R)
    cert = below.certificate
    assert below.robust == "holds" and below.margin < 0.2 and cert["proven"] and cert["exact"]
    assert cert["analyses"] <= 64 and cert["cover"] == pytest.approx(1.2584085723, rel=1e-8)
    closed = min(float(lambda5(1, 1, 1, RHO, f + R)), float(lambda6(1, RHO, f - R)))
    assert 0 < cert["lowest"] <= closed
    above = robust(f, 1.01 * distance)
    assert above.robust == "depends" and not above.certificate["proven"]
    forces = np.array(above.counterexample["forces"])
    assert forces.shape == (1, 3) and np.linalg.norm(forces[0] - [-f, 0.0, 0.0]) <= 1.01 * distance
    path = tmp_path / "counterexample.json"
    path.write_text(json.dumps(granstab.scene_to_dict(perturbed(pair(f), forces))))
    assert main(["analyze", str(path), "--metric", "L", "--rotation-length", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["summary"]["verdict"] == above.counterexample["verdict"] == "unstable" and out["summary"]["sufficient"]


@pytest.mark.parametrize("f, radius, want", [(22.0, 3.0, "depends"), (12.0, 13.0, "depends"),
                                             (30.0, 5.0, "holds"), (12.0, 6.0, "holds")])
def test_3d_band_crossing_or_clear(f, radius, want):
    """A ball whose normal diameter crosses a threshold depends (the counter-example inside it gives the other
    verdict); one clear of both holds."""
    crosses = (f + radius > F_STAR > f - radius) or (f - radius < 0 < f) or (f + radius > F_STAR > f)
    assert crosses == (want == "depends")
    got = robust(f, radius)
    assert got.robust == want
    if want == "depends":
        forces = np.array(got.counterexample["forces"])
        assert np.linalg.norm(forces[0] - [-f, 0.0, 0.0]) <= radius
        res, _ = lowest(forces[0], f)
        assert res.verdict.verdict == got.counterexample["verdict"] != got.verdict and res.verdict.sufficient


def test_3d_certificate_against_a_sampling_of_the_ball():
    """f = 20, 0.99 of the distance to f*: 40 forces on the ball's surface (a Fibonacci sphere, the normal
    direction among them) and 10 inside are all stable, none below the certificate's lowest vertex value."""
    f = 20.0
    R = 0.99 * (F_STAR - f)
    got = robust(f, R)
    assert got.robust == "holds"
    k = np.arange(40) + 0.5
    z = 1 - 2 * k / 40
    phi = np.pi * (1 + 5 ** 0.5) * k
    surface = np.c_[z, np.sqrt(1 - z ** 2) * np.cos(phi), np.sqrt(1 - z ** 2) * np.sin(phi)]
    surface[0] = [-1.0, 0.0, 0.0]
    rng = np.random.default_rng(5)
    inner = rng.normal(size=(10, 3))
    inner *= (rng.uniform(size=(10, 1)) ** (1 / 3)) / np.linalg.norm(inner, axis=1, keepdims=True)
    for u in np.r_[surface * (1 - 1e-9), inner]:
        res, low = lowest(np.array([-f, 0.0, 0.0]) + R * u, f)
        assert res.verdict.verdict == "stable" and res.verdict.sufficient
        assert got.certificate["lowest"] <= low


@pytest.mark.parametrize("dim, K, factor", [(2, 1, 1 / np.cos(np.pi / 8)), (2, 2, np.sqrt(2)),
                                            (3, 1, 1 / np.sqrt((5 + 2 * np.sqrt(5)) / 15)), (3, 2, np.sqrt(3))])
def test_the_covers_cover_the_ball(dim, K, factor):
    """The first cover's covering factor is the polygon's or polyhedron's circumradius over inradius (1/cos(π/8),
    √2, the icosahedron's, √3: to 1e-8), c_L decreases with the level, and every point of the unit ball lies in a
    simplex (0, c_L u_1, …, c_L u_d) of some piece of levels 0-3 (barycentric coordinates >= 0, summing to <= 1;
    2,000 random points, the pieces made by `split` as the certificate makes them)."""
    assert covering_factor(dim, K, 0) == pytest.approx(factor, rel=1e-8)
    assert len(first_cover(dim, K)) == len(COVERS[(dim, K)][1])
    rng = np.random.default_rng(1)
    x = rng.normal(size=(2000, dim))
    x *= (rng.uniform(size=(2000, 1)) ** (1 / dim)) / np.linalg.norm(x, axis=1, keepdims=True)
    x[:dim] = np.eye(dim)                       # the cover's own vertex directions, on the sphere
    pieces = first_cover(dim, K)
    for level in range(4):
        c = covering_factor(dim, K, level)
        U = np.array([p[1] for p in pieces])                      # (P, d, d) rows u_i
        coords = np.linalg.solve(np.swapaxes(U, 1, 2)[None], x[:, None, :, None])[..., 0] / c   # (n, P, d)
        inside = np.all(coords >= -1e-12, axis=2) & (coords.sum(axis=2) <= 1 + 1e-12)
        assert inside.any(axis=1).all()
        if level:
            assert c < covering_factor(dim, K, level - 1)
        pieces = [q for p in pieces for q in split(p)]
