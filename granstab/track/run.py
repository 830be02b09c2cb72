"""`track`: a sequence of frames → frames.parquet, particles.parquet, events.json, summary.json (the CONTRACT of
granstab/track/__init__.py). Frames are independent tasks (frame.py), run in this process or on local Dask workers
as the scan's are (scan/workers.py: the default rule, Ctrl-C), each leaving its parts in DIR/parts, so that an
interrupted run resumes with the frames it had; what needs two frames (D²min, contact changes, events) is computed
at the end from the parts (motion.py, quantities.py).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from ..io import is_snapshot
from ..io import open as open_input
from ..io.progress import Heartbeat
from ..io.source import pick_frames
from ..model.errors import Interrupted, require
from ..model.scene import SceneError
from ..scan.clusters import DEFAULT_BOUNDARY, boundary_rings
from ..scan.output import hold_options
from ..scan.run import _progress
from .frame import frame_task
from .tables import finish

EVENT_QUANTITIES = ("shear_stress", "stress_ratio")
POLL_SECONDS = 0.05


def select(text: str | None, keys: list, source) -> list[int]:
    """--frames A,B,C or A:B[:STEP] (the input's frames as export's --frames names them: A to B inclusive, every
    STEP-th) → their positions in the input's frame list; a one-line error for anything else or none selected."""
    if text is None:
        return list(range(len(keys)))
    chosen = set(pick_frames(text, [k for k in keys if k is not None], source))
    return [i for i, key in enumerate(keys) if key in chosen]


def check_options(window: int, d2min_radius, event_quantity: str, event_threshold: float, soft_modes: int,
                  boundary: str, rings: int) -> None:
    if window < 1:
        raise SceneError(f"--window: must be a whole number of frames >= 1, got {window}")
    if d2min_radius is not None and not d2min_radius > 0:
        raise SceneError(f"--d2min-radius: must be > 0, got {d2min_radius}")
    if event_quantity not in EVENT_QUANTITIES:
        raise SceneError(f"--event-quantity: one of {', '.join(EVENT_QUANTITIES)}, got {event_quantity!r}")
    if not event_threshold > 0:
        raise SceneError(f"--event-threshold: must be > 0, got {event_threshold}")
    if soft_modes < 1:
        raise SceneError(f"--soft-modes: must be >= 1, got {soft_modes}")
    if rings < 1:
        raise SceneError(f"--rings: must be >= 1, got {rings}")
    boundary_rings(boundary)


def track(inputs, out_dir, *, format: str = "auto", frames: str | None = None, whole: bool = False,
          scan: bool = False, rigidity: bool = False, predict: bool = False, figures: bool = True,
          window: int = 1, d2min_radius: float | None = None, event_quantity: str = "shear_stress",
          event_threshold: float = 0.05, soft_modes: int = 5, rings: int = 1, boundary: str = DEFAULT_BOUNDARY,
          workers: int | None = None, progress: bool = False, seed: int = 0, overwrite: bool = False,
          uncertainty: dict | None = None, balance: str = "loads", **import_options) -> dict:
    """Track a sequence of frames (docs/track.md).

    Parameters
    ----------
    inputs : path or list of paths
        A snapshot with frames: a LAMMPS dump pair with many timesteps, a RigidLibrary annulus or DataSim folder,
        generic tables with a `frame` column, MercuryDPM output.
    out_dir : path
        The folder (granstab/track/__init__.py: CONTRACT); one holding an interrupted run with the same options
        and inputs (their sizes and content hashes, a dump's frame by frame: scan/resume.py) resumes; other ones are refused in one line
        unless `overwrite` (start afresh).
    frames : "A,B,C" or "A:B[:STEP]", optional
        The input's frames as `--frame` names one (A to B inclusive, every STEP-th; io.source.pick_frames, as
        export's); default all. The tables' `frame` is a frame's 0-based position in the input's list.
    whole, scan, rigidity : bool
        Per frame: the whole-packing analysis (all-unloading and all-loading branches, soft-spot participation in
        the `soft_modes` lowest consistent modes), the local scan (granstab.scan, `rings`, `boundary`), the largest
        rigid cluster.
    predict, figures : bool
        Afterwards granstab.track.predict.run(out_dir) (prediction.json) and granstab.track.figures.write(out_dir),
        where those modules are installed.
    window, d2min_radius : int, float
        D²min and contact changes from a frame to the W-th next selected frame; neighbours within the radius
        (default 2.5 × the first frame's mean contact branch length ≈ 2.5 mean diameters, input length units).
    event_quantity, event_threshold : {"shear_stress", "stress_ratio"}, float
        An event: a drop of the quantity from one selected frame to the next larger than threshold × its mean
        magnitude over the run.
    workers, progress, seed : int or None, bool, int
        Local Dask workers (1: this process; default by the measured cost, scan/workers.py); a bar; the seed of the
        `random` predictor.
    **import_options
        As `granstab.io.load` (mu, k, alpha, columns, length_scale, periodic, …); a snapshot's rattlers are always
        kept.
    uncertainty : dict, optional
        With `scan`: the data's uncertainty (granstab.scan's `uncertainty`): each frame's scan gets data_robust
        (docs/uncertainty.md).
    balance : {"loads", "least-squares"}
        "least-squares": each frame's forces balanced first, walls exempt (as granstab.scan's; row's `balance`).

    Returns
    -------
    dict
        summary.json.
    """
    check_options(window, d2min_radius, event_quantity, event_threshold, soft_modes, boundary, rings)
    require("pyarrow", "scan", "the track's tables")
    paths = [str(p) for p in ([inputs] if isinstance(inputs, (str, Path)) else inputs)]
    options = {k: v for k, v in import_options.items() if v is not None}
    if len(paths) > 1 or is_snapshot(paths[0]):
        options["keep_rattlers"] = True              # a scene file (one frame) is read as written
    begun = time.perf_counter()
    source = open_input(paths, format=format, **options)      # the frames indexed once, each read once
    keys = source.frames
    positions = select(frames, keys, " + ".join(paths))
    out = Path(out_dir)
    spec = {"inputs": paths, "format": format, "import": {k: v for k, v in options.items()}, "out": str(out),
            "whole": whole, "scan": scan, "rigidity": rigidity, "soft_modes": soft_modes, "seed": seed,
            "scan_options": {"rings": rings, "boundary": boundary,
                             **({"uncertainty": uncertainty} if uncertainty else {})},
            **({"balance": balance} if balance != "loads" else {})}
    stated = {**{k: v for k, v in spec.items() if k != "out"}, "frames": frames, "window": window,
              "d2min_radius": d2min_radius, "event_quantity": event_quantity, "event_threshold": event_threshold}
    _open(out, stated, paths, overwrite, source.spans([keys[k] for k in positions]))
    spec["source"] = source
    todo = [k for k in positions if not (out / "parts" / f"frame-{k:06d}.json").exists()]
    with Heartbeat(f"track {out_dir}", enabled=not progress) as beat:      # a line a minute without a bar
        beat.stage("frames", total=len(todo))
        bar = (_progress(len(todo), "frame") if progress else None) or beat
        ran = _frames_kept(spec, todo, positions, keys, workers, bar, out_dir)
        beat.stage("between frames: D²min, contacts, events")
        summary = finish(out, positions, keys, stated, {"resumed": len(positions) - len(todo),
                                                        "frames_this_run": len(todo), "workers": ran,
                                                        "started": begun})
    return _after(out, summary, predict, figures)


def _frames_kept(spec: dict, todo: list, positions: list, keys: list, workers, bar, out_dir) -> dict:
    """run_frames; Ctrl-C: one line saying how many frames the folder keeps and how to go on."""
    out = Path(out_dir)
    try:
        try:
            return run_frames(spec, todo, keys, workers, bar)
        finally:
            bar.close()
    except KeyboardInterrupt:
        kept = sum((out / "parts" / f"frame-{k:06d}.json").exists() for k in positions)
        raise Interrupted(f"granstab track: interrupted (Ctrl-C): {kept} of {len(positions)} frames kept in "
                          f"{out_dir}; the same command (the same --out and options) resumes from "
                          "there") from None


def _open(out: Path, stated: dict, inputs: list, overwrite: bool, spans: dict) -> None:
    """The folder, options.json and inputs.json (a folder with other options or inputs, or other bytes in a frame
    it reads, `spans`: a one-line error, as the scan's; overwrite: start afresh)."""
    (out / "parts").mkdir(parents=True, exist_ok=True)
    hold_options(out, json.loads(json.dumps(stated, default=str)), "track", inputs=inputs, overwrite=overwrite,
                 spans=spans)


def run_frames(spec: dict, todo: list, keys: list, workers: int | None, bar) -> dict:
    """The frames `todo` here or on local Dask workers (`workers`; default: the first frame here measures the
    cost of the rest, scan/workers.py's rule decides). Returns how they ran (summary "workers")."""
    from ..scan.workers import dask_installed, default_workers, machine
    if not todo:
        return {"count": 0, "where": "nowhere", "why": "every frame was already in the folder"}
    if workers is not None and workers <= 1:
        _serial(spec, todo, keys, bar)
        return {"count": 1, "where": "in this process", "why": f"--workers {workers}"}
    if workers is not None:
        require("dask.distributed", "scan", f"--workers {workers}")
        _dask(spec, todo, keys, workers, bar)
        return {"count": workers, "where": f"on {workers} local Dask workers", "why": f"--workers {workers}"}
    start = time.perf_counter()
    _serial(spec, todo[:1], keys, bar)
    cores, load = machine()
    n, why = default_workers((time.perf_counter() - start) * (len(todo) - 1), cores, load, dask=dask_installed())
    if n > 1:
        _dask(spec, todo[1:], keys, n, bar)
        return {"count": n, "where": f"on {n} local Dask workers", "why": f"default: {why}"}
    _serial(spec, todo[1:], keys, bar)
    return {"count": 1, "where": "in this process", "why": f"default: {why}"}


def _serial(spec, todo, keys, bar) -> None:
    for k in todo:
        frame_task(spec, k, keys[k])
        bar.update(1)


def _dask(spec, todo, keys, n: int, bar) -> None:
    """One task a frame on `n` local workers (one thread each), results as they finish; Ctrl-C as the scan's."""
    from dask.distributed import Client, as_completed

    from ..scan.run import local_cluster
    from ..scan.workers import close_quietly, finished, sigint_flag
    cluster = client = None
    try:
        with sigint_flag() as stop:            # from the start: a Ctrl-C while the cluster starts stops it too
            cluster = local_cluster(n)
            client = Client(cluster)
            running = as_completed([client.submit(frame_task, spec, k, keys[k], pure=False, retries=1)
                                    for k in todo])
            for future in finished(running, stop, POLL_SECONDS):
                future.result()                        # a frame's error: its one line, here
                bar.update(1)
    except BaseException:
        close_quietly(client, cluster)
        raise
    client.close()
    cluster.close()


def _after(out: Path, summary: dict, predict: bool, figures: bool) -> dict:
    """granstab.track.predict and .figures where they are installed (another part of issue 27); what ran, in the
    summary."""
    import importlib
    import importlib.util
    done = {}
    for name, wanted, call in (("predict", predict, "run"), ("figures", figures, "write")):
        if not wanted:
            continue
        if importlib.util.find_spec(f"granstab.track.{name}") is None:
            done[name] = f"granstab.track.{name} is not installed in this tree: not run"
            continue
        getattr(importlib.import_module(f"granstab.track.{name}"), call)(out)
        done[name] = "written"
    if done:
        summary["after"] = done
        (out / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False), encoding="utf-8")
    return summary

