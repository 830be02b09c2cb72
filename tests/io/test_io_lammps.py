"""LAMMPS dumps (per-atom + pair/local contact dump + input script) on fixtures cut from examples/dem's run:
a corner of the periodic cell, so that contacts wrap around both boundaries (examples/dem/cut_fixture.py)."""
import io
import re

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402
from io_checks import check_contact_geometry, with_atom_columns

import granstab
from granstab.cli import main
from granstab.io import load

DATA = DATA / "io" / "lammps"
SCRIPT2, SCRIPT3 = ROOT / "examples" / "dem" / "in.disks2d", ROOT / "examples" / "dem" / "in.spheres3d"
COLUMNS = "id1,id2,fnx,fny,fnz,ftx,fty,ftz,delx,dely,delz"


def inputs(dim):
    return [DATA / f"atoms{dim}d.dump", DATA / f"contacts{dim}d.dump", SCRIPT2 if dim == 2 else SCRIPT3]


def raw_block(path, step):
    """The rows of one timestep, read independently of granstab (plain text split)."""
    text = path.read_text()
    block = text.split(f"ITEM: TIMESTEP\n{step}\n")[1].split("ITEM: TIMESTEP")[0]
    return np.loadtxt(io.StringIO(block.split("\n", 7)[7]), ndmin=2)


@pytest.mark.parametrize("dim,step", [(2, 18000), (3, 12000)])
def test_sheared_snapshot_matches_the_dump(dim, step):
    imp = load(inputs(dim), timestep=step)
    s, rep = imp.scene, imp.report
    assert s.dim == dim and rep["dimension"] == dim and rep["frame"] == step
    law = rep["law"]
    assert (law["k"]["value"], law["alpha"]["value"], law["mu"]["value"]) == (1000.0, 0.5, 0.5)
    assert all("pair_coeff" in v["source"] for v in law.values())
    atoms = raw_block(inputs(dim)[0], step)
    local = raw_block(inputs(dim)[1], step)
    radius_of = dict(zip(atoms[:, 0].astype(int), atoms[:, 5]))
    names = np.array(s.names).astype(int)
    radius = np.array([radius_of[n] for n in names])
    _, tension = check_contact_geometry(s, radius)
    assert tension.sum() <= rep["forces"]["fn_nonpositive"]["count"] < 0.01 * rep["contacts"]["in_file"]
    # every contact: the dump's branch vector x_1 − x_2 (p10-p12, minimum image) is x_p minus q's copy
    # x_q + image @ cell of the periodic scene (the images: LAMMPS's own); the force is the normal part (fx fy fz)
    # plus the tangential part (p1 p2 p3) on id1
    assert s.cell is not None and rep["periodic"]["periodic"]
    rows = {(int(a), int(b)): r for r, (a, b) in enumerate(local[:, :2])}
    pick = np.array([rows[(names[a], names[b])] for a, b in zip(s.p, s.q)])
    err = np.abs((s.x[s.p] - s.q_copy) - local[pick, 8:8 + dim]).max(axis=1)
    # 12 digits in the dump; pairs across the sheared boundary: LAMMPS's ghost atoms carry the tilt of the step
    # before (the tilt grows by 0.748/3000 in 2D, 0.23/2000 in 3D, a step)
    tilt_step = 0.748 / 3000 if dim == 2 else 0.23 / 2000
    assert np.percentile(err, 80) <= 1e-9 and err.max() <= 1.01 * tilt_step
    f_file = local[pick, 2:2 + dim] + local[pick, 5:5 + dim]
    fn = -np.sum(s.force * s.normal, 1)
    assert np.abs(fn + np.sum(f_file * s.normal, 1)).max() <= 1e-12 * np.abs(fn).max()
    moved = np.linalg.norm(s.force - f_file, axis=1) / np.linalg.norm(f_file, axis=1)
    sliding = np.asarray(s.state) == "sliding"
    assert moved[~sliding].max() <= 1e-15 and moved[sliding].max() <= rep["cone"]["yield_rtol"] * 10
    # Hookean k_n = 1000: f_n = k δ up to the dashpot (20 · m_eff · v_n, small in a quasi-static shear)
    delta = radius[s.p] + radius[s.q] - np.linalg.norm(s.x[s.q] - s.x[s.p], axis=1)
    assert np.median(np.abs(fn / (1000.0 * delta) - 1)) < 1e-2
    # non-touching neighbour pairs are dropped by overlap, and all had zero force
    touching_rows = len(local) - rep["non_touching_pairs"]["count"]
    assert touching_rows == rep["contacts"]["in_file"] and rep["non_touching_pairs"]["with_force"] == 0
    # every dump row is a scene contact or a non-touching neighbour pair: none is cut at the seam
    assert rep["contacts"]["cut_around_periodic_cell"] == 0 and rep["periodic"]["contacts_cut"] == 0
    assert len(local) == len(pick) + rep["non_touching_pairs"]["count"]
    assert rep["periodic"]["seam_contacts"] == int(np.sum(np.any(s.image != 0, axis=1))) > 0
    # the fixture's corner wraps around the cell: some contacts join atoms dumped on opposite sides
    position_of = dict(zip(atoms[:, 0].astype(int), atoms[:, 2:2 + dim]))
    raw = np.array([position_of[a] - position_of[b] for a, b in local[pick, :2].astype(int)])
    assert np.sum(np.abs(raw).max(axis=1) > 5.0) >= 5
    assert rep["cone"]["at_yield"] > 0                        # the shear mobilised some contacts


def test_timesteps_default_to_the_last_and_are_listed():
    imp = load(inputs(2))
    assert imp.frames == [18000, 21000] and imp.report["frame"] == 21000


def test_columns_instead_of_the_script_give_the_same_contacts():
    with_script = load(inputs(2), timestep=18000).scene
    named = load(inputs(2)[:2], timestep=18000, columns=COLUMNS, k=1000, alpha=0.5, mu=0.5)
    assert named.report["law"]["k"]["source"] == "command line"
    s = named.scene
    assert s.names == with_script.names and s.state == with_script.state
    for key in ("x", "point", "normal", "force", "curvature_p", "k", "alpha", "mu", "load"):
        assert np.array_equal(getattr(s, key), getattr(with_script, key)), key


def test_without_script_or_columns_the_local_columns_are_ambiguous(capsys):
    rc = main(["convert", *map(str, inputs(2)[:2]), "--out", "x.json"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "contacts2d.dump: line 284: c_ends[1]: ambiguous column" in err and "--columns" in err


def test_convert_round_trip_3d(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert main(["convert", *map(str, inputs(3)), "--timestep", "12000", "--out", str(out)]) == 0
    assert "lammps" in capsys.readouterr().out
    again, direct = granstab.load_scene(out), load(inputs(3), timestep=12000).scene
    assert again.names == direct.names and again.state == direct.state
    for key in ("x", "point", "normal", "curvature_p", "curvature_q", "force", "load", "k", "alpha", "mu"):
        a, b = getattr(again, key), getattr(direct, key)
        assert np.abs(a - b).max() <= 4 * np.finfo(float).eps * max(np.abs(b).max(), 1.0), key


def test_length_scale_scales_lengths_and_the_files_stiffness():
    base = load(inputs(2), timestep=18000)
    mm = load(inputs(2), timestep=18000, length_scale=1e-3, units="mm")
    box = 38.2e-3  # positions are unwrapped by whole cells: round-off relative to the cell
    assert np.abs(mm.scene.x - 1e-3 * base.scene.x).max() <= 8 * np.finfo(float).eps * box
    assert np.allclose(mm.scene.k, 1e3 * base.scene.k, rtol=1e-15)     # force per length: N/file unit → N/mm
    # forces unchanged (those put on the cone move with the normal's round-off only)
    assert np.abs(mm.scene.force - base.scene.force).max() <= 1e-12 * np.abs(base.scene.force).max()
    assert mm.report["units"]["length"] == "mm"


def test_hertz_law_is_the_tangent_stiffness_at_the_overlap(tmp_path):
    script = tmp_path / "in.hertz"
    script.write_text(SCRIPT2.read_text().replace("hooke ${kn} 20.0 tangential linear_history",
                                                  "hertz ${kn} 20.0 tangential mindlin"))
    imp = load([*inputs(2)[:2], script], timestep=18000)
    s = imp.scene
    names = np.array(s.names).astype(int)
    atoms = raw_block(inputs(2)[0], 18000)
    radius_of = dict(zip(atoms[:, 0].astype(int), atoms[:, 5]))
    r = np.array([radius_of[n] for n in names])
    delta = r[s.p] + r[s.q] - np.linalg.norm(s.branch, axis=1)
    a = np.sqrt(r[s.p] * r[s.q] / (r[s.p] + r[s.q]) * delta)
    # F = k_n a δ: dF/dδ by a central difference of the closed form, against the reader's k
    h = 1e-6 * delta
    force = lambda dd: 1000.0 * np.sqrt(r[s.p] * r[s.q] / (r[s.p] + r[s.q]) * dd) * dd  # noqa: E731
    assert np.allclose(s.k, (force(delta + h) - force(delta - h)) / (2 * h), rtol=1e-8)
    assert np.allclose(s.alpha, 500.0 * a / s.k, rtol=1e-12)             # mindlin: k_t a over k
    assert "1.5 k_n a" in imp.report["law"]["k"]["source"]


def test_region_box_and_ids(tmp_path):
    imp = load(inputs(2), timestep=18000, region="box:0,6,0,6")
    assert np.all(imp.scene.x <= 6 + 1e-9) and imp.report["contacts"]["cut_by_region"] > 0
    ids = tmp_path / "ids.txt"
    ids.write_text(" ".join(imp.scene.names[:5]))
    again = load(inputs(2), timestep=18000, region=f"ids:@{ids}")
    assert set(again.scene.names) <= set(imp.scene.names[:5])


def test_analyse_the_2d_fixture_dense_and_the_3d_fixture_sparse():
    """The fixtures are a corner of the cell: analysed as clusters (--no-periodic: seam contacts cut)."""
    s2 = load(inputs(2), timestep=21000, periodic=False).scene
    r2 = granstab.analyze(s2, method="dense")
    assert max(r2.errors.values()) <= 1e-10 and len(r2.branches) == 2 ** r2.to_dict()["n_sliding"]
    s3 = load(inputs(3), timestep=14000, periodic=False).scene
    r3 = granstab.analyze(s3, method="sparse", k=4)
    assert any(w.startswith("sparse path") for w in r3.to_dict()["warnings"]) and max(r3.errors.values()) <= 1e-10


def with_mass_column(src, dst, mass_of_radius):
    """The atom dump with a `mass` column appended (written here, independently of granstab's reader)."""
    return with_atom_columns(src, dst, ["mass"], lambda row: [mass_of_radius(row["radius"])])


def test_masses_from_the_file_or_a_density_give_the_inertia_metric(tmp_path, capsys):
    plain = load(inputs(2), timestep=21000).scene
    assert plain.mass is None                                    # nothing invented
    with pytest.raises(granstab.SceneError, match="mass"):
        granstab.analyze(plain, metric="inertia")
    atoms = with_mass_column(inputs(2)[0], tmp_path / "atoms.dump", lambda r: 3.0 * np.pi * r**2)
    filed = load([atoms, *inputs(2)[1:]], timestep=21000)
    dense = load(inputs(2), timestep=21000, density=3.0)
    R = raw_block(inputs(2)[0], 21000)
    radius = dict(zip(R[:, 0].astype(int), R[:, 5]))[int(plain.names[0])]
    for imp in (filed, dense):
        s = imp.scene
        assert s.names == plain.names
        assert s.mass[0] == pytest.approx(3.0 * np.pi * radius**2, rel=1e-15)
        assert s.inertia[0, 0, 0] == pytest.approx(0.5 * s.mass[0] * radius**2, rel=1e-15)   # solid disk
    assert "file's masses" in filed.report["masses"] and "density 3" in dense.report["masses"]
    a, b = (granstab.analyze(imp.scene, metric="inertia", method="dense") for imp in (filed, dense))
    lam_a, lam_b = a.branches[0].stability_eigenvalues, b.branches[0].stability_eigenvalues
    assert np.abs(lam_a - lam_b).max() <= 1e-9 * np.abs(lam_b).max()   # masses printed to 17 digits
    bad = with_mass_column(inputs(2)[0], tmp_path / "bad.dump", lambda r: 0.0)
    assert main(["convert", str(bad), *map(str, inputs(2)[1:]), "--out", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.dump: line" in err and "mass: must be a positive number" in err


ROLLING = [DATA / "atoms3d_rolling.dump", DATA / "contacts3d_rolling.dump",
           ROOT / "examples" / "dem" / "in.spheres3d_rolling"]
NO_ROLLING_COLUMNS = COLUMNS + ",-,-,-"   # the same dump with the rolling resistance columns (p5 p6 p7) ignored


def torque_closure(scene, atoms):
    """Per scene particle: |Σ (r × f + m) − LAMMPS's own torque (tqx tqy tqz)| over Σ(|r||f| + |m|)."""
    row = {int(i): k for k, i in enumerate(atoms[:, 0])}
    tq = atoms[[row[int(n)] for n in scene.names], 10:13]
    total, scale = np.zeros((scene.n_particles, 3)), np.zeros(scene.n_particles)
    for side, arm, sign in ((scene.p, scene.r_pq, 1.0), (scene.q, scene.r_qp, -1.0)):
        np.add.at(total, side, np.cross(arm, sign * scene.force) + sign * scene.moment)
        np.add.at(scale, side, np.linalg.norm(arm, axis=1) * np.linalg.norm(scene.force, axis=1)
                  + np.linalg.norm(scene.moment, axis=1))
    return np.linalg.norm(total - tq, axis=1) / scale


def test_rolling_resistance_becomes_contact_moments():
    """pair granular `rolling sds`: pair/local p5 p6 p7 = f_r, LAMMPS applies R_eff n_21 × f_r to atom 1
    (n_21 from atom 2 to atom 1); granstab's m^pq on p = id1 with n^pq from p to q is R_eff f_r × n^pq."""
    imp = load(ROLLING, timestep=14000)
    s, rep = imp.scene, imp.report
    assert s.has_moments and rep["moments_from"].startswith("rolling resistance")
    assert any(note.startswith("rolling resistance") for note in rep["law_notes"])
    atoms, local = raw_block(ROLLING[0], 14000), raw_block(ROLLING[1], 14000)
    radius = dict(zip(atoms[:, 0].astype(int), atoms[:, 5]))
    pairs = {(int(a), int(b)): k for k, (a, b) in enumerate(local[:, :2])}
    names = np.array(s.names).astype(int)
    rows = np.array([pairs[(a, b)] for a, b in zip(names[s.p].tolist(), names[s.q].tolist())])
    r1, r2 = (np.array([radius[int(i)] for i in local[rows, k]]) for k in (0, 1))
    n21 = local[rows, 8:11] / np.linalg.norm(local[rows, 8:11], axis=1)[:, None]   # p10-p12: x1 − x2
    expected = (r1 * r2 / (r1 + r2))[:, None] * np.cross(n21, local[rows, 11:14])   # LAMMPS's torque on atom 1
    assert np.abs(s.moment - expected).max() <= 1e-9 * np.abs(expected).max()   # dumped to 12 digits
    # a particle whose contacts are all in the cut fixture: its contacts and moments give LAMMPS's torque on it
    closed = torque_closure(s, atoms)
    assert np.sum(closed < 1e-8) >= 10
    plain = load(ROLLING[:2], timestep=14000, columns=NO_ROLLING_COLUMNS, k=1000, alpha=0.5, mu=0.5).scene
    assert not plain.has_moments and np.sum(torque_closure(plain, atoms) < 1e-4) == 0


def test_rolling_columns_need_every_component(tmp_path, capsys):
    rc = main(["convert", str(ROLLING[0]), str(ROLLING[1]), "--columns", COLUMNS + ",frx,fry,-",
               "--contact-k", "1", "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err == (f"{ROLLING[1]}: timestep 14000: frz: no column (3D rolling resistance needs frx, "
                               "fry, frz)"), err


@pytest.mark.parametrize("chunk", [5, 14, 15, 16, 4096])
def test_timesteps_found_across_chunk_boundaries(monkeypatch, chunk, tmp_path):
    """The scan reads a dump in chunks: a chunk edge inside or next to an ITEM: TIMESTEP line finds every
    timestep, its rows' first line and byte range as a scan of the whole file does; the rows in that range are
    the timestep's rows (CRLF line ends included)."""
    from granstab.io import lammps
    crlf = tmp_path / "contacts2d.dump"
    crlf.write_bytes((DATA / "contacts2d.dump").read_bytes().replace(b"\n", b"\r\n"))
    for path in (DATA / "contacts2d.dump", DATA / "atoms3d.dump", crlf):
        whole = [(b.timestep, b.count, b.first_line, b.start, b.end) for b in lammps.index_dump(path)[0]]
        monkeypatch.setattr(lammps, "CHUNK", chunk)
        assert [(b.timestep, b.count, b.first_line, b.start, b.end) for b in lammps.index_dump(path)[0]] == whole
        monkeypatch.undo()
        raw = path.read_bytes()
        marks = [m.start() for m in re.finditer(rb"^ITEM: TIMESTEP", raw, re.M)]
        assert [step for step, *_ in whole] == [int(raw[m:].split(b"\n")[1]) for m in marks]
        for (_step, count, line, start, end), mark in zip(whole, marks):
            rows = raw[start:end].decode()
            assert rows.count("\n") == count and not rows.startswith("ITEM")
            assert raw[:start].count(b"\n") + 1 == line and raw[mark:start].count(b"\n") == 9


def test_converting_shows_progress_when_asked(monkeypatch, capsys, tmp_path):
    """Large inputs show the reading bar (progress.ReadProgress) while converting: the dumps' bytes scanned, the
    chosen timestep's rows parsed, then build and checks; tables likewise; nothing without progress."""
    import granstab.io.progress
    monkeypatch.setattr(granstab.io.progress, "PROGRESS_BYTES", 10)
    plain = load(inputs(2))
    shown = load(inputs(2), progress=True)
    err = capsys.readouterr().err
    assert "checks atoms2d.dump + contacts2d.dump + in.disks2d" in err and "B/s" in err
    assert np.array_equal(shown.scene.force, plain.scene.force)
    tables = ROOT / "tests" / "data" / "io" / "table"
    load(tables, progress=True)
    assert "checks contacts.csv + particles.csv" in capsys.readouterr().err
    assert main(["convert", *map(str, inputs(2)), "--out", str(tmp_path / "s.npz"), "--progress"]) == 0
    assert "checks atoms2d.dump" in capsys.readouterr().err
    assert np.array_equal(granstab.load_scene(tmp_path / "s.npz").force, plain.scene.force)
    load(inputs(2))
    assert capsys.readouterr().err == ""
