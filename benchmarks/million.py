"""A million grains (issue 41): what granstab does with 10⁶ particles on this machine, measured where it ran and
estimated (said so) where it did not.

- **Reading**: `granstab.io.load` of a LAMMPS per-atom dump of 10⁶ disks and its local contact dump (~3·10⁶
  contacts and 3·10⁵ non-touching pairs, as `pair/local` lists them; benchmarks/converting.py's layout, `%.12g`),
  in a fresh process (`python -m granstab_bench.million read FOLDER`): wall and CPU time, peak resident memory, and
  where the CPU time goes (cProfile: numpy.loadtxt's parser against the rest: ids, geometry, law, cone, checks).
- **The whole packing**: `granstab.analyze(scene, k=6, metric="L")` of the periodic benchmark's packing of 10⁶
  disks with one contact at yield (the elastic and the all-loading branch) in a fresh process (`python -m
  granstab_bench.million whole N`), its phases traced by benchmarks/memtrace.py (wall, CPU, resident memory), the
  peak memory estimated before it runs (granstab/solve/memory.py) beside the measured one; a run that does not fit
  is refused in one line (tested with a fake limit: tests/solve/test_memory.py).
- **The moduli**: `granstab.moduli(scene)` of the same packing in a fresh process (`python -m granstab_bench.million
  moduli N`), its phases traced by memtrace, the peak by wait4 (and the forked proof's, RUSAGE_CHILDREN).

The folder of the dumps is written once (several minutes: the packing and the text) and reused when given
(`MILLION_DATA`); cases measured before under the benchmark lock are reused from `MILLION_MEASURED` (`measured`)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from granstab.mechanics.branches import RIGID

from .formatting import table
from .scaling import ROOT

PARTICLES = 1_000_000
QUICK_PARTICLES = 3_000
WHOLE = (100_000, 1_000_000)   # disks of the periodic benchmark's packing whose memory is estimated
SMALLER = (200_000,)           # … and whole packings measured beside the 10⁶ one (the `scale` check's size)


def write_dumps(n: int, folder: Path) -> list[Path]:
    """atoms.dump, contacts.dump and in.bench of a random 2D packing of n disks (converting.write_lammps)."""
    from . import converting
    paths = [folder / name for name in ("atoms.dump", "contacts.dump", "in.bench")]
    if all(p.exists() for p in paths):
        return paths
    folder.mkdir(parents=True, exist_ok=True)
    scene, radius = converting.packing(2, int(n * converting.CONTACTS_PER_PARTICLE[2]))
    return converting.write_lammps(scene, radius, folder)


def read_child(folder: Path) -> dict:
    """In this (fresh) process: load the dumps under cProfile (CPU time); the split and the scene's size."""
    import cProfile
    import pstats

    import granstab.io
    paths = [folder / name for name in ("atoms.dump", "contacts.dump", "in.bench")]
    prof = cProfile.Profile(time.process_time)
    t, c = time.perf_counter(), time.process_time()
    prof.enable()
    imported = granstab.io.load(paths)
    prof.disable()
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    stats = pstats.Stats(prof).stats
    parse = sum(v[2] for k, v in stats.items() if "_load_from_filelike" in k[2])
    top = sorted(((v[2], f"{Path(k[0]).name}:{k[2]}") for k, v in stats.items()
                  if "granstab" in k[0] and k[2] not in ("load", "<module>")), reverse=True)[:6]
    return {"wall": wall, "cpu": cpu, "parse_cpu": parse, "particles": imported.scene.n_particles,
            "contacts": imported.scene.n_contacts, "rows": sum(1 for _ in open(paths[1], "rb")) - 9,
            "mb": sum(p.stat().st_size for p in paths) / 2 ** 20, "top": [[s, name] for s, name in top]}


def child(*args) -> dict:
    """`python -m granstab_bench.million ARGS` in a fresh interpreter: its JSON line, its peak resident memory
    (wait4) and the 1-minute load average before and after."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    load = os.getloadavg()[0]
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen([sys.executable, "-m", "granstab_bench.million", *map(str, args)], stdout=out,
                                stderr=subprocess.DEVNULL, env=env, cwd=ROOT)
        _, status, usage = os.wait4(proc.pid, 0)
        out.seek(0)
        text = out.read().decode().strip().splitlines()
    if os.waitstatus_to_exitcode(status) != 0 or not text:
        return {"failed": True, "rc": os.waitstatus_to_exitcode(status), "load": [load, os.getloadavg()[0]]}
    return {**json.loads(text[-1]), "peak_mb": usage.ru_maxrss / 1024, "load": [load, os.getloadavg()[0]],
            "at": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


def map_child(folder: Path) -> dict:
    """In this (fresh) process: the explorer's scan map of a scan folder drawn into a recording scene API (no
    browser): CPU time of opening it, of its bodies (built once), of the first draw, and the median of 3 redraws and
    of 3 recolourings by the map's (N, 3) colours (app/views.py's one point cloud)."""
    from statistics import median
    from types import SimpleNamespace

    from granstab_app.scanmap import load_scan_map
    from granstab_app.views import SceneView
    clock = time.process_time
    api = SimpleNamespace(add_point_cloud=lambda name, points, **k: SimpleNamespace(points=points, **k),
                          remove_by_name=lambda name: None)
    c = clock()
    model = load_scan_map(folder)
    t_open, c = clock() - c, clock()
    bodies = model.bodies({})
    t_bodies = clock() - c
    session = SimpleNamespace(bodies=lambda: bodies, scene_dim=model.scene.dim, preset="scan", draggable=False,
                              size=1.0)
    view, names, colours = SceneView(api), model.scene.names, model.colours
    steps = {"draw": lambda: view.draw_particles(session), "colour": lambda: view.colour_particles(names,
                                                                                                  colours=colours)}
    out = {"particles": model.scene.n_particles, "open": t_open, "bodies": t_bodies}
    for name, step in steps.items():
        times = []
        for _ in range(4):
            c = clock()
            step()
            times.append(clock() - c)
        out[f"first_{name}"], out[name] = times[0], median(times[1:])
    return out


def browser_child(folder: Path, shot: Path | None = None) -> dict:
    """In this (fresh) process: the explorer (in-process server) opened on a scan folder in headless Debian Chromium:
    wall time from the page's load to the SCAN MAP badge (the map sent and drawn), from typing a particle's name into
    *Open cluster of* to its cluster's verdict (the GUI answering a control: the cluster cut and analysed), and from
    *Back to the map* to the map again; screenshots of both into `shot` (a folder) when given."""
    import tempfile as _tempfile

    from playwright.sync_api import sync_playwright

    from granstab_app.browser import chromium
    from granstab_app.server import App
    badge = '.granstab-verdict[data-verdict="scan-map"]'
    out = {}
    with sync_playwright() as pw, _tempfile.TemporaryDirectory() as profile:
        ctx, app = chromium(pw, profile), App(host="127.0.0.1", port=0, preset=str(folder))
        try:
            page, t = ctx.new_page(), time.perf_counter()
            page.goto(app.url)
            page.wait_for_selector(badge, timeout=300_000)
            out["map_s"] = time.perf_counter() - t
            import pyarrow.parquet as pq
            names = pq.read_table(folder / "particles.parquet", columns=["name"]).column("name")
            out["particles"], name = len(names), names[len(names) // 2].as_py()
            t = time.perf_counter()
            page.locator("input.mantine-TextInput-input:visible").nth(1).fill(name)     # Open cluster of
            page.wait_for_selector(badge.replace("[", ":not([", 1) + ")", timeout=300_000)
            out["cluster_s"] = time.perf_counter() - t
            if shot:
                page.screenshot(path=str(shot / "million-cluster.png"))
            t = time.perf_counter()
            page.get_by_role("button", name="Back to the map").click()
            page.wait_for_selector(badge, timeout=300_000)
            out["back_s"] = time.perf_counter() - t
            if shot:
                page.wait_for_timeout(2000)
                page.screenshot(path=str(shot / "million-map.png"))
        finally:
            app.stop()
            ctx.close()
    return out


def whole_memory(n: int) -> dict:
    """The sparse path's peak estimate for the periodic benchmark's packing of about n disks (3 contacts a disk,
    3 dofs a disk), against what is available now (solve/memory.py)."""
    from granstab.solve import memory
    info, refused = memory.refusal("periodic", 3 * n, 3 * n, 2, "shift-invert")
    return {"particles": n, "dofs": 3 * n, **info, "refused": refused}


def _whole(scene, device: str) -> dict:
    """`granstab.analyze(scene, k=6, metric="L", device=...)` of the whole packing: wall time, λ_min, the largest
    residual and bound, the counts."""
    import granstab
    t = time.perf_counter()
    r = granstab.analyze(scene, k=6, metric="L", device=device)
    wall = time.perf_counter() - t
    low = [float(b.stability_eigenvalues[b.codes != RIGID].min()) for b in r.branches]
    return {"wall": wall, "lambda_min": min(low), "branches": len(r.branches), "verdict": r.summary["verdict"],
            "residual": float(r.errors["eigen_residual_stability"]),
            "bound": float(max(b.bounds.max() for b in r.branches)),
            "counts": all(b.negative_count["total"] for b in r.branches),
            "below": [b.negative_count["count"] for b in r.branches], "timings": dict(r.timings),
            "warnings": list(r.warnings)}


PHASES = ("granstab.solve.methods:SparseMethod.prepare", "granstab.solve.methods:SparseMethod.problem",
          "granstab.solve.multifrontal:Factor.__init__", "granstab.solve.sparse:_block_near",
          "granstab.solve.ritz:SparseRitz.__init__", "granstab.solve.ritz:SparseRitz._branch",
          "granstab.solve.sparse:sparse_branch", "granstab.solve.methods:SparseMethod.errors")
LIMIT_GB = 18.5      # the whole packing's child stops itself above this resident memory (a shared machine)


def whole_child(n: int, sliding: int = 1) -> dict:
    """In this (fresh) process: the periodic benchmark's packing of about n disks with `sliding` contacts at yield
    (2^sliding branches), `_whole` of it with its phases traced (memtrace: wall, CPU, resident memory at entry and
    peak), the estimate it was planned with beside the measured peak."""
    from .memtrace import Trace, resident
    from .periodic_child import periodic_packing
    t = time.perf_counter()
    scene = periodic_packing(n, sliding)
    built, scene_gb = time.perf_counter() - t, resident() / 2 ** 30
    estimate = whole_memory(scene.n_particles)
    with Trace(*PHASES, limit=LIMIT_GB * 2 ** 30) as trace:
        c = time.process_time()
        out = _whole(scene, "cpu")
        out["cpu"] = time.process_time() - c
    return {**out, "particles": scene.n_particles, "contacts": scene.n_contacts, "dofs": scene.n_dof,
            "t_scene": built, "scene_gb": scene_gb, "peak_gb": trace.peak_gb(), "phases": trace.phases(),
            "estimated_gb": estimate["estimated_bytes"] / 2 ** 30}


MODULI_PHASES = ("granstab.moduli:cell_system", "granstab.moduli:_factor",
                 "granstab.solve.cellsolve:symmetric_factor", "granstab.solve.cellsolve:Floor.__init__",
                 "granstab.solve.cellsolve:Floor.tau", "granstab.solve.cellsolve:gmres", "granstab.moduli:_branch")


def moduli_child(n: int, sliding: int = 1) -> dict:
    """In this (fresh) process: `granstab.moduli` of the periodic benchmark's packing of about n disks with `sliding`
    contacts at yield, its phases traced (memtrace: the chunked assembly, the factor of sym(H) and the one proving
    the bound's floor, GMRES, the branches); the moduli, their largest bound and residual, and how it solved."""
    import numpy as np

    import granstab

    from .memtrace import Trace
    from .periodic_child import periodic_packing
    t = time.perf_counter()
    scene = periodic_packing(n, sliding)
    built = time.perf_counter() - t
    with Trace(*MODULI_PHASES, limit=LIMIT_GB * 2 ** 30) as trace:
        t, c = time.perf_counter(), time.process_time()
        m = granstab.moduli(scene)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
    scale = max(float(np.abs(b.mandel).max()) for b in m.branches)
    import resource
    proof_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024    # cellsolve.Floor's forked proof
    return {"proof_process_mb": proof_mb, "particles": scene.n_particles, "contacts": scene.n_contacts, "dofs": scene.n_dof, "t_scene": built,
            "wall": wall, "cpu": cpu, "peak_gb": trace.peak_gb(), "phases": trace.phases(), "bulk": m.bulk,
            "shear": m.shear, "branches": len(m.branches), "residual": m.errors["residual"],
            "bound": m.errors["moduli_bound"], "scale": scale, "solve": m.solve,
            "fixed_cell": m.verdicts["fixed_cell"]["verdict"]}


def _moduli_row(m: dict) -> list:
    """A moduli run's row."""
    if m.get("failed"):
        return ["failed (rc {})".format(m.get("rc")), *[""] * 10]
    s = m["solve"]
    return [f"{m['particles']:,} / {m['contacts']:,} / {m['dofs']:,}", f"{m['wall']:.0f} s", f"{m['cpu']:.0f} s",
            f"{m['peak_mb'] / 1024:.2f} GB", "{:.1f} → {:.1f}".format(*m["load"]) + (f" ({m['at']})" if "at" in m else ""),
            f"{s.get('gmres_steps', '—')}", f"{s.get('factor_entries', 0) / 1e6:.0f} M",
            f"{m['bulk']:.10g} / {m['shear']:.10g}", f"{m['residual']:.1e}",
            "—" if m["bound"] is None else f"{m['bound']:.1e}", m["fixed_cell"]]


def moduli_markdown(runs: list | None) -> str:
    """The moduli's table and the largest run's phases, or why there are none."""
    if not runs:
        return "**The moduli**: not measured in this run (`python -m granstab_bench.million moduli N`)."
    return "\n".join([
        f"**The moduli** (goal ≤ {MODULI_GOAL_S / 60:g} min and ≤ 20 GB): `granstab.moduli(scene)` of the periodic "
        "benchmark's packing with one contact at yield (the elastic and the all-loading branch), in a fresh process "
        "(`python -m granstab_bench.million moduli N`); the parts assembled in chunks of contacts "
        "(solve/cellparts.py), H solved by GMRES preconditioned by sym(H)'s multifrontal factor (solve/cellsolve.py; "
        "SuperLU's LU of both triangles would not fit at 10⁶). *peak*: resident peak (wait4); *GMRES*: preconditioned "
        "products (all right-hand sides together); *factor*: its stored entries; *bulk / shear*: of the elastic "
        "branch; *residual*: the largest ‖H^i X − Ξ^i‖ / (‖H^i‖∞‖X‖ + ‖Ξ^i‖); *bound*: the largest entrywise bound "
        "of a modulus over max|C| (residual, ‖H⁻¹‖ ≤ 1/τ proven by the inertia of sym(H) − τI, the formation "
        "errors; docs/periodic.md); *fixed cell*: sym(H)'s inertia.",
        "",
        table(["disks / contacts / dofs", "wall", "CPU", "peak", "load", "GMRES", "factor", "bulk / shear",
               "residual", "bound", "fixed cell"], [_moduli_row(m) for m in runs]),
        "",
        "**Where the largest one's time and memory go** (memtrace; `symmetric_factor` runs inside `_factor` (the "
        "preconditioner) and, for the proof of τ (counts only), "
        + ("inside `floor` after it, in this process (the code before the proof ran beside GMRES)"
           if any(p["phase"] == "floor" for p in runs[-1].get("phases", [])) else
           "inside `Floor.__init__`'s forked process (not traced here; `Floor.tau` is the wait for it)")
        + "; GMRES runs inside the first `_branch`):",
        "",
        table(["phase", "wall", "CPU", "resident at entry", "peak during"], _phase_rows(runs[-1])),
        "",
        _moduli_words(runs[-1])])


def own(m: dict, floor: dict) -> tuple:
    """The forked proof's resident peak and its part not shared with this process (GB)."""
    total = m.get("proof_process_mb", 0) / 1024
    return total, max(total - floor["entry_gb"], 0.0)


def _moduli_words(m: dict) -> str:
    """The largest run's time and memory in words, from its phases."""
    ph = {}
    for p in m.get("phases", []):
        ph.setdefault(p["phase"], []).append(p)
    factor, proof = (ph.get("symmetric_factor", []) + [None, None])[:2]
    floor = (ph.get("floor") or ph.get("Floor.__init__") or [None])[0]
    gmres = ph.get("gmres", [None])[0]
    if not (factor and floor and gmres):
        return ""
    s = m["solve"]
    rest = m["wall"] - ph["cell_system"][0]["wall"] - ph["_factor"][0]["wall"] - gmres["wall"]
    beside = proof is None or proof["wall"] < 0.5 * floor["wall"]
    return (f"In words ({m['particles']:,} disks, wall time): {m['wall']:.0f} s in all at load "
            "{:.1f} (the packing's generation not counted) — ".format(m["load"][0])
            + f"the chunked assembly {ph['cell_system'][0]['wall']:.0f} s, sym(H)'s multifrontal elimination "
            f"{factor['wall']:.0f} s ({s['factor_entries'] / 1e6:.0f} M entries, then held in float32), the estimate "
            f"θ = {s['estimate']:.3g} of λ_min(sym H) by three block inverse-iteration steps and "
            + (f"the proof of τ = θ/8 (a count-only elimination of sym(H) − τI) in a forked process beside GMRES "
               f"(resident {own(m, floor)[0]:.1f} GB at its peak, of which the {floor['entry_gb']:.1f} GB this process "
               f"held at the fork are shared copy-on-write: about {own(m, floor)[1]:.1f} GB of its own, so the two "
               f"together at most {m['peak_mb'] / 1024 + own(m, floor)[1]:.1f} GB)" if beside else
               f"the proof of τ = θ/8 (a count-only elimination of sym(H) − τI, {proof['wall']:.0f} s)")
            + f" {floor['wall']:.0f} s" + (f" (the proof itself overlapped GMRES; waiting for it took "
                                          f"{ph['Floor.tau'][0]['wall']:.0f} s more)" if beside and "Floor.tau" in ph
                                          else "") + f", GMRES {gmres['wall']:.0f} s ({s['gmres_steps']} preconditioned products of "
            f"the four right-hand sides together, {gmres['wall'] / max(s['gmres_steps'], 1):.1f} s each), the "
            f"branches' bounds and the rest {rest:.0f} s. "
            f"This process's peak {m['peak_mb'] / 1024:.1f} GB (wait4), during the elimination (the float64 factor "
            "before its float32 copy replaces it) and GMRES. Before (this session): with a float64 factor and the proof "
            "after the factor on one core, 412 s of CPU time and 14.9 GB (load 9-11); with the float32 factor and the "
            "proof still on one core, 346 s at rest (load 1.0) and 13.8 GB.")


MODULI_GOAL_S = 300.0


def scan_case(folder: Path, out: Path, workers: int = 2) -> dict:
    """`granstab scan FOLDER --out OUT --workers W --json` in a fresh process: wall and CPU time (the command, which
    also runs Dask's scheduler and nannies, and its worker processes apart), the peak resident memory of the command
    and of each worker (psutil, sampled every 0.5 s: each process's highest), its summary (without the import
    report), and the load before and after."""
    import psutil
    load = os.getloadavg()[0]
    cmd = [sys.executable, "-m", "granstab", "scan", str(folder), "--out", str(out), "--overwrite", "--workers",
           str(workers), "--json"]
    t, started = time.perf_counter(), time.time()
    with tempfile.TemporaryFile() as stdout:
        proc = psutil.Popen(cmd, stdout=stdout, stderr=subprocess.DEVNULL)
        peak, cpu = {}, {}
        while proc.poll() is None:
            for p in [proc, *_children(proc)]:
                try:
                    with p.oneshot():
                        peak[p.pid] = max(peak.get(p.pid, 0), p.memory_info().rss)
                        times = p.cpu_times()
                        cpu[p.pid] = times.user + times.system
                except psutil.Error:
                    pass
            time.sleep(0.5)
        wall = time.perf_counter() - t
        stdout.seek(0)
        text = stdout.read().decode().strip()
    main_mb, main_cpu = peak.pop(proc.pid, 0) / 2 ** 20, cpu.pop(proc.pid, 0.0)
    workers_mb = sorted((v / 2 ** 20 for v in peak.values()), reverse=True)
    summary = json.loads(text.splitlines()[-1]) if proc.returncode == 0 and text else None
    if summary:
        summary.pop("import", None)
    return {"rc": proc.returncode, "wall": wall, "cpu_main": main_cpu, "cpu_children": sum(cpu.values()),
            "main_mb": main_mb, "worker_mb": workers_mb[:workers], "summary": summary, "phases": _phases(out, started),
            "load": [load, os.getloadavg()[0]], "at": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


def _phases(out: Path, started: float) -> dict:
    """Seconds from the command's start to each step, by the times its files were written: the packing (after the
    reading), the first and the last part (the loop), the clusters table (the finish), the map (the figures)."""
    parts = sorted(p.stat().st_mtime for p in (out / "parts").glob("*.arrow"))
    files = {"packing": out / "packing.npz", "tables": out / "summary.json", "map": out / "map.svg",
             "figures": out / "lambda_min.svg"}
    got = {key: f.stat().st_mtime - started for key, f in files.items() if f.exists()}
    return {**got, **({"first_part": parts[0] - started, "last_part": parts[-1] - started, "parts": len(parts)}
                      if parts else {})}


def _children(proc) -> list:
    import psutil
    try:
        return proc.children(recursive=True)
    except psutil.Error:
        return []


def gpu_case(n: int) -> dict:
    """The periodic benchmark's packing of about n disks (one contact at yield: 2 branches) on the GPU and on this
    machine's CPU (solve/blockiter.py against the shift-invert path); {"not_run": why} without a GPU."""
    from granstab.solve.device import gpu_available

    from .periodic_child import periodic_packing
    if not gpu_available():
        return {"not_run": "no GPU in this session (CuPy not installed or no CUDA device): the code and its tests "
                           "(tests/solve/test_blockiter.py, skipped here with that reason) are ready; a session with a "
                           "GPU runs benchmarks/gpu_million.sh in one go (≤ 8 min) to fill this section"}
    scene = periodic_packing(n, 1)
    return {"particles": scene.n_particles, "gpu": _whole(scene, "gpu"), "cpu": _whole(scene, "cpu")}


def measured(name: str) -> dict | None:
    """A case measured before, under the benchmark lock (`python -m granstab_bench.million read|whole …` through
    `child`, its JSON line saved as MILLION_MEASURED/NAME.json): reused, with its own time and load, where the 10⁶
    cases take longer than a busy shared machine leaves for one `granstab bench` run; None where not given."""
    folder = os.environ.get("MILLION_MEASURED")
    path = Path(folder) / f"{name}.json" if folder else None
    return {**json.loads(path.read_text()), "reused": str(path)} if path and path.is_file() else None


def run(quick: bool = False, device: str = "cpu") -> dict:
    if device == "gpu":
        return {"gpu": gpu_case(QUICK_PARTICLES if quick else PARTICLES)}
    n = QUICK_PARTICLES if quick else PARTICLES
    if not quick and measured("read") and measured("whole"):
        whole = [measured(f"whole_{m}") for m in SMALLER] + [measured("whole")]
        return {"reading": measured("read"), "estimates": [whole_memory(m) for m in WHOLE], "map": measured("map"),
                "browser": measured("browser"), "scan": [measured(f"scan_{m}") for m in SCANS],
                "moduli": [m for m in (measured("moduli_100000"), measured("moduli")) if m],
                "whole": [w for w in whole if w], "goal_read_s": 20.0, "goal_memory_gb": 20.0, "goal_whole_s": 600.0}
    given = os.environ.get("MILLION_DATA")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(given) if given and not quick else Path(tmp)
        t = time.perf_counter()
        write_dumps(n, folder)
        written = time.perf_counter() - t
        reading = child("read", folder)
    whole = [child("whole", m) for m in (() if quick else SMALLER)] + [child("whole", n)]
    scan_folder = os.environ.get("MILLION_SCAN")
    return {"reading": {**reading, "t_write": written}, "estimates": [whole_memory(m) for m in WHOLE],
            "map": child("map", Path(scan_folder)) if scan_folder and not quick else None,
            "browser": child("browser", Path(scan_folder)) if scan_folder and not quick else None,
            "moduli": [child("moduli", m) for m in (() if quick else (100_000,))] + [child("moduli", n)],
            "whole": whole, "goal_read_s": 20.0, "goal_memory_gb": 20.0, "goal_whole_s": 600.0}


def _gb(b) -> str:
    return "—" if b is None else f"{b / 2 ** 30:.1f} GB"


def gpu_markdown(g: dict) -> str:
    head = ["## A million grains on a GPU (issue 41)", "",
            "`granstab.analyze(scene, k=6, metric=\"L\", device=\"gpu\")` of the periodic benchmark's packing of "
            "10⁶ disks (one contact at yield: 2 branches): preconditioned LOBPCG with the sparse products on the GPU "
            "(solve/blockiter.py; no inertia counts there), beside the CPU's shift-invert path on the same machine. "
            "Goal: ≤ 60 s on one GPU."]
    if "not_run" in g:
        return "\n".join(head + ["", f"**Not run:** {g['not_run']}."])
    rows = [[name, f"{d['wall']:.1f} s", f"{d['lambda_min']:.10g}", f"{d['residual']:.1e}", f"{d['bound']:.1e}",
             "proven" if d["counts"] else "not available", d["verdict"]] for name, d in (("GPU", g["gpu"]),
                                                                                         ("CPU", g["cpu"]))]
    return "\n".join(head + ["", f"{g['particles']:,} disks; speed-up {g['cpu']['wall'] / g['gpu']['wall']:.1f}×.",
                             "", table(["device", "wall", "λ_min", "residual", "largest bound", "counts", "verdict"],
                                       rows)])


def _reading_rows(r: dict) -> list:
    if r.get("failed"):
        return [["failed", "", "", "", "", "", "", "", ""]]
    where = "; ".join(f"{name} {s:.1f} s" for s, name in r["top"][:4])
    return [[f"{r['particles']:,}", f"{r['contacts']:,} ({r['rows']:,} rows)", f"{r['mb']:.0f}", f"{r['wall']:.1f} s",
             f"{r['cpu']:.1f} s" + (" (median of {}: {})".format(len(r["cpu_runs"]), ", ".join(
                 f"{c:.1f}" for c in r["cpu_runs"])) if "cpu_runs" in r else ""),
             f"{r['parse_cpu']:.1f} s ({r['parse_cpu'] / max(r['cpu'], 1e-9):.0%})",
             f"{r['peak_mb']:.0f} MB", "{:.1f} → {:.1f}".format(*r["load"]) + (f" ({r['at']})" if "at" in r else ""),
             where]]


def _whole_row(w: dict) -> list:
    """A whole packing's row."""
    if w.get("failed"):
        return ["failed (rc {})".format(w.get("rc")), *[""] * 11]
    return [f"{w['particles']:,} / {w['contacts']:,} / {w['dofs']:,}", str(w["branches"]), f"{w['wall']:.0f} s",
           f"{w['cpu']:.0f} s", f"{w['peak_mb'] / 1024:.1f} GB", f"{w['estimated_gb']:.1f} GB",
           "{:.1f} → {:.1f}".format(*w["load"]) + (f" ({w['at']})" if "at" in w else ""), f"{w['lambda_min']:.10g}", f"{w['residual']:.1e}",
           f"{w['bound']:.1e}", "proven, " + "/".join(map(str, w["below"])) + " below σ" if w["counts"] else "no",
           w["verdict"]]


def _phase_rows(w: dict) -> list:
    """Its phases (memtrace: wall, CPU, resident at entry and peak)."""
    return [[p["phase"], f"{p['wall']:.1f} s", f"{p['cpu']:.1f} s", f"{p['entry_gb']:.2f} GB", f"{p['peak_gb']:.2f} GB"]
            for p in w.get("phases", [])]


def markdown(results: dict) -> str:
    if "gpu" in results:
        return gpu_markdown(results["gpu"])
    estimates = [[f"{w['particles']:,}", f"{w['dofs']:,}", ", ".join(f"{k} {_gb(v)}" for k, v in w["parts"].items()),
                  _gb(w["estimated_bytes"]), f"{_gb(w['available_bytes'])} ({w['available_from']})",
                  "fits" if w["fits"] else "refused in one line"] for w in results["estimates"]]
    whole, phases = [_whole_row(w) for w in results["whole"]], _phase_rows(results["whole"][-1])
    return "\n".join([
        "## A million grains (issue 41)",
        "",
        " ".join(__doc__.split("\n\n", 1)[1].rsplit("\n\n", 1)[0].split()).replace(" - **", "\n- **"),
        "",
        f"**Reading** (goal ≤ {results['goal_read_s']:g} s). *CPU*: the process's CPU time of the load; *parser*: "
        "numpy.loadtxt's share of it; *load*: the 1-minute load average before and after, on 2 cores shared with "
        "other work (wall times above a load of 2 are stretched by it: the CPU time is what the work costs); "
        "*where*: the granstab functions with the most CPU time of their own (not counting what they call).",
        "",
        table(["particles", "contacts", "MB", "wall", "CPU", "parser", "peak memory", "load", "where"],
              _reading_rows(results["reading"])),
        "",
        f"**The whole packing** (goal ≤ {results['goal_whole_s'] / 60:g} min and ≤ {results['goal_memory_gb']:g} "
        "GB): `granstab.analyze(scene, k=6, metric=\"L\")` of the periodic benchmark's packing with one contact at "
        "yield (the elastic and the all-loading branch), in a fresh process (alone, under /work/wt/quiet); "
        "*peak*: its resident peak (wait4); *estimated*: solve/memory.py's estimate when it ran; *residual*: the largest "
        "‖Bv − λv‖/‖Hs‖; "
        "*bound*: the largest reported error bound of an eigenvalue (residual and formation error, "
        "accuracy.vector_bounds); *counts*: the number of eigenvalues below σ by inertia (multifrontal.py).",
        "",
        table(["disks / contacts / dofs", "branches", "wall", "CPU", "peak", "estimated", "load", "λ_min",
               "residual", "bound", "counts", "verdict"], whole),
        "",
        "**Where the largest one's time and memory go** (benchmarks/memtrace.py: each phase's wall and CPU time, the "
        "resident memory when it began and the highest sampled while it ran; Factor.__init__ and _block_near run "
        "inside SparseRitz.__init__, the elastic solve on which both branches' Ritz updates rest):",
        "",
        table(["phase", "wall", "CPU", "resident at entry", "peak during"], phases),
        "",
        WHERE_TIME,
        "",
        "**The whole packing's memory estimated before any work** (solve/memory.py; refused in one line where it "
        "exceeds what is available):",
        "",
        table(["disks", "dofs", "parts", "estimated peak", "available", "here"], estimates),
        "",
        moduli_markdown(results.get("moduli")),
        "",
        map_text(results.get("map"), results.get("browser")),
        "",
        scan_text(results.get("scan")),
        "",
        NOT_DONE,
    ])


WHERE_TIME = (
    "In words (10⁶ disks, at rest: session 10, 21:32 UTC, alone under /work/wt/quiet, load 0.5 → 1.2; one "
    "thread: the fronts and block solves run under blas_threads(1)): 335 s of wall time and 340 s of CPU in all "
    "(the packing's generation not counted) — the elastic solve 238 s (the multifrontal factorisation 78 s, the "
    "block shift-invert Krylov iteration 155 s, the Ritz basis's Taylor solves and Rayleigh quotient ~5 s), the "
    "contact blocks and assembly 41 s, the metric's congruences and norms 14 s, both branches' Ritz updates 6.4 s, "
    "their bounds and consistency tests 1.8 s, the identity checks 2.6 s. Peak 15.9 GB, as estimated (15.9 GB). "
    "An earlier run at load 8-11 (session 9, nice 10) took 354 s of CPU over 1,255 s of wall time. **A regression "
    "found and fixed on the way:** after session 9's merge, two branches went to shift-invert whatever their size "
    "(issue 39's rule for track's sheared frames, where the Ritz basis is wide), so this packing's two branches "
    "each built a factor: at 2·10⁵ disks 74 s of CPU and 5.9 GB against 50 s and 3.8 GB as Ritz updates, and the "
    "10⁶ run stopped at its own 18.5 GB memory guard (session 10, 20:38 UTC). budget.use_ritz now keeps two "
    "branches as Ritz updates when the sliding contacts' Taylor columns are no more than the elastic Krylov "
    "columns (tests/solve/test_large.py). Memory: the parts 4.8 GB, the factor 6.8 GB (float64 only: no float32 copy "
    "above multifrontal.SINGLE_MAX), the Krylov basis 4.2 GB (restarted in place); the transient peaks of the "
    "assembly (7.2 GB) and of the metric's problem (8.9 GB) fall before the factor. Before the cuts (no release of "
    "the physical H and Hm, a float32 factor copy, restart copies) the same 2·10⁵-disk case peaked at 4.37 GB and "
    "62.6 s of CPU time (load ~1.7), now 3.8 GB and 56 s; the model then estimated 22.4 GB for 10⁶ disks and refused "
    "it. **Reading** (10⁶ atoms, cProfile's CPU time): before, 22.5 s at load ~7 (numpy.loadtxt 5.5 s, building the "
    "scene 14.1 s: its checks in build_scene 5.9 s, the contact geometry 3.4 s, numpy.linalg.norm of (M, 2) rows "
    "1.8 s); now 18.2 s at load ~7 (building the scene 8.6 s, build_scene's checks ~2.5 s), every check kept: row "
    "norms by model/vec.norms (numpy.linalg.norm's values bit for bit, 2-4x faster), r^pq, r^qp and |f_t| formed once "
    "for all the checks, duplicate ids and pairs found by one sort (not np.unique's stable argsort), no copies when "
    "every contact is kept. What is left: numpy.loadtxt's C parser 4.7-6.4 s (a third), the names of the pairs the "
    "report lists (the generator's packing has many overlaps above 0.1 of a radius: 164,441 of 298,305 contacts at "
    "10⁵) 0.9-1.2 s, the minimum-image branches (read_step and build each form them) 0.9 s. Those three runs (18.2, "
    "18.4, 20.1 s of CPU) were at load 7.5; measured again at rest (the table: under /work/wt/quiet, alone, load "
    "1.0) the load takes 15.2-17.7 s of CPU and the same wall time, median 17.3 s, with cProfile's per-call "
    "overhead counted in it: numpy.loadtxt's parser 4.5-6.2 s, the rest spread over build.py's steps (0.5-0.9 s "
    "each: __getitem__, branch_vectors, build, _curvature), lammps.read_step 0.55-0.64 s and vec.sum_at 0.44-0.49 s. "
    "The goal, 20 s, is met at rest with 2.7 s to spare; it was not cut further this session.")


NOT_DONE = (
    "**Not measured here** (issue 41's other cases): the GPU (no device was lent: BENCHMARKS-gpu.md `million` "
    "and benchmarks/gpu_million.sh); 10⁶ spheres, whose factor does not fit (refused in one line with the estimate "
    "and the memory it needs: tests/solve/test_memory.py; on a GPU, or where memory allows, the LOBPCG path "
    "(solve/blockiter.py) gives the lowest modes with residual bounds but no inertia counts).")


SCANS = ("100000", "1000000")     # the scans end to end whose measured cases (MILLION_MEASURED/scan_N.json) are shown
SCAN_WHERE = (                   # where the 10⁶ scan's time goes, in words (its phases and the profiles below)
    "Where the 10⁶ scan's time goes (by the times its files were written; quiet: nothing else ran, the load "
    "average still falling from the jobs before): reading the dumps and keeping the packing 17 s, the two workers "
    "started and the first part on disk at 20 s, the loop 224.7 s (435 tasks; the workers at ~91% of a core each, "
    "the command at ~26%: cutting the chunks, Dask's client and scheduler, the parts written), the tables 2.3 s, "
    "the figures 10.8 s (the map drawn as pixels above 2·10⁵ particles: figure._pixels; one disk at a time it was "
    "16 s of CPU at 10⁵, most of it the radii's per-particle median loop and the 10⁵ ellipses). The workers' "
    "409 s of CPU are 0.41 ms a cluster: in one chunk's profile (10⁵ packing, 1,024 clusters) the eigenvalues "
    "(LAPACK syevd, 57-75 dofs a cluster) ~40%, the stacked matrices (scattering the contact blocks, the formation "
    "bounds) ~35%, the chunk's contact blocks, layout and tallies the rest. **Before** (main e6619d2; last "
    "session's smoke run: 516 s for the 99,856 clusters at load 9-11, 194 a second): (1) centres taken in the "
    "file's order, which in the benchmark's dumps (as in a DEM's insertion order) is not spatial, so a task of "
    "500 clusters carried a scene of 16,727 particles (10 MB shipped, its contact blocks built for all): 1.69 ms "
    "of CPU a cluster in one process at load 0.5, 0.84 ms with the centres in Z-order (`clusters.spatial_order`: "
    "955 particles, 0.65 MB); (2) tasks of 0.05-0.3 s (~86 clusters at that load, 3.4 particles a centre in "
    "Z-order): now 0.25-1 s (1.3-1.7 a centre); (3) every embedded:1 cluster solved with eigenvectors to tell its "
    "negative modes' place: now a cluster without sliding contacts gets its eigenvalues first (`eigvalsh`) and "
    "keeps them when they are all proven positive (`batch._values_first`; the verdicts, counts and λ_min within "
    "the bounds, tested against `analyze`), ~0.55 ms a cluster in one process at load ~6; (4) the map's per-disk "
    "drawing. The 10⁵ row above ran under the heavy queue beside other engineers' jobs (load 6-9): its wall time is "
    "stretched, its CPU time is what the work costs.")


def scan_text(scans: list | None) -> str:
    """The scans end to end (`scan_case`: `python -m granstab_bench.million scan DUMPS OUT`), one line each."""
    rows = [s for s in scans or [] if s and not s.get("failed") and s.get("summary")]
    if not rows:
        return "**The scan end to end**: not measured in this run (MILLION_MEASURED/scan_N.json)."
    head = ("**The scan end to end** (goal: 10⁶ particles ≤ 10 min with 2 workers): `granstab scan DUMPS --out OUT "
            "--workers 2 --json` of the LAMMPS dumps (atoms.dump, contacts.dump, in.bench: benchmarks/converting.py's "
            "layout) in a fresh process — reading, the packing kept (packing.npz), chunks cut in Z-order, the "
            "clusters on 2 local Dask workers, parts streamed to disk, the tables and the map (map.png/.svg, "
            "lambda_min.png/.svg) written; default options (rings 1, metric L, boundary embedded:1, attribution). "
            "*wall*: the command; *CPU*: the command's process (reading, the client, Dask's scheduler and nannies, "
            "the tables and figures) and its workers' (psutil, sampled every 0.5 s); *memory*: each process's "
            "resident peak; *loop*: the scan's own seconds (summary.json) and clusters a second in it.")
    table_rows = [[f"{r['summary']['n_particles']:,}", f"{r['summary']['clusters']:,}", f"{r['wall']:.0f} s",
                   f"{r['cpu_main']:.0f} s + {r['cpu_children']:.0f} s",
                   f"{r['main_mb'] / 1024:.2f} GB; " + ", ".join(f"{w:.0f} MB" for w in r["worker_mb"]),
                   f"{r['summary']['seconds']:.0f} s, {r['summary']['clusters_per_second']:.0f}/s",
                   ", ".join(f"{n:,} {v}" for v, n in r["summary"]["verdicts"].items()),
                   "{:.1f} → {:.1f}".format(*r["load"]) + (f" ({r['at']})" if "at" in r else "")] for r in rows]
    return "\n".join([head, "", table(["particles", "clusters", "wall", "CPU: command + workers",
                                       "memory: command; workers", "loop", "verdicts", "load"], table_rows),
                      *(["", SCAN_WHERE] if SCAN_WHERE else [])])


def map_text(m: dict | None, b: dict | None = None) -> str:
    """The explorer's scan map drawn without a browser (`map_child`) and in one (`browser_child`, `b`), or why there
    is no such line."""
    if not m:
        return "**The explorer's scan map**: not measured in this run (give MILLION_SCAN, a scan folder)."
    if m.get("failed"):
        return f"**The explorer's scan map**: failed (rc {m.get('rc')})."
    return (f"**The explorer's scan map** of a {m['particles']:,}-particle scan (`python -m granstab_bench.million map "
            f"FOLDER`, no browser: app/views.py into a recording scene API; CPU time, load "
            "{:.1f} → {:.1f}".format(*m["load"]) + (f", {m['at']}" if "at" in m else "") + "; not under the lock): "
            f"opening the folder {m['open']:.2f} s, its bodies (built once) {m['bodies']:.2f} s, the first draw of "
            f"the one point cloud {m['first_draw']:.3f} s, a redraw {m['draw'] * 1e3:.1f} ms and a recolouring by "
            f"the map's colour array {m['colour'] * 1e3:.2f} ms (medians of 3), peak {m['peak_mb']:.0f} MB. Before "
            "(the cloud's centres and radii walked in Python and a per-name colour loop on every call): a redraw "
            "0.37 s and a recolouring 0.20 s of CPU at 10⁵ (load 7).") + browser_text(b)


def browser_text(b: dict | None) -> str:
    """The same map in headless Chromium (`browser_child`), or that it was not opened."""
    if not b or b.get("failed"):
        return " The page in a browser: not measured in this run." if not b else " The page in a browser: failed."
    return (" In headless Chromium (`python -m granstab_bench.million browser FOLDER [SHOTS]`, software WebGL, "
            "one run, load {:.1f} → {:.1f}".format(*b["load"]) + (f", {b['at']}" if "at" in b else "") + "): " +
            f"the page loaded to the SCAN MAP badge in {b['map_s']:.1f} s, a particle's name typed into *Open "
            f"cluster of* answered by its cluster's verdict in {b['cluster_s']:.1f} s (the cluster cut and analysed), "
            f"*Back to the map* in {b['back_s']:.1f} s (the server's process peaked at {b['peak_mb']:.0f} MB). The screenshot of "
            "the map shows the packing as one pale square: every one of its clusters is stable, so every disk is "
            "drawn white (the legend's 0), as the map says. How the page stays responsive at this size: the map is one "
            "point cloud (one point sprite a particle, app/views.py), its positions, sizes and colours arrays built "
            "once when the folder opens and sent once; a recolouring sends only the colour array, and an opened "
            "cluster draws only its own grains; the controls answered while the map was shown.")


if __name__ == "__main__":
    if sys.argv[1:2] == ["read"]:
        print(json.dumps(read_child(Path(sys.argv[2]))))
    elif sys.argv[1:2] == ["browser"]:
        print(json.dumps(browser_child(Path(sys.argv[2]), Path(sys.argv[3]) if len(sys.argv) > 3 else None)))
    elif sys.argv[1:2] == ["map"]:
        print(json.dumps(map_child(Path(sys.argv[2]))))
    elif sys.argv[1:2] == ["scan"]:
        print(json.dumps(scan_case(Path(sys.argv[2]), Path(sys.argv[3])), default=float))
    elif sys.argv[1:2] == ["moduli"]:
        print(json.dumps(moduli_child(int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 1), default=float))
    elif sys.argv[1:2] == ["whole"]:
        print(json.dumps(whole_child(int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 1), default=float))
