"""Estimates that hold (issue 38): on every path a run can take, the plan's `cost.estimated_s` (solve/plan.py, what
`granstab analyze --plan` prints) beside the measured `timings.total`, as a ratio; measured ≤ 3× the estimate in
either direction is the promise. The cases are the issue's, rebuilt here: a 3D cluster with 13 contacts at yield
(8,192 branches, the metric family: low-rank path), 400 disks with 672 contacts and 1 at yield (floppy: the full
path with ℍ^i spectra), a 1,400-disk packing with hundreds of contacts at yield (--sample-branches 8 --metric L:
the sparse path, shift-invert), the photoelastic annulus frame in micrometres (full path), and a few more paths
(sparse Ritz updates, the attribution controls of an unstable result). `--busy` runs two busy processes beside
each case (load 4 on this 2-core machine)."""
from __future__ import annotations

import dataclasses
import json
import multiprocessing
import time
from pathlib import Path

import numpy as np

import granstab
from granstab.model.packings import random_packing
from granstab.model.scene import equilibrium_loads
from granstab.solve.plan import plan

from .formatting import table

ROOT = Path(__file__).resolve().parents[1]
PROMISE = 3.0          # measured within PROMISE× the estimate, either direction

CONTACT_FIELDS = ("p", "q", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "k", "alpha", "mu",
                  "rolling", "image")


def keep_contacts(scene, keep: np.ndarray):
    """The scene with only the contacts `keep` (indices), its loads those that balance the forces left."""
    arrays = {f: getattr(scene, f)[keep] for f in CONTACT_FIELDS}
    arrays["state"] = tuple(scene.state[i] for i in keep)
    if scene.curvature_sum is not None:
        arrays["curvature_sum"] = scene.curvature_sum[keep]
    out = dataclasses.replace(scene, **arrays)
    b, w = equilibrium_loads(out)
    return dataclasses.replace(out, load=-b, load_moment=-w)


def thinned(n_particles: int, n_contacts: int, n_sliding: int, seed: int = 0):
    """A 2D random packing thinned to `n_contacts` contacts (the sliding ones kept): floppy, as the issue's."""
    scene = random_packing(2, n_particles, n_sliding=n_sliding, seed=seed)
    rng = np.random.default_rng(seed)
    sliding = np.flatnonzero(scene.at_yield())
    others = rng.permutation(np.setdiff1d(np.arange(scene.n_contacts), sliding))[:n_contacts - len(sliding)]
    return keep_contacts(scene, np.sort(np.concatenate([sliding, others])))


def micrometres(scene, factor: float = 1e4):
    """A scene in cm as the same scene in µm: lengths × factor, curvatures and stiffnesses (force per length) /
    factor, moments × factor."""
    s = factor
    return dataclasses.replace(scene, x=scene.x * s, point=scene.point * s, curvature_p=scene.curvature_p / s,
                               curvature_q=scene.curvature_q / s, k=scene.k / s, moment=scene.moment * s,
                               load_moment=scene.load_moment * s, rolling=scene.rolling * s,
                               cell=None if scene.cell is None else scene.cell * s,
                               curvature_sum=None if scene.curvature_sum is None else scene.curvature_sum / s)


def cases(quick: bool = False) -> list:
    """(name, scene, analyze options) of every path (module docstring); quick: smaller, for tests."""
    annulus = granstab.load_scene(ROOT / "presets" / "annulus_frame.json")
    out = [("annulus frame in µm, family (full path)", micrometres(annulus), {}),
           ("3D cluster, 13 at yield, family (low-rank)" if not quick else "3D cluster, 10 at yield (low-rank)",
            random_packing(3, 32, n_sliding=10 if quick else 13, seed=2), {}),
           ("400 disks, 672 contacts, 1 at yield (floppy: full path)" if not quick else
            "150 disks thinned, 1 at yield (floppy: full path)",
            thinned(150, 250, 1) if quick else thinned(400, 672, 1), {}),
           ("1,400 disks, 300 at yield, 8 sampled, L (sparse shift-invert)" if not quick else
            "600 disks sparse, 150 at yield, 8 sampled, L",
            random_packing(2, 600 if quick else 1400, n_sliding=150 if quick else 300, seed=3),
            {"method": "sparse", "metric": "L", "sample_branches": 8}),
           ("1,400 disks, 6 at yield, family (sparse Ritz)" if not quick else "600 disks sparse, 5 at yield, L",
            random_packing(2, 600 if quick else 1400, n_sliding=5 if quick else 6, seed=4),
            {"method": "sparse", "metric": "L" if quick else "family"})]
    return out


def measure(scene, options: dict) -> dict:
    """The plan's estimate and the run's measured total (s), and their ratio measured/estimate."""
    planned = plan(scene, **options)
    start = time.perf_counter()
    result = granstab.analyze(scene, **options)
    wall = time.perf_counter() - start
    est = planned.estimated_s
    return {"estimated_s": est, "measured_s": result.timings["total"], "wall_s": wall, "path": planned.path,
            "floppy": planned.floppy, "run_estimated_s": result.cost["estimated_s"],
            "ratio": result.timings["total"] / est if est else float("inf"),
            "verdict": result.verdict.verdict}


def _spin(stop):
    while not stop.is_set():
        sum(i * i for i in range(10000))


def busy(n: int = 2):
    """Start n busy processes (a load of n beside the run); returns a function that stops them."""
    stop = multiprocessing.Event()
    procs = [multiprocessing.Process(target=_spin, args=(stop,), daemon=True) for _ in range(n)]
    for p in procs:
        p.start()
    time.sleep(1.0)

    def end():
        stop.set()
        for p in procs:
            p.join(5)
    return end


def run(quick: bool = False, loaded: bool = False) -> dict:
    rows, results = [], {}
    for name, scene, options in cases(quick):
        end = busy() if loaded else None
        try:
            got = measure(scene, options)
        finally:
            if end is not None:
                end()
        results[name] = got
        flag = "" if 1 / PROMISE <= got["ratio"] <= PROMISE else "  OUTSIDE 3×"
        rows.append([name, got["path"], f"{got['estimated_s']:.3g} s", f"{got['measured_s']:.3g} s",
                     f"{got['ratio']:.2f}{flag}"])
    print(table(["case", "path", "estimated", "measured", "measured/estimated"], rows))
    return results


def main(argv=None) -> int:
    import argparse
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--busy", action="store_true", help="two busy processes beside each case")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    results = run(args.quick, args.busy)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
