"""A scan at scale (issue 41): chunks of near centres, embedded clusters solved for eigenvalues where that proves
them, the map's radii and its pixels at 10⁶ particles."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from granstab.mechanics.accuracy import gamma
from granstab.model import packings
from granstab.scan import members, read_map, scan
from granstab.scan import run as scan_run
from granstab.scan.clusters import spatial_order, union
from granstab.scan.figure import GREY, colormap, particle_radii
from granstab.scan.run import cluster_row, scan_chunk

SLIDING = {"rings": 1, "max_sliding": 8, "sample_branches": 32, "metric": "L"}


def shuffled(scene, seed: int = 0):
    """The same packing with its particles numbered at random (as a DEM's insertion order numbers them)."""
    new = np.random.default_rng(seed).permutation(scene.n_particles)      # new[i]: the old index of particle i
    old_to_new = np.argsort(new)
    per = {k: None if getattr(scene, k) is None else getattr(scene, k)[new] for k in ("x", "load", "load_moment",
                                                                                       "mass", "inertia", "fixed")}
    return replace(scene, names=tuple(scene.names[i] for i in new), p=old_to_new[scene.p], q=old_to_new[scene.q],
                   **per)


def test_spatial_order_is_a_permutation_that_keeps_chunks_compact():
    """Z-order of the centres: every centre once; 256 consecutive ones of a randomly numbered 2D packing reach (3
    rings, embedded:1's chunk) under 2.5 particles a centre, against over 10 in their numbering."""
    scene = shuffled(packings.random_packing(2, 4000, n_sliding=0, mobilised=0.5, seed=2))
    ids = np.arange(scene.n_particles)
    order = spatial_order(scene.x, ids)
    assert np.array_equal(np.sort(order), ids)

    def reach(o):
        return np.mean([len(union(scene, o[i:i + 256], 3)) / 256 for i in range(0, 3840, 256)])

    assert reach(order) < 2.5 < 10 < reach(ids)


def test_a_scan_ships_chunks_of_near_centres(tmp_path, monkeypatch):
    """scan() cuts its chunks from centres in spatial order: each chunk's scene holds few particles a centre (the
    scene Dask ships, its contact blocks), whatever the file's numbering."""
    scene = shuffled(packings.random_packing(2, 1500, n_sliding=0, mobilised=0.5, seed=4))
    ratios, table = [], scan_run.chunk_table

    def counting(chunk, options):
        ratios.append(len(chunk.particles) / len(chunk.centers))
        return table(chunk, options)

    monkeypatch.setattr(scan_run, "chunk_table", counting)
    scan(scene, tmp_path, workers=1, chunk=250, figures=False)
    assert len(ratios) == -(-scene.n_particles // 250) and max(ratios) < 3.5, ratios
    assert sorted(read_map(tmp_path)["clusters"]["center"]) == list(range(scene.n_particles))


def test_embedded_clusters_proven_positive_by_their_eigenvalues_skip_the_vectors():
    """--boundary embedded: a cluster without sliding contacts whose eigenvalues are all proven positive by the
    a-priori bounds is solved for eigenvalues only (batched-values, its error γ_{n²}√n of max |λ| at most); the
    others (sliding contacts) get eigenvectors; every row equals `analyze` of the embedded cluster (verdict, counts,
    λ_min within 1e-10 of max(1, |λ_min|))."""
    scene = packings.random_packing(2, 120, n_sliding=8, mobilised=0.5, seed=3)
    centers = np.arange(scene.n_particles)
    options = {**SLIDING, "boundary": "embedded:1"}
    rows = scan_chunk(scene, centers, options).to_pylist()
    paths = [r["path"] for r in rows]
    assert paths.count("batched-values") >= 0.3 * len(rows) and paths.count("batched") >= 0.2 * len(rows)
    for row, c, keep in zip(rows, centers, members(scene, centers, 1)):
        ref = cluster_row(scene, c, keep, options)
        assert (row["verdict"], row["consistent_negative"], row["n_sliding"]) == \
            (ref.verdict, ref.consistent_negative, ref.n_sliding), c
        assert abs(row["lambda_min"] - ref.lambda_min) <= 1e-10 * max(1.0, abs(ref.lambda_min)), c
        if row["path"] == "batched-values":
            nd = row["n_particles"] * scene.dof_per_particle
            assert row["n_sliding"] == 0 and row["lambda_min"] > 0 and row["verdict"] == "stable"
            assert row["eigen_residual"] <= gamma(4 * nd * nd) * np.sqrt(4 * nd)   # the free dofs: < 4 nd


def test_particle_radii_are_the_medians_per_particle_bit_for_bit():
    """The map's drawing radius by one sort (no loop over particles): np.median of each particle's contact
    distances, odd and even counts, and the others' median for particles without contacts."""
    scene = packings.random_packing(2, 400, n_sliding=0, mobilised=0.5, seed=1)
    lonely = replace(scene, names=scene.names + ("alone",), x=np.r_[scene.x, [[1e3, 1e3]]],
                     load=np.r_[scene.load, [[0.0, 0.0]]], load_moment=np.r_[scene.load_moment, [[0.0]]],
                     mass=None if scene.mass is None else np.r_[scene.mass, [1.0]],
                     inertia=None if scene.inertia is None else np.r_[scene.inertia, scene.inertia[:1]])
    d = np.linalg.norm(np.r_[lonely.r_pq, lonely.r_qp], axis=1)
    owner = np.r_[lonely.p, lonely.q]
    ref = np.array([np.median(d[owner == i]) if (owner == i).any() else np.nan for i in range(lonely.n_particles)])
    ref[-1] = np.nanmedian(ref)
    counts = np.bincount(owner, minlength=lonely.n_particles)
    assert {1, 0} <= set(counts[:-1] % 2) and counts[-1] == 0
    assert np.array_equal(particle_radii(lonely), ref)


@pytest.mark.parametrize("value, hatched, expect", [
    ([0.0, 0.9, np.nan], [False] * 3, "red"), ([np.nan, np.nan, np.nan], [False] * 3, "grey"),
    ([0.0, 0.0, 0.0], [False, True, False], "hatched")])
def test_a_map_above_pixels_above_is_pixels_of_the_largest_share(value, hatched, expect):
    """_pixels: a pixel takes the largest share of its particles (an unstable one is not averaged away), grey where
    they are all in no cluster, clear where it has none; hatched where one is unstable only by the cut."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from granstab.scan.figure import _pixels
    centres = np.array([[0.0, 0.0], [1e-4, 0.0], [2e-4, 1e-4], [100.0, 100.0], [0.0, 100.0]])  # 3 in one pixel
    values = np.r_[value, 0.0, 0.0]
    fig, ax = plt.subplots()
    try:
        _pixels(ax, centres, np.full(5, 1e-9), values, np.r_[hatched, False, False])
        rgba = ax.images[0].get_array()
        corner = rgba[0, 0]
        want = {"red": colormap()(0.9), "grey": (*GREY, 1.0), "hatched": colormap()(0.0)}[expect]
        assert np.allclose(corner, want), corner
        assert rgba[rgba.shape[0] // 2, rgba.shape[1] // 2][3] == 0.0          # no particle: clear
        assert bool(ax.collections) == (expect == "hatched")
    finally:
        plt.close(fig)
