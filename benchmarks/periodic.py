"""Whole periodic packings (issue 24): `granstab.analyze` of a whole periodic packing of frictional disks (the sparse
path above the dense limit: its lowest modes, counts by inertia, the two translations as the only rigid zeros) and
`granstab.moduli`, each case in a fresh subprocess (`granstab_bench.periodic_child`) so that its peak resident memory
is its own. Goals of the issue: 10⁵ disks analysed in ≤ 20 s and ≤ 2.5 GB; moduli of 10⁴ disks in ≤ 10 s."""
from __future__ import annotations

import json
import os
import subprocess
import sys

from .formatting import fmt_t, progress, table
from .scaling import ROOT

QUICK = {"analyze": (700,), "moduli": (300,), "sliding": 2}   # analyze: above the dense limit still
FULL = {"analyze": (10_000, 100_000), "moduli": (10_000,), "sliding": 2}
GOALS = {"analyze": (100_000, 20.0, 2.5 * 1024), "moduli": (10_000, 10.0, None)}   # particles, seconds, MB


def child(kind: str, n: int, sliding: int) -> dict:
    """One case in a fresh interpreter; {"failed": the last stderr line} if it fails."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, "-m", "granstab_bench.periodic_child", kind, str(n), str(sliding)],
                          capture_output=True, text=True, timeout=1800, env=env, cwd=ROOT)
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines() or ["no output"]
        return {"kind": kind, "particles": n, "failed": lines[-1][:120]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    cases = [(kind, n) for kind in ("analyze", "moduli") for n in cfg[kind]]
    bar = progress(len(cases), "periodic (subprocesses)")
    data = []
    for kind, n in cases:
        bar.set_postfix_str(f"{kind} N={n}")
        data.append(child(kind, n, cfg["sliding"]))
        bar.update()
    bar.close()
    return {"cases": data, "goals": GOALS}


def _goal(d: dict) -> str:
    """Whether the case at the goal's size met it (time and memory) and, where missed, by how much; else "—"."""
    size, seconds, mb = GOALS[d["kind"]]
    if abs(d["particles"] - size) > 0.02 * size:
        return "—"
    t = d["t_scene"] + d["t_run"]
    cpu = (f" (CPU time {d['cpu_run']:.0f} s, 1-minute load {max(d['load']):.0f} on 2 cores)"
           if "cpu_run" in d else "")
    over = ([f"time {t:.0f} s, {t / seconds:.1f}× the goal{cpu}"] if t > seconds else []) + \
           ([f"memory {d['peak_mb']:.0f} MB, {d['peak_mb'] - mb:.0f} MB ({d['peak_mb'] / mb - 1:.0%}) over"]
            if mb is not None and d["peak_mb"] > mb else [])
    goal = f"≤ {seconds:g} s" + ("" if mb is None else f", ≤ {mb / 1024:g} GB")
    return f"missed ({goal}): " + "; ".join(over) if over else f"met ({goal})"


def markdown(results: dict) -> str:
    rows = []
    for d in results["cases"]:
        if "failed" in d:
            rows.append([d["kind"], f"{d['particles']:,}", "failed: " + d["failed"]] + [""] * 9)
            continue
        what = (f"{d['backend']}, {d['branches']} branches, {d['verdict']}, rigid zeros {d['rigid']}, counts "
                f"{'exact' if d['exact_counts'] else 'not proven'}, λ_min {d['lambda_min']:.3g}, error "
                f"{d['error']:.1e}" if d["kind"] == "analyze" else
                f"{d['branches']} branches, bulk {d['bulk']:.4g}, shear {d['shear']:.4g}, residual "
                f"{d['residual']:.1e}, symmetry defect {d['symmetry_defect']:.1e}")
        rows.append([d["kind"], f"{d['particles']:,}", f"{d['contacts']:,} ({d['seam']:,} across the seam)",
                     f"{d['dof']:,}", str(d["sliding"]), fmt_t(d["t_scene"]), fmt_t(d["t_run"]),
                     fmt_t(d["cpu_run"]), "{:.1f} → {:.1f}".format(*d["load"]), f"{d['peak_mb']:.0f} MB", what,
                     _goal(d)])
    return "\n".join([
        "## Whole periodic packings: analyze and moduli",
        "",
        "A periodic packing of frictional disks (`granstab_bench.periodic_child.periodic_packing`: a jittered "
        "triangular lattice closing on itself in the cell, polydisperse radii, tangential forces up to half the "
        "cone, two contacts exactly at yield, so four branches), each case in a fresh subprocess: peak resident "
        "memory above the interpreter's baseline. `analyze` is `granstab.analyze(scene, k=6, metric=\"L\")` (the "
        "sparse path above `sparse.DENSE_MAX_DOF` dofs: the lowest 6 eigenpairs of every branch, the count below σ "
        "by inertia; the two translations are the only rigid motions of a periodic scene); `moduli` is "
        "`granstab.moduli(scene)` (the elastic and all-loading branches). The goals are the issue's (issue 24). "
        "*run CPU*: the process's CPU time over the run (every thread); *load*: the 1-minute load average at the "
        "case's start and end, on 2 cores shared with other work: wall times above a load of 2 are stretched by it.",
        "",
        table(["", "particles", "contacts", "dofs", "sliding", "build", "run", "run CPU", "load", "peak memory",
               "result", "goal"], rows),
    ])
