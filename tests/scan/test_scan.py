"""The local stability scan (issue 10): clusters, equality with analyze, partial branches, resume, Dask, the map."""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import threading
import time
from types import SimpleNamespace

import numpy as np
import pyarrow as pa
import pytest
from helpers import ROOT  # noqa: E402

import granstab
from granstab.mechanics.accuracy import gamma, value_bounds, vector_bounds
from granstab.mechanics.branches import RIGID
from granstab.model import packings
from granstab.scan import extract, members, read_map, scan
from granstab.scan.clusters import CONTACT_FIELDS, boundary_ring, subscene
from granstab.scan.rows import ROW_COLUMNS, Row, columns_table, rows_table, schema
from granstab.scan.run import (
    CHUNK,
    FIRST_TASK,
    TASK_SECONDS,
    Guide,
    chunk_cut,
    chunk_table,
    cluster_row,
    reach,
    scan_chunk,
)
from granstab.solve.device import gpu_available, residual_norms

ANNULUS = ROOT / "presets" / "annulus_frame.json"


def lowest(result) -> float:
    return min(b.stability_eigenvalues[b.codes != RIGID].min() for b in result.branches)


def test_clusters_are_the_contact_hops_of_a_breadth_first_search():
    """members() by sparse products = a plain breadth-first search over the contact list, for 1 to 3 rings."""
    scene = granstab.load_scene(ANNULUS)
    neighbours = {i: set() for i in range(scene.n_particles)}
    for a, b in zip(scene.p, scene.q):
        neighbours[a].add(b)
        neighbours[b].add(a)
    centers = np.arange(0, scene.n_particles, 7)
    for rings in (1, 2, 3):
        for c, got in zip(centers, members(scene, centers, rings)):
            seen = {c}
            for _ in range(rings):
                seen |= {n for s in seen for n in neighbours[s]}
            assert got.tolist() == sorted(seen)


def test_extracted_cluster_has_every_inner_contact_and_equilibrium_loads():
    scene = granstab.load_scene(ANNULUS)
    center = scene.names[40]
    sub = extract(scene, center, rings=2)
    inside = set(sub.names)
    expected = sum(scene.names[a] in inside and scene.names[b] in inside for a, b in zip(scene.p, scene.q))
    assert sub.n_contacts == expected and center in inside
    # loads are the scene format's equilibrium defaults: Σ b + Σ f = 0 per particle, relative to Σ|f|
    b = np.zeros_like(sub.x)
    np.add.at(b, sub.p, sub.force)
    np.add.at(b, sub.q, -sub.force)
    scale = np.abs(sub.force).sum()
    assert np.abs(sub.load + b).max() <= 1e-12 * scale


def test_scan_rows_equal_analyze_of_the_extracted_scene(tmp_path):
    """Sampled rows of a scan = analyze() on `extract`: same verdict and counts, λ_min within 1e-10·max|λ|."""
    scene = granstab.load_scene(ANNULUS)
    names = [scene.names[i] for i in (3, 50, 99, 140)]
    scan(scene, tmp_path, centers=",".join(names), boundary="loads", workers=1, figures=False)
    rows = read_map(tmp_path)["clusters"]
    assert list(rows["center"]) == [3, 50, 99, 140]                   # indices into the packing
    assert [list(m) for m in rows["members"]] == [list(m) for m in members(scene, [3, 50, 99, 140], 1)]
    for i, name in enumerate(names):
        res = granstab.analyze(extract(scene, name), metric="L")
        scale = max(np.abs(b.stability_eigenvalues).max() for b in res.branches)
        assert rows["verdict"][i] == res.summary["verdict"]
        assert rows["consistent_negative"][i] == res.summary["consistent_negative"]
        assert rows["consistent_positive"][i] == res.summary["consistent_positive"]
        assert abs(rows["lambda_min"][i] - lowest(res)) <= 1e-10 * scale


SLIDING = {"rings": 1, "max_sliding": 8, "sample_branches": 32}


@pytest.mark.parametrize("dim, n, metric, boundary", [(2, 200, "L", "loads"), (2, 120, "10L", "loads"),
                                                     (3, 80, "L", "loads"), (2, 200, "L", "fixed"),
                                                     (3, 80, "L", "fixed")])
def test_batched_rows_equal_analyze_per_cluster(dim, n, metric, boundary):
    """The batched path (scan/batch.py) against `analyze` on every cluster's sub-scene (the loop it replaces; with
    --boundary fixed its ring held), on packings with contacts at yield: same counts, verdict, proof flags; λ_min
    within 1e-10·(the cluster's max |λ|); eigen-residuals and rigid leakage at round-off (<= 1e-12, relative to the
    cluster's norm); clusters without sliding contacts solved for eigenvalues only, their error the a-priori
    γ_{n²}‖|A|‖∞ (<= γ_{n²}√n relative to max |λ| = ‖A‖₂)."""
    scene = packings.random_packing(dim, n, n_sliding=n // 6, mobilised=0.5, seed=3)
    centers = np.arange(scene.n_particles)
    options = {**SLIDING, "metric": metric, "boundary": boundary}
    rows = scan_chunk(scene, centers, options).to_pylist()
    paths = [r["path"] for r in rows]
    assert paths.count("batched") + paths.count("batched-values") >= 0.9 * len(rows)
    assert min(paths.count("batched"), paths.count("batched-values")) >= 0.1 * len(rows)
    assert max(r["n_sliding"] for r in rows if r["path"] == "batched") >= 3     # branches were enumerated
    assert all(r["n_sliding"] == 0 for r in rows if r["path"] == "batched-values")
    for row, c, keep in zip(rows, centers, members(scene, centers, 1)):
        hold = boundary_ring(scene, c, 1)[1] if boundary == "fixed" else None
        res = granstab.analyze(subscene(scene, keep, hold=hold), metric=metric)
        scale = max(np.abs(b.stability_eigenvalues).max() for b in res.branches)
        assert (row["n_contacts"], row["n_sliding"]) == (res.scene.n_contacts, int(np.sum(res.scene.at_yield())))
        for key in ("verdict", "sufficient", "consistent_negative", "consistent_positive", "n_branches", "reason"):
            assert row[key] == res.summary[key], (row["center"], key)
        assert row["insufficient_because"] == ",".join(res.summary["insufficient_because"])
        margin = res.summary["zero_margin"]      # |λ|/bound: the batched bounds are its own, so the same side of 1
        assert np.isnan(row["zero_margin"]) if margin is None else (row["zero_margin"] > 1) == (margin > 1)
        assert abs(row["lambda_min"] - lowest(res)) <= 1e-10 * scale
        nd = row["n_particles"] * scene.dof_per_particle
        assert row["eigen_residual"] <= (gamma(nd * nd) * np.sqrt(nd) if row["path"] == "batched-values" else 1e-12)
        assert row["rigid_leakage"] <= 1e-12


@pytest.mark.parametrize("n", [21, 78])
def test_value_bounds_hold_for_eigenvalues_without_vectors(n):
    """accuracy.value_bounds (the batched-values path) against residual-certified eigenvalues of the same matrices:
    every eigvalsh eigenvalue lies within its a-priori bound plus the eigh pair's residual bound, on matrices whose
    entries span 16 decades (f/k from 1e-8 to 1e8); and the bound stays small (<= 1e-9 of ‖|A|‖∞)."""
    rng = np.random.default_rng(n)
    grade = 10.0 ** rng.uniform(-8, 8, size=(40, n))
    A = rng.standard_normal((40, n, n)) * np.sqrt(grade[:, :, None] * grade[:, None, :])
    A = 0.5 * (A + np.swapaxes(A, 1, 2))
    scale = np.abs(A).sum(axis=2).max(axis=1)[:, None]
    lam, V = np.linalg.eigh(A)
    exact = vector_bounds(lam, residual_norms(np, A, lam, V), scale, 0.0, n)
    values = np.linalg.eigvalsh(A)
    bound = value_bounds(values, scale, 0.0, n)
    assert np.all(np.abs(values - lam) <= bound + exact)
    assert np.all(bound <= 1e-9 * scale)


def test_clusters_that_need_the_eigenspace_search_go_to_analyze():
    """Symmetric clusters of the gear packing have repeated eigenvalues (Appendix D's subspace search): the batched
    path hands exactly those to `analyze`, and every row equals `cluster_row` (analyze) all the same."""
    scene = granstab.load_scene(ROOT / "presets" / "gear_packing.toml")
    centers = np.arange(scene.n_particles)
    options = {**SLIDING, "metric": "L"}
    table = scan_chunk(scene, centers, options)
    rows = table.to_pylist()
    paths = [r["path"] for r in rows]
    assert 0 < paths.count("analyze") < len(rows)
    assert table.schema == schema(Row) and table.column_names == list(ROW_COLUMNS)
    for row, c, keep in zip(rows, centers, members(scene, centers, 1)):
        ref = cluster_row(scene, c, keep, options)
        for key in ("center", "members", "n_particles", "n_contacts", "n_sliding", "branches", "n_branches",
                    "consistent_negative", "consistent_positive", "verdict", "sufficient", "insufficient_because",
                    "metric_robust", "reason"):
            assert row[key] == getattr(ref, key), (row["center"], key)


def test_every_path_makes_rows_of_the_schema_derived_from_the_row_record(tmp_path):
    """A row is defined once (rows.Row): its Arrow schema follows the record's field types, and the error row, an
    `analyze` row and the batched columns all make tables of exactly that schema; columns that are not Row's fields
    are refused; Parquet and CSV read back to the same rows and types."""
    from granstab.scan.output import read_arrow, write_table
    kinds = schema(Row)
    assert kinds.names == list(ROW_COLUMNS) == [f.name for f in dataclasses.fields(Row)]
    assert [str(kinds.field(k).type) for k in ("n_sliding", "lambda_min", "verdict", "sufficient", "metric_robust")] \
        == ["int64", "double", "string", "bool", "bool"]
    scene = granstab.load_scene(ANNULUS)
    keep = members(scene, [3], 1)[0]
    failed = cluster_row(scene, 3, keep, {**SLIDING, "metric": "inertia"})        # no masses: analyze refuses
    assert (failed.verdict, failed.n_contacts, failed.sufficient) == ("error", -1, False) and "mass" in failed.reason
    analyzed = cluster_row(scene, 3, keep, {**SLIDING, "metric": "L"})
    batched = scan_chunk(scene, np.array([3, 50]), {**SLIDING, "metric": "L"})
    assert analyzed.path == "analyze" and set(batched.column("path").to_pylist()) <= {"batched", "batched-values"}
    table = pa.concat_tables([rows_table([failed, analyzed]), batched])
    assert table.schema == kinds and table.num_rows == 4
    with pytest.raises(ValueError, match="fields of Row"):
        columns_table({key: None for key in ROW_COLUMNS if key != "reason"})
    for fmt in ("parquet", "csv"):
        write_table(table, tmp_path / f"rows.{fmt}", fmt)
        back = read_arrow(tmp_path / f"rows.{fmt}", fmt, Row)
        assert [f.type for f in back.schema] == [f.type for f in kinds], fmt
        same = [a == b or a != a and b != b or (isinstance(a, list) and np.array_equal(a, b, equal_nan=True))
                for x, y in zip(back.to_pylist(), table.to_pylist()) for a, b in zip(x.values(), y.values())]
        assert all(same), fmt


@pytest.mark.parametrize("boundary", ["loads", "fixed"])
def test_cluster_scenes_are_built_without_checking_again(monkeypatch, boundary):
    """The scan's chunks and the clusters (clusters.cluster, used by the scan, extract and the app) are slices of a
    scene checked where it was read: they are made without the scene checks (check_ranges, the friction check),
    and equal bit for bit the scene that build_scene makes and checks from the same slices (loads at equilibrium)."""
    import dataclasses as dc

    import granstab.model.scene as model
    from granstab.scan.clusters import cluster, cut
    scene = packings.random_packing(2, 150, n_sliding=25, mobilised=0.5, seed=5)
    centers = np.arange(0, scene.n_particles, 9)
    hold = boundary_ring(scene, 40, 2)[1] if boundary == "fixed" else None
    contact = ("p", "q", *CONTACT_FIELDS, "state")

    def checked(fields):
        return model.build_scene(**{k: v for k, v in fields.items() if k not in contact},
                                 arrays={k: fields[k] for k in contact})

    expected = [checked(cut(scene, members(scene, [40], 2)[0], hold=hold)),
                checked(chunk_cut(scene, centers, 1).fields)]
    calls = []
    for name in ("check_ranges", "_check_friction"):
        monkeypatch.setattr(model, name, lambda *a, name=name: calls.append(name))
    made = [cluster(scene, 40, 2, boundary), chunk_cut(scene, centers, 1).scene()]
    assert calls == []
    for a, b in zip(made, expected):
        for f in dc.fields(a):
            x, y = getattr(a, f.name), getattr(b, f.name)
            assert (np.array_equal(x, y) and x.dtype == y.dtype) if isinstance(x, np.ndarray) else x == y, f.name
    assert (made[0].fixed is not None) == (boundary == "fixed")


@pytest.mark.skipif(not gpu_available(), reason="no CuPy with a CUDA GPU here: the GPU backend is tested where one "
                                                "is present (pip install 'granstab[gpu]')")
def test_gpu_batched_rows_equal_cpu():
    scene = packings.random_packing(2, 300, n_sliding=50, mobilised=0.5, seed=4)
    centers = np.arange(scene.n_particles)
    cpu = scan_chunk(scene, centers, {**SLIDING, "metric": "L", "device": "cpu"}).to_pylist()
    gpu = scan_chunk(scene, centers, {**SLIDING, "metric": "L", "device": "gpu"}).to_pylist()
    for a, b in zip(cpu, gpu):               # no eigenvalues-only rows on a GPU (Jacobi: no a-priori bound)
        assert (a["path"].replace("batched-values", "batched"), a["verdict"], a["consistent_negative"],
                a["consistent_positive"]) == (b["path"], b["verdict"], b["consistent_negative"], b["consistent_positive"])
        assert abs(a["lambda_min"] - b["lambda_min"]) <= 1e-10 * abs(a["lambda_min"])


def _guided_sizes(guide, threads=2, cost=None):
    """The sizes of a Guide's tasks to the end (every centre checked once and in order), `cost` seconds a cluster
    reported after the first task."""
    parts = [guide.next(threads)]
    if cost is not None:
        guide.measured(pa.table({"seconds": np.full(len(parts[0]), cost)}))
    while (part := guide.next(threads)) is not None:
        parts.append(part)
    assert np.array_equal(np.concatenate(parts), guide.todo)
    return [len(p) for p in parts]


@pytest.mark.parametrize("cost", [2.0 ** -13, 2.0 ** -7, 2.0 ** -20])
def test_guide_sizes_tasks_by_the_measured_cost_and_ends_in_small_ones(cost):
    """Guided self-scheduling: FIRST_TASK clusters before a cluster's cost is known, then tasks of TASK_SECONDS of
    measured compute (2D-like, 3D-like and a cost so small that CHUNK caps them), the centres left / (2 threads)
    near the end, never growing again, every centre once."""
    sizes = _guided_sizes(Guide(np.arange(100_000)), cost=cost)
    least, most = (min(int(t / cost), CHUNK) for t in TASK_SECONDS)
    assert sizes[0] == FIRST_TASK
    assert max(sizes[1:]) == most and all(a >= b for a, b in zip(sizes[1:], sizes[2:]))
    assert min(sizes[1:-1]) >= least and sizes[-1] <= max(least, 1)
    assert sizes[-2] == least                          # the tail: the smallest affordable tasks


def test_guide_with_a_fixed_chunk_keeps_it_and_shrinks_the_tail():
    """At most the chunk, a quarter of what is left (2 threads), at least a quarter of the chunk: by hand,
    10,000 → 2048; 7,952 → 1,988; 5,964 → 1,491; 4,473 → 1,119; 3,354 → 839; 2,515 → 629; then 512 to the end."""
    assert _guided_sizes(Guide(np.arange(10_000), fixed=2048), threads=2) == [2048, 1988, 1491, 1119, 839, 629,
                                                                                512, 512, 512, 350]


@pytest.mark.parametrize("dim, n, boundary", [(2, 300, "loads"), (3, 60, "loads"), (2, 300, "fixed"),
                                            (2, 300, "embedded:1")])
def test_rows_are_the_same_bits_however_the_scan_is_chunked(dim, n, boundary):
    """A cluster's row does not depend on which clusters share its task or stack (serial, Dask, resumed scans chunk
    differently): chunks of 7 and of 41 clusters against one chunk, every number bit for bit, on packings with
    sliding contacts (stacks of different widths)."""
    scene = packings.random_packing(dim, n, n_sliding=n // 6, mobilised=0.5, seed=5)
    centers = np.arange(scene.n_particles)
    options = {**SLIDING, "metric": "L", "boundary": boundary}
    whole = chunk_table(chunk_cut(scene, centers, reach(options)), options).drop(["seconds"])
    assert max(whole.column("n_sliding").to_pylist()) >= 3
    for size in (7, 41):
        parts = [chunk_table(chunk_cut(scene, centers[i:i + size], reach(options)), options).drop(["seconds"])
                 for i in range(0, len(centers), size)]
        assert pa.concat_tables(parts).equals(whole), size


def test_scan_of_a_small_scene_equals_analyze_of_the_scene(tmp_path):
    """rings large enough that every cluster is the whole scene: every row is `analyze` of the scene."""
    scene = granstab.load_scene(ROOT / "presets" / "four_disk.toml")
    ref = granstab.analyze(scene, metric="L")
    summary = scan(scene, tmp_path, rings=4, boundary="loads", workers=1, figures=False)
    rows = read_map(tmp_path)["clusters"]
    assert summary["clusters"] == scene.n_particles
    assert set(rows["n_particles"]) == {scene.n_particles} and set(rows["n_branches"]) == {16}
    assert set(rows["consistent_negative"]) == {ref.summary["consistent_negative"]} == {9}
    assert np.allclose(rows["lambda_min"], lowest(ref), rtol=0, atol=1e-12)


def planted_lattice(center: int, rho_over_r: float):
    """A stable triangular lattice (flat contacts, ρ = 2r, f/(kr) = 1e-3) in which the contacts of one particle have
    curvature radius ρ and almost no tangential stiffness (α = 1e-4 < f/(kr)): its rotation then costs almost no
    elastic work and the geometric term decides, negative for sharp contacts (λ ∝ f(ρ - r), eq:exampleH2)."""
    scene = packings.lattice(2, 9, curvature_ratio=2.0)
    planted = (scene.p == center) | (scene.q == center)
    factor = np.where(planted, 2.0 / rho_over_r, 1.0)[:, None, None]
    arrays = {name: getattr(scene, name) for name in CONTACT_FIELDS + ("p", "q", "state") if name != "curvature_sum"}
    arrays.update(curvature_p=scene.curvature_p * factor, curvature_q=scene.curvature_q * factor,
                  alpha=np.where(planted, 1e-4, scene.alpha))
    return granstab.build_scene(2, scene.names, scene.x, arrays), planted


@pytest.mark.parametrize("rho_over_r", [0.4, 2.0])
def test_planted_unstable_cluster_is_found_and_nothing_far_away(tmp_path, rho_over_r):
    """Sharp planted contacts: the planted particle's cluster and its neighbours' are unstable, nothing beyond three
    diameters; the same contacts flat (the control): every cluster stable."""
    scene, planted = planted_lattice(40, rho_over_r)
    scan(scene, tmp_path, boundary="loads", workers=1, figures=False)
    data = read_map(tmp_path)
    verdict = dict(zip((scene.names[c] for c in data["clusters"]["center"]), data["clusters"]["verdict"]))
    fraction = np.asarray(data["particles"]["unstable_fraction"], dtype=float)
    assert list(data["particles"]["name"]) == list(scene.names)
    assert list(data["particles"]["own_verdict"]) == [verdict[n] for n in scene.names]
    if rho_over_r > 1:
        assert set(verdict.values()) == {"stable"} and np.all(fraction == 0.0)
        return
    near = {scene.names[i] for i in np.r_[scene.p[planted], scene.q[planted]]}   # the planted particle + ring 1
    assert all(verdict[n] == "unstable" for n in near)
    far = np.linalg.norm(scene.x - scene.x[40], axis=1) > 3 * 2.0            # beyond three diameters (r = 1)
    assert {verdict[scene.names[i]] for i in np.flatnonzero(far)} == {"stable"}
    assert fraction[40] == 1.0 and np.all(fraction[far] == 0.0)


def test_more_sliding_contacts_than_the_cap_examine_a_sample_and_say_so(tmp_path):
    scene = packings.lattice(2, 3, n_sliding=6, mobilised=0.5)
    summary = scan(scene, tmp_path, rings=3, max_sliding=3, sample_branches=5, boundary="loads", workers=1, figures=False)
    rows = read_map(tmp_path)["clusters"]
    assert summary["partial_branches"] == summary["clusters"] == scene.n_particles
    assert set(rows["branches"]) == {"partial"}
    assert set(rows["n_branches"]) <= set(range(3, 8))              # 2 extremes + up to 5 distinct samples
    for ok, verdict, because in zip(rows["sufficient"], rows["verdict"], rows["insufficient_because"]):
        assert ok == (verdict == "unstable" and not because)
        assert verdict == "unstable" or "unexamined_branches" in because


def test_interrupted_scan_resumes_without_repeating_a_cluster(tmp_path):
    scene = granstab.load_scene(ANNULUS)
    options = {"rings": 1, "metric": "L", "max_sliding": 8, "sample_branches": 32, "boundary": "loads",
               "attribution": True}
    from granstab.scan.output import ScanOutput
    out = ScanOutput(tmp_path, "csv", options, scene)
    out.write(chunk_table(chunk_cut(scene, np.arange(0, 20), 2), options))              # what finished before the kill
    summary = scan(scene, tmp_path, centers="every:1", boundary="loads", workers=1, fmt="csv", figures=False)
    rows = read_map(tmp_path)["clusters"]
    assert summary["clusters_this_run"] == scene.n_particles - 20
    assert list(rows["center"]) == list(range(scene.n_particles))     # each centre once, in scene order
    with pytest.raises(granstab.SceneError, match="other options"):
        scan(scene, tmp_path, rings=2, workers=1, fmt="csv", figures=False)


@pytest.mark.slow
def test_two_dask_workers_give_the_serial_rows_and_survive_a_killed_worker(tmp_path):
    """A 2-worker LocalCluster = the serial scan; a worker killed mid-scan (once the first chunk is on disk, while
    the scan still runs: one cluster a task) loses no cluster (Dask reruns its tasks; every row once)."""
    from dask.distributed import Client, LocalCluster
    scene = granstab.load_scene(ANNULUS)
    scan(scene, tmp_path / "serial", boundary="loads", workers=1, figures=False)
    parts = tmp_path / "dask" / "parts"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            victim = sorted(client.scheduler_info()["workers"])[0]
            runner = threading.Thread(target=scan, args=(scene, tmp_path / "dask"),
                                      kwargs={"scheduler": cluster.scheduler_address, "chunk": 1, "figures": False,
                                              "boundary": "loads"})
            runner.start()
            deadline = time.monotonic() + 120
            while not (parts.is_dir() and any(parts.glob("*.arrow"))) and time.monotonic() < deadline:
                time.sleep(0.01)
            client.run(os._exit, 1, workers=[victim], on_error="return")   # at once, not queued behind tasks
            killed_while_running = runner.is_alive()
            runner.join()
            assert killed_while_running
            while victim in client.scheduler_info()["workers"] and time.monotonic() < deadline:
                time.sleep(0.05)
            assert victim not in client.scheduler_info()["workers"]
    a, b = read_map(tmp_path / "serial")["clusters"], read_map(tmp_path / "dask")["clusters"]
    assert list(b["center"]) == list(a["center"]) == list(range(scene.n_particles))
    for key in ("verdict", "consistent_negative", "consistent_positive", "n_contacts", "n_branches"):
        assert list(a[key]) == list(b[key]), key
    assert np.array_equal(a["lambda_min"], b["lambda_min"])



def test_a_ctrl_c_before_the_first_task_closes_the_cluster_and_keeps_nothing(tmp_path, monkeypatch):
    """Ctrl-C after the local cluster started but before any task (here: while the client cuts the packing's
    graph): the cluster is closed, the scan says it kept 0 clusters, and the folder holds no part. It raised past
    the closing before (the cluster's workers were left to Python's exit); a fake cluster records its closing."""
    import granstab.scan.run as run
    from granstab.model.errors import Interrupted
    closed = []

    def interrupted(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "local_cluster", lambda workers: SimpleNamespace(close=lambda: closed.append(workers)))
    monkeypatch.setattr(run, "adjacency", interrupted)
    with pytest.raises(Interrupted, match=r"interrupted \(Ctrl-C\): 0 of 143 clusters kept in "):
        scan(granstab.load_scene(ANNULUS), tmp_path, workers=2, figures=False)
    assert closed == [2] and not list((tmp_path / "parts").glob("*.arrow"))

def test_cli_scan_and_extract_round_trip(tmp_path):
    out = tmp_path / "scan"
    proc = subprocess.run([sys.executable, "-m", "granstab", "scan", str(ANNULUS), "--out", str(out), "--boundary", "loads",
                           "--centers", "every:20", "--workers", "1", "--json"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["clusters"] == len(range(0, 143, 20)) and (out / "map.png").stat().st_size > 10_000
    name = read_map(out)["particles"]["name"][read_map(out)["clusters"]["center"][2]]
    sub_file = tmp_path / "sub.json"
    proc = subprocess.run([sys.executable, "-m", "granstab", "extract", str(ANNULUS), "--center", name,
                           "--out", str(sub_file)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    sub = granstab.load_scene(sub_file)
    direct = extract(granstab.load_scene(ANNULUS), name)
    assert sub.names == direct.names and np.allclose(sub.force, direct.force, rtol=0, atol=1e-15)
    bad = subprocess.run([sys.executable, "-m", "granstab", "extract", str(ANNULUS), "--center", "nope",
                          "--out", str(sub_file)], capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "'nope'" in bad.stderr


def test_fixed_boundary_holds_the_next_ring_and_keeps_the_packing_stiffness():
    """--boundary fixed: the ring one contact beyond the cluster is held (no dofs, no rigid modes, no projection),
    and the stiffness on the cluster's dofs is exactly the packing's own H restricted to them (every contact of a
    cluster particle is in the sub-scene, eq:final1), at round-off relative to ‖H‖."""
    from granstab.mechanics.stiffness import stiffness
    scene = packings.random_packing(2, 80, n_sliding=10, mobilised=0.5, seed=5)
    center = 37
    sub = extract(scene, scene.names[center], rings=1, boundary="fixed")
    inner = members(scene, [center], 1)[0]
    held = set(members(scene, [center], 2)[0]) - set(inner)
    assert {sub.names[i] for i in np.flatnonzero(sub.fixed)} == {scene.names[i] for i in held}
    assert not any(sub.fixed[a] and sub.fixed[b] for a, b in zip(sub.p, sub.q))    # no contact between two held
    per = scene.dof_per_particle
    packing_dofs = (inner[:, None] * per + np.arange(per)).ravel()
    H = stiffness(scene).H
    H_cluster = stiffness(sub).H[np.ix_(sub.free_dofs, sub.free_dofs)]
    assert np.abs(H_cluster - H[np.ix_(packing_dofs, packing_dofs)]).max() <= 1e-12 * np.abs(H).max()
    res = granstab.analyze(sub, metric="L")
    assert res.problem.rigid.shape == (len(sub.free_dofs), 0)
    assert all(not np.any(b.codes == RIGID) for b in res.branches)
    assert res.motion(res.branches[0].stability_vectors[:, 0]).shape == (sub.n_dof,)
    assert np.all(res.motion(res.branches[0].stability_vectors[:, 0]).reshape(-1, per)[sub.fixed] == 0)


def test_fixed_boundary_scan_rows_equal_analyze_of_the_extracted_scene(tmp_path):
    scene = granstab.load_scene(ANNULUS)
    names = [scene.names[i] for i in (3, 50, 99, 140)]
    scan(scene, tmp_path, centers=",".join(names), boundary="fixed", workers=1, figures=False)
    rows = read_map(tmp_path)["clusters"]
    for i, name in enumerate(names):
        res = granstab.analyze(extract(scene, name, boundary="fixed"), metric="L")
        scale = max(np.abs(b.stability_eigenvalues).max() for b in res.branches)
        assert rows["path"][i].startswith("batched") and rows["verdict"][i] == res.summary["verdict"]
        assert rows["consistent_positive"][i] == res.summary["consistent_positive"]
        assert abs(rows["lambda_min"][i] - lowest(res)) <= 1e-10 * scale
    with pytest.raises(granstab.SceneError, match="other options"):      # a resume may not mix boundaries
        scan(scene, tmp_path, centers=",".join(names), boundary="loads", workers=1, figures=False)


@pytest.mark.parametrize("value, message", [(1, "must be true or false"), ("yes", "must be true or false")])
def test_a_bad_fixed_flag_is_one_line_naming_the_particle(tmp_path, value, message):
    data = granstab.scene_to_dict(extract(granstab.load_scene(ANNULUS), granstab.load_scene(ANNULUS).names[40], boundary="fixed"))
    data["particles"][2]["fixed"] = value
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(granstab.SceneError) as err:
        granstab.load_scene(path)
    assert "particles[2]" in str(err.value) and "fixed" in str(err.value) and message in str(err.value)
    assert "\n" not in str(err.value)
    data["particles"] = [{**entry, "fixed": True} for entry in data["particles"]]
    path.write_text(json.dumps(data))
    with pytest.raises(granstab.SceneError, match="at least one must be free"):
        granstab.load_scene(path)


@pytest.mark.parametrize("fmt", ["parquet", "csv"])
def test_a_copied_scan_folder_opens_without_the_packing_it_was_scanned_from(tmp_path, fmt):
    """A scan folder keeps its packing (packing.npz) and names particles by their index in it: copied elsewhere, with
    the scanned file and the original folder deleted, it opens with read_map/read_packing and in the explorer, with
    the same clusters (each centre's members, by name, as `members` finds them in the original), and each cluster
    the explorer opens has the verdict and the consistent counts of the scan's row."""
    import shutil

    from granstab.scan import read_packing
    from granstab_app.scanmap import load_scan_map
    from granstab_app.state import Session
    scene, _ = planted_lattice(40, 0.4)
    packing = tmp_path / "lattice.json"
    packing.write_text(json.dumps(granstab.scene_to_dict(scene)))
    scanned = granstab.load_scene(packing)
    scan(scanned, tmp_path / "scan", boundary="loads", workers=1, fmt=fmt, figures=False)
    centers = np.arange(scanned.n_particles)
    expected = {scanned.names[c]: [scanned.names[m] for m in keep]
                for c, keep in zip(centers, members(scanned, centers, 1))}
    folder = tmp_path / "elsewhere" / "copy"
    shutil.copytree(tmp_path / "scan", folder)
    shutil.rmtree(tmp_path / "scan")
    packing.unlink()
    data, stored = read_map(folder), read_packing(folder)
    names = data["particles"]["name"]
    assert list(names) == list(stored.names) == list(scanned.names)
    assert {names[c]: [names[m] for m in row]
            for c, row in zip(data["clusters"]["center"], data["clusters"]["members"])} == expected
    model = load_scan_map(folder)
    assert {stored.names[c]: [stored.names[m] for m in row] for c, row in model.members.items()} == expected
    rows = data["clusters"]
    for i in (40, 0, 31, 49):                                      # the planted particle, a corner, neighbours
        res = granstab.analyze(model.cluster(scanned.names[i]).scene, metric="L")
        assert (res.verdict.verdict, res.verdict.consistent_negative, res.verdict.consistent_positive) \
            == (rows["verdict"][i], rows["consistent_negative"][i], rows["consistent_positive"][i])
    assert rows["verdict"][40] == "unstable"
    s = Session(str(folder))
    assert s.error is None and s.kind == "scan_map" and s.open_cluster(scanned.names[40]) and s.verdict == "unstable"
    (folder / "packing.npz").unlink()
    with pytest.raises(granstab.SceneError, match="no packing.npz"):
        load_scan_map(folder)


def test_a_fixed_boundary_scan_map_opens_its_cluster_with_the_ring_held(tmp_path):
    """The explorer opens a cluster of a `--boundary fixed` scan as the scan analysed it: the ring held fixed, the
    same verdict; its modes animate with the held particles at rest and are not made rigid-free."""
    from granstab_app.state import Session
    scene = granstab.load_scene(ANNULUS)
    name = scene.names[50]
    scan(scene, tmp_path, centers=name, boundary="fixed", workers=1, figures=False)
    s = Session("two_particle")
    assert s.load_preset(str(tmp_path)) and s.kind == "scan_map"
    assert s.open_cluster(name) and s.error is None
    direct = extract(scene, name, boundary="fixed")
    assert s.scene.fixed is not None and sorted(s.scene.names) == sorted(direct.names)
    assert s.analysis.summary["verdict"] == read_map(tmp_path)["clusters"]["verdict"][0]
    mode = s.modes()[0]
    bodies = {b.name: b for b in s.mode_bodies(mode, 0.2, 0.25)}
    rest = {b.name: b for b in s.bodies()}
    for i in np.flatnonzero(s.scene.fixed):
        held = s.scene.names[i]
        assert np.allclose(bodies[held].x, rest[held].x, rtol=0, atol=1e-12 * s.size)


def test_a_clusters_analysis_reads_no_machine_load(monkeypatch):
    """`analyze` of a scan's cluster plans without the time estimate (estimate=False): no fresh read of /proc, which
    took 0.34 s a cluster on the busy 2-core machine (155 of a 2,000-disk frame's 215 s, issue 39); the result's
    cost says so (estimated_s None) and its verdict is the one with the estimate."""
    from granstab.solve import threads
    reads, read = [], threads.runnable

    def counted(fresh=False):
        reads.append(fresh)
        return read(fresh)
    monkeypatch.setattr(threads, "runnable", counted)
    scene = granstab.load_scene(ANNULUS)
    keep = members(scene, [3], 1)[0]
    row = cluster_row(scene, 3, keep, {**SLIDING, "metric": "L"})
    assert row.path == "analyze" and True not in reads, reads
    sub = extract(scene, scene.names[3])
    quiet, planned = (granstab.analyze(sub, metric="L", estimate=e) for e in (False, True))
    assert quiet.cost["estimated_s"] is None and planned.cost["estimated_s"] > 0
    assert quiet.verdict.verdict == planned.verdict.verdict == row.verdict
