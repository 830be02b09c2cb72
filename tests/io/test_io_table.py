"""The generic particle + contact tables: the same scenes as the dedicated readers when the same data are
written as tables (2D magnitudes f_n, f_t with pairs listed twice; 3D force vectors), --columns, frames."""

import numpy as np
from helpers import DATA, ROOT  # noqa: E402

from granstab.cli import main
from granstab.io import load

DATA = DATA / "io"
KEYS = ("x", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "load", "k", "alpha", "mu")


def test_annulus_written_as_tables_gives_the_same_scene(tmp_path):
    pos = np.loadtxt(DATA / "annulus" / "particle_positions.txt", delimiter=",")
    adj = np.loadtxt(DATA / "annulus" / "Adjacency_list.txt", delimiter=",")
    np.savetxt(tmp_path / "particles.csv", pos[:, :5], delimiter=",", header="frame,id,x,y,radius", comments="")
    # both listings of every pair, the id1 > id2 one first (RigidLibrary's choice), as f_t, f_n magnitudes
    rows = adj[np.lexsort((adj[:, 1] < adj[:, 2], np.maximum(adj[:, 1], adj[:, 2]), np.minimum(adj[:, 1], adj[:, 2]),
                           adj[:, 0]))]
    np.savetxt(tmp_path / "contacts.txt", rows, header="frame id1 id2 ft fn", comments="")
    opts = dict(geometry="touching", mu=0.3, outside_cone="elastic", frame=2)
    table = load([tmp_path / "particles.csv", tmp_path / "contacts.txt"], **opts)
    ref = load(DATA / "annulus", **opts)
    a, b = table.scene, ref.scene
    assert a.names == b.names and np.array_equal(a.p, b.p) and a.state == b.state and a.n_contacts > 20
    for key in KEYS:
        assert np.abs(getattr(a, key) - getattr(b, key)).max() <= 1e-15 * max(np.abs(getattr(b, key)).max(), 1), key
    dup = table.report["duplicates"]
    assert dup["pairs_listed_twice"] == a.n_contacts and dup["newton_third_law_largest_relative_misfit"] == 0.0
    assert table.frames == [1.0, 2.0] and table.report["frame"] == 2.0


def test_3d_scene_through_a_force_vector_table(tmp_path):
    ref = load([DATA / "lammps" / "atoms3d.dump", DATA / "lammps" / "contacts3d.dump",
                ROOT / "examples" / "dem" / "in.spheres3d"], timestep=14000)
    s = ref.scene
    atoms = np.loadtxt((DATA / "lammps" / "atoms3d.dump").read_text().split("ITEM: TIMESTEP\n14000\n")[1]
                       .split("\n", 7)[7].splitlines())
    radius_of = dict(zip(atoms[:, 0].astype(int), atoms[:, 5]))
    ids = np.array(s.names).astype(int)
    cell = " ".join(f"{v:.17g}" for v in s.cell.ravel())               # the periodic cell as a header line
    np.savetxt(tmp_path / "p.csv", np.column_stack([ids, s.x, [radius_of[i] for i in ids]]), delimiter=",",
               header=f"# cell: {cell}\nid,x,y,z,radius", comments="")
    np.savetxt(tmp_path / "c.csv", np.column_stack([ids[s.p], ids[s.q], s.force]), delimiter=",",
               header="id1,id2,fx,fy,fz", comments="", fmt="%.17g")
    got = load([tmp_path / "p.csv", tmp_path / "c.csv"], k=1000, alpha=0.5, mu=0.5)
    a = got.scene
    assert a.dim == 3 and a.names == s.names and a.state == s.state
    assert np.array_equal(a.cell, s.cell) and np.array_equal(a.image, s.image) and np.any(a.image != 0)
    for key in ("x", "point", "normal", "curvature_p", "force", "load", "k"):
        assert np.abs(getattr(a, key) - getattr(s, key)).max() <= 1e-12 * max(np.abs(getattr(s, key)).max(), 1), key


def test_columns_rename_a_foreign_header(tmp_path, capsys):
    (tmp_path / "p.csv").write_text((DATA / "table" / "particles.csv").read_text())
    (tmp_path / "c.csv").write_text("a,b,c,d\n" + "\n".join((DATA / "table" / "contacts.csv").read_text()
                                                           .splitlines()[1:]) + "\n")
    rc = main(["convert", str(tmp_path / "p.csv"), str(tmp_path / "c.csv"), "--format", "table",
               "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err
    assert rc == 2 and "c.csv: line 1: a: unknown column: name the columns with --columns" in err
    rc = main(["convert", str(tmp_path / "p.csv"), str(tmp_path / "c.csv"), "--format", "table",
               "--columns", "id1,id2,fx,fy", "--out", str(tmp_path / "x.json")])
    assert rc == 0
    direct = load([DATA / "table" / "particles.csv", DATA / "table" / "contacts.csv"]).scene
    renamed = load([tmp_path / "p.csv", tmp_path / "c.csv"], format="table", columns="id1,id2,fx,fy").scene
    assert np.array_equal(renamed.force, direct.force) and np.array_equal(renamed.point, direct.point)


def test_three_disk_example():
    imp = load([DATA / "table" / "particles.csv", DATA / "table" / "contacts.csv"])
    s = imp.scene
    assert (s.n_particles, s.n_contacts, s.dim) == (3, 3, 2)
    d = np.linalg.norm(s.x[s.q] - s.x[s.p], axis=1)
    assert np.allclose(np.linalg.norm(s.point - s.x[s.p], axis=1), 1.0 - (2.0 - d) / 2, rtol=0, atol=1e-15)
    assert imp.report["law"]["k"]["source"].startswith("built-in default")


def test_walls_become_loads_and_the_law_columns_are_used(tmp_path):
    (tmp_path / "p.csv").write_text((DATA / "table" / "particles.csv").read_text())
    # the three disks on a floor (wall id -1) that carries their weight; per-contact kn, kt, mu
    (tmp_path / "c.csv").write_text(
        "id1,id2,fx,fy,kn,kt,mu\n"
        "1,2,-0.02,0.0,100,50,0.4\n2,3,0.01,-0.017,100,25,0.4\n3,1,0.01,0.017,200,50,0.3\n"
        "1,-1,0.0,0.05,0,0,0\n2,-1,0.0,0.05,0,0,0\n")
    imp = load([tmp_path / "p.csv", tmp_path / "c.csv"])
    s, rep = imp.scene, imp.report
    assert s.n_contacts == 3 and rep["walls"]["wall_contacts"] == 2 and rep["walls"]["particles_touching"] == 2
    assert np.array_equal(s.k, [100, 100, 200]) and np.array_equal(s.alpha, [0.5, 0.25, 0.25])
    assert np.array_equal(s.mu, [0.4, 0.4, 0.3]) and rep["law"]["k"]["source"] == "c.csv column kn"
    # the loads follow the particle contacts (b = −Σf): for 1 and 2 they carry the wall's push
    assert np.allclose(s.load[0], -(np.array([-0.02, 0.0]) - np.array([0.01, 0.017])), atol=1e-15)
    # imbalance with the wall forces: particle 1: f12 + f13 + wall = (-0.02, 0) + (-0.01, -0.017) + (0, 0.05)
    net1 = np.linalg.norm([-0.03, 0.033])
    scale1 = 0.02 + np.hypot(0.01, 0.017) + 0.05
    net2 = np.linalg.norm(np.array([0.02, 0.0]) + np.array([0.01, -0.017]) + np.array([0.0, 0.05]))
    scale2 = 0.02 + np.hypot(0.01, 0.017) + 0.05
    net3 = np.linalg.norm(np.array([-0.01, 0.017]) + np.array([0.01, 0.017]))
    scale3 = 2 * np.hypot(0.01, 0.017)
    ratios = np.array([net1 / scale1, net2 / scale2, net3 / scale3])
    assert np.isclose(rep["imbalance"]["force"]["max"], ratios.max(), rtol=1e-12)
    assert np.isclose(rep["imbalance"]["force"]["median"], np.median(ratios), rtol=1e-12)


def test_a_folder_of_tables_is_a_snapshot_for_analyze(tmp_path, capsys):
    folder = tmp_path / "snap"
    folder.mkdir()
    for name in ("particles.csv", "contacts.csv"):
        (folder / name).write_text((DATA / "table" / name).read_text())
    assert main(["analyze", str(folder), "--json"]) == 0
    out = capsys.readouterr().out
    assert '"n_particles": 3' in out and '"n_contacts": 3' in out
    (folder / "contacts.csv").unlink()
    (folder / "particles.csv").unlink()
    assert main(["analyze", str(folder)]) == 2
    assert "no snapshot files in this folder" in capsys.readouterr().err


def test_a_sequence_is_parsed_once_for_all_its_frames_and_again_when_it_changes(tmp_path, monkeypatch):
    """`track` loads every frame of a table with a frame column: the file is parsed once (held_table), each frame
    is the scene a first read gives, and a rewritten file is read anew."""
    import granstab.io.generic as generic
    from granstab.io.lines import read_table
    pos = np.loadtxt(DATA / "annulus" / "particle_positions.txt", delimiter=",")
    adj = np.loadtxt(DATA / "annulus" / "Adjacency_list.txt", delimiter=",")
    paths = [tmp_path / "particles.csv", tmp_path / "contacts.txt"]
    np.savetxt(paths[0], pos[:, :5], delimiter=",", header="frame,id,x,y,radius", comments="")
    np.savetxt(paths[1], adj, header="frame id1 id2 ft fn", comments="")
    opts = dict(geometry="touching", mu=0.3, outside_cone="elastic")
    fresh = {}
    for frame in (1, 2):
        generic._held.clear()
        fresh[frame] = load(paths, frame=frame, **opts).scene
    parsed = []
    monkeypatch.setattr(generic, "read_table", lambda path, *a, **k: parsed.append(path) or read_table(path, *a, **k))
    generic._held.clear()
    for frame in (1, 2, 1):
        s = load(paths, frame=frame, **opts).scene
        assert s.names == fresh[frame].names and np.array_equal(s.x, fresh[frame].x)
        assert np.array_equal(s.force, fresh[frame].force) and s.state == fresh[frame].state
    assert parsed == paths                                             # each table once for the three loads
    np.savetxt(paths[0], pos[:, :5] + [0, 0, 1e-3, 0, 0], delimiter=",", header="frame,id,x,y,radius",
               comments="")                                            # moved in x by 1e-3: read anew
    moved = load(paths, frame=1, **opts).scene
    assert parsed == paths + [paths[0]]
    assert np.allclose(moved.x[:, 0] - fresh[1].x[:, 0], 1e-3, rtol=0, atol=1e-9)
