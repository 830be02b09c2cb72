"""The cost of attribution (issue 25): a serial scan with every unstable cluster's attribution (work parts, rim share
and the two batched control solves, mechanics/attribution.py) against the same scan without it
(`--no-attribution`), for the loads boundary and the default (embedded:1), on RigidLibrary's sheared DEM frame where it
is beside the checkout (../shared/data) and on a random packing with contacts at yield. Goal: ≤ 2× a plain scan."""
from __future__ import annotations

import tempfile
from pathlib import Path

from granstab.model import packings
from granstab.scan import scan
from granstab.scan.clusters import DEFAULT_BOUNDARY

from .formatting import table
from .timing import timeit_pair

DATASIM = Path(__file__).resolve().parents[2] / "shared" / "data" / "rigidlibrary" / "DataSim"   # ../shared
QUICK = {"random": 300, "repeat": 1}
FULL = {"random": 5000, "repeat": 5}


def scenes(cfg: dict) -> list:
    """(name, scene) of the packings measured."""
    out = [(f"random 2D, {cfg['random']:,} particles",
            packings.random_packing(2, cfg["random"], n_sliding=cfg["random"] // 10, mobilised=0.5, seed=2))]
    if DATASIM.is_dir():
        from granstab.io import load
        out.insert(0, ("RigidLibrary DataSim (sheared DEM)", load([DATASIM]).scene))
    return out


def _scan(scene, **options):
    with tempfile.TemporaryDirectory() as out:
        return scan(scene, out, workers=1, figures=False, **options)


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    rows = []
    for name, scene in scenes(cfg):
        for boundary in ("loads", DEFAULT_BOUNDARY):
            (plain, _), (full, summary) = timeit_pair(
                lambda s=scene, b=boundary: _scan(s, boundary=b, attribution=False),
                lambda s=scene, b=boundary: _scan(s, boundary=b), repeat=cfg["repeat"], min_time=0.0, values=True)
            rows.append({"packing": name, "n_particles": scene.n_particles, "boundary": boundary,
                         "plain_s": plain, "attributed_s": full, "ratio": full / plain,
                         "unstable": summary["verdicts"].get("unstable", 0), "clusters": summary["clusters"],
                         "mechanisms": summary["mechanisms"]})
    return {"rows": rows, "repeat": cfg["repeat"]}


def markdown(results: dict) -> str:
    lines = ["## Attribution: the overhead of the controls (issue 25)", "",
             "A serial scan (`--workers 1`, rings 1, metric L) with every unstable cluster attributed — its work "
             "parts, rim share and the two control solves (all contacts elastic; the rim held), batched like the "
             "branches — against the same scan with `--no-attribution`; medians of "
             f"{results['repeat']} interleaved run(s) after one warm-up each. Only unstable clusters pay for the controls, so the overhead "
             "grows with their share (goal: ≤ 2× a plain scan).", ""]
    rows = [[r["packing"], f"{r['n_particles']:,}", r["boundary"], f"{r['unstable']:,} of {r['clusters']:,}",
             f"{r['plain_s']:.2f} s", f"{r['attributed_s']:.2f} s", f"**{r['ratio']:.2f}×**",
             ", ".join(f"{k} {v}" for k, v in r["mechanisms"].items() if v) or "–"] for r in results["rows"]]
    lines.append(table(["packing", "particles", "boundary", "unstable", "plain scan", "with attribution",
                        "ratio", "mechanisms"], rows))
    return "\n".join(lines)
