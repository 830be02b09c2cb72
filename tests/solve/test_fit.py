"""The default plan fitted to the time a run takes (solve/plan.fit; issues 36-38) and the sparse path's estimate on
a floppy 3D packing (budget.FLOPPY_PAIR_DOF), on the LIGGGHTS superquadric packing of tests/data (250 grains, 1,500
dofs, 10 contacts at yield: 1,024 branches × 4 metrics, about 4·10⁴ s in full)."""
from __future__ import annotations

import json
import time

import pytest
from helpers import DATA  # noqa: E402

import granstab
from granstab.analysis import analyze
from granstab.cli import main
from granstab.solve import budget
from granstab.solve.plan import FIT_SHARE, deficit, plan

DATA = DATA / "liggghts_superquadric"
FILES = [DATA / "atoms.dump", DATA / "contacts.dump", DATA / "in.settle"]


@pytest.fixture(scope="module")
def scene_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("fit") / "scene.json"
    assert main(["convert", *map(str, FILES), "--out", str(path)]) == 0
    return path


def test_the_default_plan_is_fitted_and_says_what_it_left_out(scene_path, capsys):
    """Without options the plan leaves out, in order, the family's other metrics, most branches and the dense
    spectra until its estimate fits; it says so and gives the full analysis's command (trial6: refused, exit 2)."""
    capsys.readouterr()
    assert main(["analyze", str(scene_path), "--plan", "--json"]) == 0
    cost = json.loads(capsys.readouterr().out)["cost"]
    assert cost["refusal"] is None and cost["fitted"] is not None
    scene = granstab.load_scene(scene_path)       # chosen on the estimate at rest: the same plan at any load
    assert plan(scene, **cost["fitted"]["options"], rest=True).estimated_s <= FIT_SHARE * budget.ASK_SECONDS
    assert cost["metric_names"] == ["L"] and cost["sampled"] and cost["method"] == "sparse"
    assert "L/10, 10L, inertia" in cost["left_out"][0] and "metric-robustness not evaluated" in cost["left_out"][0]
    assert any("a proof only of instability" in x for x in cost["left_out"])
    full = cost["fitted"]["full_estimated_s"]
    assert full > budget.ASK_SECONDS and cost["fitted"]["full_options"] == f"--timeout {int(-(-1.2 * full // 1))}"


def test_the_fitted_run_exits_0_and_claims_no_more_than_it_proves(scene_path, capsys):
    capsys.readouterr()
    assert main(["analyze", str(scene_path), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    sm = data["summary"]
    assert sm["branches"] == "partial" and not sm.get("metrics")
    assert sm["verdict"] == "unstable" or not sm["sufficient"]          # a sample proves only instability
    assert data["cost"]["fitted"]["options"]["metric"] == "L"
    assert data["cost"]["left_out"][0].startswith("the metric(s) L/10, 10L, inertia")


def test_an_explicit_choice_is_run_or_refused_as_asked(scene_path, capsys):
    """--metric family given: the work is the user's choice, refused in one line as before (no fitting)."""
    capsys.readouterr()
    assert main(["analyze", str(scene_path), "--metric", "family"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "refused: 1024 branches × 4 metric(s) of 1500 dofs" in err


@pytest.mark.serial                     # a measured time against an estimate
def test_the_sparse_estimate_holds_on_a_floppy_superquadric_packing(scene_path):
    """Issue 38's promise on the sparse path, as a ratio (no absolute time): measured within 3× of the estimate
    (the estimate's own error band; it was 7-9× low on trial6, where the floppy packing's branches, each with more
    modes at or below zero than k, were costed as Ritz updates), and not wildly above it (10×). The packing has 28
    dofs beyond its contact constraints (`deficit`), the estimate's new term."""
    scene = granstab.load_scene(scene_path)
    assert deficit(scene) == 28
    options = dict(metric="L", method="sparse", max_sliding=2, sample_branches=4)
    analyze(scene, **{**options, "sample_branches": 1})             # imports and first calls: not the branches' cost
    estimated = plan(scene, **options).estimated_s
    start = time.perf_counter()
    analyze(scene, **options)
    measured = time.perf_counter() - start
    assert 1 / 10 <= measured / estimated <= 3.0, (measured, estimated)
