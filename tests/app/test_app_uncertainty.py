"""The explorer's *Force uncertainty* and *Position uncertainty* controls (issue 42, app/panel/uncertainty.py): the plain sentence of each
answer, nothing computed at 0 %, and a session whose band changes what the Verdict tab says (no browser)."""
from types import SimpleNamespace

import numpy as np

import granstab
from granstab.uncertainty import DataRobustness
from granstab_app.panel import uncertainty as panel
from granstab_app.state import Session


def result(robust, **extra):
    return DataRobustness(robust=robust, verdict="stable", margin=extra.pop("margin", 0.5), bound=1.0,
                          band="forces ±(0.1·|f| + 0)", reason="", **extra)


def test_sentences():
    assert panel.robust_sentence(result("holds"), 0) == "" and panel.robust_sentence(None, 10) == ""
    assert panel.robust_sentence(result("holds", margin=2.0), 10).startswith("**Holds under ±10 %:**")
    flip = result("depends", counterexample={"verdict": "unstable", "forces": [[-23.5, 0.25]],
                                             "largest_band_fraction": 0.99})
    text = panel.robust_sentence(flip, 15, names=["p–q"])
    assert text.startswith("**Depends on the data:**") and "unstable instead of stable" in text
    assert "p–q: (-23.5, 0.25)" in text
    assert "proven for 0.28× the band only" in panel.robust_sentence(result("undecided", margin=0.28), 5)
    assert "no bound applies" in panel.robust_sentence(result("undecided", margin=-np.inf), 5)


def test_the_band_changes_the_session_report(monkeypatch):
    """The default pair: at 0 % nothing is computed; at 10 % the verdict holds (the pair's thresholds, f = 0 and
    f*, are far), computed once per revision and band; a new revision computes again."""
    s = Session()
    calls = []
    real = panel.data_robustness
    monkeypatch.setattr(panel, "data_robustness", lambda *a, **k: calls.append(k) or real(*a, **k))
    assert panel.robustness(s) is None and calls == []
    s.force_band = 10.0
    got = panel.robustness(s)
    assert got.robust == "holds" and got.verdict == s.analysis.verdict.verdict and len(calls) == 1
    assert calls[0]["analysis"] is s.analysis                     # the session's own analysis, reused
    assert panel.robustness(s) is got and len(calls) == 1
    assert panel.robust_sentence(got, s.force_band).startswith("**Holds under ±10 %:**")
    s.set_params(rho_r=s.params["rho_r"] * 1.1)
    assert panel.robustness(s) is not got and len(calls) == 2


def test_a_band_across_the_threshold_shows_its_counter_example():
    """The paper's pair (ρ = 1.2, f = 22: the band ±15 % crosses f* = 24): depends, and the forces shown give the
    other verdict."""
    scene = granstab.scene_from_dict({
        "dim": 2, "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [2.0, 0.0]}],
        "contacts": [{"p": "p", "q": "q", "point": [1.0, 0.0], "normal": [1.0, 0.0], "curvature_p": -1 / 1.2,
                      "curvature_q": -1 / 1.2, "force": [-22.0, 0.0], "k": 1.0, "alpha": 1.0, "state": "elastic"}]})
    analysis = granstab.analyze(scene, metric="L", attribution=False, keep="all")
    s = SimpleNamespace(force_band=15.0, position_band=0.0, analysis=analysis, scene=scene, on_map=False,
                        revision=1, robust=(None, None))
    got = panel.robustness(s)
    assert got.robust == "depends"
    assert "unstable instead of stable" in panel.robust_sentence(got, 15.0)
    from granstab.uncertainty import perturbed
    other = granstab.analyze(perturbed(scene, np.array(got.counterexample["forces"])), metric="L")
    assert other.summary["verdict"] == "unstable"


def test_position_band_server_side(monkeypatch):
    """The default pair (unstable: the rolling mode λ⁽⁶⁾ = f(ρ − r) = −0.005, r = 1): nothing computed at 0 on both
    sliders; ±0.1 % of a radius is Band(position=0.001 · the mean arm = 0.001), the same result as data_robustness
    called directly (holds: the rigorous bound, mechanics/nonaffine.py, proves a margin above 4), said in plain words;
    ±2 % is undecided (the bound proves about 0.22× the band; the old first-order estimate said 25×, no promise);
    with ±10 % on the forces too the band is both, and the margin smaller; a new band computes again."""
    from granstab.mechanics.uncertainty import Band
    s = Session()
    calls = []
    real = panel.data_robustness
    monkeypatch.setattr(panel, "data_robustness", lambda *a, **k: calls.append(a[1]) or real(*a, **k))
    assert panel.robustness(s) is None and calls == [] and s.position_band == 0
    assert panel.radius(s.scene) == 1.0
    s.position_band = 0.1
    got = panel.robustness(s)
    assert calls[-1] == Band(position=0.001) and got.nonaffine > 0
    direct = real(s.scene, Band(position=0.001), metric="L", rotation_length=s.analysis.length)
    assert got.robust == direct.robust == "holds" and got.margin == direct.margin and got.margin > 4
    text = panel.robust_sentence(got, s.force_band, position=s.position_band)
    assert text.startswith("**Holds under ±0.1 % of a radius in the positions:**")
    assert "contact positions within ±0.1 % of a radius" in text and "first order" not in text
    s.force_band = 10.0
    both = panel.robustness(s)
    assert len(calls) == 2 and calls[-1] == Band(rel=0.1, position=0.001) and both.margin < got.margin
    assert panel.robust_sentence(both, 10.0, position=0.1).startswith(
        "**Holds under ±10 % in the forces and ±0.1 % of a radius in the positions:**")
    s.force_band, s.position_band = 0.0, 2.0
    wide = panel.robustness(s)
    assert len(calls) == 3 and wide.robust == "undecided" and 0.1 < wide.margin < 1
    assert panel.robust_sentence(wide, 0.0, position=2.0).startswith("**Undecided at ±2 % of a radius")


def test_position_sentences_for_depends_and_undecided():
    flip = result("depends", counterexample={"verdict": "unstable", "forces": [[-23.5, 0.25]],
                                             "largest_band_fraction": 0.99})
    text = panel.robust_sentence(flip, 15, names=["p–q"], position=1.0)
    assert "Counter-example forces (positions as measured): p–q: (-23.5, 0.25)" in text
    assert panel.robust_sentence(result("undecided"), 0, position=0.5).startswith(
        "**Undecided at ±0.5 % of a radius in the positions:**")
    assert panel.robust_sentence(result("holds"), 0, position=0) == ""
