"""RigidLibrary readers on the real data (../shared/data/rigidlibrary): the annulus frame of
presets/annulus_frame.json is reproduced, DataSim's Lees–Edwards snapshot converts with its ≈540 sliding contacts."""

import numpy as np
from helpers import ROOT  # noqa: E402
from io_checks import check_contact_geometry

import granstab
from granstab.cli import main
from granstab.io import load

DATA = ROOT.parent / "shared" / "data"
ANNULUS = DATA / "rigidlibrary" / "DataAnnulus" / "10"
DATASIM = DATA / "rigidlibrary" / "DataSim"
FRAME = DATA / "annulus_frame.json"
ARRAYS = ("x", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "load", "load_moment", "k",
          "alpha", "mu")


def annulus_as_reference(**extra):
    ref = granstab.load_scene(FRAME)
    return ref, load(ANNULUS, frame=1, geometry="touching", outside_cone="elastic", length_scale=0.027, units="cm",
                     mu=0.3, region=list(ref.names), **extra)


def test_annulus_frame_1_gives_the_reference_cluster_and_spectrum():
    ref, imported = annulus_as_reference()
    s = imported.scene
    assert s.names == ref.names and np.array_equal(s.p, ref.p) and np.array_equal(s.q, ref.q)
    for key in ARRAYS:  # lengths ~10 cm, forces ~1e-2 N: agreement to round-off of the unit conversion
        a, b = getattr(s, key), getattr(ref, key)
        assert np.abs(a - b).max() <= 1e-13 * max(np.abs(b).max(), 1.0), key
    assert s.state == ref.state and s.state.count("elastic") == 10
    ours, theirs = granstab.analyze(s), granstab.analyze(ref)
    lam, lam_ref = ours.branches[0].stability_eigenvalues, theirs.branches[0].stability_eigenvalues
    assert np.abs(lam - lam_ref).max() <= 1e-12 * np.abs(lam_ref).max()
    assert ours.summary["verdict"] == theirs.summary["verdict"] == "unstable"
    rep = imported.report
    assert rep["frames_available"] == 20 and imported.frames == list(range(1, 21))
    assert rep["particles"] == {"in_file": 1781, "in_scene": 143, "outside_region": 1638,
                                "without_contacts_dropped": 0, "dropped": []}
    assert rep["duplicates"]["pairs_listed_twice"] == rep["contacts"]["in_file"] == 2447
    assert rep["duplicates"]["disagreeing_listings"] == 0
    # the photoelastic radii are nominal: centre distances from 0.92 to 1.34 of R_p + R_q (issue 9)
    ratio = rep["geometry"]["distance_over_sum_of_radii"]
    assert 0.91 < ratio["min"] < 0.93 and 1.33 < ratio["max"] < 1.35
    assert rep["walls"]["inner (edge −1)"] == 84 and rep["walls"]["outer (edge +1)"] == 149


def test_outside_cone_policies_on_the_annulus_frame():
    counts = {}
    for policy in ("sliding", "project", "elastic"):
        imp = load(ANNULUS, frame=1, geometry="touching", mu=0.3, outside_cone=policy)
        s, out = imp.scene, imp.report["cone"]["outside"]
        counts[policy] = out["count"]
        assert len(out["names"]) == out["count"] and out["policy"] == policy
        fn = -np.sum(s.force * s.normal, axis=1)
        ft = np.linalg.norm(s.tangential_force(), axis=1)
        over = ft > s.mu * fn * (1 + 1e-12)
        if policy == "elastic":   # forces kept: the named contacts stay outside, elastic
            assert over.sum() == out["count"] and all(np.asarray(s.state)[over] == "elastic")
        else:                     # projected exactly onto the cone
            assert not over.any()
            assert s.state.count("sliding" if policy == "sliding" else "elastic") == out["count"]
    # RigidLibrary's μ = 0.3 puts 6.5 % of this frame's contacts outside the cone
    assert len(set(counts.values())) == 1 and 150 < counts["sliding"] < 170


def test_error_policy_names_the_first_contact_outside(capsys):
    rc = main(["convert", str(ANNULUS), "--frame", "1", "--mu", "0.3", "--outside-cone", "error", "--out", "x.json"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and "outside the friction cone" in err and str(ANNULUS) in err


def test_convert_round_trips_to_the_same_arrays(tmp_path, capsys):
    out = tmp_path / "frame.json"
    rc = main(["convert", str(ANNULUS), "--frame", "2", "--geometry", "touching", "--length-scale", "0.027",
               "--units", "cm", "--mu", "0.3", "--out", str(out)])
    printed = capsys.readouterr().out
    assert rc == 0 and "outside" in printed and f"wrote {out}" in printed
    again = granstab.load_scene(out)
    direct = load(ANNULUS, frame=2, geometry="touching", length_scale=0.027, units="cm", mu=0.3).scene
    assert again.names == direct.names and again.state == direct.state
    for key in ARRAYS:  # JSON keeps doubles exactly; 2D curvature goes through κ = t·K·t (a few ulps)
        a, b = getattr(again, key), getattr(direct, key)
        assert np.abs(a - b).max() <= 4 * np.finfo(float).eps * np.abs(b).max(), key
    # load_scene and analyze accept the folder itself
    assert granstab.load_scene(ANNULUS).n_particles > 1000


def test_datasim_lees_edwards_snapshot():
    imp = load(DATASIM)
    s, rep = imp.scene, imp.report
    assert rep["frame"] == 5000 and rep["law"]["mu"] == {"value": 0.1, "source": "Parameters_final.dat mu"}
    assert rep["law"]["k"]["value"] == 1.0 and "k_rep" in rep["law"]["k"]["source"]
    assert rep["contacts"]["in_file"] == 1928 and rep["cone"]["at_yield"] == 541  # the file's mobilised flags
    assert rep["cone"]["outside"]["count"] == 0 and rep["forces"]["fn_nonpositive"]["count"] == 0
    raw = np.loadtxt(DATASIM / "Contact5000.dat")
    # normals and force magnitudes kept: f_n = −f·n as in the file
    rows = {(int(i), int(j)): r for r, (i, j) in enumerate(raw[:, :2])}
    pick = np.array([rows[(int(s.names[a]), int(s.names[b]))] for a, b in zip(s.p, s.q)])
    assert np.abs(s.normal - raw[pick, 2:4]).max() <= 1e-6
    assert np.abs(-np.sum(s.force * s.normal, 1) - raw[pick, 5]).max() <= 1e-12 * raw[:, 5].max()
    check_contact_geometry(s, np.loadtxt(DATASIM / "posinit.dat")[[int(n) for n in s.names], 3])
    # Hookean k_rep = 1: f_n = k δ with δ = R_p + R_q − d (the file's 6 digits)
    radius = np.loadtxt(DATASIM / "posinit.dat")[:, 3]
    d = np.linalg.norm(s.branch, axis=1)
    delta = radius[[int(n) for n in np.asarray(s.names)[s.p]]] + radius[[int(n) for n in np.asarray(s.names)[s.q]]] - d
    assert np.median(np.abs(-np.sum(s.force * s.normal, 1) / delta - 1)) < 1e-4
    # the periodic seam: every file contact is a scene contact (tests/io/test_io_periodic.py checks the images);
    # all sliding ones at yield exactly
    assert rep["contacts"]["in_scene"] == 1928 and rep["periodic"]["contacts_cut"] == 0
    sliding = np.asarray(s.state) == "sliding"
    assert np.abs(s.yield_function()[sliding]).max() <= 1e-12 * np.abs(s.force).max()
    assert rep["imbalance"]["moment"]["median"] < 1e-3


def test_datasim_imbalance_statistics_match_a_direct_sum():
    imp = load(DATASIM, keep_rattlers=True)
    raw = np.loadtxt(DATASIM / "Contact5000.dat")
    i, j = raw[:, 0].astype(int), raw[:, 1].astype(int)
    n = raw[:, 2:4] / np.linalg.norm(raw[:, 2:4], axis=1)[:, None]  # six digits: renormalised
    t = np.stack([-n[:, 1], n[:, 0]], 1)
    f = -raw[:, 5:6] * n + raw[:, 6:7] * t
    net = np.zeros((1024, 2))
    size = np.zeros(1024)
    for side, sign in ((i, 1), (j, -1)):
        np.add.at(net, side, sign * f)
        np.add.at(size, side, np.linalg.norm(f, axis=1))
    ratio = np.linalg.norm(net, axis=1)[size > 0] / size[size > 0]
    got = imp.report["imbalance"]["force"]
    assert np.isclose(got["median"], np.median(ratio), rtol=1e-12)
    assert np.isclose(got["p95"], np.percentile(ratio, 95), rtol=1e-12)
    assert np.isclose(got["max"], ratio.max(), rtol=1e-12)
    # RigidLibrary's tangential sign balances the forces; the opposite sign would not (moment balance about the
    # centres cannot tell: flipping every f_t flips every disk's torque)
    flipped = -raw[:, 5:6] * n - raw[:, 6:7] * t
    net = np.zeros((1024, 2))
    for side, sign in ((i, 1), (j, -1)):
        np.add.at(net, side, sign * flipped)
    assert np.median(np.linalg.norm(net, axis=1)[size > 0] / size[size > 0]) > 100 * got["median"]
    assert imp.report["imbalance"]["moment"]["median"] < 1e-3
