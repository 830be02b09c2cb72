"""granstab.track.predict: the AUC against hand counts and a brute-force pair count, the block bootstrap's coverage
on a synthetic case of known AUC, NaN rows, the fixed targets, and `run` on a contract folder with planted answers."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import norm
from track_folder import EVENTS, N_FRAMES, WINDOW, write

from granstab.track import predict, scores


def brute_auc(score, label) -> float:
    """Every (positive, negative) pair counted by a double loop: 1 for a win, ½ for a tie."""
    pos, neg = score[label], score[~label]
    return sum(1.0 if p > q else 0.5 if p == q else 0.0 for p in pos for q in neg) / (len(pos) * len(neg))


def test_auc_hand_computed_cases():
    # the textbook four: pairs (0.35 > 0.1, 0.35 < 0.4, 0.8 > both) → 3 of 4
    assert predict.auc([0.1, 0.4, 0.35, 0.8], [0, 0, 1, 1]) == 0.75
    # with a tie: positives {2, 3}, negatives {1, 2}: 2>1, 2=2 (½), 3>1, 3>2 → 3.5 / 4
    assert predict.auc([1, 2, 2, 3], [0, 1, 0, 1]) == 0.875
    assert predict.auc([5, 5, 5], [0, 1, 0]) == 0.5                  # all tied: chance
    assert np.isnan(predict.auc([1, 2], [1, 1]))                     # one class empty


def test_block_interval_covers_the_true_auc():
    """Binormal scores (positives N(δ, 1), negatives N(0, 1): AUC = Φ(δ/√2)) with a shared random shift per frame
    and a per-frame share of positives, so that a frame's rows are correlated. Over 40 independent runs the 95 %
    block-bootstrap interval holds the true AUC at least 34 times (a binomial(40, 0.95) falls below 34 with
    probability ~1 %), and the interval is not trivially wide (below 0.25)."""
    delta, truth, held = 0.8, norm.cdf(0.8 / np.sqrt(2)), 0
    for rep in range(40):
        rng = np.random.default_rng(100 + rep)
        frames = 20
        share = rng.uniform(0.1, 0.4, frames)
        block = np.repeat(np.arange(frames), 150)
        label = rng.random(len(block)) < share[block]
        score = delta * label + rng.standard_normal(len(block)) + 0.3 * rng.standard_normal(frames)[block]
        r = scores.with_intervals(score, label, block, n_boot=500, seed=rep)
        held += r["auc_ci_low"] <= truth <= r["auc_ci_high"]
        assert r["auc_ci_high"] - r["auc_ci_low"] < 0.25
    assert held >= 34, held


def test_nan_scores_are_left_out_and_counted():
    score = np.array([np.nan, 0.2, 0.9, np.nan, 0.1, 0.7])
    label = np.array([1, 0, 1, 0, 0, 1], bool)
    r = scores.with_intervals(score, label, np.arange(6))
    assert r["n"] == 4 and r["n_positive"] == 2
    assert r["auc"] == brute_auc(score[[1, 2, 4, 5]], label[[1, 2, 4, 5]]) == 1.0
    assert r["auc_ci_low"] is None and "too few events" in r["note"]            # 2 positive blocks < MIN_EVENTS
    empty = scores.with_intervals(np.full(3, np.nan), np.array([1, 0, 1], bool), np.arange(3))
    assert empty["n"] == 0 and empty["auc"] is None


def test_targets_top_tenth_per_frame_and_events_in_the_window():
    d2 = np.concatenate([np.arange(20.0), np.arange(10.0), [np.nan, np.nan]])
    pos = np.array([0] * 20 + [1] * 10 + [2, 2])
    changed = np.zeros(32)
    changed[0] = 1
    t = predict.particle_targets(pos, d2, changed)
    # frame 0: the 0.9 quantile of 0..19 is 17.1 → 18, 19; frame 1: of 0..9 is 8.1 → 9; frame 2 has no window
    assert np.flatnonzero(t["d2min_top10"]).tolist() == [18, 19, 29]
    assert np.flatnonzero(t["rearranges"]).tolist() == [0, 18, 19, 29]
    assert t["valid"].sum() == 30
    label, valid = predict.event_target(6, 2, np.array([3]))
    assert label.tolist() == [False, True, True, False, False, False]   # 3 in (t, t+2] for t = 1, 2
    assert valid.tolist() == [True, True, True, True, False, False]


def test_lead_times_count_the_unstable_run_before_each_event():
    lam = np.array([1.0, -0.1, -0.2, 0.5, 0.4, -0.3, 0.2])
    n_negative = np.array([0, 0, 1, 0, 0, 0, 0])                       # only frame 2 is proven unstable
    steps = 100 * np.arange(7)
    lt = predict.lead_times(lam, n_negative, steps, np.array([2, 5]))
    assert [e["lead_frames_negative"] for e in lt["events"]] == [2, 1]
    # steps from the first unstable frame to the frame the event ends at: frames × steps per frame (issue 39:
    # lead_frames_proven 1 had lead_steps_proven 0)
    assert [e["lead_steps_negative"] for e in lt["events"]] == [200, 100]
    assert [e["lead_frames_proven"] for e in lt["events"]] == [1, 0]
    assert [e["lead_steps_proven"] for e in lt["events"]] == [100, 0]
    assert lt["unstable_frame_rate"] == {"negative": pytest.approx(3 / 7), "proven": pytest.approx(1 / 7)}
    assert lt["frames_to_next_event"] == [2, 1, 0, 2, 1, 0, -1]
    # Spearman's ρ of λ_min against the frames to the next event, over frames 0..5 (frame 6 has none)
    from scipy.stats import spearmanr
    assert lt["spearman_rho"] == pytest.approx(spearmanr(lam[:6], [2, 1, 0, 2, 1, 0])[0], abs=1e-12)
    assert "proven" not in predict.lead_times(lam, np.full(7, -1), steps, np.array([2]))["readings"]   # the fill


def test_every_frame_predictor_has_leads_against_its_base_rate():
    """8 frames, events starting at 3 and 7. stress_ratio (larger: more likely): its top quarter (>= the 0.75
    quantile 0.4) is frames 2, 3 (0.7, 0.9): the event at 3 has lead 2, at 7 (0.1) none; base rate 2/8, so
    independent frames would lead a quarter of the events and a mean of (1/4)/(3/4) = 1/3 frame. z is negated
    (fewer contacts: more likely). n_negative_loading is mostly 0: it signals only where positive (frame 7)."""
    by_name = {"stress_ratio": np.array([0.1, 0.2, 0.7, 0.9, 0.3, 0.2, 0.1, 0.1]),
               "z": np.array([4.0, 4.0, 4.0, 3.0, 4.0, 4.0, 4.0, 4.0]),
               "n_negative_loading": np.array([0, 0, 0, 0, 0, 0, 0, 2.0])}
    got = predict.predictor_leads(by_name, np.array([3, 7]))
    s = got["stress_ratio"]
    assert s["leads"] == [2, 0] and s["share_led"] == 0.5 and s["mean_lead"] == 1.0
    assert s["base_rate"] == 0.25 and s["null_share_led"] == 0.25
    assert s["null_mean_lead"] == pytest.approx(1 / 3, abs=1e-15)
    assert got["z"]["leads"] == [1, 0] and got["z"]["base_rate"] == 1 / 8        # only frame 3 (z = 3) signals
    assert got["n_negative_loading"]["leads"] == [0, 1] and got["n_negative_loading"]["base_rate"] == 1 / 8
    assert predict.predictor_leads(by_name, np.array([], int)) == {}


def test_run_on_a_contract_folder_finds_the_planted_answers(tmp_path, monkeypatch):
    truth = write(tmp_path)
    monkeypatch.setattr(scores, "frame_block", lambda n: 1)     # single frames: 24 blocks, intervals printed
    result = predict.run(tmp_path)
    rows = {(r["target"], r["predictor"]): r for r in json.loads((tmp_path / "prediction.json").read_text())}
    planted = rows[("d2min_top10", "unstable_fraction")]
    # 64 particles x (24 − W) frames with a window; the planted movers (15 %) fill the top 10 % of D²min
    assert planted["n"] == 64 * (N_FRAMES - WINDOW) and planted["auc"] > 0.9 and planted["auc_ci_low"] > 0.85
    assert rows[("d2min_top10", "cluster_lambda_min")]["auc"] == planted["auc"]    # −λ = unstable: negated
    assert rows[("d2min_top10", "random")]["auc_ci_low"] < 0.5 < rows[("d2min_top10", "random")]["auc_ci_high"]
    assert ("d2min_top10", "soft_participation") not in rows                      # all NaN: not computed
    assert ("event", "n_negative_unloading") not in rows                          # the fill −1: not computed
    assert "soft_participation" in result["verdict"]
    # the event target over the frames whose window is inside the run; λ_min counted independently
    ev = rows[("event", "lambda_min_loading")]
    import pyarrow.parquet as pq
    lam = pq.read_table(tmp_path / "frames.parquet").column("lambda_min_loading").to_numpy()
    t = np.arange(N_FRAMES - WINDOW)
    label = np.array([any(t0 < e + 1 <= t0 + WINDOW for e in EVENTS) for t0 in t])
    assert ev["n"] == len(t) and ev["n_positive"] == label.sum() == 2 * len(EVENTS)
    assert ev["auc"] == pytest.approx(brute_auc(-lam[t], label), abs=1e-15)
    lead = result["lead"]["loading"]
    assert [e["lead_frames_negative"] for e in lead["events"]] == [1, 1, 1]       # λ < 0 exactly at each event
    assert [e["lead_frames_proven"] for e in lead["events"]] == [1, 1, 1]         # n_negative_loading = (λ < 0)
    text = (tmp_path / "prediction.txt").read_text()
    assert truth["movers"].mean() > predict.TOP_FRACTION and "event (6 of 22 positive)" in text
    assert f"proven at 3 of {N_FRAMES} frames (frames {', '.join(map(str, EVENTS))})" in text
    assert f"hinging on an S within the tolerance at frames {EVENTS[1]}" in text
    for name in ("soft_spots_frictionless", "soft_spots_branch", "d2min_previous", "softness"):
        assert f"  {name}: " in text                                                # the definitions
    # every row: the three metrics; 6 events < MIN_EVENTS: the event rows' intervals are null with the note
    for r in rows.values():
        assert {"auc", "ap", "precision_top5", "n", "n_positive", "n_events"} <= r.keys() and r["n_events"] == 6
        for m in ("auc", "ap", "precision_top5"):
            assert (r[f"{m}_ci_low"] is None) == (r[f"{m}_ci_high"] is None)
            if r[f"{m}_ci_low"] is not None:
                assert r[f"{m}_ci_low"] <= r[m] <= r[f"{m}_ci_high"]
    assert ev["auc_ci_low"] is None and ev["note"].startswith("too few events")
    prev = rows[("d2min_top10", "d2min_previous")]
    assert prev["n"] == 64 * (N_FRAMES - 2 * WINDOW)                                 # the first W frames have none


def test_roc_curve_area_is_the_auc():
    rng = np.random.default_rng(5)
    score = rng.integers(0, 8, 200).astype(float)                   # ties: each distinct score one step
    label = rng.random(200) < 0.4
    fpr, tpr = predict.roc_curve(score, label)
    assert fpr[0] == tpr[0] == 0 and fpr[-1] == tpr[-1] == 1 and len(fpr) == len(np.unique(score)) + 1
    assert np.all(np.diff(fpr) >= 0) and np.all(np.diff(tpr) >= 0)
    assert np.sum(np.diff(fpr) * (tpr[1:] + tpr[:-1]) / 2) == pytest.approx(brute_auc(score, label), abs=1e-12)


def test_the_whole_row_says_why_a_verdict_is_not_determined_and_whether_it_hinges():
    """A verdict that is not a proof reads `not determined because <gaps>: <reason>`, with whole_proven 0 and the
    hinges_on_tolerance flag carried; a proof keeps its reason and whole_proven 1."""
    from types import SimpleNamespace

    from helpers import random_cluster, scene

    import granstab
    from granstab.track.frame import WHOLE, whole_row
    res = granstab.analyze(scene(random_cluster(2, 4, seed=1)), k=6, **WHOLE)
    assert whole_row(res)["whole_reason"] == (res.verdict.reason if res.verdict.sufficient else
                                              "not determined because " + ", ".join(res.verdict.insufficient_because)
                                              + ": " + res.verdict.reason)
    weak = res.verdict.weaker(("unresolved_sign",), "; S within tolerance", hinges_on_tolerance=True)
    row = whole_row(SimpleNamespace(verdict=weak, backend="dense"))
    assert row["whole_reason"].startswith("not determined because ") and "unresolved_sign" in row["whole_reason"]
    assert row["whole_proven"] == 0 and row["whole_hinges_on_tolerance"] == 1 and row["whole_method"] == "dense"


def test_per_particle_intervals_resample_contiguous_frame_blocks_or_say_too_few_frames(tmp_path):
    """Per-particle targets resample runs of ⌈F^(1/3)⌉ contiguous frames (scores.frame_block: 3 of the 24 frames
    here, so 8 blocks): fewer than MIN_EVENTS blocks hold a positive, so no interval is printed and the note says
    too few frames; the event rows keep their own note."""
    write(tmp_path)
    assert [scores.frame_block(n) for n in (20, 24, 40, 200)] == [3, 3, 4, 6]
    predict.run(tmp_path)
    rows = json.loads((tmp_path / "prediction.json").read_text())
    particle = [r for r in rows if r["target"] != "event"]
    assert particle and all(r["auc_ci_low"] is None for r in particle)
    notes = {r["note"].split(" (")[0] for r in particle}
    assert "too few frames for a calibrated interval" in notes <= {"too few frames for a calibrated interval",
                                                                   "one class is empty: no metric"}, notes
    assert all(r["note"].startswith("too few events") for r in rows if r["target"] == "event")
