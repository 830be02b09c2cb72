"""A million grains (issue 41): what granstab does with 10⁶ particles on this machine, measured where it ran and
estimated (said so) where it did not.

- **Reading**: `granstab.io.load` of a LAMMPS per-atom dump of 10⁶ disks and its local contact dump (~3·10⁶
  contacts and 3·10⁵ non-touching pairs, as `pair/local` lists them; benchmarks/converting.py's layout, `%.12g`),
  in a fresh process (`python -m granstab_bench.million read FOLDER`): wall and CPU time, peak resident memory, and
  where the CPU time goes (cProfile: numpy.loadtxt's parser against the rest: ids, geometry, law, cone, checks).
- **The whole packing**: the sparse path's peak memory estimated before it runs (granstab/solve/memory.py,
  calibrated on the periodic benchmark) for 10⁶ disks of the periodic benchmark's packing, against the memory
  available now; a run that does not fit is refused in one line (tested with a fake limit:
  tests/solve/test_memory.py).

The folder of the dumps is written once (several minutes: the packing and the text) and reused when given
(`MILLION_DATA`)."""
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


def scan_case(folder: Path, out: Path, workers: int = 2) -> dict:
    """`granstab scan FOLDER --out OUT --workers W --json` in a fresh process: wall and CPU time (the command and its
    Dask workers), the peak resident memory of the command and of each worker (psutil, sampled every 0.5 s: each
    process's highest), its summary, and the load before and after."""
    import psutil
    load = os.getloadavg()[0]
    cmd = [sys.executable, "-m", "granstab", "scan", str(folder), "--out", str(out), "--overwrite", "--workers",
           str(workers), "--json"]
    t = time.perf_counter()
    with tempfile.TemporaryFile() as stdout:
        proc = psutil.Popen(cmd, stdout=stdout, stderr=subprocess.DEVNULL)
        peak, cpu = {}, {}
        while proc.poll() is None:
            try:
                for p in [proc, *proc.children(recursive=True)]:
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
    main_mb = peak.pop(proc.pid, 0) / 2 ** 20
    return {"rc": proc.returncode, "wall": wall, "cpu_sampled": sum(cpu.values()), "main_mb": main_mb,
            "worker_mb": sorted((v / 2 ** 20 for v in peak.values()), reverse=True),
            "summary": json.loads(text.splitlines()[-1]) if proc.returncode == 0 and text else None,
            "load": [load, os.getloadavg()[0]]}


def gpu_case(n: int) -> dict:
    """The periodic benchmark's packing of about n disks (one contact at yield: 2 branches) on the GPU and on this
    machine's CPU (solve/blockiter.py against the shift-invert path); {"not_run": why} without a GPU."""
    from granstab.solve.device import gpu_available

    from .periodic_child import periodic_packing
    if not gpu_available():
        return {"not_run": "no GPU in this session (CuPy not installed or no CUDA device): the code and its tests "
                           "(tests/solve/test_blockiter.py, skipped here with that reason) are ready"}
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
        return {"reading": measured("read"), "estimates": [whole_memory(m) for m in WHOLE],
                "whole": measured("whole"), "goal_read_s": 20.0, "goal_memory_gb": 20.0, "goal_whole_s": 600.0}
    given = os.environ.get("MILLION_DATA")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(given) if given and not quick else Path(tmp)
        t = time.perf_counter()
        write_dumps(n, folder)
        written = time.perf_counter() - t
        reading = child("read", folder)
    whole = child("whole", n)
    return {"reading": {**reading, "t_write": written}, "estimates": [whole_memory(m) for m in WHOLE],
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
             f"{r['cpu']:.1f} s", f"{r['parse_cpu']:.1f} s ({r['parse_cpu'] / max(r['cpu'], 1e-9):.0%})",
             f"{r['peak_mb']:.0f} MB", "{:.1f} → {:.1f}".format(*r["load"]) + (f" ({r['at']})" if "at" in r else ""),
             where]]


def _whole_rows(w: dict) -> tuple[list, list]:
    """The whole packing's row and its phases' rows (memtrace: wall, CPU, resident at entry and peak)."""
    if w.get("failed"):
        return [["failed (rc {})".format(w.get("rc")), *[""] * 11]], []
    row = [f"{w['particles']:,} / {w['contacts']:,} / {w['dofs']:,}", str(w["branches"]), f"{w['wall']:.0f} s",
           f"{w['cpu']:.0f} s", f"{w['peak_mb'] / 1024:.1f} GB", f"{w['estimated_gb']:.1f} GB",
           "{:.1f} → {:.1f}".format(*w["load"]) + (f" ({w['at']})" if "at" in w else ""), f"{w['lambda_min']:.10g}", f"{w['residual']:.1e}",
           f"{w['bound']:.1e}", "proven, " + "/".join(map(str, w["below"])) + " below σ" if w["counts"] else "no",
           w["verdict"]]
    phases = [[p["phase"], f"{p['wall']:.1f} s", f"{p['cpu']:.1f} s", f"{p['entry_gb']:.2f} GB",
               f"{p['peak_gb']:.2f} GB"] for p in w["phases"]]
    return [row], phases


def markdown(results: dict) -> str:
    if "gpu" in results:
        return gpu_markdown(results["gpu"])
    estimates = [[f"{w['particles']:,}", f"{w['dofs']:,}", ", ".join(f"{k} {_gb(v)}" for k, v in w["parts"].items()),
                  _gb(w["estimated_bytes"]), f"{_gb(w['available_bytes'])} ({w['available_from']})",
                  "fits" if w["fits"] else "refused in one line"] for w in results["estimates"]]
    whole, phases = _whole_rows(results["whole"])
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
        "yield (the elastic and the all-loading branch), in a fresh process; *peak*: its resident peak (wait4); "
        "*estimated*: solve/memory.py's estimate, made before the run; *residual*: the largest ‖Bv − λv‖/‖Hs‖; "
        "*bound*: the largest reported error bound of an eigenvalue (residual and formation error, "
        "accuracy.vector_bounds); *counts*: the number of eigenvalues below σ by inertia (multifrontal.py).",
        "",
        table(["disks / contacts / dofs", "branches", "wall", "CPU", "peak", "estimated", "load", "λ_min",
               "residual", "bound", "counts", "verdict"], whole),
        "",
        "**Where its time and memory go** (benchmarks/memtrace.py: each phase's wall and CPU time, the resident "
        "memory when it began and the highest sampled while it ran; nested phases inside SparseRitz.__init__):",
        "",
        table(["phase", "wall", "CPU", "resident at entry", "peak during"], phases),
        "",
        "**The whole packing's memory estimated before any work** (solve/memory.py; refused in one line where it "
        "exceeds what is available):",
        "",
        table(["disks", "dofs", "parts", "estimated peak", "available", "here"], estimates),
        "",
        NOT_DONE,
    ])


NOT_DONE = (
    "**Not run here**: the moduli of 10⁶ disks (moduli.py factors the grounded non-symmetric H by SuperLU in "
    "minimum-degree order, an LU of both triangles that would not fit at 3·10⁶ dofs; the multifrontal factor above "
    "is symmetric), and the 10⁶-particle scan end to end with the explorer's map (its map builds one Body per "
    "particle in Python).")


if __name__ == "__main__":
    if sys.argv[1:2] == ["read"]:
        print(json.dumps(read_child(Path(sys.argv[2]))))
    elif sys.argv[1:2] == ["scan"]:
        print(json.dumps(scan_case(Path(sys.argv[2]), Path(sys.argv[3])), default=float))
    elif sys.argv[1:2] == ["whole"]:
        print(json.dumps(whole_child(int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 1), default=float))
