"""The local stability scan (issue 10): the batched path against a loop of `analyze` calls on the same clusters,
whole scans of a 10⁵-particle 2D and a 10⁴-particle 3D packing (serial, 2 Dask workers, and the GPU where CuPy
sees one), the peak memory of a chunk at two packing sizes, and a 10⁶-particle extrapolation from these costs."""
from __future__ import annotations

import os
import statistics
import tempfile
import time
import tracemalloc

import numpy as np

from granstab.model import packings
from granstab.scan import members, read_map, scan
from granstab.scan.run import CHUNK, TASK_SECONDS, chunk_scene, cluster_row, scan_chunk
from granstab.solve.device import gpu_available
from granstab.solve.threads import blas_threads

TASK_OVERHEAD_S = 10e-3     # client and scheduler CPU a task, measured here (a 10⁵ scan in 49 against 13 tasks:
                            # 1.15 against 0.80 s of the client process), for the extrapolation
OPTIONS = {"rings": 1, "metric": "L", "max_sliding": 8, "sample_branches": 32}
QUICK = {"sizes": {2: 3000, 3: 600}, "sample": 128, "memory": (2000, 8000), "repeats": 1, "plain_chunks": 1}
FULL = {"sizes": {2: 100_000, 3: 10_000}, "sample": 512, "memory": (10_000, 100_000), "repeats": 5,
        "plain_chunks": 8}


def packing(dim: int, n: int):
    """A random packing with one contact in ~30 at yield (2^Ms branches per cluster, Ms up to ~5)."""
    return packings.random_packing(dim, n, n_sliding=n // 10, mobilised=0.5, seed=2)


def batched_vs_loop(scene, sample: int) -> dict:
    """The same `sample` clusters: one batched chunk (median of 3) against a loop of `analyze` (one pass)."""
    centers = np.linspace(0, scene.n_particles - 1, sample).astype(int)
    times = []
    for _ in range(3):
        t = time.perf_counter()
        rows = scan_chunk(*chunk_scene(scene, centers, 1), OPTIONS).to_pylist()
        times.append(time.perf_counter() - t)
    t = time.perf_counter()
    ref = [cluster_row(scene, c, keep, OPTIONS) for c, keep in zip(centers, members(scene, centers, 1))]
    loop = time.perf_counter() - t
    same = all((a["verdict"], a["consistent_negative"], a["consistent_positive"]) ==
               (b.verdict, b.consistent_negative, b.consistent_positive) for a, b in zip(rows, ref))
    diff = max(abs(a["lambda_min"] - b.lambda_min) / abs(b.lambda_min) for a, b in zip(rows, ref))
    return {"clusters": sample, "batched_s": statistics.median(times), "loop_s": loop,
            "speedup": loop / statistics.median(times), "same_verdicts": same, "max_rel_diff": diff,
            "paths": {path: sum(r["path"] == path for r in rows) for path in sorted({r["path"] for r in rows})}}


def whole_scan(scene, workers: int = 1, device: str = "cpu", scheduler: str | None = None,
               centers: str = "all", worker_pids: tuple = ()) -> tuple[float, dict]:
    """Seconds of one scan and its rows; with `worker_pids`, also the CPU seconds of the scan alone (_cpu_seconds)."""
    with tempfile.TemporaryDirectory() as out:
        before = _cpu_seconds(worker_pids)
        t = time.perf_counter()
        summary = scan(scene, out, workers=workers, figures=False, device=device, scheduler=scheduler,
                       centers=centers)
        seconds = time.perf_counter() - t
        after = _cpu_seconds(worker_pids)
        rows = read_map(out)["clusters"]
        return seconds, {"summary": summary, "lambda_min": np.asarray(rows["lambda_min"]),
                         "verdict": list(rows["verdict"]), "cpu": {key: after[key] - before[key] for key in after}}


def scaling(scene, repeats: int) -> dict:
    """Whole scans, medians of `repeats`: serially in this process and on local Dask clusters of 1 and of 2 worker
    processes (the scaling 1 → 2 workers: each round starts the cluster, warms it by an untimed scan of every 8th
    centre, as a running one is warm, times one scan and closes it, so that no idle cluster shares the cores), the
    three interleaved round by round so that a shared machine's load falls on all of them alike; then
    `--workers 2` with its cluster's start-up included (what one command costs).

    The CPU seconds of each timed Dask scan are split into the workers' and this process's (the client, which on a
    local cluster also runs the scheduler and the nannies): with them the best 1 → 2 ratio this machine allows is
    `ceiling` = t(1 worker) / max(workers' CPU / 2, all CPU / cores) — the workers cannot finish sooner than that."""
    import dask
    from dask.distributed import Client, LocalCluster

    from granstab.scan.run import WORKER_ENVIRON
    serial, ref = whole_scan(scene)
    times = {"serial": [serial]}
    cpu = {}
    same = True
    for _ in range(repeats):
        for w in (1, 2):
            with dask.config.set({"distributed.nanny.pre-spawn-environ": WORKER_ENVIRON}), \
                    LocalCluster(n_workers=w, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
                with Client(cluster) as client:
                    pids = list(client.run(os.getpid).values())
                whole_scan(scene, scheduler=cluster.scheduler_address, centers="every:8")
                seconds, got = whole_scan(scene, scheduler=cluster.scheduler_address, worker_pids=pids)
            times.setdefault(f"dask{w}", []).append(seconds)
            for key, value in got["cpu"].items():
                cpu.setdefault(f"{key}{w}", []).append(value)
            same &= got["verdict"] == ref["verdict"]
        times["serial"].append(whole_scan(scene)[0])
    for _ in range(max(1, repeats // 2)):
        seconds, got = whole_scan(scene, workers=2)
        times.setdefault("startup2", []).append(seconds)
        same &= got["verdict"] == ref["verdict"]
    med = {key: statistics.median(value) for key, value in times.items()}
    cpu = {key: statistics.median(value) for key, value in cpu.items()}
    cores = os.cpu_count() or 1
    floor2 = max(cpu["workers2"] / 2, (cpu["workers2"] + cpu["client2"]) / cores)
    return {"summary": ref["summary"], "lambda_min": ref["lambda_min"], "verdict": ref["verdict"],
            "seconds": med, "cpu": cpu, "cores": cores, "ceiling_1_to_2": med["dask1"] / floor2,
            "same_verdicts": same, "speedup_1_to_2": med["dask1"] / med["dask2"],
            "speedup_serial_to_2": med["serial"] / med["startup2"]}


def _cpu_seconds(worker_pids: list) -> dict:
    """CPU seconds so far of the worker processes and of this process (all its threads: client, scheduler,
    nannies)."""
    if not worker_pids:
        return {}
    import psutil
    return {"workers": sum(sum(psutil.Process(pid).cpu_times()[:2]) for pid in worker_pids),
            "client": time.process_time()}


def plain_processes(scene, chunks: int = 8) -> dict:
    """What the machine gives two processes, without Dask: the same `chunks` chunks computed by one process alone,
    then by each of two at once (medians of 3). parallel = 2 · t(one) / t(two at once): 2.0 where two cores do not
    slow each other (shared caches, memory bandwidth, a hyperthread pair)."""
    import multiprocessing as mp
    parts = [chunk_scene(scene, np.arange(i * CHUNK, (i + 1) * CHUNK) % scene.n_particles, 1)
             for i in range(chunks)]
    ctx = mp.get_context("spawn")
    one, two = [], []
    with ctx.Pool(2) as pool:
        pool.map(_time_chunks, [parts[:1]] * 2)                                   # warm both processes
        for _ in range(3):
            one.append(pool.apply(_time_chunks, (parts,)))
            two.append(max(pool.map(_time_chunks, [parts, parts], chunksize=1)))
    return {"one_s": statistics.median(one), "two_s": statistics.median(two),
            "parallel": 2 * statistics.median(one) / statistics.median(two)}


def _time_chunks(parts) -> float:
    t = time.perf_counter()
    with blas_threads(1):
        for chunk_scene_, centers in parts:
            scan_chunk(chunk_scene_, centers, OPTIONS)
    return time.perf_counter() - t


def chunk_memory(n: int) -> float:
    """Peak traced memory (MB) of one batched chunk of CHUNK clusters in an n-particle 2D packing (its chunk_scene
    and its rows: what a task holds)."""
    scene = packing(2, n)
    centers = np.arange(min(CHUNK, scene.n_particles))
    tracemalloc.start()
    scan_chunk(*chunk_scene(scene, centers, 1), OPTIONS)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2 ** 20


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    rows = []
    for dim, n in cfg["sizes"].items():
        scene = packing(dim, n)
        row = {"dim": dim, "n_particles": scene.n_particles, "n_contacts": scene.n_contacts,
               "at_yield": int(scene.at_yield().sum()), **batched_vs_loop(scene, cfg["sample"])}
        a = scaling(scene, cfg["repeats"])
        serial = a["seconds"]["serial"]
        row.update(serial_s=serial, scan_vs_loop=(row["loop_s"] / row["clusters"]) / (serial / scene.n_particles),
                   dask1_s=a["seconds"]["dask1"], dask2_s=a["seconds"]["dask2"],
                   startup2_s=a["seconds"]["startup2"], speedup_1_to_2=a["speedup_1_to_2"],
                   speedup_serial_to_2=a["speedup_serial_to_2"], clusters_per_s_serial=scene.n_particles / serial,
                   verdicts=a["summary"]["verdicts"], same_verdicts_dask=a["same_verdicts"], cpu=a["cpu"],
                   ceiling_1_to_2=a["ceiling_1_to_2"])
        if gpu_available():
            gpu, c = whole_scan(scene, 1, device="gpu")
            row["gpu"] = {"seconds": gpu, "clusters_per_s": scene.n_particles / gpu, "vs_cpu_serial": serial / gpu,
                          "same_verdicts": c["verdict"] == a["verdict"],
                          "max_rel_diff": float(np.nanmax(np.abs(c["lambda_min"] - a["lambda_min"])
                                                          / np.abs(a["lambda_min"])))}
        rows.append(row)
    memory = [{"n_particles": n, "peak_MB": chunk_memory(n)} for n in cfg["memory"]]
    return {"rows": rows, "memory": memory, "extrapolation": _extrapolate(rows[0]), "gpu": gpu_available(),
            "repeats": cfg["repeats"], "cores": os.cpu_count(),
            "plain": plain_processes(packing(2, cfg["sizes"][2]), chunks=cfg["plain_chunks"])}


def _extrapolate(row: dict) -> list[dict]:
    """10⁶ particles (2D, rings = 1) from the measured serial rate: compute / workers against the scheduler's
    per-task cost (serial at the scheduler) and reading an NPZ of 3·10⁶ contacts (≈ 3 s per 10⁶, BENCHMARKS.md)."""
    n = 1_000_000
    per_cluster = row["serial_s"] / row["n_particles"]
    out = []
    for workers in (1, 16, 256):
        compute = n * per_cluster / workers
        scheduling = _tasks(n, per_cluster) * TASK_OVERHEAD_S
        reading = 9.0
        parts = {"compute": compute, "scheduling": scheduling, "reading": reading}
        out.append({"workers": workers, "minutes": (max(compute, scheduling) + reading) / 60,
                    "bottleneck": max(parts, key=parts.get), **parts})
    return out


def _tasks(n: int, per_cluster: float) -> float:
    """Dask tasks of a scan of n clusters (run.Guide): TASK_SECONDS[1] of compute each, at most CHUNK clusters."""
    return max(n / CHUNK, n * per_cluster / TASK_SECONDS[1])


def markdown(results: dict) -> str:
    lines = ["## The local scan: clusters per second (issue 10)", "",
             "`granstab scan` (rings = 1, metric L, max-sliding 8) on random packings with one contact in ~30 at "
             "yield. **The batched scan against a loop of `analyze`**: a loop of `analyze` calls (`cluster_row`: cut "
             "the cluster, analyse it; one pass over evenly spread clusters) against (a) the same clusters as one "
             "batched chunk (`granstab/scan/batch.py`: their chunk scene cut out, the stacked eigenproblems per "
             "cluster size; median of 3; spread centres share few contacts, the batched path's worst case) and (b) "
             "the whole serial scan below, per cluster (every particle a centre, rows written). The error is the "
             "largest relative difference of λ_min between batched and loop; *paths*: how the sampled rows were "
             "made (`batched`: eigenvectors and residual bounds; `batched-values`: no sliding contact, eigenvalues "
             "only with a-priori bounds; `analyze`: handed back). **Whole scan**, medians of "
             f"{results['repeats']}: serially in this process (`--workers 1`); on running local Dask clusters of 1 "
             "and of 2 single-threaded worker processes (`--scheduler`: the scaling 1 → 2 workers; each round starts "
             "the cluster, warms it by an untimed scan of every 8th centre, as a running one is warm, times a scan and "
             "closes it, so that no idle cluster shares the cores; serial, 1 and 2 workers interleaved round by "
             "round so that the shared machine's load falls on all three alike); `--workers 2` with its "
             "cluster's start-up included (one command).", "",
             "| packing | particles | contacts (at yield) | loop of analyze (clusters) | (a) batched chunk | "
             "(a) speed-up | **(b) scan vs loop** | error (verdicts) | paths (sample) | serial | Dask 1 worker | "
             "2 workers | **1 → 2** | `--workers 2` (start-up incl.) | serial → it | clusters/s | verdicts |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        lines.append(
            f"| {r['dim']}D random | {r['n_particles']:,} | {r['n_contacts']:,} ({r['at_yield']:,}) | "
            f"{r['loop_s']:.1f} s ({r['clusters']}) | {r['batched_s']:.2f} s | {r['speedup']:.1f}× | "
            f"**{r['scan_vs_loop']:.1f}×** | "
            f"{r['max_rel_diff']:.1e} ({'same' if r['same_verdicts'] else '**DIFFER**'}) | "
            + ", ".join(f"{k} {v}" for k, v in r["paths"].items()) + f" | {r['serial_s']:.1f} s | "
            f"{r['dask1_s']:.1f} s | {r['dask2_s']:.1f} s | **{r['speedup_1_to_2']:.2f}×** | {r['startup2_s']:.1f} s | "
            f"{r['speedup_serial_to_2']:.2f}× | {r['clusters_per_s_serial']:.0f} | "
            + ", ".join(f"{k} {v}" for k, v in r["verdicts"].items())
            + ("" if r["same_verdicts_dask"] else " (**differ between serial and Dask**)") + " |")
    plain = results["plain"]
    lines += ["", f"**What bounds 1 → 2 on this machine ({results['cores']} cores).** CPU seconds of one timed scan "
              "(medians): the workers' processes, and this process's (the client, which on a local cluster also runs "
              "the scheduler and the nannies). On a machine with no core to spare, the two workers cannot finish "
              "before all that CPU is spent: *ceiling* = t(1 worker) / max(workers' CPU / 2, all CPU / cores), the "
              "best ratio this machine allows. Two plain processes computing the same "
              f"{plain['one_s']:.1f} s of chunks at once, without Dask: {plain['two_s']:.1f} s, a parallel "
              f"efficiency of **{plain['parallel']:.2f}** of 2 (the cores themselves do not slow each other).", "",
              "| packing | 1 worker: workers' CPU | client | 2 workers: workers' CPU | client | ceiling here | "
              "measured |", "|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        c = r["cpu"]
        lines.append(f"| {r['dim']}D, {r['n_particles']:,} | {c['workers1']:.1f} s | {c['client1']:.2f} s | "
                     f"{c['workers2']:.1f} s | {c['client2']:.2f} s | {r['ceiling_1_to_2']:.2f}× | "
                     f"{r['speedup_1_to_2']:.2f}× |")
    if results["gpu"]:
        lines += ["", "| packing | GPU whole scan | clusters/s | vs CPU serial | λ_min rel. diff (verdicts) |",
                  "|---|---|---|---|---|"]
        for r in results["rows"]:
            g = r["gpu"]
            lines.append(f"| {r['dim']}D, {r['n_particles']:,} | {g['seconds']:.1f} s | {g['clusters_per_s']:.0f} | "
                         f"{g['vs_cpu_serial']:.1f}× | {g['max_rel_diff']:.1e} "
                         f"({'same' if g['same_verdicts'] else '**DIFFER**'}) |")
    else:
        lines += ["", "No GPU on this machine: `--device gpu` scans are measured where CuPy sees one "
                  "(`granstab bench --device gpu`)."]
    mem = results["memory"]
    lines += ["", f"Peak traced memory of one chunk of {CHUNK} clusters (tracemalloc): "
              + ", ".join(f"{m['peak_MB']:.0f} MB in a {m['n_particles']:,}-particle packing" for m in mem)
              + " — set by the chunk, not by the packing.", "",
              "A 10⁶-particle 2D scan extrapolated from the serial rate above (compute / workers, the client's and "
              f"scheduler's ~{TASK_OVERHEAD_S * 1e3:.0f} ms a task (measured) for tasks of "
              f"{TASK_SECONDS[1]} s of compute, at most {CHUNK} clusters (`run.Guide`), reading an NPZ snapshot):", "",
              "| workers | compute | scheduling | reading | total | bottleneck |", "|---|---|---|---|---|---|"]
    for e in results["extrapolation"]:
        lines.append(f"| {e['workers']} | {e['compute']:.0f} s | {e['scheduling']:.0f} s | {e['reading']:.0f} s | "
                     f"{e['minutes']:.1f} min | {e['bottleneck']} |")
    lines += ["", "How the 1 → 2 ratio moved from run to run, and what is missing to 2: "
              "[docs/bench/notes.md](docs/bench/notes.md#the-local-scan-1--2-workers-from-run-to-run)."]
    return "\n".join(lines) + "\n"
