"""No silent minutes (issue 26): the path a 300-disk packing's branches take, the up-front estimate (path and metric
family), the heartbeat of a non-interactive run, and --timeout honoured on the threaded low-rank path."""
import json
import time

import numpy as np
import pytest

import granstab
from granstab.cli import main
from granstab.io import progress
from granstab.mechanics.branches import branch_matrices
from granstab.mechanics.metric import family
from granstab.model.packings import random_packing
from granstab.solve import budget, lowrank, threads


@pytest.fixture(scope="module")
def disks300():
    """About 300 frictional disks (867 dofs) with 2 contacts at the friction limit: 4 branches."""
    return random_packing(2, 300, n_sliding=2, seed=1)


@pytest.fixture(scope="module")
def disks300_file(disks300, tmp_path_factory):
    path = tmp_path_factory.mktemp("disks300") / "disks300.npz"
    granstab.save_scene(disks300, path)
    return path


def test_a_300_disk_packing_takes_the_low_rank_path(disks300):
    """Below 2^10 branches every branch of a ~900-dof cluster used to take the full path (eig + SVD of 900×900,
    seconds a branch); the cost report says which path each branch took."""
    result = granstab.analyze(disks300, metric="L")
    assert result.cost["paths"] == {"low_rank": 4, "full": 0} and result.cost["branches_per_metric"] == 4
    # the low-rank eigenvalues are those of the branch's full sym(𝓗) (a direct dense eigvalsh); the tolerance is
    # the reported per-eigenvalue bound plus the direct solve's own backward error (n ε ‖sym 𝓗‖)
    b = result.branches[0]
    _, _, Hsym = branch_matrices(result.problem, b.mask[None])
    direct = np.linalg.eigvalsh(Hsym[0])
    slack = Hsym.shape[-1] * np.finfo(float).eps * np.abs(direct).max()
    assert np.all(np.abs(np.sort(b.stability_eigenvalues) - direct) <= b.accuracy.max() + slack)


def test_the_estimate_counts_every_metric_of_the_family(disks300_file, monkeypatch, capsys):
    """The default family repeats every branch in each metric; the --timeout estimate ignored that (3-4× low)."""
    from granstab.solve import plan as planning
    from granstab.solve import threads
    scene = granstab.load_scene(disks300_file)
    n_metrics = len(family(scene, None))
    per_branch = 1.0                                              # a fixed measured cost: the estimate is exact
    monkeypatch.setattr(budget, "branch_seconds", lambda n, stack=4, lowrank=False: per_branch)
    monkeypatch.setattr(threads, "free_cores", lambda: 2)        # two free cores, no other process
    monkeypatch.setattr(threads, "slowdown", lambda: 1.0)
    planned = planning.plan(scene)
    # 4 low-rank branches shared by the 2 free cores, and the path's once-per-metric work (budget.SETUP_BRANCHES)
    one = (4 / 2 + budget.SETUP_BRANCHES) * per_branch
    assert planned.path == "low_rank" and planned.parts["branches"] == n_metrics * one
    assert planned.parts["robustness"] == planning.ROBUST_EIGH * 4 * per_branch
    assert planned.one_metric_s == one + planned.parts["attribution"]
    timeout = 0.5 * (planned.one_metric_s + planned.estimated_s)   # the family does not fit, one metric does
    assert main(["analyze", str(disks300_file), "--timeout", f"{timeout}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "refused" in err
    assert f"4 branches × {n_metrics} metric(s) of {scene.n_dof} dofs (low-rank path)" in err
    assert f"need about {planned.estimated_s:.3g} s" in err
    assert f"--metric L alone (about {planned.one_metric_s:.3g} s)" in err
    monkeypatch.setattr(lowrank, "solve_branches_lowrank", _stop)            # the refusal came before any work
    assert main(["analyze", str(disks300_file), "--timeout", f"{timeout}", "--metric", "L"]) == 2
    assert "work started" in capsys.readouterr().err


def _stop(*args, **kwargs):
    raise granstab.SceneError("work started")


def test_without_timeout_long_work_is_refused_in_one_line_before_it_starts(disks300_file, monkeypatch, capsys):
    monkeypatch.setattr(budget, "branch_seconds", lambda n, stack=4, lowrank=False: 2 * budget.ASK_SECONDS)
    monkeypatch.setattr(lowrank, "solve_branches_lowrank", _stop)
    assert main(["analyze", str(disks300_file), "--metric", "L", "--json"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1
    assert "give --timeout" in err and "--method sparse" in err and "work started" not in err


def test_a_non_interactive_run_prints_heartbeats_and_keeps_json_clean(disks300_file, monkeypatch, capsys):
    """stderr is not a terminal under capsys: no bar, a heartbeat line (interval set small here) with the stage."""
    monkeypatch.setattr(progress, "HEARTBEAT_FIRST", 0.2)
    monkeypatch.setattr(progress, "HEARTBEAT_EVERY", 0.2)
    slow = lowrank.solve_branches_lowrank

    def slowed(*args, **kwargs):                                  # at least a few heartbeats long on any machine
        time.sleep(0.7)
        return slow(*args, **kwargs)

    monkeypatch.setattr(lowrank, "solve_branches_lowrank", slowed)
    assert main(["analyze", str(disks300_file), "--metric", "L", "--json", "--timeout", "600"]) == 0
    out, err = capsys.readouterr()
    data = json.loads(out)                                        # stdout: the JSON result alone
    assert data["cost"]["paths"]["low_rank"] == 4
    beats = [line for line in err.splitlines() if line.startswith(f"granstab: analyze {disks300_file}: ")]
    assert len(beats) >= 2 and beats == err.splitlines()
    assert any("branches, metric L (" in line and "of 4)" in line for line in beats)


def test_timeout_stops_the_threaded_low_rank_branches(disks300, monkeypatch):
    """--timeout's deadline stops the low-rank branches, which run in a thread pool: the chunks still queued are
    dropped, not solved. The deadline is set to fire 0.5 s after the first chunk starts (whatever the load)."""
    import signal
    calls = []
    stack = lowrank.branch_stack

    def slowly(*args, **kwargs):
        if not calls:
            signal.setitimer(signal.ITIMER_REAL, 0.5)             # re-arms --timeout's timer (process-wide)
        calls.append(1)
        time.sleep(0.5)
        return stack(*args, **kwargs)

    monkeypatch.setattr(lowrank, "branch_stack", slowly)
    scene = random_packing(2, 300, n_sliding=5, seed=1)          # 32 branches, one a chunk
    with pytest.raises(budget.OverBudget, match="stopped after --timeout"):
        with budget.deadline(600, scene.source, ["advice"]):
            granstab.analyze(scene, metric="L")
    time.sleep(2.0)                                               # chunks still queued would run now
    assert 0 < len(calls) < 32


def test_tiny_timeout_is_one_line_and_a_nonzero_exit(disks300_file, monkeypatch, capsys):
    monkeypatch.setattr(budget, "branch_seconds", lambda n, stack=4, lowrank=False: 0.0)   # not refused up front
    monkeypatch.setattr(threads, "slowdown", lambda: 1.0)   # nor by the plan's overhead scaled by this machine's load
    assert main(["analyze", str(disks300_file), "--metric", "L", "--json", "--timeout", "0.05"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and "stopped after --timeout 0.05 s" in err


def test_a_3000_disk_chain_is_solved_and_says_where_it_is(tmp_path, monkeypatch, capsys):
    """The held-out floppy zig-zag chain (9,000 dofs: the sparse path; 2,773 clustered negative eigenvalues below
    the default shift, on which the Lanczos estimate of λ_min stalled past --timeout on main) is solved by spectrum
    slicing (sparse._slice: bisection on the shift by inertia counts, one LU each) and proven unstable, its lowest
    eigenvalues inertia-verified. Each LU is slowed here so that the run outlasts the heartbeat's first wait
    whatever the machine: the heartbeat lines name the sparse path, and --json stays clean on stdout."""
    from granstab.model.packings import chain
    from granstab.solve import sparse
    path = tmp_path / "chain.npz"
    granstab.save_scene(chain(2, 3000, zigzag=0.3), path)
    monkeypatch.setattr(progress, "HEARTBEAT_FIRST", 0.2)
    monkeypatch.setattr(progress, "HEARTBEAT_EVERY", 0.2)
    factor = sparse.factor
    monkeypatch.setattr(sparse, "factor", lambda sp_, sigma: (time.sleep(0.05), factor(sp_, sigma))[1])
    assert main(["analyze", str(path), "--metric", "L", "--json", "--timeout", "300"]) == 0
    out, err = capsys.readouterr()
    data = json.loads(out)
    assert data["summary"]["verdict"] == "unstable" and data["summary"]["sufficient"] is True
    lam = np.array(data["branches"][0]["stability_eigenvalues"])
    assert lam.min() < -np.array(data["branches"][0]["accuracy"]).max()     # a negative eigenvalue, resolved
    lines = err.strip().splitlines()
    assert lines and all(line.startswith(f"granstab: analyze {path}: ") for line in lines)
    assert any("(sparse)" in line for line in lines)


def test_the_3d_chain_is_sliced_too():
    """A 3D zig-zag chain of 1,000 spheres (6,000 dofs, shift-invert): the same slicing, proven unstable, the lowest
    modes inertia-verified (the 3,000-sphere chain: the same in 7-13 s at load 11-18, docs/cli.md)."""
    from granstab.model.packings import chain
    from granstab.solve import sparse
    sc = chain(3, 1000, zigzag=0.3)
    modes = sparse.lowest_modes(sparse.sparse_problem(sc), k=6)
    assert modes.verified and modes.method == "shift-invert" and modes.eigenvalues.max() < 0
    res = granstab.analyze(sc, metric="L", method="sparse")
    assert res.summary["verdict"] == "unstable" and res.summary["sufficient"] is True


def test_a_thousand_disks_on_the_sparse_path_are_refused_before_work(tmp_path, capsys):
    """Issue 26's goal: an analyze of ≤ 10³ particles finishes in ≤ 10 s or refuses in one line before work starts.
    1,024 disks with 10 contacts at yield (3,072 dofs: the sparse path, 1,024 branches) took 386 s with the default
    family and never refused, since only the dense path was estimated; budget.sparse_estimate now says about 420 s
    (3 metrics: 10L's Ritz updates redone by ARPACK, budget.RITZ_FALLBACK) and 53 s (--metric L alone: Ritz updates, issue 38's model), and the CLI refuses both without
    --timeout, before any work. The measured times are the calibration machine's: the estimate is compared
    without this machine's speed factor (budget.speed), within the promise of 3× either way."""
    path = granstab.save_scene(random_packing(2, 1000, n_sliding=10, seed=1), tmp_path / "disks.json")
    for extra, metrics in ((["--metric", "family"], 3), (["--metric", "L"], 1)):   # refused before work (the
        # default plan, no option given, is fitted to the budget instead: test_fit.py)
        assert main(["analyze", str(path), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and f"refused: 1024 branches × {metrics} metric(s) of 3072 dofs (sparse path)" in err
    n, branches = 3072, 1024                            # the estimate against the measured, within the stated band
    there = budget.speed()
    assert 1 / 3 <= budget.sparse_estimate(n, branches, 3, n_sliding=10) / there / 386.0 <= 3.0
    assert 1 / 3 <= budget.sparse_estimate(n, branches, 1, n_sliding=10) / there / 51.0 <= 3.0


@pytest.fixture
def small_file(tmp_path):
    path = tmp_path / "small.json"
    granstab.save_scene(random_packing(2, 40, n_sliding=2, seed=1), path)    # 4 branches, 0.1 s in all
    return path


def _priced(monkeypatch, per_metric: float, often: float = 60.0):
    """Every plan estimated `per_metric` s a metric (at rest and now; whatever its path and branches)."""
    from dataclasses import replace

    from granstab.solve import plan as plan_module
    monkeypatch.setattr(plan_module, "_estimated", lambda p, k, rest=False: replace(
        p, estimated_s=per_metric * len(p.metrics), parts={"branches": per_metric * len(p.metrics)},
        one_metric_s=per_metric))


def test_the_cheapest_default_plan_within_90_s_runs_unasked_with_a_line_and_a_heartbeat(small_file, monkeypatch,
                                                                                       capsys):
    """Issue 41's held-out check runs `granstab analyze FILE --json` without --timeout on a 2·10⁵-disk packing
    (about a minute). Over budget.ASK_SECONDS, where no reduction of the default plan fits it, its cheapest form
    (here L alone, 40 s estimated; the family 120 s) runs when estimated within RUN_UNASKED_SECONDS: ONE line on
    stderr up front with the estimate and --timeout (in the heartbeat's form: a check that allows heartbeat lines
    allows it), a heartbeat every UNASKED_HEARTBEAT s (set small here, the
    first line's wait and the minute's left long so that only the shorter period can give the lines), stdout the JSON alone; the result
    says it was run unasked and what it left out. At 100 s a metric it is refused up front as before."""
    import granstab.cli as cli
    _priced(monkeypatch, 40.0)
    monkeypatch.setattr(progress, "HEARTBEAT_FIRST", 600.0)
    monkeypatch.setattr(progress, "HEARTBEAT_EVERY", 600.0)
    monkeypatch.setattr(cli, "UNASKED_HEARTBEAT", 0.15)
    run = cli.analyze
    monkeypatch.setattr(cli, "analyze", lambda *a, **kw: (time.sleep(1.0), run(*a, **kw))[1])
    assert main(["analyze", str(small_file), "--json"]) == 0
    out, err = capsys.readouterr()
    data = json.loads(out)
    assert data["cost"]["metric_names"] == ["L"] and data["cost"]["fitted"]["unasked"] is True
    assert data["cost"]["estimated_s"] == 40.0 and any("L/10, 10L of the family" in w for w in data["cost"]["left_out"])
    lines = err.splitlines()                               # every line in the heartbeat's form, the first says why
    assert all(line.startswith(f"granstab: analyze {small_file}: ") for line in lines)
    assert "estimated 40 s on this machine now" in lines[0] and "--timeout S" in lines[0]
    assert sum("--timeout" in line for line in lines) == 1
    assert len(lines) >= 4                                 # 1 s of work, a line every 0.15 s
    assert main(["analyze", str(small_file), "--plan"]) == 0           # --plan says so, runs nothing
    out = capsys.readouterr().out
    assert "branches: 4 per metric (all) × 1 metric(s): L" in out and "nothing cheaper fits the 10 s" in out
    assert "the full analysis needs about 120 s: run it with --timeout 144" in out
    _priced(monkeypatch, 100.0)
    assert main(["analyze", str(small_file), "--json"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and "refused" in err and "give --timeout" in err


def test_a_heartbeat_made_more_frequent_wakes_at_once():
    """`often` shortens the wait already under way: the minute's second line comes at the new period."""
    import io
    stream = io.StringIO()
    with progress.Heartbeat("x", stream=stream) as beat:
        beat.often(0.1)
        time.sleep(0.45)
    assert 3 <= len(stream.getvalue().splitlines()) <= 5
