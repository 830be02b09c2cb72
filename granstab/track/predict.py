"""The prediction test of `granstab track --predict` (issue 27): does instability at frame t mark where, and whether,
the packing rearranges in the window (t, t+W] that follows?

Everything here is fixed before any result is seen, and stated in the output:

- **Targets.** `rearranges` (per particle): its D²min over (t, t+W] is in the top 10 % of that window's particles
  (`TOP_FRACTION`), or one of its contacts was made or broken; its two halves `d2min_top10` and `contacts_changed`
  are reported too. `event` (per frame): a stress drop of events.json ends in (t, t+W]. A row whose window runs past
  the last frame (D²min or the contact count NaN) has no target and is left out.
- **Sign.** Every predictor is oriented so that a larger score means "more likely to rearrange" (`PARTICLE`,
  `FRAME`): λ_min, the coordination, the force and the distance to the nearest sliding contact are negated, so an
  AUC above 0.5 always means predictive and one below 0.5 anti-predictive.
- **AUC** is the Mann–Whitney statistic: the probability that a positive row outscores a negative one, ties
  counting one half (average ranks); no scikit-learn needed. Rows whose predictor is NaN are left out (`n` says how
  many were used).
- **95 % intervals** by a percentile bootstrap of `N_BOOT` resamples (seed `SEED`). The rows are not independent:
  the particles of one frame share its stress state, and consecutive frames share their windows. So whole blocks
  are resampled: a per-particle target resamples frames (all particles of a frame together), the event target
  resamples runs of W consecutive frames. Each resample's AUC comes exactly from one (blocks × blocks) table of
  pair counts, so the bootstrap costs no re-ranking.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

TOP_FRACTION = 0.10
N_BOOT = 2000
SEED = 0
#: per-particle predictors → +1 when larger means more unstable, −1 when smaller does (then negated)
PARTICLE = {"unstable_fraction": 1, "unstable_fraction_nonboundary": 1, "cluster_lambda_min": -1,
            "soft_participation": 1, "coordination": -1, "mobilised_fraction": 1, "force_magnitude": -1,
            "sliding_distance": -1, "in_largest_rigid_cluster": -1, "random": 1}
#: frame-level predictors of the event target; `mean_unstable_fraction` is the frame's mean of the particles'
FRAME = {"lambda_min_unloading": -1, "lambda_min_loading": -1, "n_negative_unloading": 1, "n_negative_loading": 1,
         "mean_unstable_fraction": 1, "mobilised_fraction": 1, "stress_ratio": 1, "z": -1,
         "rigid_largest_fraction": -1, "random": 1}
BASELINES = ("coordination", "mobilised_fraction", "force_magnitude", "sliding_distance", "stress_ratio", "z")
#: integer columns whose negative values mean "not computed" (the track contract's fill)
FILLED = ("n_negative_unloading", "n_negative_loading")
TARGETS = {
    "rearranges": f"D²min over (t, t+W] in the top {TOP_FRACTION:.0%} of that window, or a contact made or broken",
    "d2min_top10": f"D²min over (t, t+W] in the top {TOP_FRACTION:.0%} of that window",
    "contacts_changed": "a contact of the particle made or broken in (t, t+W]",
    "event": "a stress drop of events.json ends in (t, t+W]",
}


# ------------------------------------------------------------------------------------------------------- the AUC

def pair_counts(score: np.ndarray, label: np.ndarray, block: np.ndarray, n_blocks: int) -> np.ndarray:
    """U (n_blocks, n_blocks): U[f, g] = #{positive i of block f, negative j of block g: s_i > s_j} + ½ #{s_i = s_j}.
    The AUC of any multiset of blocks with multiplicities m is mᵀUm / ((m·P)(m·N))."""
    pos, neg = label.astype(bool), ~label.astype(bool)
    U = np.zeros((n_blocks, n_blocks))
    s_pos, b_pos = score[pos], block[pos]
    for g in np.unique(block[neg]):
        s_neg = np.sort(score[neg & (block == g)])
        wins = np.searchsorted(s_neg, s_pos, "left") + np.searchsorted(s_neg, s_pos, "right")
        U[:, g] = 0.5 * np.bincount(b_pos, weights=wins, minlength=n_blocks)
    return U


def auc(score, label) -> float:
    """Mann–Whitney AUC, ties one half; NaN when one class is empty."""
    score, label = np.asarray(score, float), np.asarray(label, bool)
    if label.all() or not label.any():
        return float("nan")
    U = pair_counts(score, label, np.zeros(len(score), int), 1)
    return float(U[0, 0] / (label.sum() * (~label).sum()))


def auc_with_interval(score, label, block, n_boot: int = N_BOOT, seed: int = SEED) -> dict:
    """AUC and its 95 % percentile-bootstrap interval, resampling whole blocks (rows with a NaN score dropped).
    Returns {auc, ci_low, ci_high, n, n_positive}; auc NaN when a class is empty."""
    score, label, block = np.asarray(score, float), np.asarray(label, bool), np.asarray(block)
    keep = np.isfinite(score)
    score, label = score[keep], label[keep]
    _, block = np.unique(block[keep], return_inverse=True)
    n, n_pos = int(len(score)), int(label.sum())
    out = {"auc": float("nan"), "ci_low": float("nan"), "ci_high": float("nan"), "n": n, "n_positive": n_pos}
    if n_pos == 0 or n_pos == n:
        return out
    F = int(block.max()) + 1
    U = pair_counts(score, label, block, F)
    P, N = np.bincount(block, weights=label, minlength=F), np.bincount(block, weights=~label, minlength=F)
    out["auc"] = float(U.sum() / (P.sum() * N.sum()))
    rng = np.random.default_rng(seed)
    m = rng.multinomial(F, np.full(F, 1.0 / F), size=n_boot).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        boot = np.einsum("bf,fg,bg->b", m, U, m) / ((m @ P) * (m @ N))
    if np.isfinite(boot).sum() >= n_boot // 2:        # a resample without positives (or negatives) has no AUC
        out["ci_low"], out["ci_high"] = (float(v) for v in np.nanpercentile(boot, [2.5, 97.5]))
    return out


# ----------------------------------------------------------------------------------------------------- the targets

def frame_positions(frames: np.ndarray, order: np.ndarray) -> np.ndarray:
    """The position of each row's frame in the sorted frame list `order`."""
    return np.searchsorted(order, frames)


def particle_targets(frame_pos: np.ndarray, d2min: np.ndarray, changed: np.ndarray) -> dict:
    """{target: labels} per row, and `valid` (the window is inside the run: D²min finite). The top-10 % threshold
    is the (1 − TOP_FRACTION) quantile of the finite D²min of the row's own frame."""
    valid = np.isfinite(d2min) & np.isfinite(np.asarray(changed, float))
    top = np.zeros(len(d2min), bool)
    for f in np.unique(frame_pos[valid]):
        rows = valid & (frame_pos == f)
        top[rows] = d2min[rows] >= np.quantile(d2min[rows], 1.0 - TOP_FRACTION)
    moved = valid & (np.nan_to_num(np.asarray(changed, float)) > 0)
    return {"valid": valid, "rearranges": top | moved, "d2min_top10": top, "contacts_changed": moved}


def event_target(n_frames: int, window: int, event_end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(label, valid) per frame position t: an event ends at a position in (t, t+W]; valid when t + W is a frame."""
    t = np.arange(n_frames)
    label = ((event_end[None, :] > t[:, None]) & (event_end[None, :] <= t[:, None] + window)).any(axis=1)
    return label, t + window < n_frames


def lead_times(lam: np.ndarray, n_negative, steps: np.ndarray, event_start: np.ndarray) -> dict:
    """λ_min before each event. Two readings of "unstable at frame t": `negative`, λ_min(t) < 0 (any negative
    eigenvalue, consistent or not: no proof), and `proven`, a consistent negative mode (n_negative > 0, eq:instab;
    None when not computed). Per event and reading, how many frames up to its start were unstable without a break
    (the lead, in frames and steps from the first of them), beside the base rate of such frames; per frame, the
    frames to the next event's start, and Spearman's ρ of λ_min against it (positive ρ: λ_min falls as an event
    nears)."""
    from scipy.stats import spearmanr
    n = len(lam)
    nxt = np.full(n, -1)
    for e in sorted(event_start, reverse=True):
        nxt[: e + 1] = e
    to_next = np.where(nxt >= 0, nxt - np.arange(n), -1)
    readings = {"negative": lam < 0}
    if n_negative is not None and np.all(np.asarray(n_negative) >= 0):
        readings["proven"] = np.asarray(n_negative) > 0
    events = []
    for e in np.unique(event_start):
        row = {"frame_position": int(e), "lambda_min": _num(lam[e])}
        for name, unstable in readings.items():
            k = 0
            while e - k >= 0 and unstable[e - k]:
                k += 1
            row[f"lead_frames_{name}"] = k
            row[f"lead_steps_{name}"] = _num(steps[e] - steps[e - k + 1]) if k else 0.0
        events.append(row)
    ok = (to_next >= 0) & np.isfinite(lam)
    rho, p = spearmanr(lam[ok], to_next[ok]) if ok.sum() > 2 and np.ptp(lam[ok]) > 0 else (np.nan, np.nan)
    return {"events": events, "readings": sorted(readings),
            "unstable_frame_rate": {k: _num(np.mean(v[np.isfinite(lam)])) if np.isfinite(lam).any() else None
                                    for k, v in readings.items()},
            "spearman_rho": _num(rho), "spearman_p": _num(p), "frames_to_next_event": to_next.tolist()}


def _num(v) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


# ------------------------------------------------------------------------------------------------------ the table

def particle_cases(cols: dict, order: np.ndarray):
    """(target, predictor, oriented score, label, block) of every per-particle test with a finite score; `cols`
    the columns of particles.parquet. Blocks: frames."""
    pos = frame_positions(cols["frame"], order)
    targets = particle_targets(pos, cols["d2min"], cols["contacts_changed"])
    valid = targets.pop("valid")
    for target, label in targets.items():
        for name, sign in PARTICLE.items():
            if name in cols and np.isfinite(cols[name][valid]).any():
                yield target, name, sign * cols[name][valid], label[valid], pos[valid]


def frame_predictors(frames: dict, particles: dict, order: np.ndarray) -> dict:
    """The frame-level scores, in frame order: frames.parquet's columns and the frames' mean unstable fraction."""
    out = {k: np.where(np.asarray(frames[k]) < 0, np.nan, frames[k]) if k in FILLED else np.asarray(frames[k], float)
           for k in FRAME if k in frames and k != "random"}
    if "unstable_fraction" in particles:
        pos = frame_positions(particles["frame"], order)
        v = particles["unstable_fraction"]
        ok = np.isfinite(v)
        with np.errstate(invalid="ignore"):
            out["mean_unstable_fraction"] = (np.bincount(pos[ok], v[ok], len(order))
                                             / np.bincount(pos[ok], minlength=len(order)))
    out["random"] = np.random.default_rng(SEED).random(len(order))
    return out


def event_cases(scores: dict, label: np.ndarray, valid: np.ndarray, window: int):
    """(target, predictor, oriented score, label, block) of the event tests; blocks: runs of W frames."""
    block = np.arange(len(label)) // max(window, 1)
    for name, s in scores.items():
        if np.isfinite(s[valid]).any():
            yield "event", name, FRAME[name] * s[valid], label[valid], block[valid]


def cases(out_dir) -> tuple[list, dict]:
    """Every test of a track folder as (target, predictor, score, label, block), and the folder's context
    (window, frames, events' positions, steps), read once for the table and the figures."""
    out_dir = Path(out_dir)
    summary = json.loads((out_dir / "summary.json").read_text())
    window = int(summary["window"] if "window" in summary else summary["windows"]["window"])
    frames, particles = read_columns(out_dir / "frames.parquet"), read_columns(out_dir / "particles.parquet")
    order = np.sort(frames["frame"])
    frames = {k: v[np.argsort(frames["frame"])] for k, v in frames.items()}
    events = json.loads((out_dir / "events.json").read_text())
    start = frame_positions(np.array([e["frame"] for e in events], np.int64), order)
    end = frame_positions(np.array([e["next_frame"] for e in events], np.int64), order)
    label, valid = event_target(len(order), window, end)
    found = [*particle_cases(particles, order), *event_cases(frame_predictors(frames, particles, order), label,
                                                               valid, window)]
    return found, {"window": window, "frames": frames, "order": order, "start": start, "end": end}


def roc_curve(score, label) -> tuple[np.ndarray, np.ndarray]:
    """(false positive rate, true positive rate) at every distinct threshold, from (0, 0) to (1, 1); tied scores
    form one step, so the trapezoid area equals the Mann–Whitney AUC."""
    score, label = np.asarray(score, float), np.asarray(label, bool)
    keep = np.isfinite(score)
    score, label = score[keep], label[keep]
    idx = np.argsort(-score, kind="stable")
    s, y = score[idx], label[idx]
    last = np.r_[np.flatnonzero(np.diff(s)), len(s) - 1]          # the last row of each run of equal scores
    tp, fp = np.cumsum(y)[last], np.cumsum(~y)[last]
    return np.r_[0.0, fp / max(fp[-1], 1)], np.r_[0.0, tp / max(tp[-1], 1)]


def verdict(rows: list[dict], lead: dict | None) -> str:
    """A few plain sentences: per target the winner, its margin over the best baseline and over chance, and whether
    λ_min < 0 came before the events."""
    lines = []
    fmt = "{predictor} AUC {auc:.3f} [{ci_low:.3f}, {ci_high:.3f}]"
    for target in TARGETS:
        mine = [r for r in rows if r["target"] == target and np.isfinite(r["auc"])]
        if not mine:
            some = [r for r in rows if r["target"] == target]
            if some:
                lines.append(f"{target}: {some[0]['n_positive']} of {some[0]['n']} rows positive, no AUC.")
            continue
        best = max((r for r in mine if r["predictor"] != "random"), key=lambda r: r["auc"], default=None)
        base = max((r for r in mine if r["predictor"] in BASELINES), key=lambda r: r["auc"], default=None)
        if best is None:
            continue
        n, npos = best["n"], best["n_positive"]
        chance = "above chance" if best["ci_low"] > 0.5 else "NOT distinguishable from chance (interval holds 0.5)"
        text = f"{target} ({npos} of {n} positive): best {fmt.format(**best)}, {chance}"
        if base is not None and base is not best:
            text += f"; {best['auc'] - base['auc']:+.3f} over the best baseline, {fmt.format(**base)}"
        elif base is best:
            text += "; a baseline wins"
        lines.append(text + ".")
    skipped = sorted({*PARTICLE, *FRAME} - {r["predictor"] for r in rows})
    if skipped:
        lines.append("not computed (no finite values): " + ", ".join(skipped) + ".")
    for branch, lt in (lead or {}).items():
        ev = lt["events"]
        if not ev:
            lines.append(f"λ_min ({branch}): no events to precede.")
            continue
        for name in lt["readings"]:
            led = sum(e[f"lead_frames_{name}"] > 0 for e in ev)
            what = "λ_min < 0" if name == "negative" else "a consistent negative mode (eq:instab)"
            lines.append(f"all-{branch}: {what} at the frame an event starts from for {led} of {len(ev)} events "
                         f"(base rate of such frames {lt['unstable_frame_rate'][name]:.2f}).")
        rho, p = lt["spearman_rho"], lt["spearman_p"]
        lines.append(f"all-{branch}: Spearman ρ(λ_min, frames to the next event) = "
                     + ("n/a." if rho is None else f"{rho:.3f} (p = {p:.2f})."))
    return "\n".join(lines)


def read_columns(path: Path, skip: tuple = ()) -> dict:
    """A parquet table's numeric columns as float arrays (nulls → NaN), `frame` as int; list columns skipped."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    table = pq.read_table(path)
    out = {}
    for name in table.column_names:
        col = table.column(name)
        if name in skip or not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)
                                or pa.types.is_boolean(col.type)):
            continue
        out[name] = col.cast(pa.float64()).fill_null(float("nan")).to_numpy()
    out["frame"] = out["frame"].astype(np.int64)
    return out


def run(out_dir) -> dict:
    """Read a track folder (frames.parquet, particles.parquet, events.json, the window W of summary.json), write
    prediction.json (the AUC list), prediction_lead.json (λ_min before each event) and prediction.txt (the targets,
    the conventions and the verdict); return {rows, lead, verdict}."""
    out_dir = Path(out_dir)
    found, ctx = cases(out_dir)
    rows = [{"target": t, "predictor": p, **auc_with_interval(s, y, b)} for t, p, s, y, b in found]
    frames = ctx["frames"]
    steps = frames.get("step", ctx["order"].astype(float))
    lead = {b: lead_times(frames[f"lambda_min_{b}"], frames.get(f"n_negative_{b}"), steps, ctx["start"])
            for b in ("unloading", "loading")
            if f"lambda_min_{b}" in frames and np.isfinite(frames[f"lambda_min_{b}"]).any()}
    text = verdict(rows, lead)
    clean = [{k: (_num(v) if k.startswith(("auc", "ci")) else v) for k, v in r.items()} for r in rows]
    (out_dir / "prediction.json").write_text(json.dumps(clean, indent=1))
    (out_dir / "prediction_lead.json").write_text(json.dumps(lead, indent=1))
    (out_dir / "prediction.txt").write_text(header(ctx["window"]) + "\n" + text + "\n")
    return {"rows": clean, "lead": lead, "verdict": text}


def header(window: int) -> str:
    """The fixed targets and conventions, stated before the results."""
    lines = [f"window W = {window} frames; targets (fixed before the results):"]
    lines += [f"  {k}: {v}" for k, v in TARGETS.items()]
    lines.append("scores oriented so that AUC > 0.5 is predictive (negated: "
                 + ", ".join(k for k, s in {**PARTICLE, **FRAME}.items() if s < 0) + ")")
    lines.append(f"95 % intervals: percentile bootstrap, {N_BOOT} resamples, seed {SEED}; per-particle targets "
                 "resample whole frames (a frame's particles are correlated), the event target runs of W frames")
    return "\n".join(lines)
