"""What the metric family (issue 11) costs: analyze(metric="family") against the single-metric path (metric="L")
in one run, per scene: median wall times, their ratio, and the verdicts and consistent counts of every metric
side by side with the achieved accuracy (largest eigen-residual, smallest zero margin)."""
from __future__ import annotations

import statistics
import time
from pathlib import Path

import granstab
from granstab.model import packings

from .timing import repeats

ROOT = Path(__file__).resolve().parents[1]


def _scenes(quick: bool) -> dict:
    out = {"four_disk (16 branches, 12 dof)": granstab.load_scene(ROOT / "presets" / "four_disk.toml"),
           "ellipsoid_trio (3D shapes, masses)": granstab.load_scene(ROOT / "presets" / "ellipsoid_trio.toml"),
           "annulus_frame (143 disks, 429 dof)": granstab.load_scene(ROOT / "presets" / "annulus_frame.json")}
    if not quick:
        out["random 2D packing, 1,500 disks (sparse, 4,500 dof)"] = packings.random_packing(2, 1500, seed=1)
    return out


def _interleaved(fns: dict, repeat: int) -> dict:
    """Median wall time and last result of each function, runs interleaved so that load drift hits all alike."""
    times = {k: [] for k in fns}
    results = {}
    for _ in range(repeat):
        for k, fn in fns.items():
            t = time.perf_counter()
            results[k] = fn()
            times[k].append(time.perf_counter() - t)
    return {k: (statistics.median(v), results[k]) for k, v in times.items()}


def run(quick: bool = False) -> dict:
    repeat = repeats(3 if quick else 5)
    rows = []
    for name, scene in _scenes(quick).items():
        runs = _interleaved({"L": lambda s=scene: granstab.analyze(s, metric="L"),
                             "family": lambda s=scene: granstab.analyze(s, metric="family")}, repeat)
        (t_single, single), (t_family, family) = runs["L"], runs["family"]
        s = family.summary
        rows.append({
            "scene": name, "backend": family.backend, "n_dof": scene.n_dof, "branches": s["n_branches"],
            "single_s": t_single, "family_s": t_family, "ratio": t_family / t_single,
            "n_metrics": len(s["metrics"]), "metric_robust": s["metric_robust"],
            "metrics": s["metrics"], "verdict": s["verdict"], "sufficient": s["sufficient"],
            "eigen_residual_stability": family.errors["eigen_residual_stability"],
            "zero_margin": s["zero_margin"],
            "same_primary": single.summary["consistent_negative"] == s["consistent_negative"],
        })
    return {"repeat": repeat, "rows": rows}


def markdown(results: dict) -> str:
    lines = ["## The metric family: cost and robustness (issue 11)", "",
             "`analyze` evaluates the verdict in L/10, L, 10L (and the inertia metric where masses are known); the "
             "blocks and the assembly are shared, the projection and the eigenproblems are redone per metric. "
             f"Median of {results['repeat']} interleaved runs each, same machine, same process.", "",
             "| scene | backend | dof | branches | single metric (s) | family (s) | ratio | metrics: verdict +/- "
             "| robust | eigen-residual | zero margin |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        fam = "; ".join(f"{e['metric']} {e['verdict']} {e['consistent_positive']}/{e['consistent_negative']}"
                        for e in r["metrics"])
        margin = "–" if r["zero_margin"] is None else f"{r['zero_margin']:.3g}"
        lines.append(f"| {r['scene']} | {r['backend']} | {r['n_dof']} | {r['branches']} | {r['single_s']:.3g} | "
                     f"{r['family_s']:.3g} | {r['ratio']:.2f} | {fam} | {r['metric_robust']} | "
                     f"{r['eigen_residual_stability']:.1e} | {margin} |")
    lines += ["", "`--metric L` (API `metric=\"L\"`) keeps the single-metric path at the single-metric price."]
    return "\n".join(lines) + "\n"
