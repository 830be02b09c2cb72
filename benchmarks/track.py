"""Track (issue 27): a sequence of frames with `--scan`, per stage (read, the frame's own quantities, the scan, the
between-frame pass), against the obvious alternative: `granstab.scan` of each frame alone (what track adds is the
rest). Goal: 100 frames of 10⁴ disks with --scan in 10 min on 2 cores.

The sequence: the scan benchmark's random 2D packing (a tenth of its contacts at yield), moved from frame to frame
by a small simple shear plus noise (a thousandth of a radius), contacts and forces kept, written as generic tables
with a `frame` column (parsed once per process, io.generic.held_table, then each frame taken from it).

The full size writes the whole sequence (100 frames of 10⁴ disks: the tables the goal is about) and tracks every
`every`-th frame of it in this process (one core), so that a shared 2-core machine can measure it: the per-frame
stages are those of the full run; the total is scaled by the frames left out (conservative: the one read of the
tables is scaled too), and the 2-core figure is the CPU time over 2 (frames are independent tasks).
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from granstab.model import packings
from granstab.scan import scan
from granstab.track import track

QUICK = {"frames": 3, "particles": 1000, "workers": 1, "every": 1}
FULL = {"frames": 100, "particles": 10_000, "workers": 1, "every": 10}
GOAL_SECONDS = 600.0


def write_sequence(folder: Path, n_particles: int, n_frames: int) -> list[Path]:
    """The packing and its sheared copies as particles.csv + contacts.csv (fx fy: the force on id1 by id2)."""
    scene = packings.random_packing(2, n_particles, n_sliding=n_particles // 10, mobilised=0.5, seed=2)
    radius = np.linalg.norm(scene.branch, axis=1).mean() / 2 * np.ones(scene.n_particles)
    touched = np.zeros(scene.n_particles)
    np.maximum.at(touched, scene.p, np.linalg.norm(scene.point - scene.x[scene.p], axis=1))
    np.maximum.at(touched, scene.q, np.linalg.norm(scene.point - scene.q_copy, axis=1))
    radius = np.where(touched > 0, touched, radius)
    rng = np.random.default_rng(0)
    ids = np.arange(1, scene.n_particles + 1)
    prow, crow = [], []
    for frame in range(n_frames):
        x = scene.x + frame * 1e-4 * np.c_[scene.x[:, 1], np.zeros(scene.n_particles)] \
            + 1e-3 * radius[:, None] * rng.standard_normal(scene.x.shape)
        prow.append(np.c_[np.full(len(ids), frame), ids, x, radius])
        crow.append(np.c_[np.full(scene.n_contacts, frame), ids[scene.p], ids[scene.q], scene.force])
    paths = [folder / "particles.csv", folder / "contacts.csv"]
    np.savetxt(paths[0], np.vstack(prow), delimiter=",", header="frame,id,x,y,radius", comments="", fmt="%.10g")
    np.savetxt(paths[1], np.vstack(crow), delimiter=",", header="frame,id1,id2,fx,fy", comments="", fmt="%.10g")
    return paths


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = write_sequence(folder, cfg["particles"], cfg["frames"])
        begun, cpu = time.perf_counter(), time.process_time()
        summary = track(paths, folder / "out", mu=0.5, scan=True, workers=cfg["workers"], figures=False,
                        frames=f"0:{cfg['frames']}:{cfg['every']}")
        seconds, cpu = time.perf_counter() - begun, time.process_time() - cpu
        from granstab.io import load
        alone = load(paths, frame=0.0, mu=0.5).scene
        t = time.perf_counter()
        scan(alone, folder / "alone", workers=1, figures=False)
        scan_alone = time.perf_counter() - t
    tracked = len(range(0, cfg["frames"], cfg["every"]))
    scale = (FULL["frames"] * FULL["particles"]) / (tracked * cfg["particles"])
    serial = summary["cost"]["workers"]["count"] == 1
    return {"frames": cfg["frames"], "tracked": tracked, "particles": cfg["particles"], "seconds": seconds,
            "cpu_seconds": cpu if serial else None,
            "extrapolated_full_cpu_2_cores": cpu * scale / 2 if serial else None,
            "stages": summary["cost"]["stages"], "workers": summary["cost"]["workers"],
            "scan_alone_one_frame": scan_alone, "goal_seconds": GOAL_SECONDS,
            "extrapolated_full": seconds * scale}


def markdown(results: dict) -> str:
    r = results
    s = r["stages"]
    cpu = "" if r.get("cpu_seconds") is None else f" ({r['cpu_seconds']:.1f} s)"
    per_core = "" if r.get("extrapolated_full_cpu_2_cores") is None else \
        f" ({r['extrapolated_full_cpu_2_cores']:.0f} s)"
    tracked = r.get("tracked", r["frames"])
    size = f"{r['frames']} × {r['particles']:,}" + ("" if tracked == r["frames"] else
                                                    f", every {r['frames'] // tracked}th tracked ({tracked})")
    return "\n".join([
        "## Track: a sequence of frames with --scan (issue 27)", "",
        "`granstab.track.track(tables, out, scan=True)` on a sheared random 2D packing (module docstring), per stage "
        "summed over the tracked frames; *scan alone*: `granstab.scan` of its first frame, the obvious alternative "
        "per frame. Goal: 100 frames of 10⁴ disks in 10 min on 2 cores. The full size writes all 100 frames and "
        "tracks every 10th in this process (one worker): the tables read are the full run's (parsed once, then "
        "each frame taken from them), each frame's stages are the full run's; *extrapolated* scales the total by "
        "the frames × particles left out (the one read of the tables too: conservative), and, from the CPU time "
        "of this process, to 2 cores (CPU / 2: frames are independent tasks; the machine's load does not enter "
        "it, it does the wall time).", "",
        "| frames × particles | total (CPU) | read | frame | scan | between frames | scan alone (one frame) × "
        "frames | where | extrapolated to 100 × 10⁴ (CPU / 2 cores) |",
        "|---|---|---|---|---|---|---|---|---|",
        f"| {size} | **{r['seconds']:.1f} s**{cpu} | {s['read']:.1f} s | "
        f"{s['frame']:.2f} s | {s['scan']:.1f} s | {s['between']:.2f} s | {r['scan_alone_one_frame'] * tracked:.1f} s "
        f"| {r['workers']['where']} | {r['extrapolated_full']:.0f} s{per_core} (goal {r['goal_seconds']:.0f} s) |",
        ""])
