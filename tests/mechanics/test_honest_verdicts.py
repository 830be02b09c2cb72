"""Issue 15: verdicts never claim more than the numbers prove — per-eigenvalue accuracy bounds decide sign against
zero (accuracy.py), `sufficient` is True only when every number is finite and resolved, every branch examined and
the verdict holds across the metric family; the sparse path labels its counts and proves "stable" only by inertia.
(The sharp pair at f/k = 1e-13 and 1e-14 is in test_extreme.py.)"""
import dataclasses
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

import granstab
from granstab.mechanics.branches import INCONSISTENT, RIGID, Branch
from granstab.mechanics.verdicts import summarize
from granstab.model.scene import SceneError

PRESETS = ROOT / "presets"


def scaled_forces(path: Path, factor: float) -> dict:
    """A contact-level scene with every contact force (and moment) × factor; loads re-derived (equilibrium)."""
    d = json.loads(path.read_text())
    for c in d["contacts"]:
        c["force"] = [factor * v for v in c["force"]]
        if "moment" in c:
            c["moment"] = (np.asarray(c["moment"], float) * factor).tolist()
    for p in d["particles"]:
        p.pop("load", None)
        p.pop("moment", None)
    return d


@pytest.mark.slow
def test_annulus_frame_with_forces_times_1e_8_stays_proven_unstable():
    """annulus_frame × 1e-8: its negative eigenvalues (≈ -1.5e-11, -1.4e-11, -1e-11) were all below the old zero
    threshold 64·n·ε·‖A‖ ≈ 6.7e-11 and the frame read 'neutral, sufficient'. Each is now resolved by its own bound
    (≈ 6.6e-12, from the residual and the separate scales of Hm and Hg): unstable like the unscaled frame, proven,
    zero_margin > 1."""
    ref = granstab.analyze(granstab.load_scene(PRESETS / "annulus_frame.json"), metric="L")
    res = granstab.analyze(granstab.scene_from_dict(scaled_forces(PRESETS / "annulus_frame.json", 1e-8)),
                           metric="L")
    assert ref.summary["verdict"] == res.summary["verdict"] == "unstable"
    assert res.summary["sufficient"] is True and res.summary["zero_margin"] > 1.0
    b = res.branches[0]
    n = b.stability_eigenvalues.size
    old_threshold = 64 * n * np.finfo(float).eps * np.abs(b.stability_eigenvalues).max()
    neg = b.stability_eigenvalues < -b.accuracy
    assert neg.sum() == 3 and res.summary["consistent_negative"] >= 1
    assert np.all(-b.stability_eigenvalues[neg] < old_threshold)          # all three were hidden before
    assert np.all(b.accuracy[neg] < 0.7 * np.abs(b.stability_eigenvalues[neg]))


def contact_free(n=30) -> granstab.Scene:
    return granstab.scene_from_dict({"dim": 2, "particles": [{"name": f"p{i}", "x": [1.5 * i, 0.0]}
                                                             for i in range(n)]}, source="free.toml")


def test_contact_free_scene_dense_is_proven_neutral():
    """H ≡ 0 exactly: every eigenvalue is exactly zero with a zero bound, so 'neutral' is proven (free particles move
    without work) — never 'unstable, sufficient' as the old ‖Hs‖-relative tolerance gave on the sparse path."""
    res = granstab.analyze(contact_free(), method="dense", metric="L")
    b = res.branches[0]
    assert np.all(b.stability_eigenvalues == 0) and np.all(b.accuracy == 0)
    assert res.summary["verdict"] == "neutral" and res.summary["sufficient"] is True
    assert b.n_zero == 90 and np.sum(b.codes == RIGID) == 3
    assert res.summary["consistent_zero"] == 1          # the zero eigenspace is searched once (Appendix D)


def test_contact_free_scene_sparse_is_not_unstable():
    """The sparse path's tolerances survive ‖Hs‖ = 0: its eigenvalues (Rayleigh quotients of the deflated operator,
    ~1e-35) sit inside their bounds, so the verdict is neutral and not proven, with the reason."""
    res = granstab.analyze(contact_free(), method="sparse", metric="L")
    assert res.summary["verdict"] == "neutral"
    assert res.summary["sufficient"] is False and "unresolved_sign" in res.summary["insufficient_because"]
    assert res.summary["consistent_negative"] == 0


def test_sparse_counts_are_labelled_and_become_totals_with_enough_k():
    """four_disk (16 branches, dense: 9 consistent negatives): with k = 1 the sparse counts are lower bounds
    (labelled, with a suggested k); with k = 12 every branch's negatives are computed, the negative count per
    branch equals the dense one and the consistent negatives are the dense total."""
    scene = granstab.load_scene(PRESETS / "four_disk.toml")
    dense = granstab.analyze(scene, metric="L", method="dense")
    dense_neg = [int(np.sum(b.stability_eigenvalues < -b.accuracy)) for b in dense.branches]
    low = granstab.analyze(scene, metric="L", method="sparse", k=1)
    assert low.summary["counts_are"]["consistent_negative"] == "lower bounds" and low.summary["suggest_k"] >= 2
    assert low.summary["consistent_negative"] <= dense.summary["consistent_negative"]
    assert all(b.negative_count["count"] <= n for b, n in zip(low.branches, dense_neg))
    full = granstab.analyze(scene, metric="L", method="sparse", k=12)
    assert set(full.summary["counts_are"].values()) == {"totals"}           # k = 12 >= 9 non-rigid: everything
    mid = granstab.analyze(scene, metric="L", method="sparse", k=5)
    assert mid.summary["counts_are"]["consistent_positive"] == "lower bounds"
    assert [b.negative_count["count"] for b in full.branches] == dense_neg
    assert all(b.negative_count["total"] for b in full.branches)
    assert full.summary["consistent_negative"] == dense.summary["consistent_negative"] == 9
    assert full.summary["verdict"] == "unstable" and full.summary["sufficient"] is True


def _branch(lam, codes, acc=1e-15):
    n = len(lam)
    return Branch(mask=np.zeros(1, np.int8), stability_eigenvalues=np.array(lam, float),
                  stability_vectors=np.eye(n), codes=np.array(codes, np.int8), hinges=np.zeros(n, bool), n_zero=0,
                  zero_tol=acc, uniqueness_eigenvalues=np.zeros(0, complex), uniqueness_n_zero=-1,
                  bounds=np.full(n, acc))


def test_partial_spectrum_with_an_inconsistent_lowest_mode_is_not_stable():
    """A sparse branch whose only computed eigenpair (k = 1) is negative and inconsistent: more negatives may exist
    beyond it, so the verdict is 'not determined' with a suggested k — never 'stable'. The same branch with a
    complete spectrum is 'stable' but not sufficient (an inconsistent negative proves nothing, Sec. 3.2)."""
    b = _branch([0.0, 0.0, 0.0, -0.3], [RIGID, RIGID, RIGID, INCONSISTENT])
    partial = summarize([b], {"complete": False, "suggest_k": 28})
    assert partial.verdict == "not determined" and partial.sufficient is False
    assert partial.insufficient_because == ("partial_spectrum",) and partial.suggest_k == 28
    assert "k >= 28" in partial.reason and partial.to_dict()["suggest_k"] == 28
    full = summarize([b], {"complete": True})
    assert full.verdict == "stable" and full.insufficient_because == ("inconsistent_negative",)
    assert "suggest_k" not in full.to_dict()


def test_overflow_is_never_a_proof():
    """Scene files with magnitudes beyond 1e50 are refused at reading (one line naming the field); a Scene built
    around those checks (dataclasses.replace) with forces and stiffness × 1e300 keeps H finite but overflows the
    error estimates → not sufficient, the reason says so; × 1e308 the stiffness itself overflows → SceneError."""
    d = tomllib.loads((PRESETS / "two_particle.toml").read_text())

    def scaled(s):
        return {**d, "defaults": {**d["defaults"], "k": s},
                "contacts": [{**c, "force": [s * v for v in c["force"]]} for c in d["contacts"]]}

    with pytest.raises(SceneError, match=r"big.toml: defaults: k: \|value\| = 1e\+300 exceeds 1e\+50"):
        granstab.scene_from_dict(scaled(1e300), source="big.toml")
    base = granstab.scene_from_dict(d, source="big.toml")

    def unchecked(s):
        return dataclasses.replace(base, k=base.k * s, force=base.force * s, load=base.load * s,
                                   load_moment=base.load_moment * s)

    with np.errstate(over="ignore"):
        res = granstab.analyze(unchecked(1e300))
        assert res.summary["sufficient"] is False and "non_finite" in res.summary["insufficient_because"]
        assert "not finite" in res.summary["reason"]
        with pytest.raises(SceneError, match="big.toml: the stiffness H has non-finite entries"):
            granstab.analyze(unchecked(1e308))
    ok = granstab.analyze(granstab.scene_from_dict(scaled(1e45), source="big.toml"))
    assert ok.summary["verdict"] == "unstable" and ok.summary["sufficient"] is True


def test_frame_in_micrometres_with_the_literal_metric_is_not_a_proof():
    """annulus_frame with lengths × 1e6 (µm; k, curvatures ÷ 1e6): with the default L (mean contact radius) nothing
    changes — unstable, 4 consistent negatives, proven. With --rotation-length 1 (the paper's literal metric, here
    10⁶ times smaller than the contact radius) the rotational eigenvalues drop below their accuracy bounds: the old
    code said 'neutral, sufficient'; now 'neutral' is not sufficient and says why."""
    d = json.loads((PRESETS / "annulus_frame.json").read_text())
    s = 1e6
    d["defaults"]["k"] /= s
    for p in d["particles"]:
        p["x"] = [s * v for v in p["x"]]
    for c in d["contacts"]:
        c["point"] = [s * v for v in c["point"]]
        for key in ("curvature_p", "curvature_q"):
            c[key] = (np.asarray(c[key]) / s).tolist()
    scene = granstab.scene_from_dict(d, source="frame_um.json")
    default = granstab.analyze(scene, metric="L")
    assert default.summary["verdict"] == "unstable" and default.summary["consistent_negative"] == 4
    assert default.summary["sufficient"] is True
    literal = granstab.analyze(scene, metric="L", rotation_length=1.0)
    assert literal.summary["sufficient"] is False
    assert "unresolved_sign" in literal.summary["insufficient_because"] and literal.summary["zero_margin"] < 1


def test_verdict_columns_equal_verdict_of_and_finalize_per_cluster():
    """The scan's vectorised verdicts (verdicts.verdict_columns: one evaluation per distinct input, spread) against
    verdict_of + finalize on every cluster alone, over every combination that changes the verdict or its proof:
    negative, zero and proven-zero counts, hinges, inconsistent or unresolved eigenvalues, non-finite numbers,
    undetermined rolling, non-finite error estimates; each field equal, margins each cluster's own."""
    from granstab.mechanics.verdicts import KEYED, finalize, verdict_columns, verdict_of
    rng = np.random.default_rng(15)
    n = 600
    zero = rng.integers(0, 3, n)
    counts = {"neg": rng.integers(0, 3, n) * (rng.random(n) < 0.4), "zero": zero,
              "proven_zero": np.minimum(zero, rng.integers(0, 3, n)), "pos": rng.integers(0, 40, n),
              **{k: rng.random(n) < 0.2 for k in ("hinge", "inconsistent_negative", "unresolved_other", "non_finite")},
              "margin": np.where(rng.random(n) < 0.3, np.inf, 10.0 ** rng.uniform(-2, 12, n))}
    n_branches, finite = 2 ** rng.integers(0, 4, n), rng.random(n) < 0.9
    undetermined = rng.integers(0, 2, n) * (rng.random(n) < 0.2)
    got = verdict_columns(counts, n_branches, finite, undetermined)
    assert len(np.unique(np.column_stack([counts[k] for k in KEYED]), axis=0)) > 50     # many distinct inputs
    for i in range(n):
        sm = verdict_of({k: v[i] for k, v in counts.items()}, None, n_branches=int(n_branches[i]))
        sm = finalize(sm, {"eigen_residual": 0.0 if finite[i] else np.nan, "rigid_leakage": 0.0},
                      int(undetermined[i]), None)
        for key in ("verdict", "sufficient", "reason", "consistent_negative", "consistent_positive"):
            assert got[key][i] == getattr(sm, key), (i, key)
        assert got["insufficient_because"][i] == ",".join(sm.insufficient_because)
        assert (np.isnan(got["zero_margin"][i]) if sm.zero_margin is None
                else got["zero_margin"][i] == sm.zero_margin)


def test_the_verdict_is_a_frozen_record_that_each_step_refines_into_a_new_one():
    """finalize, flag_undetermined and mark_partial return new Verdicts and leave their input as it was;
    `sufficient` is True exactly when nothing is listed in insufficient_because; to_dict is the JSON summary."""
    from granstab.mechanics.verdicts import finalize, flag_undetermined, mark_partial, verdict_of
    counts = {"neg": 1, "zero": 0, "proven_zero": 0, "pos": 5, "hinge": False, "inconsistent_negative": False,
              "unresolved_other": False, "non_finite": False, "margin": 3.0}
    first = verdict_of(counts, None, n_branches=4)
    before = first.to_dict()
    with pytest.raises(dataclasses.FrozenInstanceError):
        first.verdict = "stable"
    flagged = flag_undetermined(first, 2)
    assert first.to_dict() == before and first.sufficient and not flagged.sufficient
    assert flagged.insufficient_because == ("rolling_undetermined",) and flagged.hinges_on_tolerance
    assert flagged.reason.startswith(first.reason) and "2 loaded contact(s)" in flagged.reason
    done = finalize(first, {"eigen_residual": np.nan}, 0, None)
    assert done.insufficient_because == ("non_finite",) and "not finite" in done.reason
    assert first.to_dict() == before
    sampled = mark_partial(first, 10, 12)                       # a proven instability stands on a sample
    assert sampled.sufficient and sampled.branches == "partial" and "10 of the 2^12" in sampled.reason
    assert set(sampled.to_dict()["counts_are"].values()) == {"lower bounds"}
    assert set(first.to_dict()["counts_are"].values()) == {"totals"}
    weak = mark_partial(verdict_of({**counts, "neg": 0}, None, n_branches=4), 10, 12)
    assert weak.verdict == "stable" and weak.insufficient_because == ("unexamined_branches",)
    assert json.loads(json.dumps(done.to_dict(), allow_nan=False)) == done.to_dict()
