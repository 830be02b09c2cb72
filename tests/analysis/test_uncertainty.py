"""Verdicts under the data's own uncertainty (issue 42, granstab/uncertainty.py, docs/uncertainty.md).

Two-particle cluster of Sec. 4.1 (r = 1, ρ = 1.2, k = α = 1, the paper's metric L = 1): λ⁽⁵⁾ = 4 − f(4 − 3ρ)/(2ρ)
changes sign at f* = 8ρ/(4 − 3ρ) = 24 (paper.two_particle.lambda5), λ⁽⁶⁾ = f(ρ − r) > 0: stable below f*, unstable
above. The band [f(1 − rel), f(1 + rel)] crossing f* must give "depends" with a counter-example inside the band that
`analyze` proves the other way; a band that stays clear of f* by the bound's own factor gives "holds"."""
import json

import numpy as np
import pytest

import granstab
from granstab.cli import main
from granstab.mechanics.branches import RIGID
from granstab.mechanics.stiffness import contact_blocks, geometric
from granstab.mechanics.uncertainty import Band, unit_blocks
from granstab.paper.two_particle import lambda5, lambda6
from granstab.uncertainty import balance_least_squares, data_robustness, perturbed

RHO = 1.2
F_STAR = 8 * RHO / (4 - 3 * RHO)


def two(f):
    return granstab.scene_from_dict({
        "dim": 2, "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [2.0, 0.0]}],
        "contacts": [{"p": "p", "q": "q", "point": [1.0, 0.0], "normal": [1.0, 0.0], "curvature_p": -1 / RHO,
                      "curvature_q": -1 / RHO, "force": [-f, 0.0], "k": 1.0, "alpha": 1.0, "state": "elastic"}]})


def robust(f, rel):
    return data_robustness(two(f), Band(rel=rel), metric="L", rotation_length=1.0)


def test_closed_form_threshold():
    assert abs(lambda5(1, 1, 1, RHO, F_STAR)) <= 1e-12
    assert granstab.analyze(two(0.9 * F_STAR), metric="L", rotation_length=1).summary["verdict"] == "stable"
    assert granstab.analyze(two(1.1 * F_STAR), metric="L", rotation_length=1).summary["verdict"] == "unstable"


def test_geometric_blocks_are_linear_in_the_forces():
    """The premise of the bound: Hg1 + Hg2 + Hg3 of the data = Σ_j f_j G_j (to round-off of the blocks' size)."""
    scene = granstab.load_scene("../shared/data/annulus_frame.json")
    G = unit_blocks(scene)
    hg = geometric(contact_blocks(scene).blocks)
    assert np.abs(hg - np.einsum("mj,mjab->mab", scene.force, G)).max() <= 1e-12 * np.abs(hg).max()


@pytest.mark.parametrize("f, rel", [(20.0, 0.25), (22.0, 0.15), (27.0, 0.2), (30.0, 0.3), (16.0, 0.55)])
def test_band_across_the_threshold_depends(f, rel):
    """The band crosses f*: depends, and the counter-example lies in the band and gives the other verdict."""
    assert (f * (1 - rel) - F_STAR) * (f * (1 + rel) - F_STAR) < 0
    got = robust(f, rel)
    assert got.robust == "depends"
    forces = np.array(got.counterexample["forces"])
    assert np.linalg.norm(forces[0] - [-f, 0.0]) <= rel * f
    other = granstab.analyze(perturbed(two(f), forces), metric="L", rotation_length=1).summary
    assert other["verdict"] == got.counterexample["verdict"] != got.verdict and other["sufficient"]


@pytest.mark.parametrize("f, rel", [(30.0, 0.1), (40.0, 0.35), (10.0, 0.1), (16.0, 0.05), (4.0, 0.2)])
def test_band_clear_of_the_threshold_holds(f, rel):
    """The band is clear of f*: holds. Above f* (unstable) the bound is exact: the margin is (f − f*)/(rel f)."""
    got = robust(f, rel)
    assert got.robust == "holds" and got.margin > 1
    if f > F_STAR:
        assert abs(got.margin - (f - F_STAR) / (rel * f)) <= 1e-6 * got.margin


@pytest.mark.parametrize("f", [5.0, 20.0])
def test_vertex_certificate_is_exact_at_the_closed_form_threshold(f):
    """The band's radius at 0.99 and 1.01 of the distance to the nearest threshold (f = 0, where λ⁽⁶⁾ = f(ρ − r)
    changes sign, or f* of λ⁽⁵⁾): holds (by the vertex certificate, vertices.py: the bound alone proves < 0.6× the
    band here) and depends, with a counter-example inside the band that `analyze` proves unstable. The certificate's
    lowest value is a lower bound of the closed-form λ_min over the band, min(λ⁽⁵⁾(f + R), λ⁽⁶⁾(f − R)), and > 0."""
    distance = min(f, F_STAR - f)
    below = robust(f, 0.99 * distance / f)
    assert below.robust == "holds" and below.margin < 0.6 and below.certificate["proven"]
    assert below.certificate["exact"] and below.certificate["analyses"] <= 64
    R = 0.99 * distance
    closed = min(float(lambda5(1, 1, 1, RHO, f + R)), float(lambda6(1, RHO, f - R)))
    assert 0 < below.certificate["lowest"] <= closed
    above = robust(f, 1.01 * distance / f)
    assert above.robust == "depends" and not above.certificate["proven"]
    forces = np.array(above.counterexample["forces"])
    assert np.linalg.norm(forces[0] - [-f, 0.0]) <= 1.01 * distance
    other = granstab.analyze(perturbed(two(f), forces), metric="L", rotation_length=1).summary
    assert other["verdict"] == "unstable" and other["sufficient"]


def test_vertex_certificate_against_a_dense_sampling_of_the_band():
    """A band the certificate proves (f = 20, 0.99 of the distance to f*): 200 forces on its edge and inside are all
    stable, and no sampled λ_min (less its accuracy) is below the certificate's lowest value."""
    f = 20.0
    R = 0.99 * (F_STAR - f)
    got = robust(f, R / f)
    assert got.robust == "holds" and got.certificate["proven"]
    rng = np.random.default_rng(3)
    angles = np.r_[np.linspace(0, 2 * np.pi, 120, endpoint=False), rng.uniform(0, 2 * np.pi, 80)]
    radii = np.r_[np.full(120, R * (1 - 1e-9)), R * np.sqrt(rng.uniform(size=80))]
    lowest = np.inf
    for a, r in zip(angles, radii):
        res = granstab.analyze(perturbed(two(f), np.array([[-f + r * np.cos(a), r * np.sin(a)]])), metric="L",
                               rotation_length=1, attribution=False, keep="all")
        assert res.summary["verdict"] == "stable" and res.summary["sufficient"]
        b = res.branches[0]
        lowest = min(lowest, float(np.min((b.stability_eigenvalues - b.accuracy)[b.codes != RIGID])))
    assert got.certificate["lowest"] <= lowest


def test_vertex_certificate_with_more_contacts_than_it_enumerates():
    """Four disks of a triangular lattice (5 elastic contacts, ρ/r = 1.3) under a band of 7 |f| (large, so that the
    bound alone proves only 0.97× of it): the certificate enumerates two contacts and bounds the other three by Weyl
    (exact: False) and proves it; 100 force sets on the band's edge and inside are all stable, none with a lowest
    non-rigid eigenvalue below the certificate's lowest vertex value less the Weyl rest."""
    from dataclasses import replace

    from granstab.model.packings import lattice
    scene = lattice(2, size=2, kind="triangular", f_over_k=0.01, curvature_ratio=1.3, seed=2)
    scene = replace(scene, state=("elastic",) * scene.n_contacts)
    got = data_robustness(scene, Band(rel=7.0))
    cert = got.certificate
    assert got.robust == "holds" and got.margin < 1 and cert["proven"] and not cert["exact"]
    assert len(cert["enumerated"]) == 2 and cert["rest"] > 0
    delta = 7.0 * np.linalg.norm(scene.force, axis=1) * (1 - 1e-9)
    rng = np.random.default_rng(0)
    for i in range(100):
        angle = rng.uniform(0, 2 * np.pi, scene.n_contacts)
        radius = delta * (1.0 if i % 2 == 0 else np.sqrt(rng.uniform(size=scene.n_contacts)))
        res = granstab.analyze(perturbed(scene, scene.force + radius[:, None] * np.c_[np.cos(angle), np.sin(angle)]),
                               metric="L", attribution=False, keep="all")
        assert res.summary["verdict"] == "stable" and res.summary["sufficient"]
        b = res.branches[0]
        assert np.min((b.stability_eigenvalues + b.accuracy)[b.codes != RIGID]) >= cert["lowest"] - cert["rest"]


def test_holds_is_never_contradicted_inside_the_band():
    """Random forces in a band that holds give the same verdict (the bound is a promise)."""
    rng = np.random.default_rng(1)
    for f, rel in ((10.0, 0.1), (30.0, 0.1)):
        got = robust(f, rel)
        assert got.robust == "holds"
        for _ in range(20):
            step = rng.normal(size=2)
            force = np.array([[-f, 0.0]]) + rel * f * rng.uniform() * step / np.linalg.norm(step)
            assert granstab.analyze(perturbed(two(f), force), metric="L",
                                    rotation_length=1).summary["verdict"] == got.verdict


def test_analyze_cli(tmp_path, capsys):
    path = tmp_path / "two.json"
    path.write_text(json.dumps(granstab.scene_to_dict(two(22.0))))
    assert main(["analyze", str(path), "--metric", "L", "--rotation-length", "1", "--force-uncertainty", "0.15",
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["data_uncertainty"]["robust"] == "depends"
    assert data["balance"]["method"] == "loads absorb the imbalance"
    assert main(["analyze", str(path), "--force-uncertainty", "0.1,x"]) == 2
    assert "--force-uncertainty" in capsys.readouterr().err


def test_analyze_cli_vertex_certificate(tmp_path, capsys):
    """analyze --force-uncertainty at 0.99 of the distance to f*: holds by the vertex certificate, in the JSON (a
    non-finite lowest value is written as a string, so the JSON stays strict) and in the table's line."""
    path = tmp_path / "two.json"
    path.write_text(json.dumps(granstab.scene_to_dict(two(20.0))))
    band = str(0.99 * (F_STAR - 20.0) / 20.0)
    assert main(["analyze", str(path), "--metric", "L", "--rotation-length", "1", "--force-uncertainty", band,
                 "--json"]) == 0
    got = json.loads(capsys.readouterr().out)["data_uncertainty"]
    assert got["robust"] == "holds" and got["margin"] < 1 and got["certificate"]["proven"]
    assert main(["analyze", str(path), "--metric", "L", "--rotation-length", "1", "--force-uncertainty", band]) == 0
    assert "HOLDS" in capsys.readouterr().out
    from granstab.uncertainty import DataRobustness
    odd = DataRobustness(robust="undecided", verdict="stable", margin=0.5, bound=1.0, band="", reason="",
                         certificate={"proven": False, "lowest": -np.inf, "probe": None})
    assert odd.to_dict()["certificate"]["lowest"] == "-inf"


def test_balance_least_squares():
    """The balanced forces balance every particle to round-off, the report's corrections are the forces' changes,
    and this cut cluster (its rim's cut contacts not exempt) needs corrections far outside a 10 % band; the
    correction is the least one: adding a self-stress (a null vector of the equilibrium map) makes it larger in
    the band's weights."""
    scene = granstab.load_scene("../shared/data/annulus_frame.json")
    band = Band(rel=0.1, abs=1e-3)
    out, report = balance_least_squares(scene, band)
    assert report["imbalance_after"] <= 1e-10 and report["imbalance_before"] > 0.1
    assert report["inside_band"] is False
    assert np.all(np.isclose(np.linalg.norm(out.force - scene.force, axis=1), report["correction_norm"]))
    from scipy.linalg import null_space

    from granstab.uncertainty import _equilibrium_matrix
    B = _equilibrium_matrix(scene).toarray()
    w = np.repeat(band.force_radius(scene.force), 2)
    c = (out.force - scene.force).ravel()
    N = null_space(B)
    assert N.shape[1] > 0
    for j in range(3):
        other = c + 0.01 * np.linalg.norm(c) * N[:, j]
        assert np.abs(B @ (other - c)).max() <= 1e-12 * np.abs(scene.force).max()
        assert np.sum((other / w) ** 2) > np.sum((c / w) ** 2)


@pytest.fixture(scope="module")
def annulus():
    from granstab_bench.uncertainty_study import solutions
    return solutions(1)


@pytest.mark.parametrize("rel, centers, boundary, need", [(0.2, "every:60", "loads", "holds"),
                                                         (0.1, "every:60", "embedded:1", "depends")])
def test_held_out_two_force_solutions(annulus, rel, centers, boundary, need):
    """Annulus experiments 10 and 6 (one frame, two force solutions): every cluster that `scan --force-uncertainty`
    calls holds, whose other solution lies within the band contact by contact, has the same verdict under it, and
    every depends row's counter-example (its forces, from the scan's table) gives the other verdict in `analyze`.
    Each case has at least one cluster of the kind it checks (the check is not vacuous)."""
    from granstab_bench.uncertainty_study import study
    got = study(1, rel, centers, boundary, scenes=annulus)["check"]
    assert got["holds_changed"] == [] and got["depends_not_reproduced"] == []
    assert (got["holds_within_band"] if need == "holds" else got["depends"]) >= 1


def test_held_out_check_on_another_frame_with_the_spread_band():
    """The held-out check on a frame the docs' table does not use (20, every 60th centre, embedded:1), with
    each contact's band the spread between the two solutions (`scan --force-uncertainty file`, force_err =
    |f⁶ − f¹⁰|, a hair wider: the other solution lies within the band wherever a cluster has the same contacts):
    no cluster called holds changes its verdict under the other solution, and every depends row's counter-example
    reproduces the other verdict in `analyze`; both kinds occur (the check is not vacuous). The wider simulation
    (frames 3, 5, 10, 15, 20, every 20th or 40th centre, both boundaries, and REL 0.1): docs/uncertainty.md."""
    from granstab_bench.uncertainty_study import solutions, study
    got = study(20, "spread", "every:60", "embedded:1", scenes=solutions(20))["check"]
    assert got["holds_changed"] == [] and got["depends_not_reproduced"] == []
    assert got["holds_within_band"] >= 1 and got["depends"] >= 1


def test_focused_factors_keep_outside_modes_outside():
    """mechanics.uncertainty.focused_factors: for every symmetric E with ‖E‖ below the factor, the eigenpairs of
    A + E that are not positive keep their share on the 'inside' dofs below `need` (random A with negative modes
    mostly outside, random E of that norm; the bound is a promise)."""
    from granstab.mechanics.uncertainty import focused_factors
    rng = np.random.default_rng(3)
    n, need = 8, 0.5
    inside = np.arange(n) < 3
    for _ in range(20):
        Q = np.linalg.qr(rng.normal(size=(n, n)))[0]
        Q[:, :2] = np.linalg.qr(np.vstack([0.3 * rng.normal(size=(3, 2)), rng.normal(size=(n - 3, 2))]))[0]
        Q = np.linalg.qr(Q)[0]
        lam0 = np.sort(np.r_[-2.0, -1.0, rng.uniform(1, 5, n - 2)])
        A = (Q * lam0) @ Q.T
        lam, V = np.linalg.eigh(A)
        share = np.sum(V[inside] ** 2, axis=0)
        bounds = np.full(n, 1e-13)
        t = focused_factors(lam[None], bounds[None], share[None], [1.0], need).min()
        if not t > 0:
            continue
        for _ in range(20):
            E = rng.normal(size=(n, n))
            E = E + E.T
            E *= 0.999 * t / np.linalg.norm(E, 2)
            mu, W = np.linalg.eigh(A + E)
            low = mu <= 0
            assert np.all(np.sum(W[inside][:, low] ** 2, axis=0) < need)


def hatched_map(folder, scene) -> dict:
    """The map of a scan folder drawn again (scan.figure.write_figures, the figure kept): the centres of the
    collections hatched DEPENDS_HATCH and whether the legend names them."""
    from granstab.scan import figure
    kept = []
    real = figure._save
    try:
        figure._save = lambda fig, stem: kept.append(fig) or []
        figure.write_figures(scene, folder)
    finally:
        figure._save = real
    ax = kept[0].axes[0]
    centres = {tuple(np.round(xy, 9)) for c in ax.collections if c.get_hatch() == figure.DEPENDS_HATCH
               for xy in c.get_offsets()}
    legend = any("depends on the data" in t.get_text() for a in kept[0].axes if a.get_legend()
                 for t in a.get_legend().get_texts())
    import matplotlib.pyplot as plt
    plt.close("all")
    return {"centres": centres, "legend": legend}


def test_scan_columns_and_map(tmp_path):
    """`scan --force-uncertainty 0.15 --search-counterexamples` of the two-particle scene at f = 22 (the band
    crosses f* = 24): both clusters depend on the data, their rows carry the counter-example's forces, which give
    the other verdict, and the map hatches both centres (DEPENDS_HATCH) with a legend entry saying what the
    hatching means; at f = 16 and 0.05 the batched bound alone (no search) proves both."""
    from granstab.scan import read_map
    path = tmp_path / "two.json"
    path.write_text(json.dumps(granstab.scene_to_dict(two(22.0))))
    common = ["scan", str(path), "--boundary", "loads", "--workers", "1"]
    assert main(common + ["--out", str(tmp_path / "a"), "--force-uncertainty", "0.15",
                          "--search-counterexamples"]) == 0
    rows = read_map(tmp_path / "a")["clusters"]
    assert list(rows["data_robust"]) == ["depends", "depends"]
    for forces in rows["counterexample"]:
        got = granstab.analyze(perturbed(two(22.0), np.reshape(forces, (1, 2))), metric="L")
        assert got.verdict.verdict == "unstable" != rows["verdict"][0]
    assert (tmp_path / "a" / "map.png").exists()
    drawn = hatched_map(tmp_path / "a", two(22.0))
    assert drawn["centres"] == {(0.0, 0.0), (2.0, 0.0)} and drawn["legend"]
    path.write_text(json.dumps(granstab.scene_to_dict(two(16.0))))
    assert main(common + ["--out", str(tmp_path / "b"), "--force-uncertainty", "0.05"]) == 0
    assert list(read_map(tmp_path / "b")["clusters"]["data_robust"]) == ["holds", "holds"]


def test_batched_holds_are_holds_of_the_cluster(annulus, tmp_path):
    """The scan's batched bound (scan/uncertain.py) is never bolder than data_robustness on the cluster's own scene:
    every row it proves holds (without the search) holds there too, with a margin at least as large (its bound is
    Weyl's, the cluster's adds the first-order terms); embedded boundary, annulus frame 1, a subset."""
    from granstab.scan import read_map, scan
    from granstab.scan.clusters import cluster
    from granstab.scan.run import _sub_index
    scene = annulus[0]
    scan(scene, tmp_path / "s", centers="every:70", workers=1, figures=False, attribution=False,
         uncertainty={"rel": 0.1, "abs": 0.0})
    rows = read_map(tmp_path / "s")["clusters"]
    held = [i for i, r in enumerate(rows["data_robust"]) if r == "holds"]
    assert len(held) >= 5
    for i in held:
        c = rows["center"][i]
        sub = cluster(scene, c, 1, "embedded:1")
        got = data_robustness(sub, Band(rel=0.1), max_sliding=8, search=False,
                              inside=(_sub_index(sub, scene, rows["members"][i]), 0.5))
        assert got.robust == "holds" and got.verdict == rows["verdict"][i]
        assert got.margin >= rows["robust_margin"][i] * (1 - 1e-9)
