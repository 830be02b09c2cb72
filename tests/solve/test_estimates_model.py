"""The cost model's pieces (issue 38: estimates within 3× on every path), without timing anything: the machine's
speed (budget.speed) and load (threads.runnable) are fixed here, so that only the model is tested. The measured
numbers the model is held to are BENCHMARKS.md's and budget.py's calibration notes (CPU time, this machine)."""
import numpy as np
import pytest
from helpers import DATA

import granstab
from granstab.model.packings import random_packing
from granstab.solve import budget, threads
from granstab.solve.plan import plan

PROMISE = 3.0


@pytest.fixture
def at_rest(monkeypatch):
    """The calibration machine, every core free: the estimate is the model alone."""
    monkeypatch.setattr(budget, "speed", lambda: 1.0)
    monkeypatch.setattr(threads, "runnable", lambda fresh=False: 0.0)
    monkeypatch.setattr(threads, "slowdown", lambda: 1.0)


@pytest.fixture(scope="module")
def disks1400():
    return random_packing(2, 1400, n_sliding=6, seed=4)       # 4,107 dofs, 64 branches: the sparse family case


def test_a_family_metric_whose_ritz_updates_fall_back_is_counted_as_arpack(at_rest, disks1400):
    """The issue's sparse metric family, 3.3× over its estimate: each metric after L counted a fixed 3.5 L's, but
    10L's Ritz updates do not converge and 63 of its 64 branches are solved again by ARPACK (measured: 10L 41.1 s
    of CPU time against L's 4.66 s, 8.8×; L/10 0.6-1.1 L's). The plan of 10L alone must be within 3× of 8.8 L's
    (the old model: 0.88 L's, since L/10 and 10L were priced alike and below L)."""
    L, ten = plan(disks1400, metric="L"), plan(disks1400, metric="10L")
    assert L.path == ten.path == "sparse" and L.n_branches == 64
    assert 8.8 / PROMISE <= ten.estimated_s / L.estimated_s <= 8.8 * PROMISE
    tenth = plan(disks1400, metric="L/10")
    assert 1 / PROMISE <= tenth.estimated_s / L.estimated_s <= PROMISE
    fam = plan(disks1400)                                    # the family's parts name the fall-back
    assert fam.parts["fallback"] == pytest.approx(63 * budget.ARPACK_BRANCH_PER_DOF * 4107, rel=1e-12)


def test_the_sparse_family_estimate_holds_against_its_measured_cpu_time(at_rest, disks1400):
    """The family's estimate (L, L/10, 10L one by one) against the measured CPU time of its three runs, 4.66 + 4.3
    (L/10, about an L) + 41.1 s, within 3× either way."""
    assert 1 / PROMISE <= plan(disks1400).estimated_s / (4.66 + 4.3 + 41.1) <= PROMISE


def test_the_fall_back_is_counted_only_where_ritz_runs(at_rest):
    """RITZ_FALLBACK prices Ritz updates redone by ARPACK: where the Ritz basis does not fit (hundreds of sliding
    contacts, sampled branches: every branch a shift-invert solve already) or there is one branch (the elastic solve
    alone), 10L costs what L does; on the Ritz path it costs L plus (branches - 1) ARPACK solves."""
    n = 4107
    for branches, Ms in ((10, 300), (1, 0)):
        ten, L = budget.sparse_parts(n, branches, "10L", Ms), budget.sparse_parts(n, branches, "L", Ms)
        assert "fallback" not in ten and ten == L
    ten, L = budget.sparse_parts(n, 64, "10L", 6), budget.sparse_parts(n, 64, "L", 6)
    assert L["fallback"] == 0 and ten["fallback"] == pytest.approx(63 * budget.ARPACK_BRANCH_PER_DOF * n)
    assert {k: v for k, v in ten.items() if k != "fallback"} == {k: v for k, v in L.items() if k != "fallback"}


def test_the_estimate_follows_the_load_and_the_free_cores(monkeypatch, disks1400):
    """Beside two busy processes on 2 cores the plan has 1 free core and every part takes 1.5× (threads.slowdown):
    the estimate follows the load as the measured time does."""
    monkeypatch.setattr(budget, "speed", lambda: 1.0)
    monkeypatch.setattr(threads, "cores", lambda: 2)
    monkeypatch.setattr(threads, "SAMPLE_GAP", 0.0)
    monkeypatch.setattr(threads, "ready", lambda: [])
    monkeypatch.setattr(threads, "_runnable_cache", [-1.0, 0.0, 1.0])   # not a read made by a test just before (the
    monkeypatch.setattr(threads, "_fresh_at", [-1.0])                    # real load; under xdist: 1 free core of 2)
    rest = plan(disks1400, metric="L")
    monkeypatch.setattr(threads, "ready", lambda: [(1, "session a"), (2, "session b")])
    monkeypatch.setattr(threads, "_fresh_at", [-1.0])          # the next plan over FRESH_SECONDS later: read afresh
    busy = plan(disks1400, metric="L")
    assert rest.workers == 2 and busy.workers == 1
    assert busy.estimated_s == pytest.approx(1.5 * rest.estimated_s, rel=1e-12)


def test_a_fresh_load_read_is_the_mean_of_several_scans(monkeypatch):
    """One scan of /proc sees the threads ready at that instant; a plan's fresh read averages FRESH_SAMPLES scans
    (here 1, 3, 0, 2, 4 ready threads: 2.0), the BLAS policy's cached read takes one."""
    seen = iter([[(i, f"s{i}") for i in range(n)] for n in (1, 3, 0, 2, 4, 7)])
    monkeypatch.setattr(threads, "ready", lambda: next(seen))
    monkeypatch.setattr(threads, "SAMPLE_GAP", 0.0)
    monkeypatch.setattr(threads, "_runnable_cache", [-1.0, 0.0])
    assert threads.FRESH_SAMPLES == 5 and threads.runnable(fresh=True) == 2.0
    assert threads.runnable() == 2.0                          # within RUNNABLE_SECONDS: the cached read
    monkeypatch.setattr(threads, "_runnable_cache", [-1.0, 0.0])
    assert threads.runnable() == 7.0                          # a stale cache: one scan


def test_a_fresh_load_read_is_reused_for_a_second(monkeypatch):
    """Issue 36: a plan reads the load fresh three times and the explorer's pair moves several times a second; each
    fresh read scanned /proc FRESH_SAMPLES times (0.3 s a move at load 6, for a 0.02 s analysis). A fresh read within
    FRESH_SECONDS of the last one, with nothing read since, is that one; once the cache is stale (or another read
    came between) it scans again."""
    scans = []
    monkeypatch.setattr(threads, "ready", lambda: scans.append(1) or [(1, "s1"), (2, "s2")])
    monkeypatch.setattr(threads, "SAMPLE_GAP", 0.0)
    monkeypatch.setattr(threads, "_runnable_cache", [-1.0, 0.0, 1.0])
    assert threads.runnable(fresh=True) == 2.0 and len(scans) == threads.FRESH_SAMPLES
    assert threads.runnable(fresh=True) == 2.0 and len(scans) == threads.FRESH_SAMPLES     # reused
    monkeypatch.setattr(threads, "_fresh_at", [threads._fresh_at[0] - threads.FRESH_SECONDS])   # a second later
    assert threads.runnable(fresh=True) == 2.0 and len(scans) == 2 * threads.FRESH_SAMPLES


def test_the_slowdown_follows_the_scheduling_groups():
    """CFS shares the cores between groups (sessions: autogroups) first. Alone: 1. Threads each in a group of their
    own: (ready + 1) / cores, as before. Two busy processes in this session beside five other busy sessions on 2
    cores: the session's third of a core split three ways, 9, three times the 3 at rest (measured: 3.4× the time at
    rest; the count of ready threads said (10 + 1) / (7 + 1) = 1.4×). A group that cannot use its share leaves the
    rest to the others (filled from the smallest)."""
    me = "me"
    assert threads.group_slowdown([], me, 2) == 1.0
    assert threads.group_slowdown(["a", "b", "c"], me, 2) == 2.0
    others = ["a", "b", "c", "d", "e"]
    rest = threads.group_slowdown(others, me, 2)
    assert rest == pytest.approx(3.0) and threads.group_slowdown(others + [me, me], me, 2) == pytest.approx(9.0)
    assert threads.group_slowdown([me, me], me, 2) == pytest.approx(1.5)
    assert threads.group_slowdown(["a", "a", "a", "a"], me, 2) == 1.0       # one other session: a core each


@pytest.fixture(scope="module")
def sheared():
    """Frame 23 of the sheared 1,400-disk periodic LAMMPS run (examples/track/in.shear2d_track, n 1400;
    benchmarks/estimates.sheared_frame): 4,101 dofs, 85 contacts at yield."""
    return granstab.load_scene(DATA / "solve" / "sheared1400_frame23.npz")


def test_the_ritz_path_of_many_sliding_contacts_is_predicted_by_the_plan(at_rest, sheared):
    """Issue 38: `--sample-branches 8 --metric L` on the sheared frame ran 10.4× its estimate: the model took the
    Ritz basis for 355 columns (k + 9 + 4 Ms) and every branch for a Ritz update, where the basis was 792 columns
    and 6 of the 10 branches had kk = 7 or more eigenvalues below σ, so that no Ritz update could be accepted and
    shift-invert solved each with kk + ν pairs. The plan now predicts the width within 25% and counts each
    branch's ν before the run (plan.probe), equal to what the run's SparseRitz finds for the same masks; its
    estimate is within 3× of the run's measured CPU time (18.1 s, 2026-11-29, this machine, since ritz.py sends
    those branches straight to shift-invert; 34.8 s before)."""
    from granstab.mechanics.branches import sample_masks
    from granstab.mechanics.metric import resolve
    from granstab.solve.ritz import SparseRitz
    from granstab.solve.sparse import sparse_problem
    p = plan(sheared, metric="L", sample_branches=8)
    assert p.path == "sparse" and p.n_sliding == 85 and p.n_branches == 10
    masks = sample_masks(np.flatnonzero(sheared.at_yield()), sheared.n_contacts, 8, 0)    # analyze's, seed 0
    spb = sparse_problem(sheared, metric=resolve(sheared, "L"))
    ritz = SparseRitz(spb, 7)
    on = masks[:, spb.sliding] == 1
    assert list(p.below["L"]) == [ritz.below(o) for o in on]                  # the run's counts, exactly
    nu = np.array(p.below["L"])
    assert np.sum(nu >= 7) == 6                                               # straight to shift-invert
    width = budget.ritz_width(p.n_dof, 85, 7)
    assert abs(width / ritz.W.shape[1] - 1) <= 0.25 and ritz.W.shape[1] > 1.5 * (7 + 8 + 4 * 85)
    assert p.parts["direct"] == pytest.approx(np.sum((7 + nu) * (nu >= 7)) * p.n_dof
                                          * (budget.ARPACK_PAIR_DOF + budget.ARPACK_PAIR_COLUMN * (6 + 85)))
    assert 1 / PROMISE <= p.estimated_s / 18.1 <= PROMISE



def test_no_ritz_basis_is_built_where_every_branch_goes_to_shift_invert(monkeypatch):
    """Leave out work the scene does not need: a branch with kk = k + 1 or more eigenvalues below σ cannot be a Ritz
    update (ritz.SparseRitz.modes). Where that holds for every branch (here 8 sampled branches of 192 dofs with 12-17
    below σ, probed by the plan) no basis is built (its width grows by ~8.5 columns a sliding contact:
    budget.ritz_width) and every branch is a shift-invert solve with the shared factor, as where the Ritz problem
    does not fit (budget.RITZ_BYTES: the same eigenvalues within both bounds); where some branch can use it
    (forces a third as large: ν 0-3), the basis is built once. The estimate leaves it out too ("ritz" 0)."""
    from granstab.solve import ritz
    builds, sym_updates = [], ritz.sym_updates
    monkeypatch.setattr(ritz, "sym_updates", lambda *a: builds.append(1) or sym_updates(*a))   # once a basis
    options = {"metric": "L", "method": "sparse", "k": 6, "max_sliding": 6, "sample_branches": 6}
    crushed = random_packing(2, 60, n_sliding=7, mobilised=0.3, f_over_k=0.3, curvature_ratio=0.2, seed=1)
    p = plan(crushed, **options)
    assert p.n_branches == 8 and min(p.below["L"]) >= 7 and p.parts["ritz"] == 0 and p.parts["direct"] > 0
    res = granstab.analyze(crushed, **options)
    assert builds == [] and len(res.branches) == 8
    monkeypatch.setattr(budget, "RITZ_BYTES", 0)
    direct = granstab.analyze(crushed, **options)
    for a, b in zip(res.branches, direct.branches):
        bound = 1e-10 * np.abs(a.stability_eigenvalues).max()      # both verified to 1e-12 ‖Hs‖
        assert np.allclose(a.stability_eigenvalues, b.stability_eigenvalues, rtol=0, atol=bound)
    monkeypatch.undo()
    monkeypatch.setattr(ritz, "sym_updates", lambda *a: builds.append(1) or sym_updates(*a))
    firm = random_packing(2, 60, n_sliding=7, mobilised=0.3, f_over_k=0.1, curvature_ratio=0.2, seed=1)
    assert plan(firm, **options).parts["ritz"] > 0
    granstab.analyze(firm, **options)
    assert builds == [1]


def _scene_3d(name: str):
    """A 3D random packing "random N MS SEED", or the fixture frame of a sheared periodic 3D LAMMPS run (386 spheres,
    2,316 dofs, 20 of its 109 contacts at yield, the rest stated elastic: benchmarks/estimates.ritz_3d)."""
    if name == "periodic":
        return granstab.load_scene(DATA / "solve" / "sheared3d_386_frame.npz")
    n, Ms, seed = map(int, name.split()[1:])
    return random_packing(3, n, n_sliding=Ms, seed=seed)


@pytest.mark.parametrize("name,options,cpu", [
    ("random 100 4 11", {}, 0.71),                                     # 648 dofs, 16 branches, 3.6 refinements each
    ("random 500 20 5", {"sample_branches": 6}, 3.72),                 # 3,000 dofs, 2.6
    ("random 500 60 13", {"sample_branches": 6}, 4.79),                # 3,000 dofs, 0.9
    ("periodic", {"sample_branches": 6}, 0.56)])                       # 2,316 dofs, 0
def test_the_3d_ritz_estimate_holds_against_measured_cpu_time(at_rest, name, options, cpu):
    """budget.RITZ_3D against the CPU time of 3D sparse runs (`--method sparse --metric L`, measured 2026-11-29 on
    this machine, load 9, niced; BENCHMARKS.md "estimates"), within 3× either way: their refinements a branch with
    ν = 0 were 0-3.6; the periodic frame's 0 was 0.23× its estimate at the old 2.5 refinements priced (0.37× at 1 and speed 1)."""
    p = plan(_scene_3d(name), method="sparse", metric="L", **options)
    assert p.path == "sparse" and p.parts["ritz"] > 0
    assert 1 / PROMISE <= cpu / p.estimated_s <= PROMISE
