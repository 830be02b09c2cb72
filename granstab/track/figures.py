"""The figures of a track folder (issue 27; matplotlib, the `scan` extra), each as PNG and SVG:

- `timeline`: λ_min(t) of the all-unloading and all-loading branches on a signed log scale (symlog, linear within
  the smallest |λ_min|; eq:instab: below zero a consistent negative mode), the frames whose whole-packing verdict
  is proven starred, above the shear stress and the pressure, the events of events.json shaded on both;
- `maps`: for chosen frames (the frame each of the largest events starts from, else evenly spaced ones), the
  instability map (the share of a particle's clusters that are unstable, the scan's colours; the soft-mode
  participation where no scan was run), its clusters' lowest λ_min where the scan gave it, and the D²min of the
  window that starts there (logarithmic);
- `roc`: the ROC curves of the prediction test, one panel a target, the same scores and labels as prediction.json
  (`predict.cases`), softness left out (its classifier is the prediction test's; refitting it for a figure took as
  long as the test itself on 2,000 disks × 200 frames).

3D packings are drawn as their projection on x-y. Particles are drawn with the dump's radius where the folder has a
`radius` column, else with half the distance to their nearest neighbour (in 3D, in space).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..scan.figure import GREY, _disks, _save
from . import predict

N_MAPS = 3


def write(out_dir, frames: list[int] | None = None) -> list[Path]:
    """timeline, maps and roc (.png, .svg) in out_dir; `frames`: the frame numbers of the maps (default: chosen)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out_dir = Path(out_dir)
    found, ctx = predict.cases(out_dir, structure_wanted=False)
    events = json.loads((out_dir / "events.json").read_text())
    particles = predict.read_columns(out_dir / "particles.parquet")
    paths = timeline(plt, ctx, events, out_dir / "timeline")
    chosen = chosen_frames(ctx, particles, events) if frames is None else list(frames)
    paths += maps(plt, particles, chosen, ctx["window"], out_dir / "maps")
    return paths + roc(plt, found, out_dir / "roc")


def timeline(plt, ctx: dict, events: list[dict], stem: Path) -> list[Path]:
    """λ_min(t) above the stress(t), events shaded; x: the step where the folder has one, else the frame."""
    f = ctx["frames"]
    x = f["step"] if "step" in f and np.isfinite(f["step"]).all() else ctx["order"].astype(float)
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7.5, 5.5), height_ratios=(1, 1.3))
    drawn = []
    for branch, colour in (("unloading", "tab:blue"), ("loading", "tab:red")):
        lam = f.get(f"lambda_min_{branch}")
        if lam is not None and np.isfinite(lam).any():
            top.plot(x, lam, "o-", ms=3, color=colour, label=f"all-{branch}")
            drawn.append(lam)
    proven = f.get("whole_proven")
    if drawn and proven is not None and np.any(proven == 1):
        low = np.nanmin(np.concatenate(drawn))
        top.plot(x[proven == 1], np.full(int(np.sum(proven == 1)), low), "k*", ms=7,
                 label="verdict proven (eq:stab / eq:instab)")
    top.axhline(0, color="k", lw=0.6)
    if drawn:
        both = np.abs(np.concatenate(drawn))
        both = both[np.isfinite(both) & (both > 0)]
        top.set_yscale("symlog", linthresh=float(np.min(both)) if both.size else 1.0)
        top.legend(fontsize=8, title="λ_min of the whole packing (signed log scale)", title_fontsize=8, loc="best")
    else:
        top.text(0.5, 0.5, "λ_min not computed (track without --whole)", ha="center", va="center",
                 transform=top.transAxes, color="0.4")
    top.set_ylabel("λ_min (force / length)")
    bottom.plot(x, f["shear_stress"], "o-", ms=3, color="k", label="shear stress")
    if "pressure" in f:
        bottom.plot(x, f["pressure"], "-", color="0.6", label="pressure")
    for k, (a, b) in enumerate(zip(ctx["start"], ctx["end"])):
        for ax in (top, bottom):
            ax.axvspan(x[a], x[b], color="orange", alpha=0.35, lw=0, label="event" if k == 0 and ax is bottom
                       else None)
    bottom.set_ylabel("stress")
    bottom.set_xlabel("step" if x is not ctx["order"] and "step" in f else "frame")
    bottom.legend(fontsize=8)
    quantity = events[0]["quantity"] if events else "shear_stress"
    top.set_title(f"{len(events)} events (drops of {quantity}); window W = {ctx['window']} frames", fontsize=10)
    return _save(fig, stem)


def chosen_frames(ctx: dict, particles: dict, events: list[dict]) -> list[int]:
    """Up to N_MAPS frame numbers whose window is inside the run: those the largest events start from, else evenly
    spaced ones."""
    ok = np.unique(particles["frame"][np.isfinite(particles["d2min"])])
    by_size = [e["frame"] for e in sorted(events, key=lambda e: -e["drop"]) if e["frame"] in ok]
    if by_size:
        return sorted(by_size[:N_MAPS])
    return sorted({int(v) for v in ok[np.linspace(0, len(ok) - 1, min(N_MAPS, len(ok))).astype(int)]}) if len(
        ok) else []


def drawing_radii(xy: np.ndarray, cols: dict, rows: np.ndarray) -> np.ndarray:
    """The folder's `radius` where it has one, else half the distance to the nearest other centre (in 3D over all
    three coordinates, not the projection)."""
    if "radius" in cols:
        return cols["radius"][rows]
    from scipy.spatial import cKDTree
    if len(xy) < 2:
        return np.full(len(xy), 0.5)
    d, _ = cKDTree(xy).query(xy, k=2)
    return 0.5 * d[:, 1]


def maps(plt, cols: dict, chosen: list[int], window: int, stem: Path) -> list[Path]:
    """One row a chosen frame: the instability map, the clusters' λ_min where the scan gave it, and the D²min of
    the window that starts there."""
    field = "unstable_fraction" if _finite(cols, "unstable_fraction") else (
        "soft_participation" if _finite(cols, "soft_participation") else None)
    panels = 3 if _finite(cols, "cluster_lambda_min") else 2
    fig, axes = plt.subplots(max(len(chosen), 1), panels, figsize=(5 * panels, 4.6 * max(len(chosen), 1)),
                             squeeze=False)
    for row, frame in zip(axes, chosen):
        rows = cols["frame"] == frame
        centres = np.stack([cols[k][rows] for k in ("x", "y", "z") if k in cols], 1)
        xy, r = centres[:, :2], drawing_radii(centres, cols, rows)
        value = cols[field][rows] if field else np.full(len(xy), np.nan)
        pc = _disks(row[0], xy, r, value, np.zeros(len(xy), bool))
        row[0].set_title(f"frame {frame}: {field or 'no instability map (track without --scan/--whole)'}",
                         fontsize=9)
        fig.colorbar(pc, ax=row[0], shrink=0.8)
        if panels == 3:
            _scaled(fig, row[1], xy, r, cols["cluster_lambda_min"][rows], "RdBu", symmetric=True)
            row[1].set_title(f"frame {frame}: its clusters' lowest λ_min (< 0: unstable)", fontsize=9)
        _scaled(fig, row[-1], xy, r, cols["d2min"][rows], "viridis", symmetric=False)
        row[-1].set_title(f"D²min over frames ({frame}, {frame} + {window}]", fontsize=9)
    if not chosen:
        axes[0][0].text(0.5, 0.5, "no frame has a window inside the run", ha="center", transform=axes[0][0].transAxes)
    return _save(fig, stem)


def _finite(cols: dict, key: str) -> bool:
    return key in cols and bool(np.isfinite(cols[key]).any())


def _scaled(fig, ax, xy, r, value, cmap: str, symmetric: bool) -> None:
    """Disks coloured on a logarithmic scale (D²min) or a symmetric one, linear within the median |value| (λ_min)."""
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, SymLogNorm
    pc = _disks(ax, xy, r, value, np.zeros(len(xy), bool))
    pc.set_cmap(colormaps[cmap].with_extremes(bad=GREY))            # NaN grey, as in the scan's map
    ok = value[np.isfinite(value)]
    if symmetric and ok.size:
        top = float(np.abs(ok).max()) or 1.0
        pc.set_norm(SymLogNorm(linthresh=float(np.median(np.abs(ok))) or top, vmin=-top, vmax=top))
    elif (ok > 0).any():
        pos = ok[ok > 0]
        pc.set_norm(LogNorm(vmin=max(pos.min(), pos.max() * 1e-6), vmax=pos.max()))
    fig.colorbar(pc, ax=ax, shrink=0.8)


def roc(plt, found: list, stem: Path) -> list[Path]:
    """One panel a target with both classes: every predictor's ROC curve, its AUC in the legend (random dashed)."""
    targets = [t for t in predict.TARGETS if any(c[0] == t and c[3].any() and not c[3].all() for c in found)]
    fig, axes = plt.subplots(1, max(len(targets), 1), figsize=(4.6 * max(len(targets), 1), 4.8), squeeze=False)
    for ax, target in zip(axes[0], targets):
        for _, name, score, label, _ in (c for c in found if c[0] == target):
            if label.all() or not label.any():
                continue
            fpr, tpr = predict.roc_curve(score, label)
            ax.plot(fpr, tpr, "--" if name == "random" else "-", lw=1.2,
                    label=f"{name} {predict.auc(score[np.isfinite(score)], label[np.isfinite(score)]):.2f}")
        ax.plot([0, 1], [0, 1], color="0.7", lw=0.8)
        ax.set_title(f"{target}", fontsize=10)
        ax.set_xlabel("false positive rate")
        ax.set_ylabel("true positive rate")
        ax.set_aspect("equal")
        ax.legend(fontsize=6.5, loc="lower right", title="AUC", title_fontsize=7)
    if not targets:
        axes[0][0].text(0.5, 0.5, "no target has both classes", ha="center", transform=axes[0][0].transAxes)
    return _save(fig, stem)
