"""Scans of periodic packings (issue 24): a cluster at the seam of the cell keeps every contact with its minimum-image
geometry (unwrapped from its centre along its contacts), and a scan row of a seam particle equals `analyze` of its
extracted cluster, on the batched path and on the per-cluster one. RigidLibrary's Lees–Edwards DataSim frame."""

import numpy as np
import pyarrow.parquet as pq
import pytest
from helpers import ROOT  # noqa: E402
from test_io_periodic import lattice_dumps

import granstab
from granstab.cli import main
from granstab.io import load
from granstab.mechanics.branches import RIGID
from granstab.scan import extract, members, scan
from granstab.scan.clusters import particle_index

DATASIM = ROOT.parent / "shared" / "data" / "rigidlibrary" / "DataSim"


@pytest.fixture(scope="module")
def packing():
    return load(DATASIM).scene


def seam_centres(scene, count, max_sliding=6):
    """Particles on a seam contact whose one-ring cluster has few sliding contacts (every branch enumerated)."""
    seam = np.any(scene.image != 0, axis=1)
    ends = np.unique(np.r_[scene.p[seam], scene.q[seam]])
    sliding = scene.at_yield()
    chosen = []
    for c, kept in zip(ends, members(scene, ends, 1)):
        inside = np.isin(scene.p, kept) & np.isin(scene.q, kept)
        if 0 < np.sum(sliding & inside) <= max_sliding:
            chosen.append(int(c))
    return chosen[:count]


def test_a_seam_cluster_keeps_every_contact_with_minimum_image_geometry(packing):
    s = packing
    centre = seam_centres(s, 1)[0]
    kept = members(s, [centre], 1)[0]
    inside = np.flatnonzero(np.isin(s.p, kept) & np.isin(s.q, kept))
    assert np.any(s.image[inside] != 0)                       # the cluster crosses the seam
    sub = extract(s, s.names[centre])
    assert sub.cell is None and not sub.image.any() and sub.n_contacts == len(inside)
    # each contact's branch and contact point relative to p are the packing's (round-off of the lattice shift)
    order = {(s.names[a], s.names[b]): c for c, a, b in zip(inside, s.p[inside], s.q[inside])}
    c = np.array([order[(sub.names[a], sub.names[b])] for a, b in zip(sub.p, sub.q)])
    scale = np.abs(s.cell).max()
    assert np.abs(sub.branch - s.branch[c]).max() <= 1e-13 * scale
    assert np.abs(sub.r_pq - s.r_pq[c]).max() <= 1e-13 * scale and np.abs(sub.r_qp - s.r_qp[c]).max() <= 1e-13 * scale
    assert np.array_equal(sub.force, s.force[c])
    # unwrapped: the cluster sits together around its centre, no particle a cell away
    assert np.linalg.norm(sub.x - sub.x[sub.names.index(s.names[centre])], axis=1).max() < 0.1 * scale
    # --no-periodic cuts the seam contacts into loads: the same particle's cluster may lose contacts, never gain
    cut = load(DATASIM, periodic=False).scene
    assert extract(cut, s.names[centre]).n_contacts <= sub.n_contacts


@pytest.mark.parametrize("workers_chunk", [None, 2])
def test_scan_rows_of_seam_particles_equal_analyze_of_the_extracted_cluster(packing, tmp_path, workers_chunk):
    """Batched rows (every chunking: one chunk, chunks of 2) against analyze(extract(...)) with the same metric:
    the same verdict and counts, λ_min within 1e-10 max|λ| (round-off of the unwrapping shift)."""
    s = packing
    names = [s.names[c] for c in seam_centres(s, 4)]
    assert len(names) == 4
    scan(s, tmp_path / "scan", centers=names, workers=1, chunk=workers_chunk, figures=False, boundary="loads")
    rows = pq.read_table(tmp_path / "scan" / "clusters.parquet").to_pylist()
    assert [s.names[r["center"]] for r in rows] == names
    assert {r["path"] for r in rows} <= {"batched", "batched-values"}
    for row, name in zip(rows, names):
        sub = extract(s, name)
        res = granstab.analyze(sub, metric="L")
        lam = np.concatenate([b.stability_eigenvalues for b in res.branches])
        assert row["verdict"] == res.summary["verdict"], name
        assert (row["n_contacts"], row["n_branches"]) == (sub.n_contacts, len(res.branches)), name
        for key in ("consistent_negative", "consistent_positive"):
            assert row[key] == res.summary[key], (name, key)
        lowest = min(b.stability_eigenvalues[b.codes != RIGID].min() for b in res.branches)
        assert abs(row["lambda_min"] - lowest) <= 1e-10 * np.abs(lam).max(), name


def test_a_cluster_that_wraps_around_a_small_cell_is_a_one_line_error(tmp_path, capsys):
    """A 4×4 periodic lattice: the two-ring cluster of a disk reaches the disk two sites away from both sides, so
    its contacts close a loop around the cell; extract says so in one line, a scan row says so as its reason."""
    paths, _, _ = lattice_dumps(tmp_path)
    out = tmp_path / "lattice.json"
    assert main(["convert", *map(str, paths), "--columns", "id1,id2,fx,fy,fz", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["extract", str(out), "--center", "6", "--rings", "2", "--out", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cluster of 6" in err and "wraps around the periodic cell" in err, err
    scene = granstab.load_scene(out)
    one = extract(scene, "6", rings=1)                       # one ring: no loop, 4 contacts
    assert one.n_contacts == 4 and one.cell is None
    scan(scene, tmp_path / "scan", rings=2, centers=["6"], workers=1, figures=False)
    row = pq.read_table(tmp_path / "scan" / "clusters.parquet").to_pylist()[0]
    assert row["verdict"] == "error" and "wraps around the periodic cell" in row["reason"]
    assert particle_index(scene, "6") == row["center"]


def test_embedded_seam_clusters_are_batched_and_equal_the_per_cluster_path(packing, tmp_path):
    """The default boundary (embedded:1) holds a ring beyond the free ones; the batch unwraps each cluster along its
    contacts by their places in the chunk (a held particle has no free rank: before, the ranks were used, every seam
    cluster read as wrapping around the cell and went to `analyze`, 23 % of a 2,000-disk Lees–Edwards scan). Rows
    against scan.run.cluster_row (analyze on the extracted cluster, focused): the same verdict and counts, λ_min
    within 1e-10 of the cluster's largest |λ| (round-off of the unwrapping shift)."""
    from granstab.scan.clusters import cluster
    from granstab.scan.run import cluster_row
    s = packing
    centres = seam_centres(s, 4)
    scan(s, tmp_path / "scan", centers=[s.names[c] for c in centres], workers=1, figures=False)
    rows = pq.read_table(tmp_path / "scan" / "clusters.parquet").to_pylist()
    assert {r["path"] for r in rows} <= {"batched", "batched-values"}, [r["path"] for r in rows]
    options = {"rings": 1, "boundary": "embedded:1", "metric": "L", "max_sliding": 8, "sample_branches": 32}
    for row, c in zip(rows, centres):
        alone = cluster_row(s, c, members(s, [c], 1)[0], options)
        assert alone.path == "analyze", c
        for key in ("verdict", "n_contacts", "n_sliding", "n_branches", "consistent_negative", "consistent_positive"):
            assert row[key] == getattr(alone, key), (c, key)
        whole = granstab.analyze(cluster(s, c, 1, "embedded:1"), metric="L", attribution=False)
        scale = max(np.abs(b.stability_eigenvalues).max() for b in whole.branches)
        assert abs(row["lambda_min"] - alone.lambda_min) <= 1e-10 * scale, c
