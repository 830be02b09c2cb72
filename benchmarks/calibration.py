"""Track, issue 39's calibration of the prediction intervals (granstab.track.scores): over seeds of a random score,
the share whose 95 % AUC interval holds 0.5 must lie in 93–97 %. tests/track/test_track_scores.py checks one
per-particle size and one event size at 200 seeds (binomial sd of the share 1.5 %, fast enough for CI); here those
and the per-particle size that read 0.975 at 200 seeds, at 1,000 seeds (sd 0.7 %), so that a share outside the band
is told from a 2-sd draw of 200 seeds.

The per-particle target: `per_frame` rows a frame, positives clustered in frames at a rate drawn per frame in
[0, 0.3], resampled in runs of scores.frame_block(F) contiguous frames, as predict does; the event target: one row a
frame, `events` positive frames spread evenly, single-frame blocks. Interval: scores.with_intervals with 1,000
resamples, as in the test.
"""
from __future__ import annotations

import time

import numpy as np

from granstab.track import scores

# (frames, events, rows a frame): events > 0 is the event target, else a per-particle target
CASES = [(200, 0, 10), (200, 0, 20), (60, scores.MIN_EVENTS, 1)]   # the test's two sizes and the widest one measured
QUICK = {"seeds": 10, "cases": CASES[:1] + CASES[-1:]}                   # above the band at 200 seeds (0.975)
FULL = {"seeds": 1000, "cases": CASES}
BAND = (0.93, 0.97)


def coverage(n_frames: int, n_events: int, seeds: int, per_frame: int = 1, grouped: bool = False,
             first_seed: int = 0) -> float:
    """The share of seeds whose 95 % AUC interval holds 0.5 for a random score: the event target (one row a frame,
    n_events positive frames) or, with per_frame rows, a per-particle target whose positives cluster in frames
    (`grouped`: resampled in runs of scores.frame_block contiguous frames, as predict does). Seeds first_seed to
    first_seed + seeds - 1."""
    rng = np.random.default_rng(0)
    block = np.repeat(np.arange(n_frames), per_frame)
    if per_frame == 1:
        label = np.zeros(n_frames, bool)
        label[np.linspace(0, n_frames - 1, n_events).astype(int)] = True
    else:
        label = rng.random(len(block)) < rng.uniform(0.0, 0.3, n_frames)[block]
    min_events = scores.MIN_EVENTS if per_frame == 1 or grouped else 0
    block = block // scores.frame_block(n_frames) if grouped else block
    held = 0
    for seed in range(first_seed, first_seed + seeds):
        score = np.random.default_rng(1000 + seed).random(len(block))
        r = scores.with_intervals(score, label, block, n_boot=1000, seed=seed, min_events=min_events)
        held += r["auc_ci_low"] <= 0.5 <= r["auc_ci_high"]
    return held / seeds


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    rows = []
    for frames, events, per_frame in cfg["cases"]:
        begun = time.process_time()
        share = coverage(frames, events, cfg["seeds"], per_frame, grouped=events == 0)
        rows.append({"frames": frames, "events": events, "per_frame": per_frame, "seeds": cfg["seeds"],
                     "blocks": -(-frames // scores.frame_block(frames)) if events == 0 else frames,
                     "share": share, "sd": float(np.sqrt(0.95 * 0.05 / cfg["seeds"])),
                     "cpu_seconds": time.process_time() - begun})
    return {"seeds": cfg["seeds"], "band": BAND, "cases": rows}


def markdown(results: dict) -> str:
    lines = ["## Track: calibration of the prediction intervals over seeds (issue 39)", "",
             "`granstab.track.scores.with_intervals` on a random score (benchmarks/calibration.py): the share of "
             f"{results['seeds']:,} seeds whose 95 % AUC interval holds 0.5; goal {results['band'][0]:.0%}–"
             f"{results['band'][1]:.0%}. *sd*: the binomial standard deviation of the share at 95 %. Per-particle "
             "targets resample runs of ⌈F^(1/3)⌉ contiguous frames; events, single frames.", "",
             "| target | frames × rows a frame | blocks | share holding 0.5 | sd | in the band | CPU |",
             "|---|---|---|---|---|---|---|"]
    for r in results["cases"]:
        target = f"event ({r['events']} events)" if r["events"] else "per particle"
        inside = results["band"][0] <= r["share"] <= results["band"][1]
        lines.append(f"| {target} | {r['frames']} × {r['per_frame']} | {r['blocks']} | **{r['share']:.3f}** | "
                     f"{r['sd']:.3f} | {'yes' if inside else 'no'} | {r['cpu_seconds']:.0f} s |")
    return "\n".join(lines + [""])
