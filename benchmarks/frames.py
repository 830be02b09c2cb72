"""Reading the frames of a dump (issue 40): `granstab.io.open` indexes a LAMMPS dump pair once (one pass over each
dump: the byte offsets of every timestep) and reads each frame's rows alone, against the way track, export and
convert read frames before it: `io.frames()` loaded the default frame in full to list the keys, and every frame's
`io.load(frame=k)` indexed the whole dump again, 2(F + 1) passes over the dumps and F + 1 reads for F frames.

The dumps: the track benchmark's random 2D packing written F times as a LAMMPS per-atom dump (id type x y z radius)
and a local dump (id1 id2 fx fy fz), one timestep a frame, read with --columns-free canonical names and k, α, μ
given. Counted (not timed) beside the times: passes over a dump (`lammps._marks`) and row blocks parsed
(`lines.read_window`), so that the table says what the time is made of. `hashing`: what a resumable track folder
adds (issue 38, scan/resume.py): every frame of both dumps hashed (BLAKE2b) for inputs.json, against the whole
files hashed and against reading every frame.
"""
from __future__ import annotations

import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import granstab.io
from granstab.io import lammps
from granstab.model import packings

QUICK = {"frames": 20, "particles": 300}
FULL = {"frames": 200, "particles": 2000}
LAW = {"k": 1000.0, "alpha": 0.5, "mu": 0.5}


def write_dumps(folder: Path, n_particles: int, n_frames: int) -> list[Path]:
    """The packing as F timesteps (0, 100, ...) of an atom dump and a local dump (forces on id1 by id2)."""
    scene = packings.random_packing(2, n_particles, n_sliding=n_particles // 10, mobilised=0.5, seed=2)
    reach = np.zeros(scene.n_particles)
    np.maximum.at(reach, scene.p, np.linalg.norm(scene.point - scene.x[scene.p], axis=1))
    np.maximum.at(reach, scene.q, np.linalg.norm(scene.point - scene.q_copy, axis=1))
    radius = np.where(reach > 0, reach, reach[reach > 0].mean())
    ids = np.arange(1, scene.n_particles + 1)
    lo, hi = scene.x.min(axis=0) - 2 * radius.max(), scene.x.max(axis=0) + 2 * radius.max()
    box = f"ITEM: BOX BOUNDS ff ff ff\n{lo[0]} {hi[0]}\n{lo[1]} {hi[1]}\n-0.5 0.5\n"
    atoms = "\n".join(f"{i} 1 {x:.12g} {y:.12g} 0 {r:.12g}" for i, (x, y), r in zip(ids, scene.x, radius))
    force = scene.force
    local = "\n".join(f"{ids[a]} {ids[b]} {fx:.12g} {fy:.12g} 0" for a, b, (fx, fy) in zip(scene.p, scene.q, force))
    paths = [folder / "atoms.dump", folder / "contacts.dump"]
    with open(paths[0], "w") as fa, open(paths[1], "w") as fc:
        for t in range(n_frames):
            fa.write(f"ITEM: TIMESTEP\n{100 * t}\nITEM: NUMBER OF ATOMS\n{len(ids)}\n{box}"
                     f"ITEM: ATOMS id type x y z radius\n{atoms}\n")
            fc.write(f"ITEM: TIMESTEP\n{100 * t}\nITEM: NUMBER OF ENTRIES\n{len(force)}\n{box}"
                     f"ITEM: ENTRIES id1 id2 fx fy fz\n{local}\n")
    return paths


@contextmanager
def counted():
    """Counts of passes over a dump and of row blocks parsed while the block runs."""
    counts = {"passes": 0, "reads": 0}
    marks, window = lammps._marks, lammps.read_window

    def wrap(name, fn):
        def call(*args, **kwargs):
            counts[name] += 1
            return fn(*args, **kwargs)
        return call
    lammps._marks, lammps.read_window = wrap("passes", marks), wrap("reads", window)
    try:
        yield counts
    finally:
        lammps._marks, lammps.read_window = marks, window


def before(paths) -> list:
    """The frames as track, export and convert read them before io.open: the default frame in full to list the
    keys, then load(frame=k) per frame (each indexing the dumps again)."""
    keys = granstab.io.load(paths, **LAW).frames
    return [granstab.io.load(paths, frame=k, **LAW).scene.n_contacts for k in keys]


def after(paths) -> list:
    source = granstab.io.open(paths, **LAW)
    return [source.read(k).scene.n_contacts for k in source.frames]


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    out = {"frames": cfg["frames"], "particles": cfg["particles"]}
    with tempfile.TemporaryDirectory() as tmp:
        paths = write_dumps(Path(tmp), cfg["particles"], cfg["frames"])
        out["megabytes"] = sum(p.stat().st_size for p in paths) / 1e6
        for name, way in (("before", before), ("after", after)):
            with counted() as counts:
                start = time.perf_counter()
                contacts = way(paths)
                out[name] = {"seconds": time.perf_counter() - start, **counts}
            out["contacts"] = contacts[0]
        start = time.perf_counter()
        source = granstab.io.open(paths, **LAW)
        out["index_seconds"] = time.perf_counter() - start
        start = time.perf_counter()
        source.read(source.frames[len(source.frames) // 2])
        out["one_read_seconds"] = time.perf_counter() - start
        out["hashing"] = hashing(paths, source, out["after"]["seconds"])
    return out


def hashing(paths, source, read_seconds: float, repeats: int = 3) -> dict:
    """Medians of `repeats`: the dumps hashed frame by frame (inputs.json of a track: resume.fingerprint with the
    source's spans) and whole (the way before), and their share of reading every frame (`read_seconds`)."""
    from granstab.scan.resume import fingerprint

    def median(fn):
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            fn()
            times.append(time.perf_counter() - start)
        return float(np.median(times))
    framed = median(lambda: fingerprint(paths, source.spans()))
    return {"frames": len(source.frames), "megabytes": sum(p.stat().st_size for p in paths) / 1e6,
            "per_frame_s": framed, "whole_s": median(lambda: fingerprint(paths)), "read_s": read_seconds,
            "share": framed / read_seconds}


def hashing_lines(h: dict) -> list:
    return [f"Resumable folders (issue 38): hashing both dumps frame by frame for a track's inputs.json "
            f"({h['frames']} frames, {h['megabytes']:.0f} MB) takes {h['per_frame_s']:.3f} s (median of 3; the "
            f"whole files hashed: {h['whole_s']:.3f} s), {100 * h['share']:.1f} % of reading every frame "
            f"({h['read_s']:.1f} s).", ""]


def markdown(results: dict) -> str:
    r = results
    b, a = r["before"], r["after"]
    return "\n".join([
        "## Reading the frames of a dump (issue 40)", "",
        "`granstab.io.open(paths)` indexes a LAMMPS dump pair in one pass over each dump (every timestep's byte "
        "offsets) and `Source.read(frame)` parses that frame's rows only; *before*: the way track, export and "
        "convert read a sequence until then (`io.frames()` loaded the default frame in full to list the keys, "
        "then `io.load(frame=k)` indexed the dumps again for every frame). The dumps: a random 2D packing written "
        "once a timestep (module docstring). Passes over a dump and row blocks parsed are counted, not timed. "
        "One run each (a run takes seconds).", "",
        "| frames × particles (contacts) | dumps | way | time | passes over a dump | row blocks parsed |",
        "|---|---|---|---|---|---|",
        f"| {r['frames']} × {r['particles']:,} ({r['contacts']:,}) | {r['megabytes']:.0f} MB | before | "
        f"{b['seconds']:.1f} s | {b['passes']} | {b['reads']} |",
        f"| | | **io.open** | **{a['seconds']:.1f} s** | {a['passes']} | {a['reads']} |", "",
        f"io.open's index alone: {r['index_seconds']:.2f} s; one frame's read (rows, build, checks): "
        f"{r['one_read_seconds']:.3f} s. Speed-up {b['seconds'] / a['seconds']:.1f}×.", "",
        *hashing_lines(r["hashing"])])
