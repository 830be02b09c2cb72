"""`granstab` command line: parse, call the core, print; exit 0 on success, 2 on invalid input (one line)."""
from __future__ import annotations

import argparse
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
from .io import load
from .io import open as open_input
from .io.scenes import save_scene, scene_to_dict
from .io.syntax import paused_gc
from .mechanics.branches import BOTH, MINUS, PLUS, RIGID
from .mechanics.metric import CHOICES as METRIC_CHOICES
from .mechanics.stiffness import MaskError, stiffness
from .model.errors import Interrupted, MissingExtra, require
from .model.scene import SceneError
from .moduli import moduli
from .scan.clusters import DEFAULT_BOUNDARY
from .solve.budget import DENSE_ADVICE, SPARSE_ADVICE, OverBudget, deadline
from .solve.plan import fit, fit_lines, plan


class InputError(Exception):
    """Invalid command-line input; printed as one line, exit status 2."""


class Parser(argparse.ArgumentParser):
    def error(self, message):  # one line instead of usage + message
        raise InputError(f"{self.prog}: {message}")


def parse_mask(text: str, n_contacts: int) -> np.ndarray:
    try:
        mask = np.array([int(v) for v in text.split(",")])
    except ValueError:
        raise InputError(f"--mask: expected comma-separated +1, -1, 0, got {text!r}") from None
    if mask.shape != (n_contacts,) or not np.all(np.isin(mask, (-1, 0, 1))):
        raise InputError(f"--mask: needs {n_contacts} entries (one per contact, file order), each +1, -1 or 0")
    return mask


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


def import_lines(loaded) -> list[str]:
    """The import's warnings (projected forces, dropped rattlers, cut contacts, ...; none for a scene file) as
    lines of a command's output."""
    return [f"warning: import: {w}" for w in loaded.warnings]


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
        loaded = load(args.scene)
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


MARK = {PLUS: "+v", MINUS: "-v", BOTH: "±v", RIGID: "rigid"}


TABLE_LOWEST = 8   # eigenvalues per branch in the readable table (all of them with --all)


def format_table(result, show_all: bool = False) -> str:
    """A readable report of an Analysis: per branch the lowest TABLE_LOWEST eigenvalues with consistency marks and
    the counts (every eigenvalue with show_all), then the verdict."""
    s = result.scene
    d = result.to_dict()
    lines = [f"{s.title or s.source}: {s.dim}D, {s.n_particles} particles, {s.n_contacts} contacts, "
             f"{d['n_sliding']} potentially sliding, {len(result.branches)} branch(es), metric {result.metric.name}"
             + ("" if result.length is None else f", L = {result.length:.4g}") + f" (eigenvalues in {result.metric.units})"]
    for b in result.branches:
        mask = " ".join(f"{int(v):+d}" for v in b.mask[result.problem.sliding]) or "(all elastic)"
        lines.append(f"branch [{mask}]  zeros: {b.n_zero} (tol {b.zero_tol:.1e})  ℍ nullity: {b.uniqueness_n_zero}")
        lam, codes = np.asarray(b.stability_eigenvalues), np.asarray(b.codes)
        shown = np.argsort(lam, kind="stable") if show_all else np.argsort(lam, kind="stable")[:TABLE_LOWEST]
        cells = [f"{lam[i]: .6g}{'(' + MARK[codes[i]] + ')' if codes[i] in MARK else ''}" for i in shown]
        rest = len(lam) - len(shown)
        lines.append(f"  sym(𝓗) eigenvalues ({'all ' if not rest else f'lowest {len(shown)} of '}{len(lam)}: "
                     f"{int(np.sum(lam < -b.zero_tol))} negative, {b.n_zero} zero, {int(np.sum(lam > b.zero_tol))} "
                     f"positive): " + ", ".join(cells) + (f", … ({rest} more: --all)" if rest else ""))
    sm = d["summary"]
    lines.append(f"verdict: {sm['verdict'].upper()} — {sm['reason']}")
    low = [k.split("_")[1] for k, v in sm["counts_are"].items() if v != "totals"]
    lines.append(f"consistent eigenvalues: {sm['consistent_positive']} positive, {sm['consistent_negative']} "
                 f"negative, {sm['consistent_zero']} zero"
                 + (f" ({', '.join(low)}: lower bounds; suggested k: {sm.get('suggest_k')})" if low else "")
                 + "; Type-2 non-uniqueness: "
                 f"{'yes' if sm['type2_nonuniqueness'] else 'no'}"
                 + ("; verdict hinges on an S within tolerance" if sm["hinges_on_tolerance"] else ""))
    if sm.get("metrics"):
        robust = {True: "verdict proven metric-robust", False: "verdict proven to depend on the metric"}.get(
            sm["metric_robust"], "verdict's metric-robustness not proven")
        counts = "counts equal" if sm.get("counts_robust") else "counts differ"
        lines.append(f"metric family ({robust}; {counts}): " + "; ".join(
            f"{e['metric']}: {e['verdict']} {e['consistent_positive']}+/{e['consistent_negative']}-"
            for e in sm["metrics"]))
    if result.attribution is not None:
        lines.append(result.attribution.line())
    if not sm["sufficient"]:
        lines.append("not sufficient because: " + ", ".join(sm["insufficient_because"]))
    lines.append("errors (relative): " + ", ".join(f"{k} {v:.1e}" for k, v in d["errors"].items()))
    lines.append("timings: " + ", ".join(f"{k} {1e3 * v:.2f} ms" for k, v in d["timings"].items()))
    lines += [f"warning: {w}" for w in d["warnings"]]
    return "\n".join(lines)


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
            band = band_of(args)
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


def format_moduli(result, scene) -> str:
    """A readable report of a Moduli result: stress, C in Voigt-like index pairs, isotropic summaries, the branches'
    eigenvalues (fixed cell and fixed stress), the direction's consistent branches, zero modes, errors, time."""
    d = result.dim
    pairs = [(i, i) for i in range(d)] + ([(0, 1)] if d == 2 else [(1, 2), (0, 2), (0, 1)])
    axes = "xyz"
    label = [axes[i] + axes[j] for i, j in pairs]
    C = result.C
    lines = [f"{scene.title or scene.source}: {d}D periodic, {scene.n_particles} particles, {scene.n_contacts} "
             f"contacts, volume {result.volume:.6g}",
             "stress σ (tension positive): " + "; ".join(" ".join(f"{v: .6g}" for v in row) for row in result.stress)
             + f"   (pressure {result.pressure:.6g})",
             "C_ijkl (elastic branch)  " + "  ".join(f"{lab:>11}" for lab in label)]
    for (i, j), lab in zip(pairs, label):
        lines.append(f"  {lab:>22}  " + "  ".join(f"{C[i, j, k, m]:11.5g}" for k, m in pairs))
    lines.append(f"bulk {result.bulk:.6g}, shear {result.shear:.6g} (isotropic averages)")
    for b in result.branches:
        lines.append(f"branch {b.name}: eigenvalues of sym(C) " + ", ".join(f"{v:.5g}" for v in b.eigenvalues)
                     + "; at fixed stress sym(C - Q) " + ", ".join(f"{v:.5g}" for v in b.fixed_stress_eigenvalues))
    if result.direction is not None:
        found = result.direction["consistent"]
        lines.append(f"strain direction: {len(found)} consistent branch(es) of {result.direction['n_branches']}"
                     + "".join(f"; modulus {c['modulus']:.6g}" for c in found))
        if "note" in result.direction:
            lines.append(f"  {result.direction['note']}")
    fs = result.verdicts["fixed_stress"]
    lines.append(f"fixed stress: {fs['verdict'].upper()} ({'proven' if fs['sufficient'] else 'not proven'}; "
                 f"min eigenvalue {fs['min_eigenvalue']:.4g}, tolerance {fs['tolerance']:.1e}, "
                 f"{fs['n_branches']} branch(es)); fixed cell: {result.verdicts['fixed_cell']['verdict'].upper()} "
                 "(sym(H), elastic branch; granstab analyze for every branch)")
    z = result.zero_modes
    lines.append(f"zero modes: {z['translations']} translations, {z['free_spins']} free spins, {z['rattlers']} "
                 f"rattlers, {z['mechanisms']} mechanisms")
    lines.append("errors (relative): " + ", ".join(f"{k} {v:.1e}" for k, v in result.errors.items())
                 + f"; time {1e3 * result.seconds:.1f} ms")
    lines += [f"note: {n}" for n in result.notes]
    return "\n".join(lines)


def parse_strain(text: str | None, dim: int):
    """--strain: d·d numbers separated by commas or blanks (row by row), or None."""
    if text is None:
        return None
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise InputError(f"--strain: numbers expected, got {text!r}") from None
    if len(values) != dim * dim:
        raise InputError(f"--strain: {dim * dim} numbers expected (a {dim}x{dim} tensor row by row), got {len(values)}")
    return np.array(values).reshape(dim, dim)


def uncertainty_arguments(p, balance: bool = True) -> None:
    """--force-uncertainty, --position-uncertainty, --balance (issue 42, docs/uncertainty.md)."""
    p.add_argument("--force-uncertainty", default=None, metavar="REL[,ABS]",
                   help="each contact force within REL·|f| + ABS of its value: the verdict holds / depends on the "
                        "data / undecided (docs/uncertainty.md)")
    p.add_argument("--position-uncertainty", type=positive_number, default=None, metavar="LEN",
                   help="contact points and centres within LEN (first order only)")
    if not balance:
        p.add_argument("--search-counterexamples", action="store_true",
                       help="clusters the batched bound does not decide: the per-cluster bound and the search for "
                            "forces within the band that change the verdict (depends; costs more: BENCHMARKS.md)")
        return
    p.add_argument("--balance", choices=["loads", "least-squares"], default="loads",
                   help="loads (default): the loads absorb the measured imbalance; least-squares: forces moved to the "
                        "nearest balanced set, weighted by the force uncertainty")


def band_of(args):
    """The Band of --force-uncertainty / --position-uncertainty, or None."""
    from .mechanics.uncertainty import Band, parse_force_uncertainty
    if args.force_uncertainty is None and args.position_uncertainty is None:
        return None
    try:
        rel, abs_ = parse_force_uncertainty(args.force_uncertainty or "0")
    except ValueError as exc:
        raise InputError(str(exc)) from None
    return Band(rel=rel, abs=abs_, position=args.position_uncertainty or 0.0)


def band_options(args) -> dict | None:
    """The scan's `uncertainty` option (Band fields, search) of --force-uncertainty / --position-uncertainty."""
    band = band_of(args)
    return None if band is None else {"rel": band.rel, "abs": band.abs, "position": band.position,
                                      "search": bool(getattr(args, "search_counterexamples", False))}


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


def uncertainty_lines(robust, balance: dict) -> list[str]:
    out = [f"balance: {balance['method']}" + ("" if balance.get("inside_band") is None else
           f"; corrections {'inside' if balance['inside_band'] else 'OUTSIDE'} the band (largest "
           f"{balance['largest_correction_over_band']:.3g}× a contact's band)")]
    if robust is not None:
        out.append(f"data uncertainty ({robust.band}): the verdict {robust.verdict} {robust.robust.upper()} — "
                   f"{robust.reason}" + ("; first order in positions" if robust.first_order else ""))
    return out


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


FIT_DEFAULTS = {"metric": "family", "max_sliding": 16, "method": "auto", "k": 6}   # analyze's, where not given


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
        result = rigidity(loaded.scene, model=args.model, walls=args.walls, wall_flags=loaded.wall_flags)
        result["import"] = loaded.report
        require_finite({k: v for k, v in result.items() if k != "import"}, loaded.scene.source)
    if args.figure:
        from .rigidity.figure import write_figure
        result["figure"] = str(write_figure(loaded.scene, result, args.figure))
    if args.out:
        from .rigidity.output import write_result
        result["out"] = str(write_result(loaded.scene, result, args.out))
    print(json.dumps(result, allow_nan=False) if args.json else "\n".join([format_rigidity(result),
                                                                          *import_lines(loaded)]))
    return 0


def format_rigidity(result: dict) -> str:
    """A readable summary of a rigidity result: per model the clusters, modes, counts and cost."""
    lines = [f"{result['source']}: {result['dim']}D, walls {result['walls']}"
             + (", periodic cell (fixed)" if result["periodic"] else "")]
    for name in ("physical", "generic"):
        if name not in result:
            continue
        r, c = result[name], result[name]["counts"]
        sizes = ", ".join(str(len(cl["particles"])) for cl in r["clusters"][:5])
        lines.append(f"{name} ({r['method']}): {len(r['clusters'])} rigid clusters (largest: {sizes or 'none'} "
                     f"particles); {r['floppy_modes']['count']} internal floppy modes + {r['trivial_modes']['count']} "
                     f"trivial; {r['self_stresses']} self-stresses; {len(r['rattlers'])} rattlers; "
                     f"z = {c['z']:.3f} (without rattlers {c['z_without_rattlers']:.3f}), z_iso = "
                     f"{c['z_iso']:.3f}; Maxwell: {c['maxwell']['dofs']} dofs - {c['maxwell']['constraints']} "
                     f"constraints + {c['maxwell']['self_stresses']} self-stresses = {c['maxwell']['floppy']} floppy; "
                     f"{r['seconds']:.2f} s")
        if name == "physical":
            t = r["rank_tolerance"]
            gap = "none dropped (full rank)" if t["gap"] is None else f"{t['gap']:.3g}"
            lines.append(f"  rank tolerance {t['largest']:.2e}, singular-value gap {gap}")
            ps = r["prestress"]
            for branch in ("all_loading", "all_unloading"):
                if ps.get("evaluated"):
                    b = ps[branch]
                    lines.append(f"  prestress, {branch.replace('_', '-')}: {b['stabilised']} floppy directions "
                                 f"stabilised, {b['destabilised']} destabilised, {b['neutral']} neutral")
    if "differ" in result:
        d = result["differ"]
        lines.append("models agree on every contact" if d["same_partition"] else
                     f"models differ on {d['count']} contacts (--json: differ.contacts)")
    if "figure" in result:
        lines.append(f"wrote {result['figure']}")
    if "out" in result:
        lines.append(f"wrote {result['out']} (rigidity.json, packing.npz): granstab-app --preset {result['out']}")
    return "\n".join(lines)


def cmd_reproduce(args) -> int:
    from .paper import reproduce
    reproduce(args.name, Path(args.out), root=args.root)
    return 0


def cmd_bench(args) -> int:
    from granstab_bench.document import NotGenerated  # outside the core package; only this command needs it
    from granstab_bench.runner import TOPICS, run

    from .solve.device import gpu_available
    unknown = sorted(set(args.only or ()) - set(TOPICS))
    if unknown:
        raise InputError(f"--only: unknown topic {unknown[0]!r} (choose from {', '.join(TOPICS)})")
    if args.device == "gpu" and not gpu_available():
        raise InputError("--device gpu: needs CuPy and a CUDA GPU (pip install 'granstab[gpu]'); without one the "
                         "CPU benchmarks are `granstab bench`")
    try:
        run(quick=args.quick, out=Path(args.out), only=args.only, device=args.device)
    except NotGenerated as exc:
        raise InputError(str(exc)) from None
    return 0


def cmd_publish(args) -> int:
    """A scene recorded into one self-contained HTML page (issue 29): the explorer's drawing, played offline."""
    require("viser", "app", "granstab publish")
    from granstab_app.publish import publish  # outside the core package (it needs viser); only this command needs it
    done = publish(args.scene, Path(args.out))
    print(f"wrote {args.out}: {done['bytes'] / 1e6:.2f} MB, {done['seconds']:.0f} s of recording, {done['steps']} "
          f"{'steps of ρ/r' if done['sweep'] else 'modes'}; it opens offline in a browser (no dragging, no sliders: "
          "its playback bar plays the recording)")
    return 0


def positive_number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def count(low: int):
    """argparse type: an integer >= low."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {text!r}")
        return value
    return parse


def cmd_convert(args) -> int:
    """Snapshot(s) (or a scene file) → contact-level scene JSON or NPZ; prints the validation report (issue 9)."""
    from .io import format_report

    loaded = load_with_import_options(args.inputs, args)
    if Path(args.out).suffix.lower() == ".npz":
        save_scene(loaded.scene, args.out)             # binary: 10⁶ contacts in a fraction of a second
    else:
        with paused_gc():
            data = scene_to_dict(loaded.scene)
            for entry, extra in zip(data["particles"], _grain_entries(loaded)):
                entry.update(extra)                    # the grains' true shapes, for drawing (model/grains.py)
            text = json.dumps(data)
        Path(args.out).write_text(text, encoding="utf-8")
    report = {**loaded.report, "out": args.out}
    print(json.dumps(report) if args.json else format_report(report) + f"\nwrote {args.out}")
    return 0


def _grain_entries(loaded) -> list:
    """Per particle, the `shape` and `orientation` entries of an import's grains (none for disks and spheres)."""
    from .model.grains import from_loaded
    grains = from_loaded(loaded)
    return [] if grains is None else grains.entries()


def cmd_extract(args) -> int:
    """The cluster of one particle as a scene file (issue 10): re-analyse, open in the app, check by hand."""
    from .scan import extract
    loaded = load(args.input, **periodic_options(args))
    sub = extract(loaded.scene, args.center, rings=args.rings, boundary=args.boundary)
    Path(args.out).write_text(json.dumps(scene_to_dict(sub), allow_nan=False), encoding="utf-8")
    held = "" if sub.fixed is None else f" ({int(sub.fixed.sum())} of them held fixed)"
    print("\n".join([f"wrote {args.out}: {sub.n_particles} particles{held}, {sub.n_contacts} contacts",
                     *import_lines(loaded)]))
    return 0


def cmd_scan(args) -> int:
    """Every local cluster of a packing → DIR/clusters, particles, summary.json, map (issue 10)."""
    from .scan import scan
    from .solve.device import DeviceError
    loaded = load_with_import_options(args.input, args)
    try:
        summary = scan(loaded.scene, args.out, rings=args.rings, centers=args.centers, metric=args.metric,
                       boundary=args.boundary, max_sliding=args.max_sliding, sample_branches=args.sample_branches,
                       scheduler=args.scheduler, workers=args.workers, progress=args.progress, fmt=args.format,
                       device=args.device, attribution=not args.no_attribution, inputs=args.input,
                       overwrite=args.overwrite, uncertainty=band_options(args))
    except DeviceError as exc:
        raise InputError(f"--device: {exc}") from None
    warned = write_import_warnings(args.out, loaded.report, [(loaded.report.get("frame"), loaded.warnings)])
    print(json.dumps({**summary, "import": loaded.report}, allow_nan=False) if args.json else "\n".join(
        [*scan_lines(summary, args.out), *warned]))
    return 0


def periodic_arguments(p, cell: bool = False) -> None:
    """The periodic-cell import options of a command that reads snapshots (io/build.py: Options)."""
    p.add_argument("--no-periodic", dest="periodic", action="store_false",
                   help="a periodic snapshot as a free cluster: cut the contacts across the cell's seam (their "
                        "forces become loads) instead of keeping them with their images")
    if cell:
        p.add_argument("--cell", help="the periodic cell of tables without one: the rows a_1 … a_d "
                                      "(e.g. 20,0,5,20 in 2D) or an orthogonal box (20,20)")


def periodic_options(args) -> dict:
    """--no-periodic / --cell as load() options (none given: none, so that scene files take them too)."""
    options = {} if args.periodic else {"periodic": False}
    if getattr(args, "cell", None) is not None:
        options["cell"] = args.cell
    return options


def scan_lines(summary: dict, out) -> list[str]:
    """A scan's readable output: clusters, time and verdicts (and, resumed, how many an interrupted run had kept),
    then where it ran and why (the default's rule: granstab/scan/workers.py)."""
    kept = summary.get("resumed", 0)
    resumed = (f" (resumed: {kept} already in the folder, {summary['clusters_this_run']} analysed now)"
               if kept else "")
    mechanisms = summary.get("mechanisms", {})
    return [f"{summary['clusters']} clusters{resumed} in {summary['seconds']:.1f} s: "
            + ", ".join(f"{v} {c}" for v, c in summary["verdicts"].items())
            + ("; unstable by mechanism: " + ", ".join(f"{m} {c}" for m, c in mechanisms.items() if c)
               if any(mechanisms.values()) else "") + f"; wrote {out}",
            *(["verdicts under the data's uncertainty (docs/uncertainty.md): "
               + ", ".join(f"{v} {c}" for v, c in summary["data_robust"].items())] if "data_robust" in summary else []),
            f"ran {summary['workers']['where']} ({summary['workers']['why']})"]


def input_argument(p, dest: str) -> None:
    """The input of analyze, stiffness, extract and scan: a scene file, or one snapshot as a folder or its files
    (`analyze atoms.dump contacts.dump in.disks`), as `convert` takes it (granstab.io.load)."""
    p.add_argument(dest, nargs="+", metavar="SCENE_OR_FILES",
                   help="a scene file (TOML, JSON, NPZ), or a snapshot: its folder or its files (docs/formats.md)")


def source_of(paths: list) -> str:
    """The inputs as messages name them: the path, or the files joined by ' + ' (as the snapshot readers do)."""
    return " + ".join(map(str, paths))


def overwrite_argument(p) -> None:
    p.add_argument("--overwrite", action="store_true",
                   help="start afresh in an --out that holds a run (by default it resumes, refusing changed inputs "
                        "or options)")


def boundary_argument(p, default: str) -> None:
    p.add_argument("--boundary", default=default, metavar="loads|fixed|embedded[:R]",
                   help="loads: the cut contacts' forces act as dead loads (the isolated cluster, Sec. 5); fixed: the "
                        "next ring of particles is held fixed (no rigid modes); embedded:R: the next R rings (default "
                        f"2) free and elastic, the ring beyond held, the verdict on the cluster's own modes (default "
                        f"{default}; the scan's: docs/attribution.md)")


def add_scan(sub) -> None:
    p = sub.add_parser("extract", help="the cluster of one particle (centre + N contact rings) as a scene file")
    input_argument(p, "input")
    p.add_argument("--center", required=True, help="the centre particle's name")
    p.add_argument("--rings", type=int, default=1, help="contact hops from the centre (default 1)")
    boundary_argument(p, "loads")
    p.add_argument("--out", required=True, help="scene file to write (JSON)")
    periodic_arguments(p)
    p.set_defaults(run=cmd_extract)
    p = sub.add_parser("scan", help="local stability scan: every cluster of a packing, as a map")
    input_argument(p, "input")
    p.add_argument("--out", required=True, help="output directory (an interrupted scan there resumes)")
    overwrite_argument(p)
    p.add_argument("--rings", type=int, default=1, help="contact hops from each centre (default 1)")
    boundary_argument(p, DEFAULT_BOUNDARY)
    p.add_argument("--centers", default="all", help="all | every:K | NAME,NAME,...")
    p.add_argument("--metric", choices=list(METRIC_CHOICES), default="L",
                   help="projection metric of every cluster (default L; family: robustness, 2-3x the time)")
    p.add_argument("--max-sliding", type=int, default=8,
                   help="clusters with more sliding contacts examine a sample of their branches (branches: partial)")
    p.add_argument("--sample-branches", type=int, default=32, help="random branches examined beyond max-sliding")
    p.add_argument("--scheduler", default=None, help="address of a running Dask scheduler (tcp://HOST:8786)")
    p.add_argument("--workers", type=int, default=None,
                   help="local Dask workers (1: in this process; default: by the work's measured size, the idle "
                        "cores and the load, said in the output; docs/scan.md)")
    p.add_argument("--format", choices=["parquet", "csv"], default="parquet")
    p.add_argument("--no-attribution", action="store_true",
                   help="skip each unstable cluster's mechanism and its two control solves (docs/attribution.md)")
    p.add_argument("--device", choices=["cpu", "gpu", "auto"], default="cpu",
                   help="where the stacked cluster eigenproblems run (gpu: CuPy, the gpu extra)")
    p.add_argument("--progress", action="store_true", help="a progress bar with the time left (stderr)")
    p.add_argument("--json", action="store_true", help="print summary.json")
    uncertainty_arguments(p, balance=False)
    import_arguments(p, rename={"format": "--input-format", "progress": None})
    p.set_defaults(run=cmd_scan)


def frame_list(text: str, available: list | None, source: str) -> list:
    """--frames: 'A,B,C' or 'A:B[:STEP]' (the input's frames from A to B inclusive, every STEP-th), checked against
    the frames the input holds."""
    if not available:
        raise InputError(f"--frames: {source} holds one frame")
    try:
        if ":" in text:
            parts = [frame_number(v) for v in text.split(":")]
            if len(parts) not in (2, 3) or (len(parts) == 3 and (parts[2] < 1 or parts[2] != int(parts[2]))):
                raise ValueError
            chosen = [f for f in available if parts[0] <= f <= parts[1]][::int(parts[2]) if len(parts) == 3 else 1]
        else:
            chosen = [frame_number(v) for v in text.split(",")]
    except (ValueError, argparse.ArgumentTypeError):
        raise InputError(f"--frames: expected A,B,C or A:B[:STEP], got {text!r}") from None
    missing = [f for f in chosen if f not in available]
    if missing or not chosen:
        raise InputError(f"--frames: {source} has no frame {missing[0] if missing else text} (its frames: "
                         f"{', '.join(map(str, available[:8]))}{', …' if len(available) > 8 else ''})")
    return chosen


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
    source = open_input(args.input, **periodic_options(args))    # the frames indexed once, each read once
    if args.track or args.frames:
        if args.scan:
            raise InputError("--scan: a scan folder holds one packing; a sequence (--frames, --track) takes none")
        available = [f for f in source.frames if f is not None]
        if args.track:
            wanted = track_frames(args.track)
            keys = [k for _, k in wanted if k is not None]
            if keys:                                              # the track's frames are the input's
                frame_list(",".join(map(str, keys)), available, source)
        else:
            wanted = [(None, f) for f in frame_list(args.frames, available, source)]
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
            extra = track_fields(args.track, position, loaded.scene.names) if args.track else None
            beat.stage(f"frame {f}: fields and modes" if f is not None else "fields and modes")
            frames.append(export_frame(loaded.scene, scan=args.scan, modes=args.modes, time=f or 0, extra=extra,
                                       orientation=loaded.orientation, shape=loaded.shape,
                                       analysis=modes_options(args.modes, args.sample_branches, args.max_sliding)))
            notes.append((f, loaded.warnings))
    paths = write(frames, args.out, args.format, Path(args.input[0]).stem or "packing")
    names = [p.name for p in paths] if len(paths) <= 6 else [paths[0].name, "…", paths[-1].name]
    warned = write_import_warnings(args.out, loaded.report, notes)
    print("\n".join([f"wrote {len(frames)} frame(s) as {args.format} in {time.perf_counter() - start:.1f} s: "
                      f"{len(paths)} file(s) in {args.out} ({', '.join(names)})", *warned]))
    return 0


def add_export(sub) -> None:
    p = sub.add_parser("export", help="particles, contacts, cell, verdicts and modes for OVITO and ParaView")
    input_argument(p, "input")
    p.add_argument("--out", required=True, help="folder to write (created)")
    p.add_argument("--format", choices=["vtp", "xyz", "dump"], default="vtp",
                   help="vtp: VTK PolyData for ParaView (the export extra); xyz: extended XYZ for OVITO and ASE; "
                        "dump: a LAMMPS-style dump pair, atoms + local (docs/export.md)")
    p.add_argument("--scan", default=None, help="a granstab scan folder of this packing: its verdict fields")
    p.add_argument("--modes", type=count(0), default=0,
                   help="the K lowest consistent modes of the whole packing as vector fields (default 0)")
    p.add_argument("--max-sliding", type=count(0), default=16,
                   help="with --modes: enumerate the 2^Ms branches up to this many potentially sliding contacts")
    p.add_argument("--sample-branches", type=count(1), default=None,
                   help="with --modes, beyond --max-sliding: the all-loading, all-unloading and N random branches")
    p.add_argument("--frames", default=None, help="a sequence: A,B,C or A:B[:STEP] of the input's frames")
    p.add_argument("--track", default=None, help="a granstab track folder: its frames, with its particle fields")
    p.add_argument("--timeout", type=positive_number, default=None,
                   help="with --modes: stop after this many seconds (one line, exit 2); a whole-packing analysis "
                        "whose measured cost exceeds it (without --timeout: 10 s) is refused before it starts")
    periodic_arguments(p)
    p.set_defaults(run=cmd_export)


def frame_number(text: str):
    """--frame/--timestep: an integer where it is one (frame numbers, steps), else a float (times)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    return int(value) if value.is_integer() else value


def import_arguments(p, rename: dict | None = None) -> None:
    """The import options of a snapshot (convert's, and every command that reads one through them): format,
    frame or timestep, region, contact law, geometry, cone policy, units, columns, rattlers, progress. `rename`
    gives another flag to an option the command already uses otherwise (analyze's --k, scan's --format): its value
    is then kept as import_<name>; a command with its own --progress keeps it (rename {"progress": None})."""
    rename = rename or {}

    def flag(name: str) -> dict:
        return {"dest": f"import_{name}"} if name in rename else {"dest": name}

    p.add_argument(rename.get("format", "--format"), default="auto", **flag("format"),
                   help="auto (from the files) or a name of granstab.io.formats()")
    if "progress" not in rename:
        p.add_argument("--progress", action="store_true",
                       help="a progress bar on stderr while large files are read (default when stderr is a terminal)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--frame", type=frame_number, default=None, help="frame to read (default: the first)")
    which.add_argument("--timestep", type=frame_number, default=None, help="timestep to read (default: the first)")
    p.add_argument("--region", help="box:lo,hi,lo,hi[,lo,hi] | ids:ID,... | ids:@FILE (keep these particles)")
    p.add_argument(rename.get("k", "--k"), type=float, help="normal stiffness (overrides the file's law)", **flag("k"))
    p.add_argument("--alpha", type=float, help="tangential/normal stiffness ratio")
    p.add_argument("--mu", type=float, help="friction coefficient")
    p.add_argument("--geometry", choices=["centres", "touching"], default=None,
                   help="centres: contact at the middle of the overlap (default); touching: d split by the radii")
    p.add_argument("--outside-cone", dest="outside_cone", choices=["sliding", "project", "elastic", "error"],
                   default=None, help="forces outside the friction cone (default sliding: project, mark at yield)")
    p.add_argument("--yield-rtol", dest="yield_rtol", type=float, default=None,
                   help="relative distance to |f_t| = μ f_n that counts as at yield (default 1e-4)")
    p.add_argument("--length-scale", dest="length_scale", type=float, default=None,
                   help="scene length per file length unit (e.g. 0.027 for px → cm)")
    p.add_argument("--units", help="name of the scene's length unit (report)")
    p.add_argument("--density", type=float, default=None,
                   help="mass per volume (2D: per area) when the file gives no masses: disks/spheres for the inertia "
                        "metric")
    p.add_argument("--columns", help="what each column is, e.g. id1,id2,fx,fy,fz (formats with named columns)")
    p.add_argument("--keep-rattlers", action="store_true", help="keep particles without contacts")
    periodic_arguments(p, cell=True)


def import_options(args) -> dict:
    """The load() options `import_arguments` defined, only those given (a scene file takes none)."""
    def given(key):
        return getattr(args, f"import_{key}", getattr(args, key, None))

    options = {key: given(key) for key in ("k", "alpha", "mu", "geometry", "outside_cone", "yield_rtol",
                                           "length_scale", "units", "region", "columns", "density")
               if given(key) is not None}
    if args.keep_rattlers:
        options["keep_rattlers"] = True
    options.update(periodic_options(args))
    return options


def load_with_import_options(inputs, args):
    """`granstab.io.load` of `inputs` with the options `import_arguments` defined (only those given are passed,
    so that a scene file, which takes none, is read as written)."""
    fmt = getattr(args, "import_format", args.format)
    return load(inputs, format=fmt, frame=args.frame, timestep=args.timestep,
                progress=args.progress or sys.stderr.isatty(), **import_options(args))


def cmd_track(args) -> int:
    """A sequence of frames → DIR/frames.parquet, particles.parquet, events.json, summary.json (issue 27)."""
    from .track import track
    if args.frame is not None or args.timestep is not None:
        raise InputError(f"--{'frame' if args.frame is not None else 'timestep'}: track reads every frame of the "
                         "input; choose them with --frames A:B:STEP")
    options = {k: v for k, v in import_options(args).items() if k != "keep_rattlers"}   # track keeps them always
    summary = track(args.inputs, args.out, format=args.format, frames=args.frames, whole=args.whole,
                    scan=args.scan, rigidity=args.rigidity, predict=args.predict, figures=not args.no_figures,
                    window=args.window, d2min_radius=args.d2min_radius, event_quantity=args.event_quantity,
                    event_threshold=args.event_threshold, soft_modes=args.soft_modes, rings=args.rings,
                    boundary=args.boundary, workers=args.workers, progress=args.progress, seed=args.seed,
                    overwrite=args.overwrite, uncertainty=band_options(args), **options)
    resumed = summary["cost"]["resumed"]
    lines = [f"{summary['frames']} frames ({resumed} already in the folder) in {summary['cost']['seconds']:.1f} s; "
             f"{summary['events']} events ({summary['thresholds']['event_quantity']} drops over "
             f"{summary['thresholds']['event_threshold']:g} × its mean); wrote {args.out}",
             f"ran {summary['cost']['workers']['where']} ({summary['cost']['workers']['why']})",
             *[f"{name}: {what}" for name, what in summary.get("after", {}).items()],
             *[f"warning: import: {w}" for w in summary["import_warnings"]]]
    print(json.dumps(summary) if args.json else "\n".join(lines))
    return 0


def add_track(sub) -> None:
    p = sub.add_parser("track", help="a sequence of frames: per-frame stress, analyses, D²min, contact changes, "
                                     "events (docs/track.md)")
    p.add_argument("inputs", nargs="+", help="a snapshot with frames: its folder or its files")
    p.add_argument("--out", required=True, help="output directory (an interrupted track there resumes)")
    overwrite_argument(p)
    p.add_argument("--frames", default=None, metavar="A:B:STEP",
                   help="positions in the input's frame list, 0-based, B excluded (default: all)")
    p.add_argument("--whole", action="store_true",
                   help="per frame the whole-packing analysis (all-unloading and all-loading branches, soft spots)")
    p.add_argument("--scan", action="store_true", help="per frame the local scan map (granstab scan)")
    p.add_argument("--rigidity", action="store_true", help="per frame the largest rigid cluster")
    p.add_argument("--predict", action="store_true", help="then the prediction test (prediction.json)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.add_argument("--window", type=count(1), default=1, help="D²min and contact changes over W frames (default 1)")
    p.add_argument("--d2min-radius", type=positive_number, default=None,
                   help="D²min neighbourhood radius in input length units (default 2.5 mean contact branch lengths)")
    p.add_argument("--event-quantity", choices=["shear_stress", "stress_ratio"], default="shear_stress")
    p.add_argument("--event-threshold", type=positive_number, default=0.05,
                   help="an event: a drop over this fraction of the run's mean (default 0.05)")
    p.add_argument("--soft-modes", type=count(1), default=5, help="lowest consistent modes of the soft-spot measure")
    p.add_argument("--rings", type=count(1), default=1, help="--scan: contact hops from each centre (default 1)")
    boundary_argument(p, DEFAULT_BOUNDARY)
    p.add_argument("--workers", type=int, default=None,
                   help="local Dask workers over frames (1: in this process; default: by the measured cost)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random predictor")
    p.add_argument("--json", action="store_true", help="print summary.json")
    uncertainty_arguments(p, balance=False)
    import_arguments(p)
    p.set_defaults(run=cmd_track)


def add_convert(sub) -> None:
    p = sub.add_parser("convert", help="DEM snapshots / experimental frames → a contact-level scene (JSON)")
    p.add_argument("inputs", nargs="+", help="a folder or file(s) of one snapshot")
    p.add_argument("--out", required=True, help="scene file to write (JSON; NPZ when it ends in .npz)")
    import_arguments(p)
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    p.set_defaults(run=cmd_convert)


def add_rigidity(sub) -> None:
    from .rigidity import MODELS, WALL_OPTIONS
    p = sub.add_parser("rigidity", help="rigid clusters, floppy modes, self-stresses and Maxwell counts")
    p.add_argument("input", nargs="+", help="any scene or snapshot that analyze reads (a folder or files)")
    p.add_argument("--model", choices=list(MODELS), default="physical",
                   help="physical: rank and null space of the compatibility matrix (default); generic: the pebble "
                        "game; both: side by side with the contacts where they differ")
    p.add_argument("--walls", choices=list(WALL_OPTIONS), default="free",
                   help="free: wall forces are loads (default); bodies: each annulus wall one body (RigidLibrary)")
    p.add_argument("--figure", default=None, help="write the packing with contacts coloured by cluster (PNG/SVG)")
    p.add_argument("--out", default=None, help="write the result and its packing to this folder (rigidity.json, "
                                               "packing.npz): the explorer opens it (granstab-app --preset DIR)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    import_arguments(p)
    p.set_defaults(run=cmd_rigidity)


def build_parser() -> Parser:
    parser = Parser(prog="granstab", description="Stability of granular clusters (Kuhn & Chang).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    p = sub.add_parser("stiffness", help="write H, Hm, Hg1, Hg2, Hg3 and dof labels to an .npz file")
    input_argument(p, "scene")
    p.add_argument("--out", required=True)
    p.add_argument("--mask", help="one of +1,-1,0 per contact in file order (default: all elastic)")
    p.set_defaults(run=cmd_stiffness)
    p = sub.add_parser("analyze", help="branches, consistent eigenmodes and verdicts")
    input_argument(p, "scene")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument("--rotation-length", type=positive_number, default=None,
                   help="L in the scaled dofs [du, L dθ] (default: mean contact radius; 1 = the paper's metric)")
    p.add_argument("--metric", choices=list(METRIC_CHOICES), default=None,
                   help="projection metric: family (default: the verdict in L/10, L, 10L and inertia where masses are "
                        "known, spectra in L, metric robustness reported), or only one of L, L/10, 10L, inertia")
    p.add_argument("--max-sliding", type=count(0), default=None,
                   help="refuse more potentially sliding contacts (default 16)")
    p.add_argument("--sample-branches", type=count(1), default=None,
                   help="beyond --max-sliding: examine the all-loading, all-unloading and N random branches "
                        "(branches: partial; a verdict only where they suffice) instead of refusing")
    p.add_argument("--method", choices=["auto", "dense", "sparse"], default=None,
                   help="dense: every eigenpair and the uniqueness analysis; sparse: the lowest --k eigenpairs per "
                        "branch without n_dof x n_dof matrices; auto (default): sparse above "
                        "granstab.solve.sparse.DENSE_MAX_DOF dofs")
    p.add_argument("--k", type=count(1), default=None, help="eigenpairs per branch on the sparse path (default 6)")
    p.add_argument("--progress", action="store_true",
                   help="progress bars with the time left on stderr (reading, branches; default when stderr is a "
                        "terminal)")
    p.add_argument("--timeout", type=positive_number, default=None,
                   help="stop after this many seconds (one line, exit 2); work whose measured cost exceeds it is "
                        "refused before it starts")
    p.add_argument("--device", choices=["cpu", "gpu", "auto"], default="cpu",
                   help="where the stacked branch eigenproblems run: gpu needs CuPy (pip install 'granstab[gpu]'); "
                        "auto: the GPU when CuPy sees one")
    p.add_argument("--all", action="store_true", help="list every eigenvalue in the table (default: the lowest "
                   f"{TABLE_LOWEST} per branch and the counts)")
    p.add_argument("--plan", action="store_true", help="print the plan (method, path, branches per metric, what is "
                   "left out) and its estimate; run nothing (--json: its `cost`)")
    uncertainty_arguments(p)
    import_arguments(p, rename={"k": "--contact-k", "progress": None})
    p.set_defaults(run=cmd_analyze)
    p = sub.add_parser("moduli", help="elastic moduli, stress and stability at fixed stress of a periodic packing")
    input_argument(p, "scene")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument("--strain", default=None,
                   help="a strain direction, d·d numbers row by row (e.g. '0,1,1,0'): the branches consistent "
                        "with it and their tangent moduli")
    p.add_argument("--max-sliding", type=count(0), default=12,
                   help="enumerate the 2^Ms branches up to this many potentially sliding contacts (beyond: a sample)")
    import_arguments(p)
    p.set_defaults(run=cmd_moduli)
    p = sub.add_parser("reproduce", help="regenerate the paper's examples (Sec. 4)")
    p.add_argument("name", choices=["two-particle", "gear", "four-disk", "sliding-contact", "all"])
    p.add_argument("--out", required=True)
    p.add_argument("--root", type=Path, default=None,
                   help="with 'all': also write REPRODUCTION.md at this repository root (links into --out)")
    p.set_defaults(run=cmd_reproduce)
    p = sub.add_parser("bench", help="error against run time; writes BENCHMARKS.md and plots",
                       description="Every topic: writes BENCHMARKS.md whole (and docs/bench/). --only TOPIC: reruns "
                                   "that topic and rewrites its section alone, each section with its own date, "
                                   "machine and load.")
    p.add_argument("--quick", action="store_true", help="small sizes and few repeats (under a minute)")
    p.add_argument("--out", default=".")
    p.add_argument("--only", action="append", metavar="TOPIC",
                   help="rerun only this topic (repeatable; choose from granstab_bench.TOPICS): its section of the "
                        "existing BENCHMARKS.md is rewritten, the others are kept byte for byte")
    p.add_argument("--device", choices=["cpu", "gpu"], default="cpu",
                   help="gpu: the GPU topics (branches, scan: GPU beside CPU) into BENCHMARKS-gpu.md")
    p.set_defaults(run=cmd_bench)
    p = sub.add_parser("publish", help="a scene recorded as one HTML page that plays offline (needs the app extra)")
    p.add_argument("scene", help="a preset name (presets/) or a scene file; two_particle: a sweep of ρ/r across 1")
    p.add_argument("--out", required=True, help="the HTML file to write (at most 5 MB)")
    p.set_defaults(run=cmd_publish)
    add_convert(sub)
    add_scan(sub)
    add_rigidity(sub)
    add_track(sub)
    add_export(sub)
    return parser


DASH_VALUES = ("--columns", "--mask", "--centers", "--center")   # values that may begin with '-' (an ignored
                                                                 # column '-', a mask entry -1, a name)
EXIT_INTERRUPTED = 130    # 128 + SIGINT, as a shell reports a command stopped by Ctrl-C


def attach_dash_values(argv) -> list:
    """`--columns -,id1,id2` as `--columns=-,id1,id2`: argparse reads a word beginning with '-' as an option, so
    these options' values would be refused ("expected one argument") unless attached with '='. A word that looks
    like an option (`--json`, `-h`) is left alone."""
    words, out, i = list(argv), [], 0
    while i < len(words):
        value = words[i + 1] if i + 1 < len(words) else ""
        an_option = value.startswith("--") or (len(value) == 2 and value[1].isalpha())
        if words[i] in DASH_VALUES and value.startswith("-") and value != "-" and not an_option:
            out.append(f"{words[i]}={value}")
            i += 2
        else:
            out.append(words[i])
            i += 1
    return out


def interrupted_line(exc: KeyboardInterrupt, command: str | None) -> str:
    """Ctrl-C as one line: what was kept and how to go on (a scan says it: Interrupted), else that nothing was."""
    if isinstance(exc, Interrupted) and str(exc):
        return str(exc)
    return (f"granstab{' ' + command if command else ''}: interrupted (Ctrl-C) before it finished; nothing was "
            "kept: run it again to start over")


def main(argv=None) -> int:
    command = None
    try:
        args = build_parser().parse_args(attach_dash_values(sys.argv[1:] if argv is None else argv))
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
