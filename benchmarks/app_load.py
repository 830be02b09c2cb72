"""The explorer's slider move with busy processes beside it (issue 26): is the slowdown a fair share of the cores?

The server's work of one move of annulus_frame's μ slider (143 disks, 429 dofs: scene build and analysis), timed
at rest and with BUSY busy-looping processes on the same cores, two ways: with the BLAS limits of the explorer now (one thread, an outer limit bounding the core's own `sized(n)`:
granstab.solve.threads) and with the library default threads, which is what the explorer ran before (its one-thread
limit was lifted inside every dense analysis of more than 96 dofs). Also *Check other metrics* (L/10, L, 10L)."""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from granstab.analysis import analyze
from granstab.solve.threads import cap_process

BUSY = 4
PRESET = Path(__file__).resolve().parent.parent / "presets" / "annulus_frame.json"
MOVES = {True: 1, False: 4}


def _moves(model, n: int) -> list[float]:
    """n μ moves: the scene built and analysed in the L metric (app/state.py `Session.recompute`)."""
    out = []
    P = model.initial_params()
    for i in range(n):
        t = time.perf_counter()
        analyze(model.build({**P, "mu": (0.35, 0.3)[i % 2]}), metric="L")
        out.append(time.perf_counter() - t)
    return out


def _measure(n: int, quick: bool) -> dict:
    """Moves and the metric family with the explorer's BLAS limit (cap_process(1), as app/server.py sets), then with
    none (the library's default threads: what the explorer ran before; not in a quick run, where it takes minutes
    beside busy processes)."""
    from granstab_app.scenes import load_model
    model = load_model(PRESET)
    out = {}
    ways = (("explorer now (1 BLAS thread)", 1), ("before (library default threads)", None))
    for name, cap in ways[:1] if quick else ways:
        cap_process(cap)
        try:
            moves = _moves(model, n)
            t = time.perf_counter()
            analyze(model.build(model.initial_params()), metric="family")
            family = time.perf_counter() - t
        finally:
            cap_process(None)
        out[name] = {"move_median_s": statistics.median(moves), "move_max_s": max(moves), "family_s": family}
    return out


def run(quick: bool = False) -> dict:
    n = MOVES[quick]
    rest = _measure(n, quick)
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(BUSY)]
    try:
        time.sleep(1.0)
        loaded = _measure(n, quick)
        load = os.getloadavg()[0]
    finally:
        for p in busy:
            p.kill()
            p.wait()
    cores = len(os.sched_getaffinity(0))
    return {"moves": n, "busy": BUSY, "cores": cores, "rest": rest, "loaded": loaded, "load_after": load,
            "fair_share": (BUSY + 1) / cores}


def markdown(r: dict) -> str:
    rows = []
    for name in r["rest"]:
        a, b = r["rest"][name], r["loaded"][name]
        rows.append(f"| {name} | {a['move_median_s']:.2f} s | {b['move_median_s']:.2f} s (max {b['move_max_s']:.2f} s) "
                    f"| {b['move_median_s'] / a['move_median_s']:.1f}× | {a['family_s']:.2f} s | {b['family_s']:.2f} s |")
    return "\n".join([
        "## The explorer's slider move beside busy processes", "",
        f"annulus_frame (143 disks): one μ move as the server does it (scene build and analysis in the L metric; the page's mode labels add ≈ 0.15-0.4 s), "
        f"median of {r['moves']} moves, at rest and with {r['busy']} busy-looping processes on the {r['cores']} cores "
        f"(benchmarks/app_load.py; 1-minute load {r['load_after']:.1f} at the end). A fair share predicts "
        f"{r['fair_share']:.1f}× slower. *Check other metrics*: L/10, L and 10L together. Goals (issue 26): ≤ 1 s at "
        "rest, ≤ 3 s at load 4. \"At rest\" is this shared machine's own load, given in the run line.", "",
        "| BLAS | move, at rest | move, busy | slowdown | other metrics, at rest | other metrics, busy |",
        "|---|---|---|---|---|---|", *rows, "",
        "With the library's threads, each LAPACK call's second thread waits for a core that the busy processes hold; "
        "with one thread the move slows in proportion to its share of the cores.",
    ]) + "\n"
