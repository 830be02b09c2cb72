"""granstab track (issue 27): frame sequences, D²min, contact changes, events, resume; each frame's row equals the
analyses of that frame taken alone."""
import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from helpers import DATA, ROOT  # noqa: E402

import granstab
from granstab.cli import main
from granstab.model.errors import Interrupted
from granstab.model.packings import lattice
from granstab.model.scene import SceneError
from granstab.track import track
from granstab.track.motion import d2min

ANNULUS = ROOT.parent / "shared" / "data" / "rigidlibrary" / "DataAnnulus" / "10"
F = np.array([[1.02, 0.05], [0.01, 0.97]])      # an affine deformation of the whole packing
DELTA = np.array([0.03, -0.02])                 # and one particle displaced beyond it


def square(n: int, spacing: float = 1.0) -> np.ndarray:
    return np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2) * spacing


# ------------------------------------------------------------------------------------------------ D²min by hand

def test_d2min_of_an_affine_motion_plus_one_displaced_particle():
    """A square lattice (spacing 1, neighbours within 1.05: the 4 nearest, A = Σ Δr Δrᵀ = 2I at interior sites)
    deformed by F, one interior particle k also moved by δ: D²min_k = 4|δ|² (its neighbours' Δr sum to zero, so the
    best X is F and each of the 4 bonds keeps δ); a neighbour i of k: min_Y Σ_j |δ[j=k] − Y Δr_j|² =
    |δ|²(1 − Δr_kᵀ A⁻¹ Δr_k) = |δ|²/2; every particle farther from k: 0."""
    x0 = square(7)
    x1 = x0 @ F.T
    k = 3 * 7 + 3
    x1[k] += DELTA
    got = d2min(x0, x1, np.ones(len(x0), bool), 1.05)
    d2 = DELTA @ DELTA
    near = np.flatnonzero(np.isclose(np.linalg.norm(x0 - x0[k], axis=1), 1.0))
    interior = np.all((x0 > 0) & (x0 < 6), axis=1)
    far = interior & (np.linalg.norm(x0 - x0[k], axis=1) > 1.5)
    # tolerance: a few ulps of the squared bond length (1) times the bonds summed
    assert got[k] == pytest.approx(4 * d2, rel=1e-12)
    assert np.allclose(got[near], d2 / 2, rtol=1e-12)
    assert np.all(np.abs(got[far]) < 1e-24)
    # a corner site has 2 neighbours, A of rank 2: defined; absent particles: NaN
    present = np.ones(len(x0), bool)
    present[0] = False
    assert np.isnan(d2min(x0, x1, present, 1.05)[0])


def test_d2min_through_a_lees_edwards_seam_with_the_cell_changing():
    """A periodic 8×8 lattice sheared affinely by γ across frames, the cell's second lattice vector tilting with it
    (Lees–Edwards) and the positions wrapped back into the box: every pair that crosses the seam keeps its vector,
    so D²min is 0 everywhere but around the one displaced particle (4|δ|² there)."""
    L, gamma = 8.0, 0.1
    x0 = square(8) + 0.5
    cell0, cell1 = np.diag([L, L]), np.array([[L, 0.0], [gamma * L, L]])
    shear = np.array([[1.0, gamma], [0.0, 1.0]])
    x1 = x0 @ shear.T
    k = 0                                                # a corner site: its bonds cross both seams
    x1[k] += DELTA
    x1[:, 0] %= L                                        # wrapped, as a dump writes them
    got = d2min(x0, x1, np.ones(len(x0), bool), 1.05, cell0, cell1)
    d2 = DELTA @ DELTA
    assert got[k] == pytest.approx(4 * d2, rel=1e-9)
    others = np.linalg.norm(((x0 - x0[k] + L / 2) % L) - L / 2, axis=1) > 1.5
    assert np.all(np.abs(got[others]) < 1e-20)


# ------------------------------------------------------------------------------------------------ a tiny sequence

RATTLER = 100


def write_sequence(folder: Path) -> list[Path]:
    """Three frames of a 4×4 lattice (16 disks, 24 contacts, 3 sliding) and a small rattler (no contact) in its
    top-right cell, as generic tables with a frame column. Frame 2: positions deformed by F and particle p05
    moved by δ; contact p05–p06 broken and p00–p05 made. Frame 3: as frame 2 with p05–p06 made again."""
    s = lattice(2, size=4, kind="square", n_sliding=3, mu=0.5)
    ids = np.arange(1, 17)
    x = np.vstack([s.x, s.x[[10, 11, 14, 15]].mean(axis=0)])
    radius = np.r_[np.ones(16), 0.2]
    every = np.r_[ids, RATTLER]
    pairs = [(int(ids[a]), int(ids[b]), f) for a, b, f in zip(s.p, s.q, s.force)]
    dropped = [c for c in pairs if {c[0], c[1]} == {6, 7}]
    changed = [c for c in pairs if {c[0], c[1]} != {6, 7}] + [(1, 6, np.array([0.0, -1e-3]))]
    moved = x @ F.T
    moved[5] += DELTA
    prow, crow = [], []
    for frame, (pos, contacts) in enumerate([(x, pairs), (moved, changed), (moved, changed + dropped)], 1):
        prow += [(frame, i, *xy, r) for i, xy, r in zip(every, pos, radius)]
        crow += [(frame, a, b, *f) for a, b, f in contacts]
    paths = [folder / "particles.csv", folder / "contacts.csv"]
    np.savetxt(paths[0], prow, delimiter=",", header="frame,id,x,y,radius", comments="")
    np.savetxt(paths[1], crow, delimiter=",", header="frame,id1,id2,fx,fy", comments="")
    return paths


@pytest.fixture(scope="module")
def tracked(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sequence")
    paths = write_sequence(folder)
    summary = track(paths, folder / "out", mu=0.5, whole=True, scan=True, rigidity=True, workers=1,
                    figures=False, d2min_radius=2.1)
    frames = pq.read_table(folder / "out" / "frames.parquet").to_pydict()
    particles = pq.read_table(folder / "out" / "particles.parquet").to_pydict()
    return paths, folder / "out", summary, frames, particles


def column(particles: dict, frame: int, name: str) -> dict:
    rows = [i for i, f in enumerate(particles["frame"]) if f == frame]
    return {particles["name"][i]: particles[name][i] for i in rows}


def test_contacts_made_broken_and_slid_on_a_hand_made_sequence(tracked):
    _, _, summary, frames, particles = tracked
    first = column(particles, 0, "contacts_changed")
    assert first["6"] == 2 and first["7"] == 1 and first["1"] == 1                  # p05–p06 broken, p00–p05 made
    assert sum(first.values()) == 4
    second = column(particles, 1, "contacts_changed")
    assert second["6"] == 1 and second["7"] == 1 and sum(second.values()) == 2      # p05–p06 made again
    assert all(np.isnan(v) for v in column(particles, 2, "contacts_changed").values())   # no frame after the last
    assert frames["n_made"][:2] == [1, 1] and frames["n_broken"][:2] == [1, 0] and np.isnan(frames["n_made"][2])
    paths = tracked[0]
    before = granstab.load(paths, frame=1.0, mu=0.5).scene
    after = granstab.load(paths, frame=2.0, mu=0.5).scene     # at yield as frame 2 is read (its normals turned)
    sliding = {frozenset((after.names[a], after.names[b])) for a, b, on in zip(after.p, after.q, after.at_yield())
               if on}
    slid = dict.fromkeys(before.names, 0)
    for a, b in zip(before.p, before.q):                      # frame 1's contacts still there and sliding at 2
        if frozenset((before.names[a], before.names[b])) in sliding:
            slid[before.names[a]] += 1
            slid[before.names[b]] += 1
    got = column(particles, 0, "contacts_slid")
    assert 0 < sum(slid.values()) and all(got[n] == v for n, v in slid.items()) and got[str(RATTLER)] == 0
    assert column(particles, 0, "rattler")[str(RATTLER)] is True and frames["n_rattlers"] == [1, 1, 1]


def test_d2min_of_the_sequence_is_the_closed_form(tracked):
    """Frame 1 → 2: every particle moved by F, p05 (id 6, interior, 4 lattice neighbours within 2.1) also by δ:
    D²min = 4|δ|², its interior neighbours |δ|²(1 − Δr_kᵀ A⁻¹ Δr_k) = |δ|²/2 (A = 2 s² I, s the spacing), its
    edge neighbours 0, the particles with no bond to it 0. Frame 2 → 3: no motion, D²min 0."""
    _, _, _, _, particles = tracked
    d = column(particles, 0, "d2min")
    d2 = DELTA @ DELTA
    assert d["6"] == pytest.approx(4 * d2, rel=1e-9)
    for j in ("7", "10"):                     # interior neighbours: A = 2 s² I
        assert d[j] == pytest.approx(d2 / 2, rel=1e-9)
    for j in ("2", "5"):                      # edge neighbours: A = s² diag(1, 2) or diag(2, 1) and their bond to
        assert abs(d[j]) < 1e-20              # k the only one along it: Δr_kᵀ A⁻¹ Δr_k = 1, D²min 0
    assert abs(d["16"]) < 1e-20 and abs(d["12"]) < 1e-20
    assert np.nanmax(np.abs(list(column(particles, 1, "d2min").values()))) < 1e-20


def test_stress_from_the_contacts_is_the_hand_sum(tracked):
    """σ = (1/V) Σ_c f^pq ⊗ (x^q − x^p) by a loop over the contact table; V the convex hull of the centres: the
    lattice's square of side 3 s (the rattler lies inside)."""
    paths, _, _, frames, _ = tracked
    parts = np.loadtxt(paths[0], delimiter=",", skiprows=1)
    contacts = np.loadtxt(paths[1], delimiter=",", skiprows=1)
    at = {(int(r[0]), int(r[1])): r[2:4] for r in parts}
    sigma = np.zeros((2, 2))
    for _, a, b, fx, fy in contacts[contacts[:, 0] == 1]:
        sigma += np.outer([fx, fy], at[(1, int(b))] - at[(1, int(a))])
    s = 1.999
    sigma /= (3 * s) ** 2
    assert np.allclose(np.reshape(frames["stress"][0], (2, 2)), sigma, rtol=1e-12, atol=1e-15 * np.abs(sigma).max())
    assert frames["pressure"][0] == pytest.approx(-np.trace(sigma) / 2, rel=1e-12)
    assert frames["z"][0] == pytest.approx(2 * 24 / 16)


def test_each_frame_row_equals_the_analyses_of_that_frame_alone(tracked, tmp_path):
    """--whole, --scan and --rigidity of frame k are analyze, scan and rigidity of `load(..., frame=k)` with the
    same import options (which drops the rattler, as track's analyses do)."""
    from granstab.rigidity import largest_rigid_cluster, rigidity
    from granstab.scan import read_map, scan
    from granstab.solve.threads import blas_threads
    from granstab.track.frame import WHOLE
    paths, _, summary, frames, particles = tracked
    for position, step in zip(summary["positions"], summary["steps"]):
        scene = granstab.load(paths, frame=step, mu=0.5).scene
        res = granstab.analyze(scene, k=6, **WHOLE)
        for name, sign in (("unloading", -1), ("loading", 1)):
            branch = [b for b in res.branches if np.all(b.mask[scene.at_yield()] == sign)][0]
            assert frames[f"lambda_min_{name}"][position] == branch.stability_eigenvalues[branch.codes != 3].min()
        out = scan(scene, tmp_path / f"scan{position}", workers=1, figures=False)
        alone = dict(zip(read_map(out_dir := tmp_path / f"scan{position}")["particles"]["name"],
                         read_map(out_dir)["particles"]["unstable_fraction"]))
        got = column(particles, position, "unstable_fraction")
        assert all(got[n] == v or (np.isnan(got[n]) and np.isnan(v)) for n, v in alone.items())
        assert np.isnan(got[str(RATTLER)])
        assert frames["scan_clusters"][position] == out["clusters"]
        with blas_threads(1):                           # as track runs it (the SVDs of a 16-disk frame take
            largest = largest_rigid_cluster(rigidity(scene))   # seconds with BLAS threads on a busy machine)
        assert frames["rigid_largest_particles"][position] == largest["size_particles"]
        assert frames["n_contacts"][position] == scene.n_contacts and frames["n_particles"][position] == 17


def test_the_whole_stage_examines_two_branches_without_uniqueness_and_its_row_is_unchanged(tracked, monkeypatch):
    """--whole needs the stability of the all-unloading and all-loading branches only: two branches, one metric,
    no ℍ^i (its eig, the costly half on 300 spheres, never runs), and the row and the soft-spot shares are those
    the same stage gives with ℍ^i evaluated (the options before it was left out)."""
    from granstab.track import frame
    paths = tracked[0]
    scene = granstab.load(paths, frame=2.0, mu=0.5).scene
    assert scene.at_yield().sum() == 2                                 # 2^2 = 4 branches if all were enumerated
    monkeypatch.setitem(frame.WHOLE, "uniqueness", True)
    row_u, share_u = frame.whole(scene, 5)
    monkeypatch.setitem(frame.WHOLE, "uniqueness", False)
    examined = []
    monkeypatch.setattr(np.linalg, "eig", lambda *a: pytest.fail("ℍ^i's eig ran in the whole stage"))
    res = granstab.analyze(scene, k=6, on_branch=examined.append, **frame.WHOLE)
    assert len(examined) == 2 and res.cost["metrics"] == 1 and res.cost["paths"] == {"full": 2}
    assert {tuple(np.unique(b.mask[scene.at_yield()])) for b in examined} == {(-1,), (1,)}
    assert all(b.uniqueness_n_zero == -1 for b in examined) and res.attribution is None
    row, share = frame.whole(scene, 5)
    assert row.keys() == row_u.keys()
    for key, value in row.items():
        if key.startswith("lambda_min"):       # the same eigh of the same 48 × 48 matrix: round-off (1e-12 relative)
            assert value == pytest.approx(row_u[key], rel=1e-12, abs=1e-12 * abs(row_u["lambda_min_loading"]))
        else:
            assert value == row_u[key]
    assert share.keys() == share_u.keys() == {"soft_participation", "soft_spots_branch", "soft_spots_frictionless"}
    for name in share:                                                 # unit-normalised shares: round-off of the modes
        assert np.allclose(share[name], share_u[name], rtol=1e-9, atol=1e-12), name


def test_resume_after_an_interruption(tmp_path, monkeypatch):
    """Ctrl-C in the second frame: one line saying 1 of 3 frames is kept; the same call then does only the rest
    and writes the same tables as an uninterrupted run."""
    import granstab.track.run as run
    paths = write_sequence(tmp_path)
    real, calls = run.frame_task, []

    def stop_at_second(spec, position, key):
        calls.append(position)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(spec, position, key)

    monkeypatch.setattr(run, "frame_task", stop_at_second)
    with pytest.raises(Interrupted, match="1 of 3 frames kept"):
        track(paths, tmp_path / "out", mu=0.5, workers=1, figures=False)
    monkeypatch.setattr(run, "frame_task", real)
    summary = track(paths, tmp_path / "out", mu=0.5, workers=1, figures=False)
    assert summary["cost"]["resumed"] == 1 and summary["cost"]["frames_this_run"] == 2
    again = track(paths, tmp_path / "fresh", mu=0.5, workers=1, figures=False)
    a = pq.read_table(tmp_path / "out" / "particles.parquet").to_pydict()
    b = pq.read_table(tmp_path / "fresh" / "particles.parquet").to_pydict()
    assert a.keys() == b.keys() and again["cost"]["resumed"] == 0
    for key in a:                                        # NaN where both are NaN (the last frame's d2min)
        np.testing.assert_array_equal(np.asarray(a[key]), np.asarray(b[key]), err_msg=key)
    with pytest.raises(SceneError, match="other options"):
        track(paths, tmp_path / "out", mu=0.3, workers=1, figures=False)


def test_events_are_stress_drops_over_the_threshold():
    from granstab.track.quantities import stress_drops
    events, mean = stress_drops(np.array([1.0, 1.1, 0.8, 0.79, 1.3]), np.arange(5), "shear_stress", 0.05)
    assert mean == pytest.approx(np.mean([1.0, 1.1, 0.8, 0.79, 1.3]))
    assert [(e["frame"], e["next_frame"]) for e in events] == [(1, 2)]        # 0.01 is under 0.05 × 0.998
    assert events[0]["drop"] == pytest.approx(0.3) and events[0]["relative_drop"] == pytest.approx(0.3 / mean)


def test_the_annulus_experiment_reads_as_a_sequence(tmp_path, capsys):
    """Its 20 frames are listed; --frames 0:20:19 tracks the first and the last, each row as that frame read
    alone."""
    assert granstab.io.frames(ANNULUS, mu=0.5) == list(range(1, 21))
    assert main(["track", str(ANNULUS), "--out", str(tmp_path), "--mu", "0.5", "--frames", "0:20:19",
                 "--workers", "1", "--no-figures"]) == 0
    assert "2 frames" in capsys.readouterr().out
    frames = pq.read_table(tmp_path / "frames.parquet").to_pydict()
    assert frames["frame"] == [0, 19] and frames["step"] == [1.0, 20.0]
    last = granstab.load(ANNULUS, frame=20, mu=0.5, keep_rattlers=True)
    assert frames["n_contacts"][1] == last.scene.n_contacts and frames["n_particles"][1] == last.scene.n_particles
    events = json.loads((tmp_path / "events.json").read_text())
    assert isinstance(events, list)


def test_cli_refuses_frame_and_bad_selections(tmp_path, capsys):
    paths = [str(p) for p in write_sequence(tmp_path)]
    assert main(["track", *paths, "--out", str(tmp_path / "o"), "--frame", "1"]) == 2
    assert capsys.readouterr().err.strip().startswith("--frame: track reads every frame")
    assert main(["track", *paths, "--out", str(tmp_path / "o"), "--mu", "0.5", "--frames", "5:9"]) == 2
    assert "--frames: " in (err := capsys.readouterr().err) and "has no frame 5:9 (its frames: " in err


LAMMPS = DATA / "io" / "lammps"
DATASIM = ANNULUS.parents[1] / "DataSim"


def test_a_periodic_lammps_run_is_a_sequence_with_its_cell_stress(tmp_path):
    """The 2D LAMMPS fixture (two timesteps of a sheared periodic box): both are tracked in order, and σ is the
    hand sum Σ f ⊗ b / det(cell), b the branch vector to q's image (the seam contacts' images counted)."""
    paths = [LAMMPS / "atoms2d.dump", LAMMPS / "contacts2d.dump", ROOT / "examples" / "dem"
             / "in.disks2d"]
    assert granstab.io.frames(paths) == [18000, 21000]
    summary = track(paths, tmp_path, workers=1, figures=False)
    frames = pq.read_table(tmp_path / "frames.parquet").to_pydict()
    assert summary["steps"] == [18000.0, 21000.0] and frames["frame"] == [0, 1]
    scene = granstab.load(paths, timestep=21000, keep_rattlers=True).scene
    sigma = sum(np.outer(f, scene.x[q] + image @ scene.cell - scene.x[p])
                for f, p, q, image in zip(scene.force, scene.p, scene.q, scene.image)) / np.linalg.det(scene.cell)
    got = np.reshape(frames["stress"][1], (2, 2))
    assert np.abs(got - sigma).max() <= 1e-12 * np.abs(sigma).max()     # summation order only
    assert frames["volume_from"][1].startswith("the periodic cell") and len(frames["cell"][1]) == 4
    d2 = pq.read_table(tmp_path / "particles.parquet").to_pydict()["d2min"]
    assert np.isfinite(d2[:frames["n_particles"][0]]).mean() > 0.9    # matched by id through the seam


def test_mercury_and_datasim_inputs_list_their_frames(tmp_path):
    from test_io_mercury import table_scene, write_mercury
    ref = table_scene().scene
    steps = [(0.5, ref.x + 1.0, np.ones(3), ref.p, ref.q, ref.force * 2, []),
             (1.0, ref.x, np.ones(3), ref.p, ref.q, ref.force, [])]
    files = write_mercury(tmp_path / "run", steps)
    assert granstab.io.frames(files, k=2.0, alpha=0.5, mu=0.4) == [0.5, 1.0]
    track(files, tmp_path / "out", k=2.0, alpha=0.5, mu=0.4, workers=1, figures=False)
    frames = pq.read_table(tmp_path / "out" / "frames.parquet").to_pydict()
    assert frames["step"] == [0.5, 1.0] and frames["n_contacts"] == [ref.n_contacts] * 2
    d2 = pq.read_table(tmp_path / "out" / "particles.parquet").to_pydict()["d2min"]
    assert np.allclose(d2[:3], 0.0, atol=1e-20)      # a rigid translation by (1, 1): no non-affine motion
    assert granstab.io.frames(DATASIM) == [5000]


def test_a_scene_file_is_a_sequence_of_one_frame(tmp_path, capsys):
    preset = ROOT / "presets" / "two_particle.toml"
    assert main(["track", str(preset), "--out", str(tmp_path), "--workers", "1", "--no-figures", "--predict"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("1 frames") and "predict: " in out          # said whether the prediction ran
    frames = pq.read_table(tmp_path / "frames.parquet").to_pydict()
    assert frames["frame"] == [0] and np.isnan(frames["step"][0]) and np.isnan(frames["n_made"][0])


def test_a_cluster_without_lambda_min_does_not_hide_its_members_lowest(monkeypatch, tmp_path):
    """scan_map's per-particle lowest λ_min over the clusters containing it: a cluster whose λ_min is NaN (an error
    row, or no analysis) is skipped, not spread over its members (np.minimum.at would make every member NaN)."""
    import granstab.scan as scan_room
    from granstab.track.frame import scan_map

    core = lattice(2, 3)                     # 9 particles; the map below is made up, the scan is not run
    clusters = {"members": [np.array([0, 1, 2]), np.array([1, 2, 3]), np.array([4])],
                "lambda_min": np.array([0.5, np.nan, np.nan]), "verdict": np.array(["stable", "error", "error"]),
                "mechanism": np.array(["", "", ""])}
    monkeypatch.setattr(scan_room, "scan", lambda *a, **k: None)
    monkeypatch.setattr(scan_room, "read_map", lambda folder: {
        "clusters": clusters, "particles": {"unstable_fraction": np.zeros(9)}, "summary": {"verdicts": {}}})
    lam = scan_map(core, tmp_path, {})[1]["cluster_lambda_min"]
    assert np.array_equal(lam, [0.5, 0.5, 0.5, np.nan, np.nan, *[np.nan] * 4], equal_nan=True)

