"""`granstab` command line: parse, call the core, print; exit 0 on success, 2 on invalid input (one line)."""
from __future__ import annotations

import json
import math
import os
import sys
import time
import warnings
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np

from .analysis import analyze
from .cli_options import (
    FIT_DEFAULTS,
    InputError,
    attach_dash_values,
    band_of,
    band_options,
    build_parser,
    import_options,
    modern_spellings,
    parse_mask,
    parse_strain,
    source_of,
)
from .cli_text import (
    format_moduli,
    format_rigidity,
    format_table,
    import_lines,
    scan_lines,
    track_lines,
    uncertainty_lines,
)
from .io import load
from .io import open as open_input
from .io.scenes import save_scene, scene_to_dict
from .io.source import pick_frames
from .io.syntax import paused_gc
from .mechanics.stiffness import MaskError, stiffness
from .model.errors import Interrupted, MissingExtra
from .model.scene import SceneError
from .moduli import moduli
from .solve.budget import DENSE_ADVICE, SPARSE_ADVICE, UNASKED_HEARTBEAT, OverBudget, deadline
from .solve.plan import fit, fit_lines, plan, unasked_line


class NumericalError(Exception):
    """Floating-point overflow, invalid operation or a failed LAPACK call: one line, exit status 2."""


@contextmanager
def strict_numerics(source: str):
    """numpy floating-point warnings (overflow, division by zero, invalid) and RuntimeWarnings become one-line
    errors naming the file instead of warnings on stderr next to a result computed from them."""
    try:
        with np.errstate(over="raise", divide="raise", invalid="raise"), warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            yield
    except (FloatingPointError, RuntimeWarning, OverflowError, np.linalg.LinAlgError) as exc:
        raise NumericalError(f"{source}: numerical failure ({type(exc).__name__}: {exc}); the scene's magnitudes "
                             "or conditioning are beyond what float64 resolves: change units or check the data") \
            from None


def non_finite_path(value, path: str = "") -> str | None:
    """The first place (dotted path) in a JSON-able result that holds NaN or ±inf, or None."""
    if isinstance(value, float):
        return None if math.isfinite(value) else (path or "value")
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, (list, tuple)):
        items = ((f"[{i}]", v) for i, v in enumerate(value))
    else:
        return None
    for key, v in items:
        sub = f"{path}{key}" if str(key).startswith("[") else (f"{path}.{key}" if path else str(key))
        found = non_finite_path(v, sub)
        if found:
            return found
    return None


def require_finite(data, source: str) -> None:
    """Strict output: a result holding a non-finite number is an error, never printed as a verdict."""
    where = non_finite_path(data)
    if where:
        raise NumericalError(f"{source}: the analysis produced a non-finite number at {where} (overflow): "
                             "change units or check the data's magnitudes")


def write_import_warnings(folder, report: dict, frames: list) -> list[str]:
    """The import warnings of a run over `frames` [(frame, its warnings)], once each (io.validation.run_warnings),
    into the output folder's import.json (source and format as `report` gives them, frames, warnings); the lines
    of the command's output."""
    from .io.validation import run_warnings
    warnings = run_warnings(frames)
    record = {"source": report["source"], "format": report["format"], "frames": [f for f, _ in frames],
              "warnings": warnings}
    (Path(folder) / "import.json").write_text(json.dumps(record, indent=1, default=str), encoding="utf-8")
    return [f"warning: import: {w}" for w in warnings]


def cmd_stiffness(args) -> int:
    with strict_numerics(source_of(args.scene)):
        loaded = load_with_import_options(args.scene, args)
    scene = loaded.scene
    mask = parse_mask(args.mask, scene.n_contacts) if args.mask else None
    try:
        with strict_numerics(scene.source):
            K = stiffness(scene, mask)
    except MaskError as exc:
        raise InputError(f"--mask: {exc}") from None
    if not all(np.isfinite(part).all() for part in (K.H, K.Hm, K.Hg1, K.Hg2, K.Hg3)):
        raise NumericalError(f"{scene.source}: H has non-finite entries (overflow): change units")
    np.savez(args.out, H=K.H, Hm=K.Hm, Hg1=K.Hg1, Hg2=K.Hg2, Hg3=K.Hg3, dofs=np.array(K.dofs))
    print("\n".join([f"wrote {args.out}: H {K.H.shape[0]}x{K.H.shape[1]} ({scene.n_particles} particles, "
                     f"{scene.n_contacts} contacts)", *import_lines(loaded)]))
    return 0


def cmd_analyze(args) -> int:
    if args.rotation_length is not None and args.metric == "inertia":
        raise InputError("--rotation-length: the inertia metric has no rotation length (use --metric L, L/10, 10L "
                         "or family)")
    from .io.progress import Heartbeat
    from .solve.device import DeviceError
    bars = args.progress or sys.stderr.isatty()
    start = time.perf_counter()
    advice = [DENSE_ADVICE]
    given = work_given(args)
    options = {key: getattr(args, key) for key in ("metric", "rotation_length", "max_sliding", "sample_branches",
                                                    "method", "k", "device")}
    # the heartbeat outside the deadline: an alarm inside Heartbeat's own enter or exit would leave its thread running
    with Heartbeat(f"analyze {source_of(args.scene)}", enabled=not bars) as beat, \
            deadline(args.timeout, source_of(args.scene), advice):
        beat.stage("reading")
        with strict_numerics(source_of(args.scene)):
            loaded = load_with_import_options(args.scene, args)
            band = band_of(args, loaded)
            scene, balance = balanced(loaded, band, args.balance)
            try:
                planned = plan(scene, **options)
                if not given and band is None:              # the default plan: fitted to the time a run takes
                    planned = fit(scene, planned, options)
                    options = {**options, **(planned.fitted or {}).get("options", {})}
                if args.plan:                                   # the plan and its estimate; nothing run
                    text = json.dumps({"source": scene.source, "cost": planned.to_dict(), "import": loaded.report},
                                      allow_nan=False) if args.json else "\n".join(planned.lines())
                    print(text)
                    return 0
                refuse_unfinishable(planned, args.timeout and args.timeout - (time.perf_counter() - start))
                beat.estimate = planned.estimated_s
                if unasked_line(planned):                       # over 10 s, nothing cheaper: runs, says so
                    beat.note(unasked_line(planned))
                    beat.often(UNASKED_HEARTBEAT)
                if planned.method == "sparse":
                    advice[0] = SPARSE_ADVICE
                beat.stage("assembly")
                result = analyze(scene, **options, progress=bars or beat)
            except DeviceError as exc:
                raise InputError(f"--device: {exc}") from None
            robust = robustness(scene, result, band, args)
            beat.stage("writing the result")
            asked = band is not None or args.balance != "loads"     # the default result stays as it was
            data = {**result.to_dict(), "import": loaded.report,
                    **({"balance": balance, "data_uncertainty": None if robust is None else robust.to_dict()}
                       if asked else {})}
            if planned.fitted:                                  # what the fit left out, in the result's cost
                data["cost"].update(left_out=list(planned.left_out), fitted=planned.fitted)
            require_finite(data, scene.source)
            text = json.dumps(data, allow_nan=False) if args.json else "\n".join(
                [format_table(result, show_all=args.all), *fit_lines(planned, listed=True),
                 *(uncertainty_lines(robust, balance) if asked else []), *import_lines(loaded)])
    print(text)
    return 0


def balanced(loaded, band, how: str):
    """The scene to analyse and the balance report (--balance; the default keeps the loads that absorb the
    imbalance)."""
    if how != "least-squares":
        return loaded.scene, {"method": "loads absorb the imbalance"}
    from .mechanics.uncertainty import Band
    from .uncertainty import balance_least_squares
    walls = None if loaded.wall_flags is None else np.asarray(loaded.wall_flags) != 0
    return balance_least_squares(loaded.scene, band or Band(), exempt=walls)


def robustness(scene, result, band, args):
    """data_robustness of the analysis's primary metric under `band` (None without one)."""
    if band is None:
        return None
    from .uncertainty import data_robustness
    single = args.metric != "family"
    try:                                    # the primary metric: L at the analysis's own length, or inertia
        return data_robustness(scene, band, metric="inertia" if result.length is None else "L",
                               rotation_length=result.length, max_sliding=args.max_sliding,
                               analysis=result if single and result.backend == "dense" else None)
    except ValueError as exc:
        raise InputError(f"--force-uncertainty: {exc}") from None


def cmd_moduli(args) -> int:
    from .io.progress import Heartbeat
    with strict_numerics(source_of(args.scene)), Heartbeat(f"moduli {source_of(args.scene)}",
                                                           enabled=not sys.stderr.isatty()) as beat:
        beat.stage("reading")
        loaded = load_with_import_options(args.scene, args)
        scene = loaded.scene
        result = moduli(scene, strain=parse_strain(args.strain, scene.dim), max_sliding=args.max_sliding,
                        progress=beat)
        beat.stage("writing the result")
        data = {**result.to_dict(), "import": loaded.report}
        require_finite(data, scene.source)
    print(json.dumps(data, allow_nan=False) if args.json else "\n".join([format_moduli(result, scene),
                                                                          *import_lines(loaded)]))
    return 0


def work_given(args) -> bool:
    """Whether `granstab analyze` was given an option that fixes its work (--metric, --max-sliding,
    --sample-branches, --method, --k, --timeout): then its plan is run or refused as asked, else fitted to the time a
    run takes (solve/plan.fit). Fills FIT_DEFAULTS for those not given."""
    given = args.sample_branches is not None or args.timeout is not None
    for key, value in FIT_DEFAULTS.items():
        given |= getattr(args, key) is not None
        setattr(args, key, value if getattr(args, key) is None else getattr(args, key))
    return given


def refuse_unfinishable(planned, seconds_left: float | None) -> None:
    """Refuse (one line, before any work) what the plan (solve/plan.py) cannot start — more sliding contacts than
    --max-sliding without a sample — or whose estimate, over every metric asked for, exceeds the time left of
    --timeout (without --timeout: budget.ASK_SECONDS); each message says what to do."""
    planned.refuse(seconds_left)


def cmd_rigidity(args) -> int:
    """Rigid clusters, floppy modes, self-stresses and Maxwell counts (issue 28): JSON or a readable summary."""
    from .rigidity import rigidity
    with strict_numerics(str(args.input[0])):
        loaded = load_with_import_options(args.input, args)
        result = rigidity(loaded.scene, model=args.kind, walls=args.walls, wall_flags=loaded.wall_flags)
        result["import"] = loaded.report
        require_finite({k: v for k, v in result.items() if k != "import"}, loaded.scene.source)
    if args.figure:
        from .rigidity.figure import write_figure
        result["figure"] = str(write_figure(loaded.scene, result, args.figure))
    if args.out:
        from .model.grains import from_loaded
        from .rigidity.output import write_result
        result["out"] = str(write_result(loaded.scene, result, args.out, from_loaded(loaded)))
    print(json.dumps(result, allow_nan=False) if args.json else "\n".join([format_rigidity(result),
                                                                          *import_lines(loaded)]))
    return 0


def cmd_reproduce(args) -> int:
    from .paper import reproduce
    reproduce(args.name, Path(args.out), root=args.root)
    return 0


def cmd_convert(args) -> int:
    """Snapshot(s) (or a scene file) → contact-level scene JSON or NPZ; prints the validation report (issue 9)."""
    from .io import format_report
    from .model.grains import from_loaded
    loaded = load_with_import_options(args.inputs, args)
    if Path(args.out).suffix.lower() == ".npz":      # binary: 10⁶ contacts in a fraction of a second
        save_scene(loaded.scene, args.out, shapes=from_loaded(loaded))   # with the grains' true shapes
    else:
        with paused_gc():
            text = json.dumps(scene_to_dict(loaded.scene, from_loaded(loaded)))
        Path(args.out).write_text(text, encoding="utf-8")
    report = {**loaded.report, "out": args.out}
    print(json.dumps(report) if args.json else format_report(report) + f"\nwrote {args.out}")
    return 0


def cmd_extract(args) -> int:
    """The cluster of one particle as a scene file (issue 10): re-analyse, open in the app, check by hand."""
    from .model.grains import cut, from_loaded
    from .scan import extract
    loaded = load_with_import_options(args.input, args)
    sub = extract(loaded.scene, args.center, rings=args.rings, boundary=args.boundary)
    shapes = cut(from_loaded(loaded), loaded.scene, sub)               # the cluster's grains as they are
    Path(args.out).write_text(json.dumps(scene_to_dict(sub, shapes), allow_nan=False), encoding="utf-8")
    held = "" if sub.fixed is None else f" ({int(sub.fixed.sum())} of them held fixed)"
    print("\n".join([f"wrote {args.out}: {sub.n_particles} particles{held}, {sub.n_contacts} contacts",
                     *import_lines(loaded)]))
    return 0


def cmd_scan(args) -> int:
    """Every local cluster of a packing → DIR/clusters, particles, summary.json, map (issue 10)."""
    from .model.grains import from_loaded
    from .scan import scan
    from .solve.device import DeviceError
    loaded = load_with_import_options(args.input, args)
    try:
        summary = scan(loaded.scene, args.out, rings=args.rings, centers=args.centers, metric=args.metric,
                       boundary=args.boundary, max_sliding=args.max_sliding, sample_branches=args.sample_branches,
                       scheduler=args.scheduler, workers=args.workers, progress=args.progress, fmt=args.out_format,
                       device=args.device, attribution=not args.no_attribution, inputs=args.input,
                       overwrite=args.overwrite, uncertainty=band_options(args, loaded), balance=args.balance,
                       exempt=None if loaded.wall_flags is None else np.asarray(loaded.wall_flags) != 0,
                       shapes=from_loaded(loaded))
    except DeviceError as exc:
        raise InputError(f"--device: {exc}") from None
    warned = write_import_warnings(args.out, loaded.report, [(loaded.report.get("frame"), loaded.warnings)])
    print(json.dumps({**summary, "import": loaded.report}, allow_nan=False) if args.json else "\n".join(
        [*scan_lines(summary, args.out), *warned]))
    return 0


def cmd_export(args) -> int:
    """A packing (or a sequence of its frames) → .vtp, extended XYZ or a dump pair for ParaView and OVITO (issue 29)."""
    from .export import frame_of as export_frame
    from .export import write
    from .export.modes import modes_options
    from .export.track import track_fields, track_frames
    start, source = time.perf_counter(), source_of(args.input)
    if args.track and args.frames:
        raise InputError("--track: the track folder names the frames; give --frames or --track, not both")
    wanted = [(None, None)]                                      # (the track's position, the reader's frame)
    source = open_input(args.input, format=args.format, progress=args.progress,    # the frames indexed once,
                        **import_options(args))                                     # each read once
    if args.frame is not None or args.timestep is not None:
        wanted = [(None, args.frame if args.frame is not None else args.timestep)]
    if args.track or args.frames:
        if args.scan_dir:
            raise InputError("--scan-dir: a scan folder holds one packing; a sequence (--frames, --track) takes "
                             "none")
        available = [f for f in source.frames if f is not None]
        if args.track:
            wanted = track_frames(args.track)
            keys = [k for _, k in wanted if k is not None]
            if keys:                                              # the track's frames are the input's
                pick_frames(",".join(map(str, keys)), available, source)
        else:
            wanted = [(None, f) for f in pick_frames(args.frames, available, source)]
    from .io.progress import Heartbeat
    frames, notes = [], []
    advice = ["export without --modes (the scan's fields and the forces need no whole-packing analysis), export "
              "a smaller region (convert --region), or raise --timeout"]
    with Heartbeat(f"export {source}") as beat, deadline(args.timeout, source, advice):   # the alarm inside the beat
        for position, f in wanted:
            beat.stage(f"frame {f}" if f is not None else "reading")
            loaded = source.read(f)
            if args.modes:                       # the whole-packing analysis: refused before it starts if too long
                planned = plan(loaded.scene, **modes_options(args.modes, args.sample_branches, args.max_sliding))
                refuse_unfinishable(planned, args.timeout and args.timeout - (time.perf_counter() - start))
                beat.estimate = planned.estimated_s
                if unasked_line(planned):                       # over 10 s, nothing cheaper: runs, says so
                    beat.note(unasked_line(planned))
                    beat.often(UNASKED_HEARTBEAT)
            extra = track_fields(args.track, position, loaded.scene.names) if args.track else None
            beat.stage(f"frame {f}: fields and modes" if f is not None else "fields and modes")
            frames.append(export_frame(loaded.scene, scan=args.scan_dir, modes=args.modes, time=f or 0, extra=extra,
                                       orientation=loaded.orientation, shape=loaded.shape,
                                       analysis=modes_options(args.modes, args.sample_branches, args.max_sliding)))
            notes.append((f, loaded.warnings))
    paths = write(frames, args.out, args.out_format, Path(args.input[0]).stem or "packing")
    names = [p.name for p in paths] if len(paths) <= 6 else [paths[0].name, "…", paths[-1].name]
    warned = write_import_warnings(args.out, loaded.report, notes)
    print("\n".join([f"wrote {len(frames)} frame(s) as {args.out_format} in {time.perf_counter() - start:.1f} s: "
                      f"{len(paths)} file(s) in {args.out} ({', '.join(names)})", *warned]))
    return 0


def load_with_import_options(inputs, args):
    """`granstab.io.load` of `inputs` with the options `import_arguments` defined (only those given are passed,
    so that a scene file, which takes none, is read as written)."""
    return load(inputs, format=args.format, frame=args.frame, timestep=args.timestep,
                progress=args.progress or sys.stderr.isatty(), **import_options(args))


def cmd_track(args) -> int:
    """A sequence of frames → DIR/frames.parquet, particles.parquet, events.json, summary.json (issue 27)."""
    from .track import track
    if args.frame is not None or args.timestep is not None:
        raise InputError(f"--{'frame' if args.frame is not None else 'timestep'}: track reads every frame of the "
                         "input; choose them with --frames A:B[:STEP]")
    if args.frames is not None:        # the old meaning, 0-based positions: one release's note (docs/cli.md)
        print("granstab track: --frames names the input's frames as export's does (A:B inclusive, by frame number "
              "or timestep), no longer 0-based positions with B excluded", file=sys.stderr)
    options = {k: v for k, v in import_options(args).items() if k != "keep_rattlers"}   # track keeps them always
    summary = track(args.inputs, args.out, format=args.format, frames=args.frames, whole=args.whole,
                    scan=args.scan, rigidity=args.rigidity, predict=args.predict, figures=not args.no_figures,
                    window=args.window, d2min_radius=args.d2min_radius, event_quantity=args.event_quantity,
                    event_threshold=args.event_threshold, soft_modes=args.soft_modes, rings=args.rings,
                    boundary=args.boundary, workers=args.workers, progress=args.progress, seed=args.seed,
                    overwrite=args.overwrite, uncertainty=band_options(args), balance=args.balance, **options)
    print(json.dumps(summary) if args.json else "\n".join(track_lines(summary, args.out)))
    return 0


RUNS = {"stiffness": cmd_stiffness, "analyze": cmd_analyze, "moduli": cmd_moduli, "reproduce": cmd_reproduce,
        "convert": cmd_convert, "extract": cmd_extract, "scan": cmd_scan, "rigidity": cmd_rigidity, "track": cmd_track,
        "export": cmd_export}   # each core command's run; packages outside the core bring their own (cli_options.PLUGINS)
EXIT_INTERRUPTED = 130    # 128 + SIGINT, as a shell reports a command stopped by Ctrl-C


def interrupted_line(exc: KeyboardInterrupt, command: str | None) -> str:
    """Ctrl-C as one line: what was kept and how to go on (a scan says it: Interrupted), else that nothing was."""
    if isinstance(exc, Interrupted) and str(exc):
        return str(exc)
    return (f"granstab{' ' + command if command else ''}: interrupted (Ctrl-C) before it finished; nothing was "
            "kept: run it again to start over")


def main(argv=None) -> int:
    command = None
    try:
        words, notes = modern_spellings(sys.argv[1:] if argv is None else argv)
        print("\n".join(notes), file=sys.stderr, end="\n" if notes else "")
        args = build_parser(RUNS).parse_args(attach_dash_values(words))
        command = args.command
        status = args.run(args)
        sys.stdout.flush()                 # a closed pipe shows here, not in the interpreter's exit
        return status
    except (SceneError, InputError, NumericalError, OverBudget, MissingExtra) as exc:
        print(" ".join(str(exc).split()), file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        line = " ".join(interrupted_line(exc, command).split())
        exc.__traceback__ = None           # the interrupted frames go now: a progress bar in them closes before
        print(line, file=sys.stderr)       # the line, which stays the last one
        return EXIT_INTERRUPTED
    except BrokenPipeError:                # the reader stopped reading (`| head`): a quiet exit, as if finished
        with suppress(OSError, ValueError):   # nothing more to flush at exit (a stdout without a file: nothing)
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # an output path that cannot be written: bad input too, one line
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"granstab: cannot write {where}{exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
