"""A whole 300-disk DEM packing (issue 26): LAMMPS's examples/dem/in.disks300 run here, converted at the end of its
shear, 7 contacts at the friction limit kept (2^7 = 128 branches, as in the issue's packing; 1 in quick mode), and
analysed whole: the up-front estimate beside the measured time, one metric and the family, the path each branch
took; the full per-branch path (eig + SVD of every branch) timed on the packing's all-elastic branch, beside the
low-rank path on the same branch (not in quick mode)."""
from __future__ import annotations

import dataclasses
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import granstab
from granstab.io import load
from granstab.mechanics.metric import family
from granstab.solve.budget import estimate
from granstab.solve.lowrank import use_lowrank
from granstab.solve.threads import cores

from .formatting import fmt_t, table
from .timing import once

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "dem" / "in.disks300"
STEP = 18000     # the end of the shear: contacts at the friction limit
CPU_RATIO = (0.5, 3.0)   # the estimate's CPU seconds (budget.estimate, one worker) over the analysis's CPU time


def packing(n_sliding: int):
    """The converted packing with only its first `n_sliding` contacts at yield left sliding (the others elastic)."""
    if shutil.which("lmp") is None:
        raise RuntimeError("the packing300 benchmark runs Debian's LAMMPS: apt-get install lammps (lmp)")
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(["lmp", "-in", str(SCRIPT), "-log", "none", "-screen", "none"], cwd=tmp, check=True,
                       timeout=300)
        scene = load([Path(tmp) / "atoms300.dump", Path(tmp) / "contacts300.dump", SCRIPT], timestep=STEP).scene
    state = np.asarray(scene.state, dtype=object)
    state[np.flatnonzero(scene.at_yield())[n_sliding:]] = "elastic"
    return dataclasses.replace(scene, state=tuple(state))


def _case(name: str, scene, metric: str, **options) -> dict:
    n_metrics = len(family(scene, None)) if metric == "family" else 1
    n_branches = 2 ** int(np.sum(scene.at_yield()))
    lowrank = options.get("lowrank", use_lowrank(n_branches, scene.n_dof))
    guess = estimate(scene.n_dof, n_branches, n_metrics, lowrank=lowrank, workers=cores())
    cpu_guess = estimate(scene.n_dof, n_branches, n_metrics, lowrank=lowrank, workers=1)
    cpu = time.process_time()
    seconds, result = once(lambda: granstab.analyze(scene, metric=metric, **options))
    cpu = time.process_time() - cpu
    return {"case": name, "metrics": n_metrics, "branches": n_branches, "paths": result.cost["paths"],
            "estimate_s": guess, "seconds": seconds, "cpu_s": cpu, "estimate_cpu_s": cpu_guess,
            "estimate_within": bool(CPU_RATIO[0] <= cpu_guess / cpu <= CPU_RATIO[1]),
            "verdict": result.summary["verdict"], "consistent_negative": result.summary["consistent_negative"]}


def run(quick: bool = False) -> dict:
    n_sliding = 1 if quick else 7
    scene = packing(n_sliding)
    rows = [_case(f"whole packing, metric L, {n_sliding} sliding", scene, "L")]
    if not quick:
        elastic = packing(0)
        rows += [_case(f"whole packing, metric family, {n_sliding} sliding", scene, "family"),
                 _case("its all-elastic branch, metric L, full path", elastic, "L", lowrank=False),
                 _case("its all-elastic branch, metric L, low-rank path", elastic, "L", lowrank=True)]
    return {"particles": scene.n_particles, "contacts": scene.n_contacts, "n_dof": scene.n_dof,
            "n_sliding": n_sliding, "cores": cores(), "rows": rows}


def markdown(results: dict) -> str:
    r = results
    lines = ["## A 300-disk DEM packing, whole (issue 26)", "",
             f"LAMMPS's `examples/dem/in.disks300` (300 frictional disks, sheared), converted at step {STEP}: "
             f"{r['particles']} disks, {r['contacts']} contacts, {r['n_dof']} dofs, {r['n_sliding']} contacts at "
             "the friction limit kept sliding (the others elastic). `estimate` is what `granstab analyze` "
             f"computes before any work (`solve/budget.py`, CPU time of {r['cores']} free cores) to refuse work over "
             "10 s or over `--timeout`; `paths` counts the branches each path solved over all metrics.", "",
             table(["case", "metrics", "branches", "paths", "estimate", "measured", "estimate / CPU time",
                    "verdict"],
                   [[c["case"], c["metrics"], c["branches"], ", ".join(f"{k} {v}" for k, v in c["paths"].items()),
                     fmt_t(c["estimate_s"]), fmt_t(c["seconds"]),
                     f"{fmt_t(c['estimate_cpu_s'])} / {fmt_t(c['cpu_s'])}"
                     + ("" if c["estimate_within"] else " **(outside 0.5–3)**"),
                     f"{c['verdict']} ({c['consistent_negative']} consistent negative)"] for c in r["rows"]]),
             "", "`estimate / CPU time`: the estimate for one core (`estimate(..., workers=1)`) beside the process's "
             f"CPU time for the analysis (all its threads; not wall time, so the load of the moment counts less): "
             f"the estimate is checked to lie within {CPU_RATIO[0]}–{CPU_RATIO[1]}× of it (flagged otherwise)."]
    if len(r["rows"]) > 2:
        full, low = r["rows"][-2], r["rows"][-1]
        lines += ["", f"One branch of this packing: the full path {fmt_t(full['seconds'])}, the low-rank path "
                  f"{fmt_t(low['seconds'])} (each with its once-per-cluster set-up); the full path's eig and SVD of "
                  "every 900 × 900 branch were what made such a packing take minutes a metric."]
    return "\n".join(lines)
