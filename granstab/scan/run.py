"""`scan`: every local cluster of a packing analysed (the paper's third application, Sec. 5), in chunks, serially or
on Dask (a local cluster by default, a real one by address), rows streamed to disk as chunks finish.

A cluster with more potentially sliding contacts than `max_sliding` is not dropped: its all-loading, all-unloading
and `sample_branches` random other branches are examined (`branches: partial`), and its verdict is a proof only
where the unexamined branches cannot change it (analysis.py, verdicts.mark_partial).
"""
from __future__ import annotations

import time
import zlib
from dataclasses import dataclass, replace

import numpy as np

from ..analysis import analyze, focus, mode_works
from ..mechanics.attribution import mechanism
from ..mechanics.branches import RIGID
from ..mechanics.verdicts import verdict_columns
from ..model.errors import Interrupted
from ..model.scene import Scene, SceneError
from ..solve.device import backend
from ..solve.threads import blas_threads
from ..uncertainty import balance_scene
from .batch import EMBEDDED_INSIDE, batchable, rim_flags, solve_chunk
from .clusters import (
    DEFAULT_BOUNDARY,
    adjacency,
    boundary_rings,
    cluster,
    control_scene,
    cut,
    incidence,
    members,
    particle_index,
    piece,
    spatial_order,
    union,
)
from .output import ScanOutput
from .rows import Row, columns_table, concat_rows, rows_table
from .uncertain import robust_columns
from .workers import (
    close_quietly,
    dask_installed,
    default_workers,
    finished,
    machine,
    require_extras,
    sigint_flag,
    sigint_held,
)

ROBUST = ("robust_stable", "robust_unstable", "robust_open")   # the batch's margins (scan/uncertain.py)
CHUNK = 4096          # most clusters a task (and the serial loop's chunk): the stacks inside stay small
                      # (batch.STACK_BYTES)
TASK_SECONDS = (0.25, 1.0)  # a Dask task's measured compute, least and most: Dask's per-task cost (~10 ms of a
                      # worker and ~10 ms of the client and scheduler, measured) stays a few per cent of it, and so
                      # does the border of a chunk's scene (the rings around its near centres, spatial_order: 3.4
                      # particles a centre at 64 clusters, 1.7 at 512; 0.96 and 0.69 ms of CPU a cluster, embedded:1)
FIRST_TASK = 64       # clusters of the first Dask tasks (and of the first serial chunk), before a cluster's cost
                      # is measured
SERIAL_SECONDS = 1.0  # a serial chunk's compute by the measured cost of a cluster: a part file about every second,
                      # so that Ctrl-C loses about that much
GPU_CHUNK = 16384     # on a GPU one stacked solve wants many clusters
IN_FLIGHT = 3         # Dask tasks out per worker thread: one running, the next ones already sent
POLL_SECONDS = 0.02   # the Dask loop's wait for results when none is ready (it checks for Ctrl-C between waits)
# Local workers' environment: one BLAS thread each, and NOT Dask's default MALLOC_TRIM_THRESHOLD_, which also turns
# off glibc's dynamic mmap threshold, so that every numpy temporary over 128 kB is a fresh mmap with page faults
# (measured: 1.6× the CPU time of a chunk in a worker against the same chunk in this process; 1.17× without it).
WORKER_ENVIRON = {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1}


def cluster_row(scene: Scene, center: int, keep: np.ndarray, options: dict, graph=None, index=None) -> Row:
    """The row of the cluster of `center` (its members `keep`) from `analyze` on its sub-scene (clusters.cluster;
    errors become a row, never a lost cluster). graph: adjacency(scene), if at hand; index: the packing's index of
    each particle of `scene` (a chunk's; None: `scene` is the packing)."""
    start = time.perf_counter()
    index = np.arange(scene.n_particles) if index is None else index
    center_id, ids = int(index[center]), index[np.asarray(keep, dtype=np.int64)].tolist()
    try:
        sub = cluster(scene, center, options["rings"], options.get("boundary", "loads"), graph=graph)
        res = analyze(sub, metric=options["metric"], max_sliding=options["max_sliding"],
                      sample_branches=options["sample_branches"], seed=zlib.crc32(scene.names[center].encode()),
                      attribution=False, estimate=False)
    except SceneError as exc:
        return Row.failed(center_id, ids, str(exc), time.perf_counter() - start)
    inner = _sub_index(sub, scene, keep)
    if boundary_rings(options.get("boundary", "loads"))[0] == "embedded":
        res = focus(res, inner, EMBEDDED_INSIDE)
    lam = [b.stability_eigenvalues[b.codes != RIGID] for b in res.branches]
    lam_min = float(min((v.min() for v in lam if v.size), default=np.nan))
    attribution = None
    if res.verdict.verdict == "unstable":       # the lowest consistent negative mode (mechanics/attribution.py)
        rim = inner[rim_flags(scene, [center], [np.asarray(keep)], graph if graph is not None else adjacency(scene))[0]]
        modes = mode_works(res, rim, inside=inner)
        scale = lam_min / modes[0].eigenvalue if modes else np.nan        # |v|² = lambda_min / λ: they sum to it
        attribution = {"work_parts": [w * scale for w in modes[0].work_parts], "rim_share": modes[0].rim_share} \
            if modes else None
    return Row.analyzed(center_id, ids, res.verdict, n_contacts=sub.n_contacts,
                        n_sliding=int(np.sum(sub.at_yield())), lambda_min=lam_min,
                        eigen_residual=res.errors["eigen_residual_stability"],
                        rigid_leakage=res.errors["rigid_leakage_modified"], seconds=time.perf_counter() - start,
                        attribution=attribution)


def _sub_index(sub: Scene, scene: Scene, keep) -> np.ndarray:
    """Where the particles `keep` of `scene` are in the cluster scene `sub` (its particles are sorted by index)."""
    return np.array([sub.names.index(scene.names[i]) for i in keep], dtype=np.int64)


def _with_mechanisms(scene, centers, member_lists, options, batched, done, rows, rest):
    """The controls of every unstable cluster of a chunk, batched together (`controls`), and their mechanism labels
    (attribution.mechanism) put into the batched columns and the `analyze` rows."""
    verdict = np.full(len(centers), "", dtype=object)
    if batched is not None:
        verdict[done] = batched["verdict"]
    for i, row in zip(rest, rows):
        verdict[i] = row.verdict
    unstable = np.flatnonzero(verdict == "unstable")
    if not unstable.size:
        return batched, rows
    got = controls(scene, centers[unstable], [member_lists[i] for i in unstable], options)
    elastic, fixed = (np.full(len(centers), "", dtype=object) for _ in range(2))
    elastic[unstable], fixed[unstable] = got["elastic"], got["rim"]
    if batched is not None:
        label = mechanism(batched["work_parts"], batched["rim_share"], elastic[done], fixed[done],
                          batched["verdict"] == "unstable")
        batched.update(mechanism=label, elastic_control=elastic[done], fixed_control=fixed[done])
    rows = [replace(row, mechanism=str(mechanism([row.work_parts], [row.rim_share], [elastic[i]], [fixed[i]],
                                                 [True])[0]),
                    elastic_control=elastic[i], fixed_control=fixed[i]) if row.work_parts is not None else row
            for i, row in zip(rest, rows)]
    return batched, rows


def controls(scene: Scene, centers: np.ndarray, member_lists: list, options: dict) -> dict:
    """The verdict strings of the two controls of each cluster (attribution.py): "elastic" (every contact elastic,
    the scan's boundary) and "rim" (the cluster alone with its rim held), solved as the branches are (batch.py, one
    stack per size); what the batch hands back, by `analyze` of the control scene (clusters.control_scene)."""
    out = {}
    for kind in ("elastic", "rim"):
        verdict = np.full(len(centers), "", dtype=object)
        opts = {**options, "control": kind, "attribute": False, "uncertainty": None}
        got = solve_chunk(scene, centers, member_lists, opts) if batchable(options) else None
        done = np.zeros(0, dtype=np.int64)
        if got is not None:
            finite = np.isfinite(got["eigen_residual"]) & np.isfinite(got["rigid_leakage"])
            done = got["position"]
            verdict[done] = verdict_columns(got["counts"], got["n_branches"], finite, got["n_undetermined"])["verdict"]
        for i in np.setdiff1d(np.arange(len(centers)), done):
            verdict[i] = _control_by_analyze(scene, centers[i], member_lists[i], opts)
        out[kind] = verdict
    return out


def _control_by_analyze(scene: Scene, center: int, keep, options: dict) -> str:
    """One control's verdict by `analyze` (the clusters the batch hands back); 'error' if it fails."""
    try:
        sub = control_scene(scene, center, options["rings"], options.get("boundary", "loads"), options["control"])
        if sub.fixed is not None and sub.fixed.all():
            return "stable"                                           # nothing free to move
        res = analyze(sub, metric=options["metric"], max_sliding=options["max_sliding"],
                      sample_branches=options["sample_branches"], seed=zlib.crc32(scene.names[center].encode()),
                      attribution=False, estimate=False)
    except SceneError:
        return "error"
    if options["control"] == "elastic" and boundary_rings(options.get("boundary", "loads"))[0] == "embedded":
        res = focus(res, _sub_index(sub, scene, keep), EMBEDDED_INSIDE)
    return res.verdict.verdict


def batched_columns(scene: Scene, centers: np.ndarray, member_lists: list, options: dict,
                    index: np.ndarray) -> dict | None:
    """The rows that the batched path serves (batch.py) as columns, one per field of `Row` (rows.columns_table),
    and `position`, their index in `centers` (None: no cluster batched); vectorised over clusters
    (verdicts.verdict_columns); seconds: the chunk's time shared equally. index: the packing's index of each
    particle of `scene`."""
    start = time.perf_counter()
    got = solve_chunk(scene, centers, member_lists, {**options, "attribute": options.get("attribution", True)})
    if got is None or not len(got["position"]):
        return None
    position = got["position"]
    errors_finite = np.isfinite(got["eigen_residual"]) & np.isfinite(got["rigid_leakage"])
    verdicts = verdict_columns(got["counts"], got["n_branches"], errors_finite, got["n_undetermined"])
    kept = [member_lists[i] for i in position]
    sizes = np.array([len(m) for m in kept])
    n = len(position)
    return {"position": position, "center": index[centers[position]],
            "members": (index[np.concatenate(kept)], np.r_[0, np.cumsum(sizes)]), "n_particles": sizes,
            "path": np.where(got["values_only"], "batched-values", "batched").astype(object),
            "n_contacts": got["n_contacts"], "n_sliding": got["n_sliding"], "branches": np.full(n, "all", object),
            "n_branches": got["n_branches"], "lambda_min": got["lambda_min"], "metric_robust": np.full(n, None, object),
            "eigen_residual": got["eigen_residual"], "rigid_leakage": got["rigid_leakage"], **verdicts,
            "seconds": np.full(n, (time.perf_counter() - start) / n),
            "work_parts": got.get("work_parts", np.full((n, 5), np.nan)), "rim_share": got.get("rim_share", np.full(n, np.nan)),
            "mechanism": np.full(n, "", object),
            "elastic_control": np.full(n, "", object), "fixed_control": np.full(n, "", object),
            "data_robust": np.full(n, "", object), "robust_margin": np.full(n, np.nan),
            "counterexample": np.full(n, None, object),
            **{key: got[key] for key in ROBUST if key in got}}


@dataclass(frozen=True)
class Chunk:
    """A chunk of centres as it travels to a worker: the fields of the sub-scene of every particle of their clusters
    (clusters.cut: slices of the packing's arrays) and the centres' indices in it. The worker makes the scene
    (clusters.piece) without checking again what was checked where the packing was read; `particles` is the
    packing's index of each of its particles (rows name particles by these). A dataclass, so that Dask ships it
    whole instead of walking its tuples for futures (measured: 4.5 s of the client's time in a 10⁵-particle
    scan)."""
    fields: dict
    centers: np.ndarray
    particles: np.ndarray

    def scene(self) -> Scene:
        return piece(self.fields)


def chunk_cut(scene: Scene, centers: np.ndarray, rings: int, graph=None, contacts_of=None) -> Chunk:
    """All that the chunk of `centers` needs: the cluster of c in its sub-scene is the cluster of c in the packing
    (every path of ≤ rings hops from c stays inside it), so a task carries its own small scene, never the packing,
    and the client only slices arrays. graph, contacts_of: clusters.adjacency(scene) and clusters.incidence(scene),
    if at hand (a scan makes them once: then cutting a chunk costs the chunk's size, not the packing's)."""
    every = union(scene, centers, rings, graph)
    return Chunk(cut(scene, every, contacts_of=contacts_of), np.searchsorted(every, centers), every)


def chunk_scene(scene: Scene, centers: np.ndarray, rings: int, graph=None) -> tuple[Scene, np.ndarray]:
    """The chunk's scene, built, and its centres' indices in it."""
    chunk = chunk_cut(scene, centers, rings, graph)
    return chunk.scene(), chunk.centers


def reach(options: dict) -> int:
    """Contact hops a chunk's scene must hold around its centres: the rings, the embedded rings, and the ring beyond
    them (held, or, for the loads boundary, what tells the rim, batch.rim_flags)."""
    return options["rings"] + boundary_rings(options.get("boundary", "loads"))[1] + 1


def scan_chunk(scene: Scene, centers: np.ndarray, options: dict, particles: np.ndarray | None = None):
    """Rows of a chunk of centres (indices into `scene`, best a chunk's scene) as an Arrow table, in the order of
    `centers`: the unit of work of a Dask task. The batched path (batch.py) takes what it can; `analyze` per
    cluster the rest (a partial cluster's branch sample is seeded by its centre's name, so it does not depend on
    the chunking). particles: the packing's index of each particle of `scene` (None: `scene` is the packing), by
    which the rows name centres and members."""
    index = np.arange(scene.n_particles) if particles is None else np.asarray(particles, dtype=np.int64)
    graph = adjacency(scene)
    member_lists = members(scene, centers, options["rings"], graph)
    with blas_threads(1):
        batched = batched_columns(scene, centers, member_lists, options, index) if batchable(options) else None
        done = np.zeros(0, dtype=np.int64) if batched is None else batched.pop("position")
        margins = {} if batched is None else {key: batched.pop(key) for key in ROBUST if key in batched}
        rest = np.setdiff1d(np.arange(len(centers)), done)
        rows = [cluster_row(scene, centers[i], member_lists[i], options, graph, index) for i in rest]
        if options.get("attribution", True):
            batched, rows = _with_mechanisms(scene, centers, member_lists, options, batched, done, rows, rest)
    tables = ([] if batched is None else [columns_table(batched)]) + ([rows_table(rows)] if rows else [])
    table = concat_rows(tables).take(np.argsort(np.r_[done, rest]))
    if options.get("uncertainty"):                                   # issue 42: scan/uncertain.py
        import pyarrow as pa
        rows = {"verdict": np.array(table.column("verdict").to_pylist(), dtype=object),
                "sufficient": np.array(table.column("sufficient").to_pylist(), dtype=bool),
                "robust_stable": np.full(len(centers), np.nan), "robust_unstable": np.full(len(centers), np.nan),
                "robust_open": np.zeros(len(centers), dtype=bool)}
        for key, values in margins.items():
            rows[key][done] = values
        got = robust_columns(scene, centers, member_lists, rows, options, graph, _sub_index, EMBEDDED_INSIDE)
        for name, values in got.items():
            column = pa.array(list(values), type=table.schema.field(name).type, from_pandas=True)
            table = table.set_column(table.schema.get_field_index(name), name, column)
    return table


def chunk_table(chunk: Chunk, options: dict):
    """The rows of a `Chunk` (scan_chunk): the unit of work of the serial loop and of a Dask task, so that the
    worker, not the client, builds the chunk's scene and the table."""
    return scan_chunk(chunk.scene(), chunk.centers, options, chunk.particles)


def select_centers(scene: Scene, centers) -> np.ndarray:
    """`all`, `every:K` (every K-th particle) or names (a list or comma-separated) → particle indices."""
    if isinstance(centers, str) and centers == "all":
        return np.arange(scene.n_particles)
    if isinstance(centers, str) and centers.startswith("every:"):
        step = centers.split(":", 1)[1]
        if not step.isdigit() or int(step) < 1:
            raise SceneError(f"--centers: every:K needs a positive integer K, got {step!r}")
        return np.arange(0, scene.n_particles, int(step))
    names = centers.split(",") if isinstance(centers, str) else list(centers)
    return np.array([particle_index(scene, name.strip()) for name in names], dtype=np.int64)


def scan(scene: Scene, out_dir, *, rings: int = 1, centers="all", metric: str = "L", max_sliding: int = 8,
         boundary: str = DEFAULT_BOUNDARY, sample_branches: int = 32, scheduler: str | None = None, workers: int | None = None,
         chunk: int | None = None, progress: bool = False, fmt: str = "parquet", figures: bool = True,
         device: str = "cpu", attribution: bool = True, inputs=None, overwrite: bool = False,
         uncertainty: dict | None = None, balance: str = "loads", exempt=None, shapes=None) -> dict:
    """Analyse the cluster of every centre of `scene` and write the tables and the map into `out_dir`: the packing
    (packing.npz, so that the folder is self-contained), clusters.* (centres and members as particle indices into
    it), particles.*, summary.json and the map.

    Parameters
    ----------
    scene : Scene
        The packing (N particles).
    out_dir : str or Path
        Output folder; centres already in it (an interrupted scan with the same options) are skipped. Ctrl-C
        raises `Interrupted` (a KeyboardInterrupt) saying how many clusters are kept there.
    rings, boundary : int, {"loads", "fixed", "embedded[:R]"}
        The cluster of a centre: `rings` contact hops; cut contacts as dead loads, the next ring held fixed, or the
        next R rings free and elastic with the ring beyond held and the verdict on the cluster's own modes
        (`extract`, clusters.embedded; default DEFAULT_BOUNDARY, docs/attribution.md).
    centers : "all", "every:K", or names
        Which particles are centres.
    metric, max_sliding, sample_branches : str, int, int
        As in `granstab.analyze`, for every cluster (default metric "L").
    scheduler, workers, chunk, device : str, int, int, {"cpu", "gpu", "auto"}
        A Dask scheduler address (tcp://HOST:PORT) or local workers (1 = serial, in this process; default: by
        the work's measured size, the idle cores and the load, workers.py, said in the summary's "workers");
        clusters per task (default: sized by the measured cost of a cluster, `Guide`); where
        the stacked eigenproblems run (granstab.solve.device).
    progress, fmt, figures : bool, {"parquet", "csv"}, bool
        A bar with the time left; the table format; whether to draw map.png/.svg and lambda_min.png/.svg.
    attribution : bool
        Every unstable cluster's attribution (mechanism, work_parts, rim_share and the two controls, batched:
        mechanics/attribution.py); False leaves those columns empty (the overhead: BENCHMARKS.md).
    inputs, overwrite : paths or None, bool
        The files the scene was read from: their sizes, times and content hashes are recorded (inputs.json), and a
        resume with changed ones is refused (scan/resume.py); overwrite: start afresh in a folder that holds a scan.
    uncertainty : dict, optional
        The data's band (Band's rel, abs, position; "per_contact": the file's columns named, Scene.force_err the radii;
        "search": the per-cluster bound and counter-example search where the batched bound does not decide): the
        columns data_robust, robust_margin and counterexample (scan/uncertain.py, docs/uncertainty.md).
    balance, exempt, shapes : {"loads", "least-squares"}, (N,) bool or None, model.grains.Grains or None
        "least-squares": forces moved to the nearest balanced set first (weighted by the band; `exempt`: loads
        kept free, e.g. walls), as `analyze --balance`; the summary's "balance" says how far (docs/uncertainty.md).
        `shapes`: the grains' true shapes, kept in packing.npz (`grains/…`) for the explorer (spheres: None).

    Returns
    -------
    dict
        summary.json: counts per verdict, time, clusters per second, the options, how many clusters a resumed
        scan found done ("resumed") and where it ran ("workers": count, where, why); the folder's other files above.
    """
    require_extras(scheduler, workers, figures)                     # before the folder: one line, nothing made
    options = _options(rings, metric, max_sliding, sample_branches, boundary, attribution, uncertainty)
    scene, balanced = balance_scene(scene, uncertainty, balance, exempt)
    options.update({"balance": balance} if balanced is not None else {})
    device = backend(device).name                                   # a missing GPU fails here, in one line
    out = ScanOutput(out_dir, fmt, options, scene, inputs=inputs, overwrite=overwrite, shapes=shapes)
    chunk = chunk or (GPU_CHUNK if device == "gpu" else None)
    chosen = select_centers(scene, centers)
    todo = spatial_order(scene.x, chosen[~np.isin(chosen, out.done_centers())])   # chunks of near centres
    bar = _progress(len(todo)) if progress else None
    start = time.perf_counter()
    try:
        try:
            ran = _run(scene, todo, chunk, {**options, "device": device}, out, bar, scheduler, workers)
        finally:
            if bar is not None:
                bar.close()
        summary = out.finish(scene, chosen, seconds=time.perf_counter() - start, n_new=len(todo),
                             extra={"resumed": int(len(chosen) - len(todo)), "workers": ran,
                                    **({"balance": balanced} if balanced is not None else {})})
        if figures:
            from .figure import write_figures
            write_figures(scene, out.path)
    except KeyboardInterrupt:                  # the parts on disk stay: say how many, and how to go on
        kept = int(np.isin(chosen, out.done_centers()).sum())
        raise Interrupted(f"granstab scan: interrupted (Ctrl-C): {kept} of {len(chosen)} clusters kept in "
                          f"{out_dir}; the same command (the same --out and options) resumes from there") from None
    return summary


def _options(rings, metric, max_sliding, sample_branches, boundary, attribution, uncertainty) -> dict:
    """The scan's options as its folder records them; a bad ring count or boundary: one line."""
    if rings < 1:
        raise SceneError(f"rings must be >= 1, got {rings}")
    boundary_rings(boundary)                                        # a bad value: one line
    options = {"rings": rings, "metric": metric, "max_sliding": max_sliding, "sample_branches": sample_branches,
               "boundary": boundary, "attribution": bool(attribution)}
    if uncertainty:
        options["uncertainty"] = dict(uncertainty)
    return options


def _run(scene, todo, chunk, options, out, bar, scheduler, workers) -> dict:
    """Analyse the centres `todo` where `scheduler`/`workers` say, or by the default rule (workers.py): the first
    FIRST_TASK clusters in this process measure the cost of the rest. Returns how it ran (summary "workers")."""
    def ran(count, where, why):
        return {"count": count, "where": where, "why": why}

    if not len(todo):
        return ran(0, "nowhere", "every cluster was already in the folder")
    if scheduler is not None:
        _run_dask(scene, todo, chunk, options, out, bar, scheduler=scheduler, workers=None)
        return ran(None, f"on the Dask cluster at {scheduler}", "--scheduler")
    if workers is not None:
        if workers <= 1:
            _run_serial(scene, todo, chunk, options, out, bar)
            return ran(1, "in this process", f"--workers {workers}")
        _run_dask(scene, todo, chunk, options, out, bar, scheduler=None, workers=workers)
        return ran(workers, f"on {workers} local Dask workers", f"--workers {workers}")
    graphs = adjacency(scene), incidence(scene)
    if options["device"] == "gpu":
        _run_serial(scene, todo, chunk, options, out, bar, graphs=graphs)
        return ran(1, "in this process", "default on a GPU: the GPU solves the stacks, workers would share it")
    cost = _run_serial(scene, todo[:FIRST_TASK], chunk, options, out, bar, graphs=graphs)
    rest = todo[FIRST_TASK:]
    cores, load = machine()
    n, why = default_workers(cost * len(rest), cores, load)
    if n > 1 and not dask_installed():
        n, why = default_workers(cost * len(rest), cores, load, dask=False)
    if n > 1:
        _run_dask(scene, rest, chunk, options, out, bar, scheduler=None, workers=n)
        return ran(n, f"on {n} local Dask workers", f"default: {why}")
    _run_serial(scene, rest, chunk, options, out, bar, cost=cost, graphs=graphs)
    return ran(1, "in this process", f"default: {why}")


def _run_serial(scene, todo, chunk, options, out, bar, cost=None, graphs=None) -> float | None:
    """The centres `todo` in this process, a part file a chunk: `chunk` clusters, or FIRST_TASK and then
    SERIAL_SECONDS of compute by the measured cost (at most CHUNK). Returns the measured seconds a cluster."""
    graph, contacts_of = graphs or (adjacency(scene), incidence(scene))
    at, done, spent = 0, 0, 0.0
    while at < len(todo):
        size = chunk or (FIRST_TASK if cost is None else min(max(int(SERIAL_SECONDS / cost), 1), CHUNK))
        part = todo[at:at + size]
        begun = time.perf_counter()
        out.write(chunk_table(chunk_cut(scene, part, reach(options), graph, contacts_of), options))
        spent, done, at = spent + time.perf_counter() - begun, done + len(part), at + len(part)
        cost = spent / done
        if bar is not None:
            bar.update(len(part))
    return cost



def local_cluster(workers: int):
    """`workers` local processes, one thread and one BLAS thread each (WORKER_ENVIRON), Ctrl-C never reaching
    them (sigint_held). No dashboard; the scheduler's own HTTP server takes a free port when 8787 is taken (another
    cluster on the machine) without distributed's warning on stderr, since nothing of it is the user's to act on."""
    import warnings

    import dask
    from dask.distributed import LocalCluster
    with dask.config.set({"distributed.nanny.pre-spawn-environ": WORKER_ENVIRON}), sigint_held(), \
            warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)

def _run_dask(scene, todo, chunk, options, out, bar, *, scheduler, workers):
    """Tasks of centres cut by a `Guide`, each with its own `Chunk` (rerun if a worker dies), results streamed to
    disk in the order they finish. At most IN_FLIGHT tasks per worker thread are out at a time: the client cuts the
    next chunk while the workers compute, and holds a few chunks, never all of them. Ctrl-C (workers.py): the
    workers ignore it, this loop stops at the next poll and closes the cluster quietly."""
    from dask.distributed import Client, as_completed
    cluster = client = None
    try:
        with sigint_flag() as stop:        # from the start: a Ctrl-C while the cluster starts stops the scan too
            cluster = None if scheduler is not None else local_cluster(workers)
            graph, contacts_of = adjacency(scene), incidence(scene)
            guide = Guide(todo, chunk)
            client = Client(scheduler or cluster)
            running = as_completed()

            def fill():                                 # the cluster's threads now (a real cluster may grow)
                threads = max(sum(client.nthreads().values()), 1)
                while running.count() < IN_FLIGHT * threads and (part := guide.next(threads)) is not None:
                    running.add(client.submit(chunk_table, chunk_cut(scene, part, reach(options), graph,
                                                                     contacts_of), options, retries=3, pure=False))

            fill()
            for future in finished(running, stop, POLL_SECONDS):
                table = future.result()
                out.write(table)
                guide.measured(table)
                if bar is not None:
                    bar.update(table.num_rows)
                fill()
    except KeyboardInterrupt:                   # Ctrl-C: what is on disk stays; no tracebacks from Dask's closing
        close_quietly(client, cluster)
        raise
    client.close()
    if cluster is not None:
        cluster.close()


class Guide:
    """Guided self-scheduling of a scan's centres into Dask tasks: a task takes 1/(2·threads) of the centres left,
    so that the scan ends in small tasks and no worker waits long for the last one; at least TASK_SECONDS[0] and at
    most TASK_SECONDS[1] of compute by the measured cost of a cluster (the rows' seconds so far; FIRST_TASK clusters
    before any is measured) and at most CHUNK clusters. `fixed`: at most that many clusters, at least a quarter of
    it (an explicit chunk; a GPU's stacks want many clusters)."""

    def __init__(self, todo: np.ndarray, fixed: int | None = None):
        self.todo, self.fixed, self.at = todo, fixed, 0
        self.rows, self.seconds = 0, 0.0

    def measured(self, table) -> None:
        """A finished task's rows (an Arrow table with a `seconds` column)."""
        import pyarrow.compute as pc
        self.rows += table.num_rows
        self.seconds += pc.sum(table.column("seconds")).as_py() or 0.0

    def next(self, threads: int) -> np.ndarray | None:
        """The next task's centres (None when every centre has a task)."""
        left = len(self.todo) - self.at
        if left <= 0:
            return None
        if self.fixed:
            least, most = max(self.fixed // 4, 1), self.fixed
        elif self.rows and self.seconds > 0:
            cost = self.seconds / self.rows
            least, most = (min(max(int(t / cost), 1), CHUNK) for t in TASK_SECONDS)
        else:
            least = most = FIRST_TASK
        size = min(max(-(-left // (2 * threads)), least), most)
        part = self.todo[self.at:self.at + size]
        self.at += len(part)
        return part


def _progress(total: int, unit: str = "cluster"):
    """A tqdm bar of `unit`s with the time left (tqdm is optional: None without it); track's counts frames."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc=f"{unit}s", unit=unit, mininterval=0.5)
