"""`granstab export`: every file read back by a reader that is not ours — vtk's XML reader for .vtp, ASE and OVITO
for extended XYZ, OVITO and LAMMPS's own read_dump for the dump — with every array identical (names included) to
the fields the export computed, and those fields checked against the scene, the scan's tables and the contact law.

Identical means bit for bit (np.array_equal, NaN equal to NaN): the writers keep float64 exactly (vtk: binary;
text: 17 significant digits), so any tolerance would hide a rounding writer. The readers (ase, ovito, vtk, pyarrow)
are in the test extra.
"""
from __future__ import annotations

import shutil
import subprocess
from xml.etree import ElementTree

import ase.io as ase_io
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import DATA  # noqa: E402
from ovito import io as ovito_io
from ovito.modifiers import LoadTrajectoryModifier
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

import granstab
from granstab.cli import main
from granstab.export import STATE_CODES, VERDICT_CODES, frame_of, write
from granstab.export.modes import contact_slip
from granstab.model import packings
from granstab.model.law import contact_stiffness, sliding_direction
from granstab.model.scene import CONTACT_FIELDS
from granstab.scan import read_map, scan


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind in "US" or b.dtype.kind in "US":
        return a.shape == b.shape and [str(v) for v in a.ravel()] == [str(v) for v in b.ravel()]
    return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)


def planted(n: int = 5, centre: int = 12):
    """A 5×5 triangular lattice (3 contacts at yield) whose particle `centre` has sharp contacts (ρ/r = 0.4) and
    almost no tangential stiffness: its cluster and its neighbours' are unstable (as test_scan's planted lattice)."""
    scene = packings.lattice(2, n, curvature_ratio=2.0, n_sliding=3, mobilised=0.5)
    at = (scene.p == centre) | (scene.q == centre)
    factor = np.where(at, 2.0 / 0.4, 1.0)[:, None, None]
    arrays = {k: getattr(scene, k) for k in CONTACT_FIELDS + ("state",) if k not in ("image", "curvature_sum")}
    arrays.update(curvature_p=scene.curvature_p * factor, curvature_q=scene.curvature_q * factor,
                  alpha=np.where(at, 1e-4, scene.alpha))
    return granstab.build_scene(2, scene.names, scene.x, arrays, source="planted")


@pytest.fixture(scope="module")
def packing(tmp_path_factory):
    """The planted lattice, its scene file, its scan folder and its export frame with 2 modes."""
    root = tmp_path_factory.mktemp("export")
    scene = planted()
    granstab.save_scene(scene, root / "lattice.json")
    scan(scene, root / "scan", workers=1, figures=False, boundary="loads")
    return scene, root, frame_of(scene, scan=root / "scan", modes=2)


@pytest.fixture(scope="module")
def periodic(tmp_path_factory):
    """A sheared jammed periodic packing (2D, 16 disks) as a scene file."""
    root = tmp_path_factory.mktemp("periodic")
    scene = packings.jammed(2, 16, shear=0.1)
    granstab.save_scene(scene, root / "jammed.npz")
    return scene, root


def test_fields_are_the_scene_the_scan_and_the_contact_law(packing):
    scene, root, frame = packing
    data = read_map(root / "scan")
    own = list(data["particles"]["own_verdict"])
    assert "unstable" in own and "stable" in own                                     # the fixture has both
    assert list(frame.particles["name"]) == list(scene.names)
    assert same(frame.particles["unstable_fraction"], data["particles"]["unstable_fraction"])
    assert list(frame.particles["own_verdict"]) == own
    assert same(frame.particles["verdict_code"], [VERDICT_CODES[v] for v in own])
    lam = dict(zip(data["clusters"]["center"], data["clusters"]["lambda_min"]))
    assert same(frame.particles["cluster_lambda_min"], [lam[i] for i in range(scene.n_particles)])
    assert np.all(frame.particles["cluster_lambda_min"][np.array(own) == "unstable"] < 0)
    # disks of radius 1 pressed by f/(k r) = 1e-3: the contact point sits δ/2 = 5e-4 inside (|r^pq| = 1 - 5e-4)
    assert np.allclose(frame.particles["radius"], 1 - 5e-4, rtol=0, atol=1e-12)
    assert same(frame.contacts["normal_force"], -np.sum(scene.force * scene.normal, axis=1))
    assert np.all(frame.contacts["normal_force"] > 0)                                 # compression positive
    ft = frame.contacts["tangential_force"][:, :2]
    assert np.allclose(ft + (-frame.contacts["normal_force"])[:, None] * scene.normal, scene.force, rtol=0,
                       atol=1e-15 * np.abs(scene.force).max())                          # f = f_n n + f_t
    assert np.sum(frame.contacts["state"] == STATE_CODES["at_yield"]) == 3 == int(scene.at_yield().sum())


def test_modes_are_the_lowest_consistent_modes_and_slip_follows_the_contact_law(packing):
    scene, _, frame = packing
    result = granstab.analyze(scene, metric="L")
    consistent = sorted(c["eigenvalue"] for b in result.branches for c in b.consistent())
    lam1, lam2 = frame.info["mode1_eigenvalue"], frame.info["mode2_eigenvalue"]
    assert lam1 == consistent[0] < 0 and lam1 <= lam2                                # the unstable packing's softest
    d = scene.dim
    U = np.c_[frame.particles["mode1_displacement"][:, :d], frame.particles["mode1_rotation"][:, 2:]].ravel()
    assert abs(np.linalg.norm(U) - 1) < 1e-12                                       # a unit physical motion
    work = granstab.second_order_work(result, U)          # the branch U's own S signs select (eq:flow)
    assert work["work"] < 0                                                          # an unstable mode (eq:instab)
    mask = frame.contacts["mode1_branch"]
    slip = frame.contacts["mode1_slip"]
    sliding = mask == 1
    assert sliding.any() and np.all(slip[~sliding] == 0) and np.all(slip[sliding] >= 0)   # consistent (eq:flow)
    assert np.all(mask[work["mask"] == 1] == 1) and np.all(slip[work["mask"] == 1] > 0)
    # the same slip from the contact law: the sliding stiffness F (eq:ContactF, law.contact_stiffness) leaves a
    # tangential force rate along h of kα (h·δu − slip); δu from the mode's relative motion (eq:dudef)
    from granstab.mechanics.stiffness import kinematics
    per = 3
    idx = np.c_[scene.p[:, None] * per + np.arange(per), scene.q[:, None] * per + np.arange(per)]
    du = np.einsum("mdn,mn->md", kinematics(scene)[0], U[idx])
    F = contact_stiffness(scene.normal, scene.k, scene.alpha, scene.mu, scene.force, sliding)
    h = sliding_direction(scene.force, scene.normal)
    rate = np.einsum("md,mde,me->m", h, F, du)
    expect = scene.k * scene.alpha * (np.sum(h * du, axis=1) - slip)
    assert np.allclose(rate[sliding], expect[sliding], rtol=1e-10, atol=1e-14)      # round-off of a few products
    assert same(slip, contact_slip(scene, U, mask))


def read_vtp(path):
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def vtk_arrays(data) -> dict:
    """Every array of a vtkFieldData-like container by name (strings as lists)."""
    out = {}
    for i in range(data.GetNumberOfArrays()):
        a = data.GetAbstractArray(i)
        out[a.GetName()] = (vtk_to_numpy(a) if hasattr(a, "GetNumberOfComponents") and a.IsNumeric()
                            else [a.GetValue(j) for j in range(a.GetNumberOfValues())])
    return out


def test_vtp_reads_back_identical_in_vtk(packing, tmp_path):
    scene, _, frame = packing
    paths = write([frame], tmp_path, "vtp", "lattice")
    assert [p.name for p in paths] == ["lattice.particles.vtp", "lattice.contacts.vtp"]   # no cell: no outline
    particles, contacts = read_vtp(paths[0]), read_vtp(paths[1])
    assert same(vtk_to_numpy(particles.GetPoints().GetData()), np.c_[scene.x, np.zeros(scene.n_particles)])
    assert particles.GetNumberOfVerts() == scene.n_particles
    got = vtk_arrays(particles.GetPointData())
    assert sorted(got) == sorted(frame.particles)
    assert all(same(got[k], v) for k, v in frame.particles.items())
    info = vtk_arrays(particles.GetFieldData())
    assert sorted(info) == sorted(frame.info) and all(same(info[k], [v]) for k, v in frame.info.items())
    assert 0 < frame.info["mode1_accuracy"] < abs(frame.info["mode1_eigenvalue"])   # the sign is resolved
    assert contacts.GetNumberOfLines() == scene.n_contacts
    ends = vtk_to_numpy(contacts.GetPoints().GetData()).reshape(-1, 2, 3)
    line = vtk_to_numpy(contacts.GetLines().GetConnectivityArray()).reshape(-1, 2)
    assert same(ends[:, 0, :2], scene.x[scene.p]) and same(ends[:, 1, :2], scene.q_copy)
    assert same(line, np.arange(2 * scene.n_contacts).reshape(-1, 2))
    got = vtk_arrays(contacts.GetCellData())
    assert sorted(got) == sorted(frame.contacts) and all(same(got[k], v) for k, v in frame.contacts.items())


def test_periodic_cell_is_an_outline_and_seam_contacts_stay_short(periodic, tmp_path):
    scene, root = periodic
    assert main(["export", str(root / "jammed.npz"), "--out", str(tmp_path), "--out-format", "vtp"]) == 0
    cell = read_vtp(tmp_path / "jammed.cell.vtp")
    corners = vtk_to_numpy(cell.GetPoints().GetData())[:, :2]
    a1, a2 = scene.cell
    assert cell.GetNumberOfLines() == 1
    assert np.allclose(corners, [0 * a1, a1, a1 + a2, a2, 0 * a1], rtol=0, atol=1e-15 * np.abs(scene.cell).max())
    ends = vtk_to_numpy(read_vtp(tmp_path / "jammed.contacts.vtp").GetPoints().GetData()).reshape(-1, 2, 3)
    seam = np.any(scene.image != 0, axis=1)
    assert seam.any()
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    assert np.all(length < 1.5)               # every line a contact's branch (< the largest diameter 1.4), none across


def test_extended_xyz_reads_back_identical_in_ase_and_ovito(packing, periodic, tmp_path):
    scene, _, frame = packing
    paths = write([frame], tmp_path, "xyz", "lattice")
    atoms = ase_io.read(paths[0], format="extxyz")
    assert same(atoms.positions, frame.positions) and not atoms.pbc.any()
    names = set(atoms.arrays) - {"numbers", "positions"}
    assert names == set(frame.particles) and all(same(atoms.arrays[k], frame.particles[k]) for k in names)
    assert atoms.info["mode2_eigenvalue"] == frame.info["mode2_eigenvalue"]
    rows = ase_io.read(paths[1], format="extxyz")
    assert same(rows.positions, frame.contacts["point"])
    assert all(same(rows.arrays[k], v) for k, v in frame.contacts.items() if k != "point")
    assert same(frame.contacts["branch"][:, :2], scene.branch)
    data = ovito_io.import_file(str(paths[0])).compute(0)
    ovito_matches(data, frame.particles, frame.positions)
    cell_scene, root = periodic
    write([frame_of(cell_scene)], tmp_path, "xyz", "jammed")
    atoms = ase_io.read(tmp_path / "jammed.xyz", format="extxyz")
    assert same(atoms.cell[:2, :2], cell_scene.cell) and list(atoms.pbc) == [True, True, False]
    data = ovito_io.import_file(str(tmp_path / "jammed.xyz")).compute(0)
    assert same(np.asarray(data.cell[:2, :2]).T, cell_scene.cell) and data.cell.pbc == (True, True, False)


def ovito_matches(data, fields: dict, positions, typed: bool = True) -> None:
    """OVITO's arrays against ours. Its text parser is not correctly rounded (ASE's, Python's float(), is): a
    float64 it reads is within 2 ulp of the written one (seen: 1.4e-16 relative), and it keeps Radius as float32,
    within one float32 rounding; integers exact (typed: as integers; a dump's columns carry no type, OVITO reads
    them as reals). Text fields are not compared (OVITO keeps them as types)."""
    renamed = {"radius": "Radius", "orientation": "Orientation"}   # OVITO maps standard names onto its own
    eps = {np.dtype(np.float64): 2 * np.finfo(float).eps, np.dtype(np.float32): np.finfo(np.float32).eps}
    for key, values in [("positions", positions), *fields.items()]:
        if values.dtype.kind in "US":
            continue
        got = np.asarray(data.particles.positions if key == "positions" else data.particles[renamed.get(key, key)])
        assert got.shape == values.shape and (got.dtype.kind == values.dtype.kind or not typed), key   # int32
        if values.dtype.kind == "f":
            assert np.allclose(got, values, rtol=eps[got.dtype], atol=0, equal_nan=True), key
        else:
            assert np.array_equal(got, values), key


def parse_dump(path, item: str) -> list[tuple[int, list[str], np.ndarray]]:
    """A plain parse of a LAMMPS text dump: (timestep, column names, rows as text) per block."""
    lines = path.read_text().splitlines()
    out, i = [], 0
    while i < len(lines):
        step, count = int(lines[i + 1]), int(lines[i + 3])
        names = lines[i + 8].split()[2:]
        assert lines[i + 8].startswith(f"ITEM: {item}")
        out.append((step, names, np.array([r.split() for r in lines[i + 9:i + 9 + count]], dtype=str)))
        i += 9 + count
    return out


def test_dump_pair_reads_back_identical(packing, tmp_path):
    scene, _, frame = packing
    atoms_path, local_path = write([frame], tmp_path, "dump", "lattice")
    [(step, names, rows)] = parse_dump(atoms_path, "ATOMS")
    table = dict(zip(names, rows.T))
    assert step == 0 and same(table["id"].astype(int), np.arange(1, scene.n_particles + 1))
    for key, values in frame.particles.items():
        if values.dtype.kind in "US":
            assert key not in table                                 # text fields travel as their codes
            continue
        cols = [key] if values.ndim == 1 else [f"{key}[{j}]" for j in (1, 2, 3)]
        assert same(np.stack([table[c].astype(values.dtype) for c in cols], axis=-1).reshape(values.shape), values)
    [(_, names, rows)] = parse_dump(local_path, "ENTRIES")
    table = dict(zip(names, rows.T))
    assert same(table["p"].astype(int) - 1, scene.p) and same(table["q"].astype(int) - 1, scene.q)
    assert same(table["mode1_slip"].astype(float), frame.contacts["mode1_slip"])
    assert same(table["normal_force"].astype(float), frame.contacts["normal_force"])
    pipeline = ovito_io.import_file(str(atoms_path))
    bonds = LoadTrajectoryModifier()                    # OVITO's way to a dump local file: bonds with properties
    names = parse_dump(local_path, "ENTRIES")[0][1]
    given = {"p": "Particle Identifiers.1", "q": "Particle Identifiers.2", "normal_force": "normal_force"}
    bonds.source.load(str(local_path), columns=[given.get(n) for n in names])
    pipeline.modifiers.append(bonds)
    data = pipeline.compute(0)
    scalars = {k: v for k, v in frame.particles.items() if v.ndim == 1}     # vectors: one column a component
    ovito_matches(data, scalars, frame.positions, typed=False)
    assert same(np.asarray(data.particles.bonds.topology), np.c_[scene.p, scene.q])
    assert np.allclose(np.asarray(data.particles.bonds["normal_force"]), frame.contacts["normal_force"],
                       rtol=2 * np.finfo(float).eps, atol=0)                     # OVITO's parser: 2 ulp (above)


@pytest.mark.dem
def test_lammps_read_dump_takes_the_periodic_box_and_positions(periodic, tmp_path):
    """LAMMPS itself (Debian's lmp, installed by .ci/run) reads the atoms dump with its box and writes it back."""
    assert shutil.which("lmp"), "needs Debian's lammps (.ci/run installs it)"
    scene, root = periodic
    write([frame_of(scene)], tmp_path, "dump", "jammed")
    (tmp_path / "in.check").write_text(
        "units lj\ndimension 2\nboundary p p p\natom_style atomic\nregion box prism 0 1 0 1 -0.5 0.5 0 0 0\n"
        "create_box 1 box\nmass 1 1\nread_dump jammed.atoms.dump 0 x y box yes add yes\n"
        'print "BOX $(xlo:%.17g) $(xhi:%.17g) $(ylo:%.17g) $(yhi:%.17g) $(xy:%.17g)"\n'
        "write_dump all custom back.dump id x y modify format float %.17g sort id\n")
    run = subprocess.run(["lmp", "-in", "in.check", "-log", "none"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0, run.stdout[-500:]
    box = [float(v) for v in next(ln for ln in run.stdout.splitlines() if ln.startswith("BOX")).split()[1:]]
    (a, _), (xy, ly) = scene.cell
    assert box == [0.0, a, 0.0, ly, xy]
    [(_, names, rows)] = parse_dump(tmp_path / "back.dump", "ATOMS")
    xy_back = rows[:, [names.index("x"), names.index("y")]].astype(float)
    # LAMMPS stores a triclinic box's atoms through box-fractional coordinates (x = lo + h·λ): its round trip
    # costs a few ulp of the box size (seen: 2 ulp); the dump's own digits are exact (the other dump tests)
    assert np.allclose(xy_back, scene.x, rtol=0, atol=8 * np.finfo(float).eps * np.abs(scene.cell).max())


def test_a_sequence_is_a_pvd_collection_and_one_trajectory_file(tmp_path):
    annulus = "tests/data/io/annulus"
    for fmt in ("vtp", "xyz", "dump"):
        assert main(["export", annulus, "--out", str(tmp_path / fmt), "--out-format", fmt, "--frames", "1:2"]) == 0
    frames = [granstab.load(annulus, frame=f).scene for f in (1, 2)]
    sets = ElementTree.parse(tmp_path / "vtp" / "annulus.pvd").getroot().find("Collection")
    entries = [(float(e.get("timestep")), e.get("part"), e.get("file")) for e in sets]
    assert [(t, p) for t, p, _ in entries] == [(1.0, "0"), (1.0, "1"), (2.0, "0"), (2.0, "1")]
    for (_, _, name), scene in zip(entries[::2], frames):
        assert same(np.array(read_vtp(tmp_path / "vtp" / name).GetPoints().GetNumberOfPoints()), scene.n_particles)
    blocks = ase_io.read(tmp_path / "xyz" / "annulus.xyz", index=":", format="extxyz")
    assert [b.info["Time"] for b in blocks] == [1, 2]
    assert all(same(b.positions[:, :2], s.x) for b, s in zip(blocks, frames))
    steps = parse_dump(tmp_path / "dump" / "annulus.local.dump", "ENTRIES")
    assert [s for s, _, _ in steps] == [1, 2] and [len(r) for _, _, r in steps] == [s.n_contacts for s in frames]


def test_a_track_folder_gives_the_frames_and_its_particle_fields(tmp_path):
    annulus = "tests/data/io/annulus"
    frames = {f: granstab.load(annulus, frame=f).scene for f in (1, 2)}
    track = tmp_path / "track"
    track.mkdir()
    # granstab.track's contract: `frame` the position in the input's frames, `step` the reader's key (frame 2)
    pq.write_table(pa.table({"frame": [1], "step": [2.0]}), track / "frames.parquet")
    names = list(frames[2].names)[::-1] + ["gone"]                  # any order; a name the scene lacks is ignored
    d2min = np.arange(len(names), dtype=float) / 7
    rows = {"frame": [1] * len(names), "name": names, "x": np.zeros(len(names)), "d2min": d2min,
            "rattler": [False] * len(names)}
    pq.write_table(pa.table(rows), track / "particles.parquet")
    assert main(["export", annulus, "--out", str(tmp_path / "out"), "--out-format", "xyz", "--track", str(track)]) == 0
    [atoms] = ase_io.read(tmp_path / "out" / "annulus.xyz", index=":", format="extxyz")
    expect = dict(zip(names, d2min))
    assert atoms.info["Time"] == 2 and same(atoms.arrays["d2min"], [expect[n] for n in frames[2].names])
    assert same(atoms.arrays["rattler"], np.zeros(len(frames[2].names))) and "x" not in atoms.arrays


def unit_quaternions(rows: int, seed: int = 5) -> np.ndarray:
    """Seeded random unit quaternions (w, x, y, z), rounded to 9 digits as a dump would print them, then scaled to
    unit norm to round-off (|q| − 1 ≤ 4e-16, inside the reader's 1e-6)."""
    q = np.round(np.random.default_rng(seed).normal(size=(rows, 4)), 9)
    return q / np.linalg.norm(q, axis=1)[:, None]


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v (3,) turned by each unit quaternion q (n, 4) as (w, x, y, z): v + 2w (u × v) + 2 u × (u × v)."""
    w, u = q[:, :1], q[:, 1:]
    t = 2 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def test_orientation_from_the_dump_in_every_format(tmp_path):
    """A LAMMPS 3D dump with quatw quati quatj quatk (appended here) → Loaded.orientation in the scene's particle
    order → OVITO's Orientation (x, y, z, w) from the extended XYZ and from the dump, vtk's `orientation` array:
    every one the file's quaternion (OVITO keeps Orientation in float32: one float32 rounding, as ovito_matches)."""
    from io_checks import with_atom_columns
    from test_io_lammps import inputs

    quats = unit_quaternions(5000)
    atoms, contacts, script = inputs(3)
    dumped = with_atom_columns(atoms, tmp_path / "atoms.dump", ["quatw", "quati", "quatj", "quatk"],
                               lambda row: quats[int(row["id"])])
    loaded = granstab.load([dumped, contacts, script])
    ids = np.array([int(n) for n in loaded.scene.names])   # LAMMPS scenes name particles by their ids
    assert same(loaded.orientation, quats[ids])            # the file's numbers, in the scene's order, not renormalised
    out = tmp_path / "out"
    for fmt in ("xyz", "dump", "vtp"):
        assert main(["export", str(dumped), str(contacts), str(script), "--out", str(out), "--out-format", fmt]) == 0
    xyzw, positions = quats[ids][:, [1, 2, 3, 0]], loaded.scene.x
    for path in (out / "atoms.xyz", out / "atoms.atoms.dump"):       # OVITO keeps Orientation as float32
        ovito_matches(ovito_io.import_file(str(path)).compute(0), {"orientation": xyzw}, positions, typed=False)
    assert same(vtk_arrays(read_vtp(out / "atoms.particles.vtp").GetPointData())["orientation"], xyzw)


def test_a_2d_angle_is_a_turn_about_e3(tmp_path):
    """A table's `angle` column (2D, radians) → q = (cos θ/2, 0, 0, sin θ/2): OVITO's Orientation turns e1 onto
    (cos θ, sin θ, 0), the physical meaning, checked against the angles written."""
    src = DATA / "io" / "table"
    lines = (src / "particles.csv").read_text().splitlines()
    angles = np.array([0.3, -2.5, 3.0])
    rows = [lines[0], lines[1] + ",angle"] + [f"{r},{a:.17g}" for r, a in zip(lines[2:], angles)]
    (tmp_path / "particles.csv").write_text("\n".join(rows) + "\n")
    shutil.copy(src / "contacts.csv", tmp_path / "contacts.csv")
    tables = [str(tmp_path / "particles.csv"), str(tmp_path / "contacts.csv")]
    assert main(["export", *tables, "--out", str(tmp_path / "out"), "--out-format", "xyz"]) == 0
    xyzw = np.asarray(ovito_io.import_file(str(tmp_path / "out" / "particles.xyz")).compute(0).particles["Orientation"])
    turned = rotate(xyzw[:, [3, 0, 1, 2]].astype(float), np.array([1.0, 0.0, 0.0]))
    # OVITO's float32 quaternion: each component within 6e-8, the turned vector within a few of those
    assert np.allclose(turned, np.c_[np.cos(angles), np.sin(angles), np.zeros(3)], rtol=0, atol=5e-7)


@pytest.mark.parametrize("columns, values, says", [
    (["quatw", "quati", "quatj", "quatk"], [0.9, 0.1, 0.1, 0.1], "quatw quati quatj quatk: not a unit quaternion"),
    (["quatw", "quati", "quatj"], [1.0, 0.0, 0.0], "quatk: missing column"),
    (["angle"], [0.5], "angle: only for 2D"),
])
def test_bad_orientation_is_one_line(tmp_path, capsys, columns, values, says):
    from io_checks import with_atom_columns
    from test_io_lammps import inputs

    atoms, contacts, script = inputs(3)
    dumped = with_atom_columns(atoms, tmp_path / "atoms.dump", columns, lambda row: values)
    assert main(["convert", str(dumped), str(contacts), str(script), "--out", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and says in err and str(dumped) in err, err


@pytest.mark.parametrize("what, argv, says", [
    ("lattice", ["--out-format", "stl"], "argument --out-format: invalid choice: 'stl'"),
    ("lattice", ["--modes", "500"], "--modes 500: more than the packing's 75 dofs"),
    # 48 dofs less 2 translations and 16 free spins (frictionless disks): at most 30 modes on its one branch
    ("jammed", ["--modes", "40"], "--modes 40: the packing has 30 distinct consistent non-rigid mode(s)"),
    ("lattice", ["--frames", "1:2"], "--frames: "),                         # a scene file holds one frame
    ("lattice", ["--modes", "1", "--timeout", "1e-6"], "stopped after --timeout 1e-06 s, unfinished; export without"),
    ("lattice", ["--scan-dir", "OTHER"], "--scan-dir: the scan's packing (16 particles"),
])
def test_bad_input_is_one_line(packing, periodic, tmp_path, capsys, what, argv, says):
    _, root, _ = packing
    scene, proot = periodic
    if "OTHER" in argv:                                           # a scan folder of another packing
        scan(scene, tmp_path / "other", workers=1, figures=False)
        argv = [str(tmp_path / "other") if a == "OTHER" else a for a in argv]
    source = root / "lattice.json" if what == "lattice" else proot / "jammed.npz"
    code = main(["export", str(source), "--out", str(tmp_path / "out"), *argv])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and says in err, err


def test_dump_refuses_a_cell_lammps_cannot_hold(periodic, tmp_path):
    scene, _ = periodic
    frame = frame_of(scene)
    c, s = np.cos(0.3), np.sin(0.3)
    frame.cell = scene.cell @ np.array([[c, s], [-s, c]])          # a1 no longer along x
    with pytest.raises(granstab.SceneError, match="restricted triclinic"):
        write([frame], tmp_path, "dump")
    write([frame], tmp_path, "xyz")                                 # extended XYZ takes any cell


def test_a_3d_triclinic_cell_in_every_format(tmp_path):
    scene = packings.jammed(3, 16, shear=0.1)                    # a3 tilted along x: LAMMPS's xz tilt
    frame = frame_of(scene, modes=1)
    write([frame], tmp_path, "vtp", "j")
    corners = vtk_to_numpy(read_vtp(tmp_path / "j.cell.vtp").GetPoints().GetData())
    expect = np.array([i * scene.cell[0] + j * scene.cell[1] + k * scene.cell[2]
                       for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    assert {tuple(c) for c in np.round(corners, 12)} == {tuple(c) for c in np.round(expect, 12)}  # the 8 corners
    write([frame], tmp_path, "xyz", "j")
    atoms = ase_io.read(tmp_path / "j.xyz", format="extxyz")
    assert same(np.asarray(atoms.cell), scene.cell) and atoms.pbc.all()
    assert same(atoms.arrays["mode1_rotation"], frame.particles["mode1_rotation"])
    write([frame], tmp_path, "dump", "j")
    lines = (tmp_path / "j.atoms.dump").read_text().splitlines()
    assert lines[4] == "ITEM: BOX BOUNDS xy xz yz pp pp pp"
    bounds = np.array([ln.split() for ln in lines[5:8]], dtype=float)
    a, xz = scene.cell[0, 0], scene.cell[2, 0]
    assert same(bounds, [[0, a + xz, 0], [0, scene.cell[1, 1], xz], [0, scene.cell[2, 2], 0]])


def test_without_vtk_the_vtp_export_names_the_extra(packing, tmp_path, capsys, monkeypatch):
    _, root, _ = packing
    monkeypatch.setitem(__import__("sys").modules, "vtkmodules", None)        # as if vtk were not installed
    assert main(["export", str(root / "lattice.json"), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and 'pip install "granstab[export]"' in err, err
