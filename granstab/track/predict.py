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
- **Metrics** (scores.py): AUC (Mann–Whitney, ties one half), average precision and the precision among the top
  5 % of scores, each with a 95 % interval from a percentile bootstrap that resamples whole blocks: frames for a
  per-particle target (a frame's particles share its stress state), runs of W frames for the event target. Rows
  whose predictor is NaN are left out (`n` says how many were used). With fewer than scores.MIN_EVENTS blocks
  holding a positive the interval is null with a `note` (the calibration of tests/track/test_track_scores.py).
- **Baselines of the field** (baselines.py, frame.py): soft spots of the frictionless dynamical matrix and of the
  all-unloading branch, the previous window's D²min, and a learned structural score (softness).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from . import baselines, scores

TOP_FRACTION = 0.10
SEED = 0
#: per-particle predictors → +1 when larger means more unstable, −1 when smaller does (then negated)
PARTICLE = {"unstable_fraction": 1, "unstable_fraction_nonboundary": 1, "cluster_lambda_min": -1,
            "soft_participation": 1, "coordination": -1, "mobilised_fraction": 1, "force_magnitude": -1,
            "sliding_distance": -1, "in_largest_rigid_cluster": -1, "random": 1,
            "soft_spots_frictionless": 1, "soft_spots_branch": 1, "d2min_previous": 1}
#: frame-level predictors of the event target; `mean_unstable_fraction` is the frame's mean of the particles'
FRAME = {"lambda_min_unloading": -1, "lambda_min_loading": -1, "n_negative_unloading": 1, "n_negative_loading": 1,
         "mean_unstable_fraction": 1, "mobilised_fraction": 1, "stress_ratio": 1, "z": -1,
         "rigid_largest_fraction": -1, "random": 1}
BASELINES = ("coordination", "mobilised_fraction", "force_magnitude", "sliding_distance", "stress_ratio", "z",
             "soft_spots_frictionless", "d2min_previous", "softness")
DEFINITIONS = {
    "soft_spots_frictionless": "participation (mean share of the mode's squared translation) in the lowest 1 % of "
                               "the modes of the whole packing's frictionless dynamical matrix: the normal stiffness "
                               "k n⊗n and the normal force's prestress −(f_n/ℓ)(I − n⊗n), uniform translations "
                               "lifted (Manning & Liu, PRL 107, 108302; track --whole)",
    "soft_spots_branch": "the same participation in the lowest 1 % of the non-rigid modes of granstab's all-unloading "
                         "branch, sym(𝓗^i) (track --whole)",
    "d2min_previous": "D²min (Falk & Langer) of the particle over the previous window (t − W, t]: persistence",
    "softness": "logistic regression (scikit-learn, balanced, C = 1) on radial structure functions G(r) at "
                f"r = {baselines.MU[0]:.1f}…{baselines.MU[-1]:.1f} d̄ (width {baselines.WIDTH} d̄, d̄ the frame's mean "
                "contact distance), trained per target on the first half of the frames, scored on the second half "
                "only (Cubuk et al., PRL 114, 108001)",
}
#: integer columns whose negative values mean "not computed" (the track contract's fill)
FILLED = ("n_negative_unloading", "n_negative_loading")
TARGETS = {
    "rearranges": f"D²min over (t, t+W] in the top {TOP_FRACTION:.0%} of that window, or a contact made or broken",
    "d2min_top10": f"D²min over (t, t+W] in the top {TOP_FRACTION:.0%} of that window",
    "contacts_changed": "a contact of the particle made or broken in (t, t+W]",
    "event": "a stress drop of events.json ends in (t, t+W]",
}


# ------------------------------------------------------------------------------------------------------- the AUC

def auc(score, label) -> float:
    """Mann–Whitney AUC, ties one half; NaN when one class is empty (scores.metrics)."""
    return scores.metrics(score, label)["auc"]


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


def lead_times(lam: np.ndarray, n_negative, steps: np.ndarray, event_start: np.ndarray,
               event_end: np.ndarray | None = None) -> dict:
    """λ_min before each event. Two readings of "unstable at frame t": `negative`, λ_min(t) < 0 (any negative
    eigenvalue, consistent or not: no proof), and `proven`, a consistent negative mode (n_negative > 0, eq:instab;
    None when not computed). Per event and reading, how many frames up to its start were unstable without a break
    (the lead, in frames, and in steps from the first of them to the frame the event ends at, `event_end`, default
    start + 1: k frames of a uniform run are k × the steps per frame), beside the base rate of such frames; per frame, the
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
    ends = dict(zip(event_start.tolist(), (event_start + 1 if event_end is None else event_end).tolist()))
    for e in np.unique(event_start):
        row = {"frame_position": int(e), "lambda_min": _num(lam[e])}
        end = steps[min(ends[e], n - 1)] if ends[e] < n else steps[e] + (steps[e] - steps[e - 1] if e else 0.0)
        for name, unstable in readings.items():
            k = run_before(unstable, e)
            row[f"lead_frames_{name}"] = k
            row[f"lead_steps_{name}"] = _num(end - steps[e - k + 1]) if k else 0.0
        events.append(row)
    ok = (to_next >= 0) & np.isfinite(lam)
    rho, p = spearmanr(lam[ok], to_next[ok]) if ok.sum() > 2 and np.ptp(lam[ok]) > 0 else (np.nan, np.nan)
    return {"events": events, "readings": sorted(readings),
            "unstable_frame_rate": {k: _num(np.mean(v[np.isfinite(lam)])) if np.isfinite(lam).any() else None
                                    for k, v in readings.items()},
            "spearman_rho": _num(rho), "spearman_p": _num(p), "frames_to_next_event": to_next.tolist()}


def run_before(sign: np.ndarray, e: int) -> int:
    """How many frames up to and including position e hold `sign` without a break (the lead of an event at e)."""
    k = 0
    while e - k >= 0 and sign[e - k]:
        k += 1
    return k


SIGN_QUANTILE = 0.75    # a frame-level predictor signals at a frame whose oriented score is in the run's top quarter


def predictor_leads(by_name: dict, event_start: np.ndarray) -> dict:
    """Per frame-level predictor (`frame_predictors`, oriented by FRAME: larger, more likely to fail) the lead of
    each event: the frames without a break up to its start at which the predictor signals (its score at or above
    the run's SIGN_QUANTILE quantile, fixed before the results; strictly above where that quantile is the minimum,
    so that a count that is mostly 0 signals only when positive), beside the base rate r of signalling frames and
    what frames signalling independently at that rate would give: a lead ≥ 1 for a share r of the events, a mean
    lead r/(1 − r) (geometric)."""
    out = {}
    for name, score in by_name.items():
        s = FRAME[name] * np.asarray(score, float)
        ok = np.isfinite(s)
        if not ok.any() or not len(event_start):
            continue
        q = np.quantile(s[ok], SIGN_QUANTILE)
        sign = ok & ((s > q) if q == s[ok].min() else (s >= q))
        leads = [run_before(sign, e) for e in np.unique(event_start)]
        r = float(sign[ok].mean())
        out[name] = {"leads": leads, "base_rate": r, "share_led": float(np.mean(np.array(leads) > 0)),
                     "mean_lead": float(np.mean(leads)), "null_share_led": r,
                     "null_mean_lead": r / (1 - r) if r < 1 else None}
    return out


def _num(v) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


# ------------------------------------------------------------------------------------------------------ the table

def particle_cases(cols: dict, order: np.ndarray, window: int, structure=None):
    """(target, predictor, oriented score, label, block) of every per-particle test with a finite score; `cols`
    the columns of particles.parquet with `code` (the particle's name as a number); `structure` the rows' G(r)
    features (baselines.frame_features) for the softness baseline. Blocks: runs of scores.frame_block contiguous
    frames."""
    pos = frame_positions(cols["frame"], order)
    block = pos // scores.frame_block(len(order))
    targets = particle_targets(pos, cols["d2min"], cols["contacts_changed"])
    valid = targets.pop("valid")
    cols = {**cols, "d2min_previous": baselines.previous_d2min(cols["code"], pos, cols["d2min"], window)}
    for target, label in targets.items():
        for name, sign in PARTICLE.items():
            if name in cols and np.isfinite(cols[name][valid]).any():
                yield target, name, sign * cols[name][valid], label[valid], block[valid]
        soft = None if structure is None else baselines.softness(structure, label, pos, valid)
        if soft is not None and np.isfinite(soft[valid]).any():
            yield target, "softness", soft[valid], label[valid], block[valid]


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


def event_cases(by_name: dict, label: np.ndarray, valid: np.ndarray, window: int):
    """(target, predictor, oriented score, label, block) of the event tests; blocks: runs of W frames."""
    block = np.arange(len(label)) // max(window, 1)
    for name, s in by_name.items():
        if np.isfinite(s[valid]).any():
            yield "event", name, FRAME[name] * s[valid], label[valid], block[valid]


def cases(out_dir, structure_wanted: bool = True) -> tuple[list, dict]:
    """Every test of a track folder as (target, predictor, score, label, block), and the folder's context
    (window, frames, events' positions, steps), read once for the table and the figures."""
    out_dir = Path(out_dir)
    summary = json.loads((out_dir / "summary.json").read_text())
    window = int(summary["window"] if "window" in summary else summary["windows"]["window"])
    frames, particles = read_columns(out_dir / "frames.parquet"), read_columns(out_dir / "particles.parquet")
    order = np.sort(frames["frame"])
    by_order = np.argsort(frames["frame"])
    frames = {k: v[by_order] for k, v in frames.items()}
    names, cells = read_strings(out_dir)
    particles["code"] = np.unique(names, return_inverse=True)[1]
    cells = [cells[k] for k in by_order]
    events = json.loads((out_dir / "events.json").read_text())
    start = frame_positions(np.array([e["frame"] for e in events], np.int64), order)
    end = frame_positions(np.array([e["next_frame"] for e in events], np.int64), order)
    label, valid = event_target(len(order), window, end)
    structure = None
    if structure_wanted:
        x = np.stack([particles[a] for a in "xyz" if a in particles], axis=1)
        structure = baselines.frame_features(x, frame_positions(particles["frame"], order), cells,
                                             frames["mean_contact_distance"])
    by_name = frame_predictors(frames, particles, order)
    found = [*particle_cases(particles, order, window, structure), *event_cases(by_name, label, valid, window)]
    return found, {"window": window, "frames": frames, "order": order, "start": start, "end": end,
                   "n_events": int(label[valid].sum()), "frame_scores": by_name}


def read_strings(out_dir: Path) -> tuple[np.ndarray, list]:
    """particles.parquet's names and frames.parquet's cells (d × d, or None), in the tables' row order."""
    import pyarrow.parquet as pq
    names = np.asarray(pq.read_table(out_dir / "particles.parquet", columns=["name"]).column("name").to_pylist(),
                       dtype=str)
    cells = []
    for c in pq.read_table(out_dir / "frames.parquet", columns=["cell", "dim"]).to_pylist():
        cells.append(np.reshape(c["cell"], (int(c["dim"]), int(c["dim"]))) if c["cell"] else None)
    return names, cells


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


def described(row: dict) -> str:
    """"name AUC a [lo, hi], AP …, precision@5% …" of a row, intervals left out where it has none."""
    parts = []
    for metric, label in (("auc", "AUC"), ("ap", "AP"), ("precision_top5", "precision@5%")):
        v, lo, hi = row[metric], row[f"{metric}_ci_low"], row[f"{metric}_ci_high"]
        if v is None:
            continue
        parts.append(f"{label} {v:.3f}" + (f" [{lo:.3f}, {hi:.3f}]" if lo is not None else ""))
    return f"{row['predictor']} " + ", ".join(parts)


def verdict(rows: list[dict], lead: dict | None) -> str:
    """A few plain sentences: per target the winner, its margin over the best baseline and over chance, and whether
    λ_min < 0 came before the events."""
    lines = []
    for target in TARGETS:
        mine = [r for r in rows if r["target"] == target and r["auc"] is not None and np.isfinite(r["auc"])]
        if not mine:
            some = [r for r in rows if r["target"] == target]
            if some:
                lines.append(f"{target}: {some[0]['n_positive']} of {some[0]['n']} rows positive, no AUC.")
            continue
        best = max((r for r in mine if r["predictor"] != "random"), key=lambda r: r["auc"], default=None)
        base = max((r for r in mine if r["predictor"] in BASELINES), key=lambda r: r["auc"], default=None)
        if best is None:
            continue
        if best["auc_ci_low"] is None:
            chance = f"no interval: {best['note']}"
        else:
            chance = "above chance" if best["auc_ci_low"] > 0.5 else \
                "NOT distinguishable from chance (interval holds 0.5)"
        text = f"{target} ({best['n_positive']} of {best['n']} positive): best {described(best)}, {chance}"
        if base is not None and base is not best:
            text += f"; {best['auc'] - base['auc']:+.3f} over the best baseline, {described(base)}"
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
    prediction.json (the AUC list), prediction_lead.json (λ_min before each event, per branch, and every frame-level
    predictor's leads against its base rate, `frame_predictors`) and prediction.txt (the targets, the conventions
    and the verdict); return {rows, lead, frame_predictors, verdict}."""
    out_dir = Path(out_dir)
    found, ctx = cases(out_dir)
    n_events = ctx["n_events"]
    rows = [{"target": t, "predictor": p,
             **scores.with_intervals(s, y, b, too_few=scores.TOO_FEW if t == "event" else scores.TOO_FEW_FRAMES),
             "n_events": n_events} for t, p, s, y, b in found]
    frames = ctx["frames"]
    steps = frames.get("step", ctx["order"].astype(float))
    lead = {b: lead_times(frames[f"lambda_min_{b}"], frames.get(f"n_negative_{b}"), steps, ctx["start"],
                              ctx["end"])
            for b in ("unloading", "loading")
            if f"lambda_min_{b}" in frames and np.isfinite(frames[f"lambda_min_{b}"]).any()}
    leads = predictor_leads(ctx["frame_scores"], ctx["start"])
    text = verdict(rows, lead) + "".join(
        f"\n{name} in its top quarter up to an event's start: {v['share_led']:.2f} of events (independent frames "
        f"at its base rate: {v['null_share_led']:.2f}), mean lead {v['mean_lead']:.2f} frames (independent: "
        + ("n/a" if v["null_mean_lead"] is None else f"{v['null_mean_lead']:.2f}") + ")."
        for name, v in leads.items())
    if not any(r["predictor"] == "softness" for r in rows):
        import importlib.util
        text += "\n" + (baselines.MISSING if importlib.util.find_spec("sklearn") is None else
                        "softness not computed: no target had both classes in the first half of the frames")
    clean = [{k: (_num(v) if isinstance(v, float) else v) for k, v in r.items()} for r in rows]
    (out_dir / "prediction.json").write_text(json.dumps(clean, indent=1))
    (out_dir / "prediction_lead.json").write_text(json.dumps({**lead, "frame_predictors": leads}, indent=1))
    (out_dir / "prediction.txt").write_text(header(ctx["window"]) + "\n" + text + "\n"
                                            + proven_frames(frames, ctx["order"]) + "\n")
    return {"rows": clean, "lead": lead, "frame_predictors": leads, "verdict": text}


def header(window: int) -> str:
    """The fixed targets, conventions, metrics and the baselines' definitions, stated before the results."""
    lines = [f"window W = {window} frames; targets (fixed before the results):"]
    lines += [f"  {k}: {v}" for k, v in TARGETS.items()]
    lines.append("scores oriented so that AUC > 0.5 is predictive (negated: "
                 + ", ".join(k for k, s in {**PARTICLE, **FRAME}.items() if s < 0) + ")")
    lines.append(f"metrics: AUC (Mann–Whitney, ties one half), AP (average precision), precision_top5 (the positives' "
                 f"share of the top {scores.TOP:.0%} of scores); 95 % intervals: percentile bootstrap, "
                 f"{scores.N_BOOT} resamples, seed {scores.SEED}; per-particle targets resample runs of ⌈F^(1/3)⌉ "
                 "contiguous frames (a frame's particles are correlated, and a particle's consecutive windows), the "
                 f"event target runs of W frames; with fewer than {scores.MIN_EVENTS} blocks holding a positive no "
                 "interval is given (null, note: too few events, or too few frames): "
                 "below that the random score's AUC interval covered 0.5 in fewer than 93 % of seeds")
    lines.append("baselines of the field (beside coordination, mobilised_fraction, force_magnitude, sliding_distance, "
                 "random):")
    lines += [f"  {k}: {v}" for k, v in DEFINITIONS.items()]
    return "\n".join(lines)


def proven_frames(frames: dict, order: np.ndarray) -> str:
    """Which frames' whole-packing verdicts are proven, which hinge on an S within the tolerance (frames.parquet's
    whole_proven, whole_hinges_on_tolerance; −1: --whole not run)."""
    proven = frames.get("whole_proven")
    if proven is None or not np.any(proven >= 0):
        return "whole-packing verdicts: not computed (track without --whole)."
    yes = order[proven == 1].tolist()
    hinge = order[frames.get("whole_hinges_on_tolerance", np.zeros(len(order))) == 1].tolist()
    text = (f"whole-packing verdicts proven at {len(yes)} of {int(np.sum(proven >= 0))} frames"
            + (f" (frames {', '.join(map(str, yes))})" if yes else "")
            + "; the others are not determined (frames.parquet whole_reason says why)")
    return text + (f"; hinging on an S within the tolerance at frames {', '.join(map(str, hinge))}." if hinge
                   else ".")
