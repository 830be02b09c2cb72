"""The local stability scan (issue 10): clusters per second serially and on 2 local Dask workers, in one run, on
random 2D and 3D packings (rings = 1); the cost of a cluster split into extraction and analysis; and, from these
measured costs, the time a 10⁶-particle scan would take on 1, 16 and 256 workers and where the bottleneck moves."""
from __future__ import annotations

import statistics
import tempfile
import time

import numpy as np

from granstab import analyze, packings
from granstab.scan import members, scan, subscene

TASK_OVERHEAD_S = 1e-3      # Dask's documented scheduler cost per task (order of magnitude), for the extrapolation
CHUNK = 64


def _scan_rate(scene, workers: int) -> tuple[float, dict]:
    with tempfile.TemporaryDirectory() as out:
        t = time.perf_counter()
        summary = scan(scene, out, workers=workers, figures=False)
        return time.perf_counter() - t, summary


def _per_cluster(scene, n: int) -> dict:
    """Median seconds per cluster to extract it and to analyse it (metric L), over n centres."""
    centers = np.linspace(0, scene.n_particles - 1, n).astype(int)
    t_extract, t_analyze = [], []
    for keep in members(scene, centers, 1):
        t = time.perf_counter()
        sub = subscene(scene, keep)
        t_extract.append(time.perf_counter() - t)
        t = time.perf_counter()
        analyze(sub, metric="L")
        t_analyze.append(time.perf_counter() - t)
    return {"extract_s": statistics.median(t_extract), "analyze_s": statistics.median(t_analyze)}


def run(quick: bool = False) -> dict:
    sizes = {2: 300 if quick else 3000, 3: 150 if quick else 1000}
    rows = []
    for dim, n in sizes.items():
        scene = packings.random_packing(dim, n, n_sliding=0, mobilised=0.5, seed=2)
        serial_s, summary = _scan_rate(scene, 1)
        dask_s, summary2 = _scan_rate(scene, 2)
        rows.append({"dim": dim, "n_particles": scene.n_particles, "n_contacts": scene.n_contacts,
                     "serial_s": serial_s, "dask2_s": dask_s, "speedup_2_workers": serial_s / dask_s,
                     "clusters_per_s_serial": scene.n_particles / serial_s,
                     "clusters_per_s_dask2": scene.n_particles / dask_s,
                     "same_verdicts": summary["verdicts"] == summary2["verdicts"], "verdicts": summary["verdicts"],
                     **_per_cluster(scene, 20 if quick else 100)})
    return {"rows": rows, "extrapolation": _extrapolate(rows[0])}


def _extrapolate(row: dict) -> list[dict]:
    """10⁶ particles (2D, rings = 1) from the measured per-cluster costs: compute / workers against the scheduler's
    per-task cost (serial at the scheduler) and reading an NPZ of 3·10⁶ contacts (≈ 3 s per 10⁶, BENCHMARKS.md)."""
    n = 1_000_000
    per_cluster = row["serial_s"] / row["n_particles"]
    out = []
    for workers in (1, 16, 256):
        compute = n * per_cluster / workers
        scheduling = n / CHUNK * TASK_OVERHEAD_S
        reading = 9.0
        parts = {"compute": compute, "scheduling": scheduling, "reading": reading}
        out.append({"workers": workers, "hours": (max(compute, scheduling) + reading) / 3600,
                    "bottleneck": max(parts, key=parts.get), **parts})
    return out


def markdown(results: dict) -> str:
    lines = ["## The local scan: clusters per second (issue 10)", "",
             "`granstab scan` (rings = 1, metric L) on random packings, serially (`--workers 1`) and on a 2-worker "
             "local Dask cluster in the same run (its start-up included); per cluster, the median cost of extracting "
             "it and of `analyze` on it. This 2-core machine is shared, so the 2-worker ratio is a lower bound.", "",
             "| packing | particles | contacts | serial | 2 workers | speed-up | clusters/s (serial) | "
             "extract / cluster | analyze / cluster | verdicts |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        lines.append(f"| {r['dim']}D random | {r['n_particles']:,} | {r['n_contacts']:,} | {r['serial_s']:.1f} s | "
                     f"{r['dask2_s']:.1f} s | {r['speedup_2_workers']:.2f}× | {r['clusters_per_s_serial']:.0f} | "
                     f"{1e3 * r['extract_s']:.1f} ms | {1e3 * r['analyze_s']:.1f} ms | "
                     + ", ".join(f"{k} {v}" for k, v in r["verdicts"].items())
                     + ("" if r["same_verdicts"] else " (**differ between serial and Dask**)") + " |")
    lines += ["", "A 10⁶-particle 2D scan extrapolated from the serial rate above (compute / workers, the scheduler's "
              f"~{TASK_OVERHEAD_S * 1e3:.0f} ms a task for {CHUNK} clusters a task, reading an NPZ snapshot):", "",
              "| workers | compute | scheduling | reading | total | bottleneck |", "|---|---|---|---|---|---|"]
    for e in results["extrapolation"]:
        lines.append(f"| {e['workers']} | {e['compute']:.0f} s | {e['scheduling']:.0f} s | {e['reading']:.0f} s | "
                     f"{e['hours'] * 60:.1f} min | {e['bottleneck']} |")
    lines += ["", "Each cluster is one `analyze` call: stacking the eigenproblems of same-size clusters into one "
              "LAPACK call (the issue's ≥ 10× goal) is not done yet.", ""]
    return "\n".join(lines)
