"""What the band moves that is not affine in the forces (issue 42, mechanics/nonaffine.py): counter-examples that move
positions (granstab.moves, `_position_step`), written out and re-analysed by the CLI, and 3D sliding contacts with a
force band, whose sliding direction h turns with the force (a Weyl-type bound over the contact's force ball)."""
import functools
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import granstab
from granstab.cli import main
from granstab.io.scenes import save_scene
from granstab.mechanics.branches import RIGID
from granstab.mechanics.uncertainty import Band, mobilisation
from granstab.uncertainty import _Data, _nonaffine, counterexample_scene, data_robustness, perturbed

RHO = 1.2
sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "track"))


def pair(rho, f=0.01):
    """The paper's two-particle cluster (Sec. 4.1, r = 1): λ⁽⁶⁾ = f(ρ − r), stable for ρ > r."""
    return granstab.scene_from_dict({
        "dim": 2, "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [2.0, 0.0]}],
        "contacts": [{"p": "p", "q": "q", "point": [1.0, 0.0], "normal": [1.0, 0.0], "curvature_p": -1 / rho,
                      "curvature_q": -1 / rho, "force": [-f, 0.0], "k": 1.0, "alpha": 1.0, "state": "elastic"}]})


@pytest.mark.parametrize("rho, length, want", [(1.02, 0.03, "unstable"), (0.98, 0.03, "stable")])
def test_a_position_counterexample_is_written_out_and_reproduced(rho, length, want, tmp_path, capsys):
    """The pair with ρ − r = ±0.02: moving both centres and the contact point by 0.03 changes the arms enough to flip
    λ⁽⁶⁾ = f(ρ − r). Forces alone (none in the band) cannot: the search moves positions along the work's first-order
    gradient and finds a set within the band (every move <= LEN) whose scene, written to a file, `granstab analyze`
    proves the other verdict."""
    scene = pair(rho)
    got = data_robustness(scene, Band(position=length), metric="L", rotation_length=1.0)
    assert got.robust == "depends" and got.counterexample["verdict"] == want
    cx = got.counterexample
    assert "positions" in got.reason and 0 < cx["largest_position_move"] <= length
    assert np.all(np.linalg.norm(np.array(cx["x"]) - scene.x, axis=1) <= length)
    assert np.all(np.linalg.norm(np.array(cx["point"]) - scene.point, axis=1) <= length)
    path = save_scene(counterexample_scene(scene, cx), tmp_path / "counterexample.json")
    capsys.readouterr()
    assert main(["analyze", str(path), "--metric", "L", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["summary"]["verdict"] == want


def test_below_the_arm_change_the_position_band_holds():
    """The stable pair (ρ − r = 0.02): a band of 1e-6 is proven (the rigorous bound, not sampled), and 0.015, whose
    arm changes (<= 0.03 in sum) cannot reach ρ − r in the search's moves, is not a proven "holds" either way."""
    scene = pair(1.02)
    tiny = data_robustness(scene, Band(position=1e-6), metric="L", rotation_length=1.0)
    assert tiny.robust == "holds" and tiny.margin > 1 and tiny.nonaffine > 0
    mid = data_robustness(scene, Band(position=0.015), metric="L", rotation_length=1.0, search=False)
    assert mid.robust == "undecided" and mid.margin < 1


def triangle(slide=2.0, mu=0.5):
    """Three spheres (r = 1, radii of curvature ρ = 1.2, twisting stiffness n⊗n) in a plane triangle, the p–q
    contact at yield (normal force `slide`, tangential μ·slide out of the plane), the others elastic with unit normal
    force: stable at slide = 2, unstable at 4."""
    s3 = np.sqrt(3)
    X = {"p": [0.0, 0.0, 0.0], "q": [2.0, 0.0, 0.0], "r": [1.0, s3, 0.0]}
    contacts = []
    for a, b, state in (("p", "q", "auto"), ("p", "r", "elastic"), ("q", "r", "elastic")):
        xa, xb = np.array(X[a]), np.array(X[b])
        n = (xb - xa) / 2
        f = -(slide if state == "auto" else 1.0) * n + (mu * slide * np.array([0, 0, 1.0]) if state == "auto" else 0)
        K = (-(np.eye(3) - np.outer(n, n)) / RHO).tolist()
        contacts.append({"p": a, "q": b, "point": ((xa + xb) / 2).tolist(), "normal": n.tolist(), "curvature_p": K,
                         "curvature_q": K, "force": f.tolist(), "k": 1.0, "alpha": 1.0, "mu": mu, "state": state,
                         "rolling_stiffness": np.outer(n, n).tolist()})
    return granstab.scene_from_dict({"dim": 3, "particles": [{"name": k, "x": v} for k, v in X.items()],
                                     "contacts": contacts})


@functools.cache
def threshold() -> float:
    """The sliding contact's force scale at which the triangle turns unstable (bisection of `analyze`, 2⁻³⁰)."""
    lo, hi = 2.0, 4.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        stable = granstab.analyze(triangle(mid), metric="L", rotation_length=1.0).summary["verdict"] == "stable"
        lo, hi = (mid, hi) if stable else (lo, mid)
    return lo


def test_3d_sliding_contact_with_a_band_holds_below_and_depends_above():
    """The triangle at slide = 2 with a band on its sliding contact only. Moving that force along itself (on the
    cone) turns the verdict unstable at the distance D = (slide* − 2)·√(1 + μ²) (slide* by bisection, 2.25): a band
    of 1.05 D gives depends (the counter-example within the band, unstable in `analyze`). Below, the bound over the
    contact's force ball, h turning by up to 2δ/|f_t| (nonaffine.py), proves holds at 0.005 D (the bound's margin
    1.9; it proves up to about 0.0096 D: conservative by about 100× against the threshold); before, such a contact had
    no bound (undecided at any band). The vertex certificate is not used (λ_min is not concave where h turns)."""
    scene = triangle()
    assert scene.at_yield().tolist() == [True, False, False]
    distance = (threshold() - 2.0) * np.sqrt(1.25)
    assert 0.2 < distance < 0.4

    def band(frac):
        return Band(per_contact=np.array([frac * distance, 0.0, 0.0]))
    low = data_robustness(scene, band(0.005), metric="L", rotation_length=1.0)
    assert low.robust == "holds" and low.certificate is None and low.nonaffine > 0 and 1 < low.margin < 4
    high = data_robustness(scene, band(1.05), metric="L", rotation_length=1.0)
    assert high.robust == "depends" and high.counterexample["largest_band_fraction"] <= 1
    again = granstab.analyze(counterexample_scene(scene, high.counterexample), metric="L", rotation_length=1.0)
    assert again.summary["verdict"] == "unstable" and again.verdict.sufficient


def lowest(scene) -> float:
    """The lowest non-rigid eigenvalue less its accuracy bound over every branch of `analyze`."""
    res = granstab.analyze(scene, metric="L", rotation_length=1.0, attribution=False, keep="all")
    assert res.summary["verdict"] == "stable"
    return min(float(np.min((b.stability_eigenvalues - b.accuracy)[b.codes != RIGID])) for b in res.branches)


def test_3d_sliding_bound_against_sampled_forces():
    """At the band the triangle's bound proves (0.009 D), 60 force sets sampled in the sliding contact's ball (a
    third on its sphere): every one is stable in `analyze`, with its lowest non-rigid eigenvalue (every branch, less
    its accuracy) at least the data's less the bound (`bound`: e + the non-affine part; Weyl on each branch)."""
    scene = triangle()
    distance = (threshold() - 2.0) * np.sqrt(1.25)
    band = Band(per_contact=np.array([0.009 * distance, 0.0, 0.0]))
    got = data_robustness(scene, band, metric="L", rotation_length=1.0)
    assert got.robust == "holds"
    floor = lowest(scene) - got.bound
    assert floor > 0
    rng = np.random.default_rng(3)
    for i in range(60):
        step = rng.normal(size=3)
        step *= band.per_contact[0] * (1.0 if i % 3 == 0 else rng.random() ** (1 / 3)) / np.linalg.norm(step)
        force = scene.force.copy()
        force[0] += step
        assert lowest(perturbed(scene, force)) >= floor


def test_the_3d_turn_enters_only_where_a_sliding_contact_has_a_band():
    """mobilisation's `turning`: the triangle's sliding contact with a force band, not its elastic ones nor a band
    of zero; a 2D force band turns nothing (h = ±t there); the non-affine knots exist exactly then."""
    scene = triangle()
    res = granstab.analyze(scene, metric="L", rotation_length=1.0, keep="all")
    on = Band(per_contact=np.array([0.01, 0.01, 0.01]))
    assert mobilisation(scene, on)["turning"].tolist() == [True, False, False]
    assert not mobilisation(scene, Band())["turning"].any()
    knots = _nonaffine(_Data.of(scene, on), res, mobilisation(scene, on), 0.0)
    assert len(knots) > 1 and all(k[1] > 0 for k in knots)
    flat = replace(pair(1.2), state=("auto",))
    assert not mobilisation(flat, Band(rel=0.1))["turning"].any()


def test_position_uncertainty_on_analyze_scan_and_track(tmp_path, capsys):
    """`--position-uncertainty LEN` on the three commands (the 3×2 grid of test_uncertainty_columns, unstable): a
    band of 1e-7 is proven by the rigorous bound (analyze: `nonaffine` > 0 in the JSON; scan and each track frame:
    every cluster holds), a band of 0.3 (near a third of a radius) is not: no bound closes there (the curvature
    sum's pseudo-inverse may change rank: `bound` and `nonaffine` "inf" in the JSON), and the search moves the
    positions to a stable counter-example: depends."""
    from test_track_uncertainty_columns import write_frames
    from test_uncertainty_columns import write

    from granstab.scan import read_map
    paths = write(tmp_path)
    for length, want in (("1e-7", "holds"), ("0.3", None)):
        assert main(["analyze", *paths, "--mu", "0.5", "--metric", "L", "--position-uncertainty", length,
                     "--json"]) == 0
        got = json.loads(capsys.readouterr().out)["data_uncertainty"]
        if want == "holds":
            assert got["robust"] == "holds" and 0 < got["nonaffine"] < got["bound"] * (1 + 1e-12)
        else:
            assert got["robust"] == "depends" and got["nonaffine"] == got["bound"] == "inf"
            assert got["counterexample"]["verdict"] == "stable" and len(got["counterexample"]["x"]) == 6
    assert main(["scan", *paths, "--mu", "0.5", "--boundary", "loads", "--position-uncertainty", "1e-7",
                 "--workers", "1", "--out", str(tmp_path / "s")]) == 0
    assert set(read_map(tmp_path / "s")["clusters"]["data_robust"]) == {"holds"}
    frames = tmp_path / "frames"
    frames.mkdir()
    assert main(["track", *write_frames(frames, loud=[3, 0]), "--mu", "0.5", "--scan", "--boundary", "loads",
                 "--position-uncertainty", "1e-7", "--workers", "1", "--no-figures", "--out", str(tmp_path / "t")]) == 0
    for frame in (0, 1):
        c = read_map(tmp_path / "t" / "scans" / f"frame-{frame:06d}")["clusters"]
        assert set(c["data_robust"]) == {"holds"}


def test_a_contact_of_uncertain_mobilisation_counts_in_both_states():
    """The stable pair (ρ = 1.2, f = 0.1) with an "auto" contact just inside the cone (|f_t| = 0.99 μ f_n): a band of
    5 % can take it onto the cone, so it is `uncertain` and the bound is taken over its sliding branch too (a
    sliding contact adds a negative direction: the margin falls below the same scene's with the contact held
    elastic); a band of 0.1 % cannot (not uncertain, the margin as the elastic one's)."""
    def scene(state):
        return granstab.scene_from_dict({
            "dim": 2, "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [2.0, 0.0]}],
            "contacts": [{"p": "p", "q": "q", "point": [1.0, 0.0], "normal": [1.0, 0.0], "curvature_p": -1 / RHO,
                          "curvature_q": -1 / RHO, "force": [-0.1, 0.99 * 0.5 * 0.1], "k": 1.0, "alpha": 1.0,
                          "mu": 0.5, "state": state}]})
    wide = data_robustness(scene("auto"), Band(rel=0.05), metric="L", rotation_length=1.0, search=False)
    held = data_robustness(scene("elastic"), Band(rel=0.05), metric="L", rotation_length=1.0, search=False)
    assert wide.uncertain == (0,) and held.uncertain == () and wide.margin < held.margin
    narrow = data_robustness(scene("auto"), Band(rel=0.001), metric="L", rotation_length=1.0, search=False)
    assert narrow.uncertain == () and narrow.robust == "holds"


def test_a_scan_row_keeps_a_position_counterexample(tmp_path):
    """`scan --position-uncertainty 0.03 --search-counterexamples` of the stable pair (ρ − r = 0.02): both rows depend
    on the data, and their `counterexample` holds the forces, then the moved centres and points
    (uncertainty.flat_counterexample), from which the cluster's scene is rebuilt and proven unstable."""
    from granstab.scan import read_map
    from granstab.uncertainty import counterexample_from_flat
    path = tmp_path / "pair.json"
    path.write_text(json.dumps(granstab.scene_to_dict(pair(1.02))))
    assert main(["scan", str(path), "--boundary", "loads", "--workers", "1", "--metric", "L", "--out",
                 str(tmp_path / "s"), "--position-uncertainty", "0.03", "--search-counterexamples"]) == 0
    rows = read_map(tmp_path / "s")["clusters"]
    assert list(rows["data_robust"]) == ["depends", "depends"]
    for flat in rows["counterexample"]:
        cx = counterexample_from_flat(pair(1.02), flat)
        assert len(flat) == 8 and np.all(np.linalg.norm(cx["x"] - pair(1.02).x, axis=1) <= 0.03)
        got = granstab.analyze(counterexample_scene(pair(1.02), cx), metric="L", rotation_length=1.0)
        assert got.summary["verdict"] == "unstable" and got.verdict.sufficient
