"""One plan a run (issues 38, 40): `analysis.plan(scene, **options)` says the method, path, branches per metric,
metrics, what is left out and the estimate; `analyze` follows it, `granstab analyze --plan` prints it and runs
nothing, every run's JSON carries `cost.estimated_s` beside `timings.total`; the run follows its plan and the estimate is the
sum of its parts (how well it holds is timing: benchmarks/estimates.py, BENCHMARKS.md "estimates") and the BLAS
threads follow the free cores."""
import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

import granstab
from granstab.analysis import plan
from granstab.cli import main
from granstab.model.packings import random_packing
from granstab.solve import budget, threads
from granstab_bench.estimates import cases, micrometres, thinned


@pytest.fixture(scope="module")
def annulus_um(tmp_path_factory):
    scene = micrometres(granstab.load_scene(ROOT / "presets" / "annulus_frame.json"))
    return scene, granstab.save_scene(scene, tmp_path_factory.mktemp("um") / "annulus_um.npz")


def test_plan_prints_the_plan_and_its_estimate_and_runs_nothing(annulus_um, monkeypatch, capsys):
    scene, path = annulus_um
    import granstab.cli as cli

    def never(*args, **kwargs):
        raise AssertionError("--plan ran the analysis")

    monkeypatch.setattr(cli, "analyze", never)
    assert main(["analyze", str(path), "--plan"]) == 0
    text = capsys.readouterr().out
    assert "plan, nothing run" in text and "method dense, full path, 429 dofs" in text
    assert "branches: 1 per metric (all) × 3 metric(s): L, L/10, 10L" in text
    assert "left out: nothing" in text and "estimate: " in text
    assert main(["analyze", str(path), "--plan", "--json", "--metric", "L", "--method", "sparse"]) == 0
    cost = json.loads(capsys.readouterr().out)["cost"]
    assert cost["path"] == "sparse" and cost["metric_names"] == ["L"] and cost["estimated_s"] > 0
    assert any("ℍ^i spectra" in w for w in cost["left_out"])


def test_every_run_carries_its_estimate_beside_its_time(annulus_um, capsys):
    _, path = annulus_um
    assert main(["analyze", str(path), "--json", "--metric", "L"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["cost"]["estimated_s"] > 0 and d["timings"]["total"] > 0
    assert d["cost"]["path"] == "full" and d["cost"]["paths"] == {"full": 1}


def test_analyze_follows_the_plan_it_was_given_and_a_floppy_packing_is_planned_on_the_full_path():
    """A packing with fewer contacts than its dofs need (floppy: a non-rigid zero in every branch) sends every
    branch from the low-rank path to the full one (lowrank._special), seconds each: the plan counts them there
    (the issue's 400 disks, 672 contacts: 3.8 s estimated, 31.6 s measured)."""
    floppy = thinned(120, 190, 1)
    p = plan(floppy, metric="L", lowrank=True)
    assert p.path == "low_rank" and p.floppy
    res = granstab.analyze(floppy, metric="L", lowrank=True)
    assert res.cost["paths"] == {"low_rank": 0, "full": 2}                # where the plan said the branches go
    firm = random_packing(2, 120, n_sliding=1, seed=3)
    p = plan(firm, metric="L", lowrank=True)
    assert not p.floppy
    assert granstab.analyze(firm, metric="L", lowrank=True).cost["paths"] == {"low_rank": 2, "full": 0}


def test_the_refusal_text_comes_from_the_plan(tmp_path, capsys):
    scene = random_packing(2, 30, n_sliding=18, seed=1)
    path = granstab.save_scene(scene, tmp_path / "s.json")
    assert main(["analyze", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == plan(granstab.load_scene(path)).refusal + "\n"
    assert main(["export", str(path), "--out", str(tmp_path / "x"), "--modes", "2"]) == 2
    err = capsys.readouterr().err
    assert "--sample-branches" in err
    main(["export", str(path), "--out", str(tmp_path / "x"), "--modes", "2", "--sample-branches", "2", "--out-format",
          "xyz"])                                           # the advice followed: export has the flag now, and
    assert "on its 4 branch(es)" in capsys.readouterr().err   # examines 2 + 2 branches (this packing: no mode)


CASES = cases(quick=True)      # a small case of every path (benchmarks/estimates.py; its full run: the sizes)


@pytest.mark.parametrize("name,scene,options", CASES, ids=[c[0] for c in CASES])
def test_the_run_follows_its_plan_and_the_estimate_is_its_parts(name, scene, options):
    """The run takes the plan's path, metrics and branches, and the estimate is the sum of its parts, each positive,
    on the plan's free cores. How close the estimate comes to the measured time is timing: benchmarks/estimates.py
    (`granstab bench --only estimates`, and `--quick` for these cases) measures it, BENCHMARKS.md records it."""
    p = plan(scene, **options)
    res = granstab.analyze(scene, **options)
    cost = res.cost
    assert cost["path"] == p.path and cost["metric_names"] == list(p.metrics)
    assert cost["branches_per_metric"] == p.n_branches and len(res.branches) == p.n_branches
    assert all(v >= 0 for v in p.parts.values()) and p.estimated_s > 0
    assert p.estimated_s == pytest.approx(sum(p.parts.values()), rel=1e-12)
    assert 1 <= p.workers <= threads.cores()


@pytest.mark.serial                     # reads the machine's ready threads, starts busy ones
def test_blas_threads_follow_the_free_cores(monkeypatch):
    """Two busy processes beside a run on 2 cores: one BLAS thread (two would wait for each other at every call:
    26× slower, issue 38); at rest every core; small matrices one thread whatever the load. `runnable` counts the
    threads ready to run at this priority: a busy process started here shows in it, a niced one does not."""
    monkeypatch.setattr(threads, "cores", lambda: 2)
    monkeypatch.setattr(threads, "_process_cap", None)   # an explorer test earlier in the run may have capped the process
    monkeypatch.setattr(threads, "ready", lambda: [(1, "session a"), (2, "session b")])   # two others, ready
    monkeypatch.setattr(threads, "SAMPLE_GAP", 0.0)
    monkeypatch.setattr(threads, "_runnable_cache", [-1.0, 0.0, 1.0])
    assert threads.runnable(fresh=True) == 2.0
    assert threads.free_cores() == 1 and threads.for_size(500) == 1 and abs(threads.slowdown() - 1.5) < 1e-12
    monkeypatch.setattr(threads, "runnable", lambda fresh=False: 0.0)
    assert threads.free_cores() == 2 and threads.for_size(500) == 2 and threads.for_size(50) == 1
    monkeypatch.undo()
    assert 1 <= threads.free_cores() <= threads.cores()
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    niced = subprocess.Popen([sys.executable, "-c", "while True: pass"], preexec_fn=lambda: os.nice(10))
    try:
        time.sleep(0.5)                              # started: each is running or ready to run (state R) from now on
        found = threads.runnable_threads()
    finally:
        for proc in (*spinners, niced):
            proc.kill()
            proc.wait()
    assert all(p.pid in found for p in spinners) and niced.pid not in found and os.getpid() not in found


@pytest.mark.serial                     # the probe's speed against the calibration
def test_the_probe_is_measured_once_and_scales_the_sparse_calibration():
    first = budget.speed()
    assert budget.speed() == first and 0.05 < first < 20        # cached; a machine within 20× of the calibration
    assert budget.sparse_estimate(4107, 10, 1, n_sliding=300) > 5 * budget.sparse_estimate(4107, 10, 1, n_sliding=0)
    parts = [sum(budget.sparse_parts(4107, 10, m, 5).values()) for m in ("L", "L/10", "10L")]
    assert np.isclose(budget.sparse_estimate(4107, 10, 3, 5) / budget.sparse_estimate(4107, 10, 1, 5),
                      sum(parts) / parts[0])               # the family: its metrics one by one, L first
