"""The command line's grammar: every subcommand registered the same way (`add_<command>`, in COMMANDS), each option
registered once with one meaning (the import, analysis and uncertainty options), the old spellings still accepted
for one release with a one-line note (DEPRECATED; docs/cli.md's table of flags)."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from .cli_text import TABLE_LOWEST
from .io.source import frame_key
from .mechanics.metric import CHOICES as METRIC_CHOICES
from .scan.clusters import DEFAULT_BOUNDARY


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
    """--force-uncertainty, --position-uncertainty, --balance (issue 42, docs/uncertainty.md); balance=False (scan,
    track): --search-counterexamples too."""
    p.add_argument("--force-uncertainty", default=None, metavar="REL[,ABS]",
                   help="each contact force within REL·|f| + ABS of its value: the verdict holds / depends on the "
                        "data / undecided (docs/uncertainty.md); 'file' (analyze, scan, track) takes each contact's from the "
                        "input's f_err (or fn_err, ft_err) column")
    p.add_argument("--position-uncertainty", type=positive_number, default=None, metavar="LEN",
                   help="contact points and centres within LEN (a rigorous bound: docs/uncertainty.md)")
    if not balance:
        p.add_argument("--search-counterexamples", action="store_true",
                       help="clusters the batched bound does not decide: the per-cluster bound and the search for "
                            "forces within the band that change the verdict (depends; costs more: BENCHMARKS.md)")
    p.add_argument("--balance", choices=["loads", "least-squares"], default="loads",
                   help="loads (default): the loads absorb the measured imbalance; least-squares: forces moved to the "
                        "nearest balanced set, weighted by the force uncertainty")


def band_of(args, loaded=None):
    """The Band of --force-uncertainty / --position-uncertainty, or None; `--force-uncertainty file`: the input's
    per-contact columns (f_err, or fn_err and ft_err: `loaded.force_uncertainty`)."""
    from .mechanics.uncertainty import Band, band_from, parse_force_uncertainty
    if args.force_uncertainty is None and args.position_uncertainty is None:
        return None
    if args.force_uncertainty == "file":
        return band_from({"per_contact": True, "position": args.position_uncertainty or 0.0}, loaded.scene)
    try:
        rel, abs_ = parse_force_uncertainty(args.force_uncertainty or "0")
    except ValueError as exc:
        raise InputError(str(exc)) from None
    return Band(rel=rel, abs=abs_, position=args.position_uncertainty or 0.0)


def band_options(args, loaded=None) -> dict | None:
    """The scan's `uncertainty` option (Band fields, search) of --force-uncertainty / --position-uncertainty;
    `file`: "per_contact" names the columns (the scan takes each scene's own, Scene.force_err), so that
    summary.json says where the band came from (the inputs' hash covers their values)."""
    search = {"search": bool(getattr(args, "search_counterexamples", False))}
    if args.force_uncertainty == "file":
        source = (loaded.report.get("force_uncertainty") or {}).get("source") if loaded is not None else None
        return {"rel": 0.0, "abs": 0.0, "position": args.position_uncertainty or 0.0,
                "per_contact": f"the file's {source or 'f_err (or fn_err, ft_err) columns'}", **search}
    band = band_of(args)
    return None if band is None else {"rel": band.rel, "abs": band.abs, "position": band.position, **search}


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


def frame_number(text: str):
    """--frame/--timestep: an integer where it is one (frame numbers, steps), else a float (times)."""
    try:
        return frame_key(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def import_arguments(p, progress: bool = True) -> None:
    """The import options of a snapshot, on every command that reads a file (convert's, with the same flags
    everywhere): format, frame or timestep, region, contact law, geometry, cone policy, units, columns, rattlers,
    progress (a command with a --progress of its own keeps it: `progress=False`)."""
    p.add_argument("--format", default="auto", help="the input's format: auto (from the files) or a name of "
                                                      "granstab.io.formats()")
    if progress:
        p.add_argument("--progress", action="store_true",
                       help="a progress bar on stderr while large files are read (default when stderr is a terminal)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--frame", type=frame_number, default=None, help="frame to read (default: the first)")
    which.add_argument("--timestep", type=frame_number, default=None, help="timestep to read (default: the first)")
    p.add_argument("--region", help="box:lo,hi,lo,hi[,lo,hi] | ids:ID,... | ids:@FILE (keep these particles)")
    p.add_argument("--contact-k", dest="contact_k", type=float,
                   help="normal contact stiffness (overrides the file's law)")
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
    names = {"contact_k": "k", **{key: key for key in ("alpha", "mu", "geometry", "outside_cone", "yield_rtol",
                                                      "length_scale", "units", "region", "columns", "density")}}
    options = {key: getattr(args, dest) for dest, key in names.items() if getattr(args, dest) is not None}
    if args.keep_rattlers:
        options["keep_rattlers"] = True
    options.update(periodic_options(args))
    return options


FIT_DEFAULTS = {"metric": "family", "max_sliding": 16, "method": "auto", "k": 6}   # analyze's, where not given

ANALYSIS_OPTIONS = {   # the analysis options: one flag, one meaning, one help; each command its own default
    "metric": (("--metric",), {"choices": list(METRIC_CHOICES),
                               "help": "projection metric: one of L, L/10, 10L, inertia, or family (the verdict in "
                                       "each, spectra in L, metric robustness reported; 2-3x the time)"}),
    "rotation_length": (("--rotation-length",), {
        "type": positive_number,
        "help": "L in the scaled dofs [du, L dθ] (default: mean contact radius; 1 = the paper's metric)"}),
    "max_sliding": (("--max-sliding",), {
        "type": count(0), "help": "enumerate the 2^N branches up to N potentially sliding contacts; beyond, a "
                                  "sample (--sample-branches) or, without one, a refusal"}),
    "sample_branches": (("--sample-branches",), {
        "type": count(1), "help": "beyond --max-sliding: the all-loading, all-unloading and N random branches "
                                  "(branches: partial; a verdict only where they suffice)"}),
    "method": (("--method",), {"choices": ["auto", "dense", "sparse"],
                               "help": "dense: every eigenpair and the uniqueness analysis; sparse: the lowest --k "
                                       "eigenpairs per branch without n_dof x n_dof matrices; auto: sparse above "
                                       "granstab.solve.sparse.DENSE_MAX_DOF dofs"}),
    "k": (("--k",), {"type": count(1), "help": "eigenpairs per branch on the sparse path"}),
    "device": (("--device",), {"choices": ["cpu", "gpu", "auto"],
                               "help": "where the stacked eigenproblems run: gpu needs CuPy (pip install "
                                       "'granstab[gpu]'); auto: the GPU when CuPy sees one"}),
    "timeout": (("--timeout",), {"type": positive_number,
                                 "help": "stop after this many seconds (one line, exit 2); work whose measured cost "
                                         "exceeds it (without --timeout: 10 s) is refused before it starts"}),
}


def analysis_arguments(p, **defaults) -> None:
    """The analysis options named in `defaults` (ANALYSIS_OPTIONS), each with this command's default (None: analyze
    fits its plan to the time a run takes, FIT_DEFAULTS)."""
    for name, default in defaults.items():
        flags, kwargs = ANALYSIS_OPTIONS[name]
        shown = FIT_DEFAULTS.get(name) if default is None else default
        note = "" if shown is None else f" (default {shown})"
        p.add_argument(*flags, default=default, **{**kwargs, "help": kwargs["help"] + note})


def json_argument(p, what: str = "one JSON object on stdout") -> None:
    p.add_argument("--json", action="store_true", help=what)


def add_stiffness(sub) -> None:
    p = sub.add_parser("stiffness", help="write H, Hm, Hg1, Hg2, Hg3 and dof labels to an .npz file")
    input_argument(p, "scene")
    p.add_argument("--out", required=True)
    p.add_argument("--mask", help="one of +1,-1,0 per contact in file order (default: all elastic)")
    import_arguments(p)


def add_analyze(sub) -> None:
    p = sub.add_parser("analyze", help="branches, consistent eigenmodes and verdicts")
    input_argument(p, "scene")
    json_argument(p)
    analysis_arguments(p, rotation_length=None, metric=None, max_sliding=None, sample_branches=None, method=None,
                       k=None, timeout=None, device="cpu")
    p.add_argument("--progress", action="store_true",
                   help="progress bars with the time left on stderr (reading, branches; default when stderr is a "
                        "terminal)")
    p.add_argument("--all", action="store_true", help="list every eigenvalue in the table (default: the lowest "
                   f"{TABLE_LOWEST} per branch and the counts)")
    p.add_argument("--plan", action="store_true", help="print the plan (method, path, branches per metric, what is "
                   "left out) and its estimate; run nothing (--json: its `cost`)")
    uncertainty_arguments(p)
    import_arguments(p, progress=False)


def add_moduli(sub) -> None:
    p = sub.add_parser("moduli", help="elastic moduli, stress and stability at fixed stress of a periodic packing")
    input_argument(p, "scene")
    json_argument(p)
    p.add_argument("--strain", default=None,
                   help="a strain direction, d·d numbers row by row (e.g. '0,1,1,0'): the branches consistent "
                        "with it and their tangent moduli")
    analysis_arguments(p, max_sliding=12)
    import_arguments(p)


def add_reproduce(sub) -> None:
    p = sub.add_parser("reproduce", help="regenerate the paper's examples (Sec. 4)")
    p.add_argument("name", choices=["two-particle", "gear", "four-disk", "sliding-contact", "all"])
    p.add_argument("--out", required=True)
    p.add_argument("--root", type=Path, default=None,
                   help="with 'all': also write REPRODUCTION.md at this repository root (links into --out)")


def add_convert(sub) -> None:
    p = sub.add_parser("convert", help="DEM snapshots / experimental frames → a contact-level scene (JSON)")
    p.add_argument("inputs", nargs="+", help="a folder or file(s) of one snapshot")
    p.add_argument("--out", required=True, help="scene file to write (JSON; NPZ when it ends in .npz)")
    import_arguments(p)
    json_argument(p, "print the report as one JSON object")


def add_extract(sub) -> None:
    p = sub.add_parser("extract", help="the cluster of one particle (centre + N contact rings) as a scene file")
    input_argument(p, "input")
    p.add_argument("--center", required=True, help="the centre particle's name")
    p.add_argument("--rings", type=int, default=1, help="contact hops from the centre (default 1)")
    boundary_argument(p, "loads")
    p.add_argument("--out", required=True, help="scene file to write (JSON)")
    import_arguments(p)


def add_scan(sub) -> None:
    p = sub.add_parser("scan", help="local stability scan: every cluster of a packing, as a map")
    input_argument(p, "input")
    p.add_argument("--out", required=True, help="output directory (an interrupted scan there resumes)")
    overwrite_argument(p)
    p.add_argument("--rings", type=int, default=1, help="contact hops from each centre (default 1)")
    boundary_argument(p, DEFAULT_BOUNDARY)
    p.add_argument("--centers", default="all", help="all | every:K | NAME,NAME,...")
    analysis_arguments(p, metric="L", max_sliding=8, sample_branches=32, device="cpu")
    p.add_argument("--scheduler", default=None, help="address of a running Dask scheduler (tcp://HOST:8786)")
    p.add_argument("--workers", type=int, default=None,
                   help="local Dask workers (1: in this process; default: by the work's measured size, the idle "
                        "cores and the load, said in the output; docs/scan.md)")
    p.add_argument("--out-format", choices=["parquet", "csv"], default="parquet", help="the tables' format")
    p.add_argument("--no-attribution", action="store_true",
                   help="skip each unstable cluster's mechanism and its two control solves (docs/attribution.md)")
    p.add_argument("--progress", action="store_true", help="a progress bar with the time left (stderr)")
    json_argument(p, "print summary.json")
    uncertainty_arguments(p, balance=False)
    import_arguments(p, progress=False)


def add_rigidity(sub) -> None:
    from .rigidity import MODELS, WALL_OPTIONS
    p = sub.add_parser("rigidity", help="rigid clusters, floppy modes, self-stresses and Maxwell counts")
    p.add_argument("input", nargs="+", help="any scene or snapshot that analyze reads (a folder or files)")
    p.add_argument("--kind", choices=list(MODELS), default="physical",
                   help="which rigidity: physical: rank and null space of the compatibility matrix (default); generic: the pebble "
                        "game; both: side by side with the contacts where they differ")
    p.add_argument("--walls", choices=list(WALL_OPTIONS), default="free",
                   help="free: wall forces are loads (default); bodies: each annulus wall one body (RigidLibrary)")
    p.add_argument("--figure", default=None, help="write the packing with contacts coloured by cluster (PNG/SVG)")
    p.add_argument("--out", default=None, help="write the result and its packing to this folder (rigidity.json, "
                                               "packing.npz): the explorer opens it (granstab-app --preset DIR)")
    json_argument(p)
    import_arguments(p)


FRAMES_HELP = "the input's frames, as --frame names one: A,B,C or A:B[:STEP] (A to B inclusive, every STEP-th)"


def add_track(sub) -> None:
    p = sub.add_parser("track", help="a sequence of frames: per-frame stress, analyses, D²min, contact changes, "
                                     "events (docs/track.md)")
    p.add_argument("inputs", nargs="+", help="a snapshot with frames: its folder or its files")
    p.add_argument("--out", required=True, help="output directory (an interrupted track there resumes)")
    overwrite_argument(p)
    p.add_argument("--frames", default=None, metavar="A:B[:STEP]", help=FRAMES_HELP + " (default: all)")
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
    json_argument(p, "print summary.json")
    uncertainty_arguments(p, balance=False)
    import_arguments(p)


def add_export(sub) -> None:
    p = sub.add_parser("export", help="particles, contacts, cell, verdicts and modes for OVITO and ParaView")
    input_argument(p, "input")
    p.add_argument("--out", required=True, help="folder to write (created)")
    p.add_argument("--out-format", choices=["vtp", "xyz", "dump"], default="vtp",
                   help="vtp: VTK PolyData for ParaView (the export extra); xyz: extended XYZ for OVITO and ASE; "
                        "dump: a LAMMPS-style dump pair, atoms + local (docs/export.md)")
    p.add_argument("--scan-dir", default=None, help="a granstab scan folder of this packing: its verdict fields")
    p.add_argument("--modes", type=count(0), default=0,
                   help="the K lowest consistent modes of the whole packing as vector fields (default 0)")
    analysis_arguments(p, max_sliding=16, sample_branches=None, timeout=None)
    p.add_argument("--frames", default=None, metavar="A:B[:STEP]", help=FRAMES_HELP + " (a sequence)")
    p.add_argument("--track", default=None, help="a granstab track folder: its frames, with its particle fields")
    import_arguments(p)


COMMANDS = (add_stiffness, add_analyze, add_moduli, add_reproduce, add_convert, add_extract, add_scan, add_rigidity,
            add_track, add_export)
PLUGINS = "granstab.commands"   # entry points of packages outside the core (the explorer's publish, the benchmarks)


def build_parser(runs: dict) -> Parser:
    """Every subcommand registered the same way: the core's COMMANDS (each run by `runs[name]`), then those of
    installed packages that register an `add(sub)` in the entry-point group PLUGINS (granstab_app's publish,
    granstab_bench's bench; each sets its own run), found through importlib.metadata so that the core names none
    of them."""
    from importlib.metadata import entry_points
    parser = Parser(prog="granstab", description="Stability of granular clusters (Kuhn & Chang).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for add in COMMANDS:
        add(sub)
    for name, run in runs.items():
        sub.choices[name].set_defaults(run=run)
    for entry in sorted(entry_points(group=PLUGINS), key=lambda e: e.name):
        entry.load()(sub)
    return parser


DEPRECATED = {   # the old spellings, accepted until the next release: (commands, old flag, value test, new flag)
    "k": (("stiffness", "moduli", "convert", "extract", "scan", "rigidity", "track", "export"), "--k", None,
          "--contact-k"),
    "input_format": (("scan",), "--input-format", None, "--format"),
    "scan_format": (("scan",), "--format", ("parquet", "csv"), "--out-format"),
    "export_format": (("export",), "--format", ("vtp", "xyz", "dump"), "--out-format"),
    "export_scan": (("export",), "--scan", None, "--scan-dir"),
    "rigidity_model": (("rigidity",), "--model", None, "--kind"),
}


def modern_spellings(argv: list) -> tuple[list, list]:
    """argv with DEPRECATED's old spellings replaced (`--flag value` and `--flag=value`), and one note a
    replacement (`granstab scan: --input-format is now --format; ...`)."""
    words = list(argv)
    command = next((w for w in words if not w.startswith("-")), None)
    notes = []
    for commands, old, values, new in DEPRECATED.values():
        if command not in commands:
            continue
        for i, word in enumerate(words):
            flag, eq, value = word.partition("=")
            value = value if eq else (words[i + 1] if i + 1 < len(words) else "")
            if flag == old and (values is None or value in values):
                words[i] = new + eq + (value if eq else "")
                notes.append(f"granstab {command}: {old}{'' if values is None else ' ' + value} is now {new} (the "
                             "old spelling is accepted until the next release; docs/cli.md)")
    return words, notes


DASH_VALUES = ("--columns", "--mask", "--centers", "--center")   # values that may begin with '-' (an ignored
                                                                 # column '-', a mask entry -1, a name)


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
