"""Periodic snapshots read as periodic scenes (issue 24): the readers keep the contacts across the cell's seam with
their images instead of cutting them into dead loads, the scene carries the cell, and --no-periodic keeps the old
cut. RigidLibrary's Lees–Edwards DataSim frame (q's copies checked against RigidLibrary's own getConPos), LAMMPS
orthogonal and triclinic boxes (images checked against LAMMPS's own minimum-image branch vectors), the generic
tables with a `# cell:` line or --cell, one-line errors on bad cells and images."""
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402
from io_checks import check_contact_geometry

import granstab
from granstab.cli import main
from granstab.io import load
from granstab.mechanics.branches import RIGID

DATASIM = ROOT.parent / "shared" / "data" / "rigidlibrary" / "DataSim"
LAMMPS = DATA / "io" / "lammps"
SHEAR = ROOT / "examples" / "dem" / "in.shear2d_periodic"


def datasim_raw():
    """The frame as RigidLibrary's Configuration.ReadData reads it: positions wrapped into the box, contacts, the
    Lees–Edwards strain γ = strain_rate · snap · distSnapshot (distSnapshot = 100, RigidLibrary's default)."""
    params = dict(line.split()[:2] for line in (DATASIM / "Parameters_final.dat").read_text().splitlines()
                  if len(line.split()) >= 2)
    L = float(params["boxVec1x"])
    pos = np.loadtxt(DATASIM / "PosVel5000.dat")
    x, y = pos[:, 0] - L * np.round(pos[:, 0] / L), pos[:, 1] - L * np.round(pos[:, 1] / L)
    con = np.loadtxt(DATASIM / "Contact5000.dat")
    return x, y, con, L, float(params["strain_rate"]) * 5000 * 100.0


def rigidlibrary_copy(x, y, i, j, L, strain):
    """RigidLibrary's Configuration.getConPos (periodic branch), vectorised: where j's copy next to i sits."""
    x0, y0, x1, y1 = x[i], y[i], x[j], y[j]
    x1 = x1 - L * np.round((x1 - x0) / L)
    yover = np.round((y1 - y0) / L)
    y1 = y1 - L * yover
    x1 = x1 - L * strain * yover
    x1 = x1 - L * np.round((x1 - x0) / L)
    return np.stack([x1, y1], axis=1)


def test_datasim_keeps_every_contact_with_its_lees_edwards_image():
    imp = load(DATASIM)
    s, rep = imp.scene, imp.report
    x, y, con, L, strain = datasim_raw()
    assert s.n_contacts == len(con) == 1928                       # every row of Contact5000.dat
    assert rep["contacts"]["cut_around_periodic_cell"] == 0 and rep["periodic"]["periodic"]
    # the cell: side L, the top row shifted by γ L (γ = 0.5 here: the offset is half a box)
    assert np.allclose(s.cell, [[L, 0], [(strain - np.round(strain)) * L, L]], rtol=1e-15, atol=0)
    names = np.array(s.names).astype(int)
    row = {(int(a), int(b)): k for k, (a, b) in enumerate(con[:, :2])}
    pick = np.array([row[(a, b)] for a, b in zip(names[s.p], names[s.q])])
    i, j = con[pick, 0].astype(int), con[pick, 1].astype(int)
    # q's copy = RigidLibrary's own copy of j next to i (the positions are the file's, rounding only)
    assert np.abs(s.x[s.p] - np.stack([x[i], y[i]], 1)).max() <= 1e-13 * L
    assert np.abs(s.q_copy - rigidlibrary_copy(x, y, i, j, L, strain)).max() <= 1e-12 * L
    seam = np.any(s.image != 0, axis=1)
    assert seam.sum() == rep["periodic"]["seam_contacts"] == 81 and len(rep["periodic"]["seam_names"]) == 81
    across_top = s.image[:, 1] != 0
    assert across_top.sum() >= 10
    # the Lees–Edwards shift matters: a plain minimum image puts q's copy of those contacts half a box away
    plain = np.stack([x[j] - x[i], y[j] - y[i]], 1)
    plain -= L * np.round(plain / L)
    assert np.linalg.norm(plain[across_top], axis=1).min() > 0.25 * L
    # the point is consistent with the image: on the branch to q's copy, ρ from each centre, the file's normal
    radius = np.loadtxt(DATASIM / "posinit.dat")[:, 3]
    check_contact_geometry(s, radius[names])
    cosine = np.sum(s.branch * con[pick, 2:4], 1) / np.linalg.norm(s.branch, axis=1) / np.linalg.norm(con[pick, 2:4], axis=1)
    assert np.degrees(np.arccos(np.minimum(cosine, 1))).max() < 2e-3        # the file's six-digit normals
    lines = granstab.io.format_report(rep)
    assert "periodic scene, 81 seam contact(s) kept with their images" in lines


def test_no_periodic_keeps_the_old_cut():
    """--no-periodic: the cell as a free cluster, the contacts closing a loop around it cut (1,858 kept and 70
    cut: the numbers of the reader before periodic scenes, main at 9b39293), every contact either kept or cut."""
    imp = load(DATASIM, periodic=False)
    s, rep = imp.scene, imp.report
    assert s.cell is None and not s.image.any()
    assert (rep["contacts"]["in_scene"], rep["contacts"]["cut_around_periodic_cell"]) == (1858, 70)
    assert rep["contacts"]["in_scene"] + rep["periodic"]["contacts_cut"] == 1928
    assert not rep["periodic"]["periodic"] and "--no-periodic" in rep["periodic"]["treatment"]
    assert any("closing a loop around the periodic cell cut" in w for w in imp.warnings)
    # the kept contacts are the periodic scene's, their copies unwrapped: the same branch vectors
    periodic = load(DATASIM).scene
    key = {(a, b): c for c, (a, b) in enumerate(zip(periodic.p.tolist(), periodic.q.tolist()))}
    index = {n: k for k, n in enumerate(periodic.names)}
    same = np.array([key[(index[s.names[a]], index[s.names[b]])] for a, b in zip(s.p, s.q)])
    assert np.abs(s.branch - periodic.branch[same]).max() <= 1e-12 * np.abs(s.x).max()


def test_convert_reports_which_treatment_and_round_trips(tmp_path, capsys):
    for flag, treatment in (([], "periodic scene, 81 seam contact(s)"), (["--no-periodic"], "70 contact(s) cut")):
        out = tmp_path / f"s{len(flag)}.json"
        assert main(["convert", str(DATASIM), "--out", str(out), *flag]) == 0
        printed = capsys.readouterr().out
        assert any(line.startswith("periodic: Lees–Edwards") and treatment in line for line in printed.splitlines())
        back = granstab.load_scene(out)
        assert (back.cell is None) == bool(flag) and back.n_contacts == (1858 if flag else 1928)
    npz = tmp_path / "s.npz"
    assert main(["convert", str(DATASIM), "--out", str(npz), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["periodic"]["cell"] == load(DATASIM).scene.cell.tolist()
    a, b = granstab.load_scene(npz), granstab.load_scene(tmp_path / "s0.json")
    assert np.array_equal(a.image, b.image) and np.array_equal(a.cell, b.cell) and np.array_equal(a.point, b.point)


def test_a_wrong_image_in_the_converted_file_is_one_line(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert main(["convert", str(DATASIM), "--out", str(out)]) == 0
    capsys.readouterr()
    data = json.loads(out.read_text())
    c = next(k for k, e in enumerate(data["contacts"]) if any(e["image"]))
    data["contacts"][c]["image"] = [0, 0]
    out.write_text(json.dumps(data))
    assert main(["analyze", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"{out}: contacts[{c}]") and "image" in err, err
    # --no-periodic is an import option: a scene file is read as written, and says so in one line
    assert main(["analyze", str(out), "--no-periodic"]) == 2
    err = capsys.readouterr().err
    assert err == f"{out}: periodic: an option of snapshots; a scene file (scene-json) is read as written\n", err


# ------------------------------------------------------------------------------------------------ LAMMPS

def lattice_dumps(folder: Path, n: int = 4, spacing: float = 0.98, gamma: float = 0.0, force: float = 0.02,
                  box: str = "pp pp pp"):
    """An n×n lattice of unit-diameter disks (site (i, j) at (i + γ j, j)·spacing) in a periodic box of n·spacing,
    orthogonal (γ = 0: `BOX BOUNDS pp pp pp`) or triclinic (tilt xy = γ n spacing), as LAMMPS dumps it: positions
    inside the box, and a local dump with each lattice bond once (id1 → its +x and +y neighbours, the force on
    id1 compressive along the bond). Returns the paths and, per row, the image of id2 that the bond reaches."""
    side = n * spacing
    cell = np.array([[side, 0.0], [gamma * side, side]])
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    frac = (np.stack([i, j], 1) + 0.25) / n
    x = (frac @ cell).tolist()
    ids = 1 + i + n * j
    rows, images = [], []
    for step in ((1, 0), (0, 1)):
        ni, nj = i + step[0], j + step[1]
        image = np.stack([ni // n, nj // n], 1)
        q = 1 + ni % n + n * (nj % n)
        bond = (np.stack([ni, nj], 1) - np.stack([i, j], 1)) / n @ cell
        f = (-force * bond / np.linalg.norm(bond, axis=1)[:, None]).tolist()
        rows += [f"{a} {b} {fx!r} {fy!r} 0" for a, b, (fx, fy) in zip(ids, q, f)]
        images.append(image)
    triclinic = gamma != 0.0
    head = "ITEM: BOX BOUNDS " + ("xy xz yz " if triclinic else "") + box
    tilt, side = float(cell[1, 0]), float(side)
    bounds = ([f"{min(0.0, tilt)!r} {side + max(0.0, tilt)!r} {tilt!r}", f"0 {side!r} 0", "-0.5 0.5 0"]
              if triclinic else [f"0 {side!r}", f"0 {side!r}", "-0.5 0.5"])
    atoms = [f"{k} 1 {a!r} {b!r} 0 0.5" for k, (a, b) in zip(ids, x)]
    for name, count, kind, body in (("atoms.dump", len(ids), "ATOMS id type x y z radius", atoms),
                                    ("contacts.dump", len(rows), "ENTRIES c_a[1] c_a[2] c_p[1] c_p[2] c_p[3]", rows)):
        what = "ATOMS" if kind.startswith("ATOMS") else "ENTRIES"
        (folder / name).write_text("\n".join(["ITEM: TIMESTEP", "100", f"ITEM: NUMBER OF {what}", str(count), head,
                                              *bounds, f"ITEM: {kind}", *body]) + "\n")
    return [folder / "atoms.dump", folder / "contacts.dump"], np.concatenate(images), cell


@pytest.mark.parametrize("gamma", [0.0, 0.1])
def test_lammps_orthogonal_and_triclinic_boxes_keep_every_bond(tmp_path, gamma):
    paths, images, cell = lattice_dumps(tmp_path, gamma=gamma)
    imp = load(paths, columns="id1,id2,fx,fy,fz")
    s, rep = imp.scene, imp.report
    assert s.n_contacts == 32 and rep["contacts"]["cut_around_periodic_cell"] == 0
    assert np.allclose(s.cell, cell, rtol=0, atol=1e-15)
    assert rep["periodic"]["kind"] == ("LAMMPS triclinic box (tilt xy xz yz 0.392 0 0)" if gamma else
                                       "LAMMPS orthogonal box")
    # images as the lattice says (rows in dump order: the reader keeps it); 4 bonds cross each seam
    assert np.array_equal(s.image, images) and rep["periodic"]["seam_contacts"] == 8
    spacing = np.linalg.norm(cell[0]) / 4
    lengths = np.linalg.norm(s.branch, axis=1)
    assert np.abs(lengths[:16] - spacing).max() <= 1e-14 and np.abs(lengths[16:] - spacing * np.hypot(1, gamma)).max() <= 1e-14
    check_contact_geometry(s, np.full(16, 0.5))
    # every disk balanced by its four bonds, seam bonds included (no dead loads)
    assert np.abs(s.load).max() <= 1e-16


def test_lammps_open_axis_falls_back_to_the_cut(tmp_path):
    paths, _, _ = lattice_dumps(tmp_path, box="pp ff pp")
    rep = load(paths, columns="id1,id2,fx,fy,fz").report
    assert not rep["periodic"]["periodic"] and "open along an axis" in rep["periodic"]["treatment"]
    assert rep["contacts"]["cut_around_periodic_cell"] == 4      # the x seam closes a loop in each of the 4 rows
    assert rep["non_touching_pairs"]["count"] == 4               # y open: the bonds across it 3 spacings long
    assert rep["contacts"]["in_scene"] == 32 - 4 - 4


# ------------------------------------------------------------------------------------------------ tables

def lattice_tables(folder: Path, gamma: float = 0.1, header: str | None = "auto"):
    """The lattice of `lattice_dumps` as generic tables; `header`: the `# cell:` line ("auto": the right one)."""
    paths, images, cell = lattice_dumps(folder, gamma=gamma)
    atoms = np.loadtxt(paths[0].read_text().split("radius\n")[1].splitlines())
    rows = np.loadtxt(paths[1].read_text().split("c_p[3]\n")[1].splitlines())
    line = " ".join(f"{v!r}" for v in cell.ravel().tolist()) if header == "auto" else header
    lines = ([f"# cell: {line}"] if line is not None else []) + ["id,x,y,radius"]
    (folder / "p.csv").write_text("\n".join(lines + [f"{int(a[0])},{a[2]!r},{a[3]!r},{a[5]!r}"
                                                     for a in atoms.tolist()]) + "\n")
    (folder / "c.csv").write_text("id1,id2,fx,fy\n" + "\n".join(f"{int(r[0])},{int(r[1])},{r[2]!r},{r[3]!r}"
                                                                for r in rows.tolist()) + "\n")
    return [folder / "p.csv", folder / "c.csv"], images, cell


def test_generic_tables_take_the_cell_from_a_header_line_or_the_option(tmp_path):
    paths, images, cell = lattice_tables(tmp_path)
    header = load(paths).scene
    assert np.array_equal(header.cell, cell) and np.array_equal(header.image, images)
    other = tmp_path / "option"
    other.mkdir()
    paths, _, _ = lattice_tables(other, header=None)
    option = load(paths, cell=",".join(f"{v!r}" for v in cell.ravel().tolist())).scene
    assert np.array_equal(option.cell, cell) and np.array_equal(option.image, images)
    assert np.array_equal(option.point, header.point) and np.abs(header.load).max() <= 1e-16
    plain = load(paths)                                     # no cell at all: the seam bonds are far apart
    assert plain.scene.cell is None and plain.report["periodic"] is None


@pytest.mark.parametrize("header, message", [
    ("3.92 0 0.392", "p.csv: line 1: cell: expected 4 numbers (the rows a_1 … a_2 of the 2D cell) or 2 (an "
                     "orthogonal box), got 3"),
    ("3.92 0 x 3.92", "p.csv: line 1: cell: not a number ('x')"),
    ("3.92 0 7.84 0", "p.csv: line 1: cell: the lattice vectors (rows) span no positive volume, det = 0"),
    ("0 3.92 3.92 0", "p.csv: line 1: cell: the lattice vectors (rows) span no positive volume, det = -15.3664 "
                      "(left-handed: swap two rows)"),
])
def test_a_malformed_cell_line_is_one_line(tmp_path, capsys, header, message):
    paths, _, _ = lattice_tables(tmp_path, header=header)
    assert main(["convert", *map(str, paths), "--out", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"{tmp_path / message}"), err


def test_cell_option_errors_are_one_line(tmp_path, capsys):
    paths, _, _ = lattice_tables(tmp_path)
    for argv, message in (
            ([*map(str, paths), "--cell", "4,4"], "--cell: " + str(paths[0]) + " line 1 gives the cell already"),
            ([str(LAMMPS / "atoms2d.dump"), str(LAMMPS / "contacts2d.dump"), str(ROOT / "examples" / "dem" /
              "in.disks2d"), "--cell", "4,4"], "--cell: only the generic tables take a cell")):
        assert main(["convert", *argv, "--out", str(tmp_path / "x.json")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(message), err


# ------------------------------------------------------------------------------------------------ a LAMMPS shear run

@pytest.fixture(scope="module")
def sheared(tmp_path_factory):
    """examples/dem/in.shear2d_periodic run by Debian's LAMMPS (about a second): 160 frictional disks sheared in a
    triclinic periodic box by fix deform xy erate 0.005 with remap v, dumped at steps 7000 (tilt 0) to 10000."""
    out = tmp_path_factory.mktemp("shear")
    subprocess.run(["lmp", "-in", str(SHEAR), "-log", "none", "-screen", "none"], cwd=out, check=True, timeout=120)
    return out


def dump_rows(path: Path, step: int) -> np.ndarray:
    """The rows of one timestep, read independently of granstab (plain text split)."""
    block = path.read_text().split(f"ITEM: TIMESTEP\n{step}\n")[1].split("ITEM: TIMESTEP")[0]
    return np.loadtxt(block.split("\n", 7)[7].splitlines(), ndmin=2)


@pytest.mark.dem
@pytest.mark.parametrize("step", [8000, 10000])
def test_lammps_periodic_shear_run_keeps_every_contact(sheared, step):
    files = [sheared / "atoms_shear2d.dump", sheared / "contacts_shear2d.dump", SHEAR]
    imp = load(files, timestep=step)
    s, rep = imp.scene, imp.report
    atoms, local = dump_rows(files[0], step), dump_rows(files[1], step)
    radius = dict(zip(atoms[:, 0].astype(int), atoms[:, 5]))
    # the touching pairs counted from the dump: R_1 + R_2 > |x_1 − x_2| with LAMMPS's own minimum-image branch
    # vector (pair/local p10 p11 p12; a neighbour pair that does not touch has all its values 0); every one of them
    # is a scene contact, none is cut at the seam
    r1, r2 = (np.array([radius[i] for i in local[:, k].astype(int)]) for k in (0, 1))
    d = np.linalg.norm(local[:, 8:10], axis=1)
    touching = (d > 0) & (r1 + r2 - d > 0)
    assert s.n_contacts == touching.sum() == rep["contacts"]["in_file"] and rep["contacts"]["in_scene"] == s.n_contacts
    assert rep["contacts"]["cut_around_periodic_cell"] == 0 and rep["periodic"]["seam_contacts"] >= 10
    # the cell: side 14.9, tilt xy = erate · t · L_y (engineering shear rate from step 7000, dt 0.004)
    assert np.allclose(s.cell, [[14.9, 0], [0.005 * (step - 7000) * 0.004 * 14.9, 14.9]], rtol=1e-12, atol=1e-12)
    # q's copy is where LAMMPS put it: x_p − (x_q + image · cell) = the dump's x_1 − x_2 (12 digits; pairs across
    # the sheared boundary: LAMMPS's ghosts carry the tilt of the step before, erate · dt · L_y)
    names = np.array(s.names).astype(int)
    row = {(int(a), int(b)): k for k, (a, b) in enumerate(local[:, :2])}
    pick = np.array([row[(a, b)] for a, b in zip(names[s.p], names[s.q])])
    err = np.abs(s.x[s.p] - s.q_copy - local[pick, 8:10]).max(axis=1)
    assert np.percentile(err, 80) <= 1e-9 and err.max() <= 1.01 * 0.005 * 0.004 * 14.9
    assert rep["cone"]["at_yield"] >= 5                       # the shear mobilised contacts


@pytest.mark.dem
def test_lammps_orthogonal_header_gives_the_same_scene(sheared, tmp_path):
    """At step 7000 the box is not tilted yet: the same dumps with an orthogonal `BOX BOUNDS pp pp pp` header give
    the same periodic scene (the orthogonal reader path) as the triclinic one."""
    orthogonal = []
    for name in ("atoms_shear2d.dump", "contacts_shear2d.dump"):
        text = (sheared / name).read_text().split("ITEM: TIMESTEP\n8000\n")[0]
        head, rest = text.split("ITEM: BOX BOUNDS xy xz yz pp pp pp\n")
        bounds, body = rest.split("\n", 3)[:3], rest.split("\n", 3)[3]
        assert all(float(b.split()[2]) == 0.0 for b in bounds)
        (tmp_path / name).write_text(head + "ITEM: BOX BOUNDS pp pp pp\n" + "\n".join(" ".join(b.split()[:2])
                                                                                       for b in bounds) + "\n" + body)
        orthogonal.append(tmp_path / name)
    a = load([*orthogonal, SHEAR], timestep=7000)
    b = load([sheared / "atoms_shear2d.dump", sheared / "contacts_shear2d.dump", SHEAR], timestep=7000)
    assert a.report["periodic"]["kind"] == "LAMMPS orthogonal box" and a.scene.n_contacts == b.scene.n_contacts
    for key in ("cell", "image", "point", "force", "x"):
        assert np.array_equal(getattr(a.scene, key), getattr(b.scene, key)), key


@pytest.mark.dem
def test_lammps_shear_run_moduli_and_lowest_modes(sheared):
    """The sheared run's last frame as a periodic medium: its stress is LAMMPS's own contact sum (1/V) Σ f ⊗ b
    over the dump's rows (independent of the reader), its moduli come with their error estimates, and its lowest
    modes on the sparse path have the two translations as the only rigid zeros."""
    files = [sheared / "atoms_shear2d.dump", sheared / "contacts_shear2d.dump", SHEAR]
    s = load(files, timestep=10000).scene
    m = granstab.moduli(s)
    local = dump_rows(files[1], 10000)
    force = local[:, 2:4] + local[:, 5:7]                     # on id1: normal part + tangential part
    sigma = np.einsum("ci,cj->ij", force, -local[:, 8:10]) / abs(np.linalg.det(s.cell))   # b = x_2 − x_1
    # the reader puts the sliding contacts exactly on the cone (|Δf| <= yield_rtol |f|): the stress moves by that
    assert np.abs(m.stress - sigma).max() <= 1e-3 * np.abs(sigma).max()
    assert m.pressure > 0 and m.volume == pytest.approx(14.9 ** 2, rel=1e-12)
    assert m.C.shape == (2, 2, 2, 2) and np.all(np.isfinite(m.C))
    # error estimates: the non-affine solve to round-off; the others are the snapshot's (a DEM frame under shear is
    # not static: load residual; frictional contacts with tangential forces: C and σ not symmetric)
    stated = {key: v for key, v in m.errors.items() if v is not None}
    assert m.bulk > 0 and m.errors["residual"] <= 1e-12 and all(np.isfinite(list(stated.values())))
    # the moduli's bound is null only where no τ > 0 is proven for ‖H⁻¹‖ (docs/periodic.md): SuperLU's solve
    assert set(m.errors) - set(stated) <= {"moduli_bound"}
    assert m.errors["moduli_bound"] is not None or m.solve["method"].startswith("SuperLU"), m.solve
    assert len(m.branches) == 2 and {b.name for b in m.branches} >= {"elastic"}
    r = granstab.analyze(s, method="sparse", k=6, metric="L", max_sliding=0, sample_branches=1)
    elastic = r.branches[0]
    rigid = np.sum(elastic.codes == RIGID)
    assert rigid == 2 and max(r.errors.values()) <= 1e-9, r.errors      # the d translations, nothing else
    assert np.all(np.isfinite(elastic.stability_eigenvalues))


# ------------------------------------------------------------------------------------------------ the whole packing

@pytest.mark.slow
def test_whole_periodic_packing_on_the_sparse_path():
    """RigidLibrary's whole frame as a periodic medium, every contact sticking (the all-unloading branch): 2,985
    dofs, above the dense limit, so `analyze` takes the sparse path. Its lowest eigenvalues are those of
    sym(D H D) (D = diag(1, 1, 1/L), L the mean contact radius; no rotation to project off in a periodic scene)
    computed densely here, the two translations are the only rigid zeros, and the count below σ is exact."""
    from dataclasses import replace

    from granstab.model.scene import mean_contact_radius
    from granstab.solve.sparse import DENSE_MAX_DOF
    s = load(DATASIM).scene
    s = replace(s, state=("elastic",) * s.n_contacts)
    assert s.n_dof > DENSE_MAX_DOF
    r = granstab.analyze(s, k=6, metric="L")
    assert r.backend == "sparse" and r.summary["verdict"] == "stable" and r.summary["sufficient"]
    b = r.branches[0]
    assert np.sum(b.codes == RIGID) == 2 and b.negative_count["total"] and b.negative_count["count"] == 0
    L = mean_contact_radius(s)
    D = np.tile([1.0, 1.0, 1.0 / L], s.n_particles)
    H = granstab.stiffness(s).H * D[:, None] * D[None, :]
    lam = np.linalg.eigvalsh(0.5 * (H + H.T))
    scale = np.abs(lam).max()
    assert np.abs(lam[:2]).max() <= 1e-12 * scale and lam[2] > 1e-6 * scale   # two translations, then positive
    got = b.stability_eigenvalues[b.codes != RIGID]
    assert np.allclose(got, lam[2:2 + len(got)], rtol=0, atol=1e-10 * scale)
