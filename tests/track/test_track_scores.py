"""granstab.track.scores: AUC, average precision and precision at the top 5 % against brute-force counts (and
scikit-learn where installed), a bootstrap resample equal to the metrics of its concatenated rows, and the
calibration of the intervals: over 400 seeds of a random score the 95 % AUC interval covers 0.5 in 93–97 % of them
at MIN_EVENTS events, and no interval is printed below it."""
from __future__ import annotations

import numpy as np
import pytest

from granstab.track import scores
from granstab_bench.calibration import coverage


def brute(score, label) -> dict:
    """AUC by a double loop over (positive, negative) pairs; AP as Σ_thresholds (R_n − R_{n−1}) P_n with each
    distinct score a threshold (counting rows with score ≥ t); precision of the first 5 % of rows."""
    pos, neg = score[label], score[~label]
    auc = sum(1.0 if p > q else 0.5 if p == q else 0.0 for p in pos for q in neg) / (len(pos) * len(neg))
    ap, recall = 0.0, 0.0
    for t in sorted(set(score.tolist()), reverse=True):
        chosen = score >= t
        tp = np.sum(chosen & label)
        ap += (tp / label.sum() - recall) * tp / chosen.sum()
        recall = tp / label.sum()
    return {"auc": auc, "ap": ap}


def test_metrics_equal_brute_force_counts_with_ties():
    rng = np.random.default_rng(3)
    score = rng.integers(0, 6, 300).astype(float)                    # many ties
    label = rng.random(300) < 0.3
    got, want = scores.metrics(score, label), brute(score, label)
    assert got["auc"] == pytest.approx(want["auc"], abs=1e-14)
    assert got["ap"] == pytest.approx(want["ap"], abs=1e-14)


def test_precision_top5_without_ties_and_pro_rata_with_them():
    rng = np.random.default_rng(4)
    score, label = rng.random(200), rng.random(200) < 0.2
    top10 = np.argsort(-score)[:10]                                    # 5 % of 200 rows
    assert scores.metrics(score, label)["precision_top5"] == pytest.approx(label[top10].mean(), abs=1e-14)
    # all tied: the top 5 % is a random share of every row, its expected precision the base rate
    assert scores.metrics(np.ones(200), label)["precision_top5"] == pytest.approx(label.mean(), abs=1e-14)
    # the mark inside a run: 3 rows over one threshold (2 positive), 40 tied below (10 positive); 5 % of 43 = 2.15
    s = np.r_[3.0, 2.0, 1.5, np.zeros(40)]
    y = np.r_[True, True, False, np.arange(40) < 10]
    assert scores.metrics(s, y)["precision_top5"] == pytest.approx(2 / 2.15, abs=1e-14)


def test_against_scikit_learn_where_installed():
    metrics = pytest.importorskip("sklearn.metrics", reason="scikit-learn: the optional baselines extra")
    rng = np.random.default_rng(5)
    score, label = rng.integers(0, 20, 500).astype(float), rng.random(500) < 0.1
    got = scores.metrics(score, label)
    assert got["auc"] == pytest.approx(metrics.roc_auc_score(label, score), abs=1e-14)
    assert got["ap"] == pytest.approx(metrics.average_precision_score(label, score), abs=1e-14)


def test_a_resample_is_the_metrics_of_its_concatenated_rows():
    """Block multiplicities m give the metrics of the drawn blocks' rows, concatenated: as row weights, and from the
    (block × run) counts (the bootstrap's path), exactly while the runs fit in BINS."""
    rng = np.random.default_rng(6)
    score, label, block = rng.integers(0, 30, 400).astype(float), rng.random(400) < 0.3, rng.integers(0, 5, 400)
    m = np.array([2, 0, 1, 0, 3])
    order, last = scores.sorted_runs(score)
    weighted = scores.weighted_metrics(label[order], last, m[block[order]][None, :].astype(float))
    counted = scores.block_metrics(label[order], block[order], scores.binned_runs(last, 400, scores.BINS),
                                   m[None, :].astype(float))
    rows = np.concatenate([np.flatnonzero(block == f) for f in range(5) for _ in range(m[f])])
    want = scores.metrics(score[rows], label[rows])
    for k in scores.METRICS:
        assert weighted[k][0] == pytest.approx(want[k], abs=1e-13), k
        assert counted[k][0] == pytest.approx(want[k], abs=1e-13), k


def test_binned_resamples_keep_ties_together_and_shift_little():
    """Beyond BINS runs the resamples see quantile bins: tied rows share a bin, and the binned AUC of 20,000
    continuous scores differs from the exact one by less than 1e-3 (a bin holds under 1/BINS of the rows)."""
    rng = np.random.default_rng(7)
    score = np.r_[rng.random(20_000), np.full(50, 0.5)]
    label = rng.random(len(score)) < 0.2
    order, last = scores.sorted_runs(score)
    binned = scores.binned_runs(last, len(score), scores.BINS)
    assert binned.max() < scores.BINS and len(np.unique(binned[score[order] == 0.5])) == 1
    got = scores.block_metrics(label[order], np.zeros(len(score), int), binned, np.ones((1, 1)))
    assert abs(got["auc"][0] - scores.metrics(score, label)["auc"]) < 1e-3


def test_calibration_random_score_covers_chance_in_95_percent_of_seeds():
    """200 seeds (binomial sd of the share 1.5 %): at MIN_EVENTS events in 60 frames the random score's interval
    covers 0.5 in 93–97 % of seeds (with scores.small_sample_factor 0.96 at 200 seeds, 0.9625 at 400; before it
    0.935 and 0.945; at 10 events in 40 frames 0.97, before 0.885)."""
    assert 0.93 <= coverage(60, scores.MIN_EVENTS, 200) <= 0.97


def test_interval_arms_are_the_resamples_percentiles_scaled_for_few_blocks():
    """25 frames: the AUC interval's arms are those of the 2.5 / 97.5 percentiles of the resamples (recomputed here
    row by row from the same multinomial draws) times sqrt(25/24) t_24 / z = 1.0747 (t_24 at 97.5 %: 2.0639)."""
    rng = np.random.default_rng(5)
    block = np.repeat(np.arange(25), 40)
    label = rng.random(1000) < 0.2
    score = rng.random(1000) + 0.3 * label
    r = scores.with_intervals(score, label, block, n_boot=400, seed=1)
    m = np.random.default_rng(1).multinomial(25, np.full(25, 1 / 25), size=400)
    rows = [np.concatenate([np.flatnonzero(block == f).repeat(k) for f, k in enumerate(draw)]) for draw in m]
    low, high = np.percentile([scores.metrics(score[i], label[i])["auc"] for i in rows], [2.5, 97.5])
    c = scores.small_sample_factor(25)
    assert c == pytest.approx(np.sqrt(25 / 24) * 2.0639 / 1.95996, abs=2e-4)
    assert r["auc_ci_low"] == pytest.approx(r["auc"] - c * (r["auc"] - low), abs=1e-12)
    assert r["auc_ci_high"] == pytest.approx(r["auc"] + c * (high - r["auc"]), abs=1e-12)


def test_calibration_per_particle_targets_contiguous_frame_blocks():
    """A per-particle target (10 rows a frame, positives clustered in frames at a rate drawn per frame in [0, 0.3]),
    200 frames resampled in runs of scores.frame_block(200) = 6 contiguous frames (34 blocks), as predict does,
    200 seeds: the random score's interval covers 0.5 in 93–97 % of seeds (0.965 measured). Other sizes measured
    (docs/track-results.md): 120 × 5 rows 0.93, 200 × 5 0.96 (200 seeds), 120 × 20 0.965 (400 seeds). At 20 frames
    (3 a block, 7 blocks) no interval is printed: the single-frame blocks of before covered 0.5 in 0.925 there."""
    assert 0.93 <= coverage(200, 0, 200, per_frame=10, grouped=True) <= 0.97
    few = np.repeat(np.arange(20), 20) // scores.frame_block(20)
    r = scores.with_intervals(np.random.default_rng(3).random(400), np.random.default_rng(4).random(400) < 0.2, few,
                              too_few=scores.TOO_FEW_FRAMES)
    assert r["auc_ci_low"] is None and r["note"].startswith("too few frames") and r["n_blocks_positive"] == 7


def test_too_few_events_print_no_interval():
    label = np.zeros(60, bool)
    label[:scores.MIN_EVENTS - 1] = True
    r = scores.with_intervals(np.random.default_rng(0).random(60), label, np.arange(60))
    assert r["auc"] is not None and r["auc_ci_low"] is None and r["ap_ci_high"] is None
    assert r["note"].startswith("too few events")
    label[scores.MIN_EVENTS - 1] = True
    r = scores.with_intervals(np.random.default_rng(0).random(60), label, np.arange(60))
    for k in scores.METRICS:
        assert r[f"{k}_ci_low"] <= r[k] <= r[f"{k}_ci_high"]
