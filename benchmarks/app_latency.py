"""The core calls behind one slider move of the explorer, as app/state.py makes them: the scene build of the
app's models and `granstab.analyze`, for the two-particle pair and a 50-disk 2D scene."""
from __future__ import annotations

import numpy as np

from granstab.analysis import analyze
from granstab.model import shapes
from granstab_app.scenes import ShapeModel, TwoParticleModel

from .formatting import fmt_t, table
from .timing import timeit

QUICK = {"repeats": 7, "min_time": 0.1}
FULL = {"repeats": 50, "min_time": 0.2}


def fifty_disks():
    """50 equal disks on a triangular patch, each pair of neighbours overlapping by 1e-3 (for ShapeModel)."""
    rows, cols = 5, 10
    R, a = 1.0, 2.0 - 1e-3
    return [(f"d{j}{i}", shapes.Disk(R), (((i + 0.5 * (j % 2)) * a, j * a * np.sqrt(3) / 2), 0.0))
            for j in range(rows) for i in range(cols)]


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    reps, min_time = cfg["repeats"], cfg["min_time"]
    pair_model = TwoParticleModel()
    P = pair_model.initial_params()
    shape_model = ShapeModel(dim=2, particles=fifty_disks(), title="50 disks")
    P50 = {**shape_model.initial_params(), "mobilised": 0.5}
    data = {}
    for name, build in (("two-particle pair (6 dofs)", lambda: pair_model.build(P)),
                        ("50 disks, 2D (150 dofs)", lambda: shape_model.build(P50))):
        t_build, scene = timeit(build, repeat=reps, min_time=min_time)
        t_an, res = timeit(lambda s=scene: analyze(s), repeat=reps, min_time=min_time)
        t_both, _ = timeit(lambda b=build: analyze(b()), repeat=reps, min_time=min_time)
        data[name] = {"t_build": t_build, "t_analyze": t_an, "t_total": t_both, "contacts": scene.n_contacts,
                      "timings": res.timings}
    return {"repeats": reps, "scenes": data}


def markdown(results: dict) -> str:
    rows = []
    for name, d in results["scenes"].items():
        parts = ", ".join(f"{k} {fmt_t(v)}" for k, v in d["timings"].items() if k != "total")
        rows.append([name, d["contacts"], fmt_t(d["t_build"]), fmt_t(d["t_analyze"]), f"**{fmt_t(d['t_total'])}**",
                     parts])
    return "\n".join([
        "## App latency",
        "",
        "The core calls behind one slider move (app.scenes (TwoParticleModel.build, ShapeModel.build) + "
        f"granstab.analyze, as app/state.py calls them); medians over ≥ {results['repeats']} repeats.",
        "",
        table(["scene", "contacts", "scene build", "analyze", "build + analyze", "analyze breakdown"], rows),
    ])
