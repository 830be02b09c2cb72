"""Attribution of instability (issue 25): the second-order work split by part, the rim share, the two controls and
the mechanism label (mechanics/attribution.py), in `analyze`, in the scan's rows (batched and per cluster) and on a
real frame; --boundary embedded[:R]; the scan's figures (issue 26)."""

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

import granstab
from granstab.analysis import attribute
from granstab.mechanics.attribution import MECHANISMS, mechanism
from granstab.model import packings
from granstab.scan import read_map, scan
from granstab.scan.clusters import adjacency, cluster, control_scene, loaded, members, subscene
from granstab.scan.run import cluster_row, scan_chunk

ANNULUS = ROOT / "presets" / "annulus_frame.json"
SLIDING = {"rings": 1, "max_sliding": 8, "sample_branches": 32, "metric": "L"}
SUM_RTOL = 1e-9    # parts vs eigenvalue: five sums of O(n²) products of O(1)-scaled terms, relative to |λ|


def pair(force, state, curvature, title):
    """Two particles of radius 1 touching at (1, 0) (presets/two_particle.toml's geometry) with contact force
    `force`, contact state `state` and curvatures -1/ρ on both sides."""
    return granstab.build_scene(2, ["p", "q"], [[0.0, 0.0], [2.0, 0.0]], {
        "p": np.array([0]), "q": np.array([1]), "point": np.array([[1.0, 0.0]]), "normal": np.array([[1.0, 0.0]]),
        "force": np.array([force]), "curvature_p": np.full((1, 2, 2), curvature),
        "curvature_q": np.full((1, 2, 2), curvature), "moment": np.zeros((1, 1)), "k": np.ones(1),
        "alpha": np.ones(1), "mu": np.full(1, 0.5), "rolling": np.zeros((1, 1, 1)), "state": (state,)}, title=title)


def chain(n: int):
    """n unit disks in a line along x, each contact compressed by f = 0.01 (dead loads at both ends)."""
    x = np.c_[2.0 * np.arange(n), np.zeros(n)]
    M = n - 1
    return granstab.build_scene(2, [f"d{i}" for i in range(n)], x, {
        "p": np.arange(M), "q": np.arange(1, n), "point": np.c_[2.0 * np.arange(M) + 1, np.zeros(M)],
        "normal": np.tile([1.0, 0.0], (M, 1)), "force": np.tile([-0.01, 0.0], (M, 1)),
        "curvature_p": np.tile(-np.eye(2), (M, 1, 1)), "curvature_q": np.tile(-np.eye(2), (M, 1, 1)),
        "moment": np.zeros((M, 1)), "k": np.ones(M), "alpha": np.ones(M), "mu": np.full(M, 0.5),
        "rolling": np.zeros((M, 1, 1)), "state": ("auto",) * M}, title=f"{n} disks in a line")


def lowest_negative(result):
    return min(c["eigenvalue"] for b in result.branches for c in b.consistent() if c["eigenvalue"] < 0)


def test_hand_made_clusters_get_their_labels_and_the_parts_sum_to_the_eigenvalue():
    """A sliding pair (frictional: the a ⊗ s term makes the work negative, all-elastic it is stable); the paper's
    sharp pair (ρ = r/2, Sec. 4.1: geometric, λ6 = f(ρ - r) from Hg1 + Hg2, no deformation, no load term); three
    disks in a line whose end disks carry the dead loads of cut contacts (boundary: they roll off; held, stable)."""
    sliding = granstab.analyze(pair([-0.01, 0.005], "sliding", -0.5, "sliding pair"), metric="L")
    sharp = granstab.analyze(granstab.load_scene(ROOT / "presets" / "two_particle.toml"), metric="L")
    rim = granstab.analyze(chain(3), metric="L", rim=[0, 2])
    labels = [(r.verdict.verdict, r.attribution.mechanism) for r in (sliding, sharp, rim)]
    assert labels == [("unstable", "frictional"), ("unstable", "geometric"), ("unstable", "boundary")]
    for r in (sliding, sharp, rim):
        a = r.attribution
        assert abs(sum(a.work_parts) - lowest_negative(r)) <= SUM_RTOL * abs(lowest_negative(r))
        assert len(a.work_parts) == 5 and a.modes[0].eigenvalue == lowest_negative(r)
    a = sliding.attribution
    assert a.work_parts[1] < 0 and a.elastic_control == "stable"
    f, rho, r = 0.01, 0.5, 1.0
    hm_el, hm_sl, hg1, hg2, hg3 = sharp.attribution.work_parts
    assert abs(hg1 + hg2 - f * (rho - r)) <= 1e-12 and abs(hm_el) + abs(hm_sl) + abs(hg3) <= 1e-12   # closed form
    assert (sharp.attribution.elastic_control, sharp.attribution.fixed_control) == ("unstable", "unstable")
    a = rim.attribution
    assert a.fixed_control == "stable" and a.rim_share > 0.5 and a.work_parts[4] < 0


def sphere_pair(force, state, rho, rolling):
    """Two unit spheres touching at (1, 0, 0), contact force `force`, state `state`, curvature radius ρ in both
    tangent directions on both sides, rolling (and twisting) stiffness `rolling`·I."""
    K = np.diag([0.0, -1 / rho, -1 / rho])[None]
    return granstab.build_scene(3, ["p", "q"], [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], {
        "p": np.array([0]), "q": np.array([1]), "point": np.array([[1.0, 0.0, 0.0]]),
        "normal": np.array([[1.0, 0.0, 0.0]]), "force": np.array([force]), "curvature_p": K, "curvature_q": K,
        "moment": np.zeros((1, 3)), "k": np.ones(1), "alpha": np.ones(1), "mu": np.full(1, 0.5),
        "rolling": rolling * np.eye(3)[None], "state": (state,)}, title="sphere pair")


def test_3d_clusters_get_their_labels_and_the_parts_sum_to_the_eigenvalue():
    """3D (spheres, three rotations): a pair sliding at the cone (f_t = μ f_n, blunt ρ = 2r, a little rolling
    stiffness so that the all-elastic pair is stable) and a fcc cell of 4 spheres with one contact at the friction
    limit (packings.lattice) are `frictional`: Hm of the sliding contacts negative, the all-elastic control stable;
    the sharp sphere pair (ρ = r/2, no tangential force) is `geometric` with Hg1 + Hg2 = f(ρ - r), the 2D closed
    form of Sec. 4.1 (each tangent direction rolls as the disk does), Hm = Hg3 = 0. Parts sum to λ to SUM_RTOL."""
    sliding = granstab.analyze(sphere_pair([-0.01, 0.005, 0.0], "sliding", 2.0, 0.1), metric="L")
    cell = granstab.analyze(packings.lattice(3, 1, n_sliding=1, seed=1), metric="L")
    sharp = granstab.analyze(sphere_pair([-0.01, 0.0, 0.0], "auto", 0.5, 0.0), metric="L")
    for r, label in ((sliding, "frictional"), (cell, "frictional"), (sharp, "geometric")):
        a = r.attribution
        assert (r.verdict.verdict, a.mechanism) == ("unstable", label)
        assert len(a.work_parts) == 5 and abs(sum(a.work_parts) - lowest_negative(r)) <= SUM_RTOL * abs(
            lowest_negative(r))
        got = mechanism(np.array([a.work_parts]), np.array([a.rim_share]), [a.elastic_control], [a.fixed_control],
                        [True])
        assert got.tolist() == [label]
    for r in (sliding, cell):
        assert r.attribution.work_parts[1] < 0 and r.attribution.elastic_control == "stable"
    f, rho, radius = 0.01, 0.5, 1.0
    hm_el, hm_sl, hg1, hg2, hg3 = sharp.attribution.work_parts
    # closed form to 1e-12: f = 1e-2, parts O(f), round-off ~1e-16 f (the 2D pair's tolerance)
    assert abs(hg1 + hg2 - f * (rho - radius)) <= 1e-12 and abs(hm_el) + abs(hm_sl) + abs(hg3) <= 1e-12
    assert (sharp.attribution.elastic_control, sharp.attribution.fixed_control) == ("unstable", "unstable")


def test_the_rule_is_first_that_holds_and_only_for_unstable_rows():
    """frictional before geometric before boundary, else mixed; '' for rows that are not unstable."""
    parts = np.array([[0, -1, 0, 0, 0],        # sliding negative, elastic control stable
                      [0, 0, -1, 0, 0],        # Hg1 + Hg2 negative, both controls unstable
                      [0, 0, 0, 0, -1],        # Hg3 negative, rim held stable
                      [0, 0, 1, 1, 1],         # rim carries it (share 0.9), rim held stable
                      [1, 1, 1, 1, -5],        # Hg3 negative but the rim-held control unstable, elastic unstable
                      [0, -1, 0, 0, 0]], dtype=float)
    share = np.array([0.1, 0.1, 0.1, 0.9, 0.1, 0.1])
    elastic = ["stable", "unstable", "unstable", "unstable", "unstable", "stable"]
    fixed = ["stable", "unstable", "stable", "stable", "unstable", "stable"]
    got = mechanism(parts, share, elastic, fixed, [True] * 5 + [False])
    assert got.tolist() == ["frictional", "geometric", "boundary", "boundary", "mixed", ""]
    assert set(got[:5]) == set(MECHANISMS)


def rim_of(scene, center, keep):
    """The cluster's particles with a contact outside it or a load like a contact force (clusters.loaded)."""
    graph = adjacency(scene)
    outside = np.setdiff1d(members(scene, [center], 2, graph)[0], keep)
    return np.flatnonzero((np.asarray(graph[keep][:, outside].sum(axis=1)).ravel() > 0) | loaded(scene)[keep])


def test_a_real_frame_reproduces_its_attribution_cluster_by_cluster(tmp_path):
    """The annulus frame (143 photoelastic disks, issue 25's held-out check): every unstable row of a scan, batched
    or not, equals `analyze` of its extracted cluster with the cluster's rim: mechanism, controls, rim share and
    the work parts (scaled as the row's: |v|² = lambda_min / λ), within 1e-8 of |lambda_min|."""
    scene = granstab.load_scene(ANNULUS)
    scan(scene, tmp_path, centers="every:3", boundary="loads", workers=1, figures=False)
    rows = read_map(tmp_path)["clusters"]
    unstable = np.flatnonzero(rows["verdict"] == "unstable")
    assert len(unstable) >= 5 and {"batched", "batched-values"} & set(rows["path"][unstable])
    for i in unstable:
        c = int(rows["center"][i])
        keep = members(scene, [c], 1)[0]
        res = granstab.analyze(subscene(scene, keep), metric="L")
        a = attribute(res, rim=rim_of(scene, c, keep), max_sliding=8, sample_branches=32)
        scale = rows["lambda_min"][i] / a.modes[0].eigenvalue
        assert (rows["mechanism"][i], rows["elastic_control"][i], rows["fixed_control"][i]) == \
            (a.mechanism, a.elastic_control, a.fixed_control), c
        assert abs(rows["rim_share"][i] - a.rim_share) <= 1e-8
        assert np.allclose(rows["work_parts"][i], np.array(a.work_parts) * scale, rtol=0,
                           atol=1e-8 * abs(rows["lambda_min"][i])), c


@pytest.mark.parametrize("boundary", ["embedded:1", "embedded"])
def test_embedded_rows_batched_equal_analyze_of_the_embedded_cluster(boundary):
    """--boundary embedded[:R]: the batch (one stack per size, the surroundings' contacts elastic, the ring beyond
    held, modes mostly outside the cluster left out) against `analyze` of clusters.embedded's scene with the same
    rule (analysis.focus), cluster by cluster: verdict, counts, lambda_min within 1e-10 of the largest |λ|."""
    scene = packings.random_packing(2, 80, n_sliding=12, mobilised=0.5, seed=3)
    centers = np.arange(0, scene.n_particles, 4)
    options = {**SLIDING, "boundary": boundary}
    batched = scan_chunk(scene, centers, options).to_pylist()
    assert sum(r["path"].startswith("batched") for r in batched) >= 0.8 * len(batched)     # -values: no sliding
    for row, c, keep in zip(batched, centers, members(scene, centers, 1)):
        ref = cluster_row(scene, c, keep, options)
        assert (row["verdict"], row["consistent_negative"], row["n_sliding"]) == \
            (ref.verdict, ref.consistent_negative, ref.n_sliding), c
        assert abs(row["lambda_min"] - ref.lambda_min) <= 1e-10 * max(1.0, abs(ref.lambda_min)), c


def test_embedded_scene_holds_the_ring_beyond_and_keeps_the_surroundings_elastic():
    """clusters.embedded: R rings free, the ring beyond held, only contacts between two cluster particles may
    slide; the rim control holds exactly the cluster particles with a contact outside it."""
    scene = packings.random_packing(2, 80, n_sliding=30, mobilised=0.5, seed=3)
    c = 40
    inner = members(scene, [c], 1)[0]
    sub = cluster(scene, c, 1, "embedded:2")
    within, beyond = members(scene, [c], 3)[0], np.setdiff1d(members(scene, [c], 4)[0], members(scene, [c], 3)[0])
    names = np.asarray(scene.names, dtype=object)
    held = set(np.asarray(sub.names, dtype=object)[sub.fixed])
    assert held == set(names[beyond]) and set(sub.names) == set(names[within]) | held
    own = np.isin(np.asarray(sub.names, dtype=object), names[inner])
    assert not np.any(sub.at_yield() & ~(own[sub.p] & own[sub.q]))
    rim = control_scene(scene, c, 1, "loads", "rim")
    assert set(np.asarray(rim.names, dtype=object)[rim.fixed]) == set(names[inner[rim_of(scene, c, inner)]])


def test_map_colours_agree_with_the_explorer_and_differ_from_the_no_cluster_grey():
    """issue 26: coolwarm's middle (0.87 grey) could not be told from 'in no cluster'. The map's colormap is the
    explorer's white → dark red, and its middle differs from the grey of 'no cluster' by at least 0.15 in some
    channel (a sixth of the range: clearly visible)."""
    from granstab.scan.figure import colormap
    from granstab_app.scanmap import GREY, RED, WHITE, fraction_colours
    cmap = colormap()
    assert np.allclose(np.array(cmap(0.0)[:3]) * 255, WHITE, atol=1) and np.allclose(np.array(cmap(1.0)[:3]) * 255,
                                                                                  RED, atol=1)
    assert np.allclose(np.array(cmap(0.5)[:3]) * 255, fraction_colours(np.array([0.5]))[0], atol=1.5)
    assert np.max(np.abs(np.array(cmap(0.5)[:3]) - np.array(GREY) / 255)) >= 0.15
    assert np.allclose(np.array(cmap(np.ma.masked_invalid([np.nan]))[0][:3]) * 255, GREY, atol=1)


def test_map_disks_of_a_periodic_packing_have_their_own_radius():
    """A jammed periodic packing (radii 0.5 and 0.7, 16 contacts across the seam): each disk is drawn with its
    radius, measured to q's copy across the seam (it was the distance to q's image, about the cell's width: DataSim's
    map drew disks 40 wide). Tolerance 10 % of r: the contact point sits midway through the overlap, which reaches
    ~13 % of r at the default φ = 0.90 (half of it ~6.5 %); the two radii differ by 0.2, far above it."""
    from granstab.scan.figure import particle_radii
    scene = packings.jammed(2, 32)
    assert np.any(scene.image != 0)
    r = particle_radii(scene)
    assert np.all(np.minimum(np.abs(r - 0.5), np.abs(r - 0.7)) <= 0.1 * r)


@pytest.mark.slow
def test_large_maps_are_rasterised_and_the_lambda_axis_fits_the_data(tmp_path):
    """A 2,601-disk map's SVG is under 1 MB (as vectors it was 1.7 MB, and 13.5 MB for 20,000 disks: issue 26); the
    λ_min histogram's axis spans the data within a factor 2 of its range (it was ±1000 × the scale for data within
    ±3) and names its scale."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from granstab.scan.figure import _lambda_histogram
    scan(packings.lattice(2, 50), tmp_path, centers="every:97", workers=1)
    assert (tmp_path / "map.svg").stat().st_size < 2 ** 20
    lam = np.r_[np.linspace(-3.0, -0.5, 50), np.linspace(0.1, 2.0, 30)] * 190.0
    captured = {}
    original = plt.Figure.savefig

    def keep(fig, *args, **kwargs):
        captured["xlim"] = fig.axes[0].get_xlim()
        captured["label"] = fig.axes[0].get_xlabel()
        return original(fig, *args, **kwargs)

    plt.Figure.savefig = keep
    try:
        _lambda_histogram(plt, lam, tmp_path)
    finally:
        plt.Figure.savefig = original
    low, high = captured["xlim"]
    assert low <= lam.min() and high >= lam.max() and high - low <= 2 * (lam.max() - lam.min())
    assert "median |λ_min|" in captured["label"]
