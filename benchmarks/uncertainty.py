"""The cost of the data-uncertainty columns (issue 42): a serial scan with `--force-uncertainty 0.1` (data_robust,
robust_margin: the batched bound first, `data_robustness` per cluster where it does not prove the verdict) against
the same scan without it, on RigidLibrary's annulus experiment 10 (frame 1) where it is beside the checkout
(../shared/data) and on a random packing with contacts at yield. Goal: ≤ 2× a plain scan."""
from __future__ import annotations

import tempfile
from collections import Counter
from pathlib import Path

from granstab.model import packings
from granstab.scan import read_map, scan
from granstab.scan.clusters import DEFAULT_BOUNDARY

from .formatting import table
from .timing import timeit_pair

ANNULUS = Path(__file__).resolve().parents[2] / "shared" / "data" / "rigidlibrary" / "DataAnnulus" / "10"
BAND = {"rel": 0.1, "abs": 0.0}                   # the default: the batched bound only (no search)
QUICK = {"random": 200, "repeat": 1, "centers": "every:20", "real": False}   # quick: the code path, in seconds
FULL = {"random": 2000, "repeat": 3, "centers": "all", "real": True}


def scenes(cfg: dict) -> list:
    """(name, scene) of the packings measured: the annulus frame where it is at hand, then a random packing."""
    from granstab.io import load
    real = [("RigidLibrary annulus 10, frame 1", load([ANNULUS]).scene)] if cfg["real"] and ANNULUS.is_dir() else []
    size = cfg["random"]
    return real + [(f"random 2D, {size:,} particles",
                    packings.random_packing(2, size, n_sliding=size // 10, mobilised=0.5, seed=2))]


def _scan(scene, **options):
    with tempfile.TemporaryDirectory() as out:
        summary = scan(scene, out, workers=1, figures=False, attribution=False, **options)
        if options.get("uncertainty"):
            summary["data_robust"] = dict(Counter(read_map(out)["clusters"]["data_robust"]))
        return summary


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    rows = []
    for name, scene in scenes(cfg):
        for boundary, band in (("loads", BAND), (DEFAULT_BOUNDARY, BAND), (DEFAULT_BOUNDARY, {**BAND, "search": True})):
            (plain, _), (full, summary) = timeit_pair(
                lambda s=scene, b=boundary: _scan(s, boundary=b, centers=cfg["centers"]),
                lambda s=scene, b=boundary, u=band: _scan(s, boundary=b, centers=cfg["centers"], uncertainty=u),
                repeat=cfg["repeat"],
                min_time=0.0, values=True)
            rows.append({"packing": name, "n_particles": scene.n_particles, "boundary": boundary,
                         "search": bool(band.get("search")),
                         "plain_s": plain, "uncertainty_s": full, "ratio": full / plain,
                         "clusters": summary["clusters"], "data_robust": summary["data_robust"]})
    return {"rows": rows, "repeat": cfg["repeat"], "band": BAND}


def markdown(results: dict) -> str:
    band = results["band"]
    lines = ["## Data uncertainty: the cost of data_robust (issue 42)", "",
             f"A serial scan (`--workers 1`, rings 1, metric L, `--no-attribution`) with `--force-uncertainty "
             f"{band['rel']:g}` against the same scan without it; medians of {results['repeat']} interleaved run(s) "
             "after one warm-up each. By default the batched bound decides (holds, or undecided where it does not "
             "prove the verdict) at the cost of one more pass over the eigenpairs (goal: ≤ 2× a plain scan); with "
             "`--search-counterexamples` the clusters it leaves undecided are analysed one by one (the tighter bound, "
             "the branches of contacts of uncertain mobilisation, the counter-example search: depends), so the cost "
             "grows with their share ([uncertainty](docs/uncertainty.md)).", ""]
    rows = [[r["packing"], f"{r['n_particles']:,}", r["boundary"], "yes" if r["search"] else "no", f"{r['clusters']:,}",
             f"{r['plain_s']:.2f} s", f"{r['uncertainty_s']:.2f} s", f"**{r['ratio']:.2f}×**",
             ", ".join(f"{k} {v}" for k, v in sorted(r["data_robust"].items()))] for r in results["rows"]]
    lines.append(table(["packing", "particles", "boundary", "--search-counterexamples", "clusters", "plain scan",
                        "with --force-uncertainty",
                        "ratio", "data_robust"], rows))
    return "\n".join(lines)
