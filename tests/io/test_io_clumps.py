"""Clumps from two engines, settled under gravity in a box: YADE (examples/yade/make_clumps.py, 60 dimers and bent
trimers, ~2 s) and LIGGGHTS multisphere (examples/liggghts_multisphere/run.sh, 100 dimers, ~2 s). The engine runs
are marked `yade` / `liggghts` and need the executables (.ci/run installs them): without them the tests fail, they
do not skip. tests/data/io/yade_clumps and tests/data/io/liggghts_multisphere are those runs' output, read
without the engines.

Checked from the raw files, independently of the readers (np.loadtxt): every member contact kept as a contact of
the two clumps; its point midway in the members' overlap and its arm from the clump's centre of mass; its
curvature that of the member's parallel surface, −(I − n⊗n)/(R − δ/2); the engine's masses and inertia tensors;
every clump's force and moment balance (contacts, walls, gravity) in the import report, at round-off for YADE
(settled to rest) and within the residual motion for LIGGGHTS; then analyze, scan, rigidity and export."""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402
from scipy.spatial.transform import Rotation

import granstab
from granstab.cli import main

EXAMPLES = ROOT / "examples"
DATA = DATA / "io"
SCRIPT = EXAMPLES / "liggghts_multisphere" / "in.clumps3d"


def _engine(name, command, tmp_path_factory):
    if shutil.which(name) is None:
        pytest.fail(f"{name}: executable not found (apt-get install -y {name}, as .ci/run does)", pytrace=False)
    out = tmp_path_factory.mktemp(name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}   # yade's own python3
    done = subprocess.run(command + [str(out)], cwd=out, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return out


@pytest.fixture(scope="module")
def yade_run(tmp_path_factory):
    return _engine("yade", ["yade", "-n", "-x", str(EXAMPLES / "yade" / "make_clumps.py")], tmp_path_factory)


@pytest.fixture(scope="module")
def liggghts_run(tmp_path_factory):
    return _engine("liggghts", ["bash", str(EXAMPLES / "liggghts_multisphere" / "run.sh")], tmp_path_factory)


# ------------------------------------------------------------------------------------------------ raw files

def yade_raw(folder):
    """(bodies, members, member contacts, wall contacts) from the tables, as dicts of arrays."""
    B = np.genfromtxt(folder / "bodies.csv", delimiter=",", names=True, skip_header=1)
    M = np.genfromtxt(folder / "members.csv", delimiter=",", names=True)
    C = np.genfromtxt(folder / "contacts.csv", delimiter=",", names=True)
    R = Rotation.from_quat(np.column_stack([B["quati"], B["quatj"], B["quatk"], B["quatw"]])).as_matrix()
    inertia = np.einsum("nik,nk,njk->nij", R, np.column_stack([B[f"inertia{k}"] for k in (1, 2, 3)]), R)
    bodies = {"id": B["body"].astype(int), "x": np.column_stack([B["x"], B["y"], B["z"]]), "mass": B["mass"],
              "inertia": inertia}
    members = {"id": M["id"].astype(int), "body": M["body"].astype(int),
               "x": np.column_stack([M["x"], M["y"], M["z"]]), "radius": M["radius"]}
    wall = C["id2"] < 0
    pairs = {"id1": C["id1"][~wall].astype(int), "id2": C["id2"][~wall].astype(int),
             "force": np.column_stack([C["fx"], C["fy"], C["fz"]])[~wall]}
    return bodies, members, pairs, int(wall.sum())


def dump_rows(path):
    text = path.read_text().split("\n")
    return np.loadtxt(text[9:], ndmin=2)


def liggghts_raw(folder):
    A, C, W, B = (dump_rows(folder / f"{n}.dump") for n in ("atoms", "contacts", "walls", "bodies"))
    axes = np.stack([B[:, 8:11], B[:, 11:14], B[:, 14:17]], 2)
    bodies = {"id": B[:, 0].astype(int), "x": B[:, 1:4], "mass": B[:, 4],
              "inertia": np.einsum("nik,nk,njk->nij", axes, B[:, 5:8], axes)}
    members = {"id": A[:, 0].astype(int), "body": A[:, 1].astype(int), "x": A[:, 3:6], "radius": A[:, 6]}
    pairs = {"id1": C[:, 0].astype(int), "id2": C[:, 1].astype(int), "force": C[:, 3:6]}
    return bodies, members, pairs, len(W)


def check_clumps(loaded, bodies, members, pairs, n_walls):
    """The scene against the raw tables (module docstring); returns the report."""
    scene, report = loaded.scene, loaded.report
    assert scene.n_contacts == len(pairs["id1"]) and report["walls"]["wall_contacts"] == n_walls   # all kept
    row = {i: k for k, i in enumerate(members["id"])}
    a = np.array([row[i] for i in pairs["id1"]])
    b = np.array([row[i] for i in pairs["id2"]])
    assert np.all(members["body"][a] != members["body"][b])                 # never two members of one clump
    touching = np.unique(members["body"][np.concatenate([a, b])])          # clumps touching another clump
    names = [str(i) for i in bodies["id"] if i in touching]                  # the rest: rattlers, dropped and named
    dropped = sorted(str(i) for i in bodies["id"] if i not in touching)
    assert report["particles"]["without_contacts_dropped"] == len(dropped)
    assert sorted(report["particles"]["dropped"]) == dropped
    index = {n: k for k, n in enumerate(scene.names)}
    body_row = {i: k for k, i in enumerate(bodies["id"])}
    p = np.array([index[str(members["body"][i])] for i in a])
    q = np.array([index[str(members["body"][i])] for i in b])
    assert np.array_equal(scene.p, p) and np.array_equal(scene.q, q)         # file order kept
    order = np.array([body_row[int(n)] for n in scene.names])
    assert sorted(scene.names) == sorted(names)
    np.testing.assert_array_equal(scene.x, bodies["x"][order])              # the clumps' centres of mass
    ca, cb, Ra, Rb = members["x"][a], members["x"][b], members["radius"][a], members["radius"][b]
    d = np.linalg.norm(cb - ca, axis=1)
    n = (cb - ca) / d[:, None]
    delta = Ra + Rb - d
    rho_p, rho_q = Ra - delta / 2, Rb - delta / 2
    point = ca + rho_p[:, None] * n
    scale = members["radius"].max()
    assert np.abs(scene.normal - n).max() <= 1e-12
    assert np.abs(scene.point - point).max() <= 1e-12 * scale              # midway in the members' overlap
    assert np.abs(scene.r_pq - (point - bodies["x"][order][p])).max() <= 1e-12 * scale   # arm from the COM
    tangent = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    for K, rho in ((scene.curvature_p, rho_p), (scene.curvature_q, rho_q)):   # the member sphere's, ρ = R − δ/2
        assert np.abs(K + tangent / rho[:, None, None]).max() <= 1e-12 / rho.min()
    # the file's forces, except contacts at yield (within yield_rtol of the cone, or outside it): projected onto the
    # cone and marked sliding, each moved by at most the report's largest change (≤ yield_rtol 1e-4 where none lies
    # outside); YADE's slipping contacts sit at the cone to ~1e-5
    size = np.linalg.norm(pairs["force"], axis=1)
    moved = np.linalg.norm(scene.force - pairs["force"], axis=1) > 1e-12 * np.abs(pairs["force"]).max()
    assert all(scene.state[c] == "sliding" for c in np.flatnonzero(moved))
    cone = report["cone"]
    assert cone["outside"]["count"] > 0 or cone["largest_change_over_force"] <= cone["yield_rtol"]
    assert np.all(np.linalg.norm(scene.force - pairs["force"], axis=1)
                  <= (cone["largest_change_over_force"] * (1 + 1e-9) + 1e-12) * size + 1e-12 * size.max())
    np.testing.assert_allclose(scene.mass, bodies["mass"][order], rtol=1e-15)
    np.testing.assert_allclose(scene.inertia, bodies["inertia"][order], rtol=0,
                               atol=1e-12 * np.abs(bodies["inertia"]).max())
    # the arms matter: with arms from each member's centre, the moment balance of a clump would fail by O(|f| L)
    off = np.linalg.norm(ca - bodies["x"][order][p], axis=1)
    assert np.median(off / Ra) > 0.3
    return report


def check_commands(scene_path, tmp_path, capsys, analyze=()):
    """analyze (with the options `analyze`), scan, rigidity and export of the converted clump scene exit 0 and write
    their outputs."""
    # --timeout: what is checked is that each command runs, not its time (a loaded machine's CPU-time probe once put
    # a fresh YADE run's estimate over the 10 s default, and the run was refused)
    for argv in (["analyze", str(scene_path), "--method", "sparse", "--k", "3", "--timeout", "600", *analyze],
                 ["scan", str(scene_path), "--out", str(tmp_path / "scan")],
                 ["rigidity", str(scene_path), "--out", str(tmp_path / "rigid")],
                 ["export", str(scene_path), "--scan-dir", str(tmp_path / "scan"), "--out", str(tmp_path / "vtp")],
                 ["export", str(scene_path), "--out-format", "xyz", "--out", str(tmp_path / "xyz")]):
        rc = main(argv)
        out = capsys.readouterr()
        assert rc == 0, (argv, out.err[-2000:])
    scanned = json.loads((tmp_path / "scan" / "summary.json").read_text())
    scene = granstab.load_scene(scene_path)
    assert scanned["clusters"] == scene.n_particles
    assert (tmp_path / "rigid" / "rigidity.json").is_file()
    vtp = len(list((tmp_path / "vtp").glob("*.vtp")))              # particles, contacts (and a periodic scene's cell)
    assert vtp == 2 + scene.periodic and list((tmp_path / "xyz").glob("*.xyz"))


# ------------------------------------------------------------------------------------------------ YADE

def check_yade(folder, tmp_path, capsys):
    out = tmp_path / "clumps.json"
    rc = main(["convert", str(folder), "--out", str(out), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["format"] == "clumps"
    loaded = granstab.io.load(folder)
    raw = yade_raw(folder)
    check_clumps(loaded, *raw)
    C = np.genfromtxt(folder / "contacts.csv", delimiter=",", names=True)
    touching = len(np.unique(raw[1]["body"][np.isin(raw[1]["id"], np.concatenate([C["id1"], C["id2"]]))]))
    # settled to rest (unbalanced force < 0.5 %, then one step without motion): every clump touching anything
    # (a clump or a wall) balances contacts, walls and gravity to 1e-7 of its summed |f| and |r||f|: measured
    # ~2e-13, and up to 7e-11 (force) and 2e-8 (moment) for a clump resting on the floor alone, still rocking at
    # the damping's residual speed (1 run in 3)
    imb = report["imbalance"]
    assert imb["particles"] == touching >= 55 and imb["force"]["max"] <= 1e-7 and imb["moment"]["max"] <= 1e-7
    assert report["geometry"]["engine_point_offset_over_radius"]["max"] <= 1e-12   # ScGeom: the same point
    assert report["bodies"]["kind"] == "clump" and report["masses"].startswith("the file's masses and inertia")
    # a fresh YADE run leaves a varying number of contacts at yield (22 once: above --max-sliding 16, refused):
    # a sample of branches, whatever the count
    check_commands(out, tmp_path, capsys, analyze=("--sample-branches", "8"))


@pytest.mark.yade
def test_yade_clump_packing_converts_and_balances(yade_run, tmp_path, capsys):
    check_yade(yade_run, tmp_path, capsys)


def test_yade_clump_fixture_converts_and_balances(tmp_path, capsys):
    check_yade(DATA / "yade_clumps", tmp_path, capsys)


def test_a_clump_resting_on_the_floor_alone_balances(tmp_path, capsys):
    """A YADE run (same script) where clump 193 touches only the floor: dropped as a rattler, yet its balance is
    reported against the size of its loads (Σ|f| of walls and gravity), not against their sum (≈ 0: was 1.0)."""
    check_yade(DATA / "yade_clumps_floor_rattler", tmp_path, capsys)


def test_two_members_of_one_clump_touching_are_refused(tmp_path, capsys):
    for name in ("bodies.csv", "members.csv", "contacts.csv"):
        shutil.copy(DATA / "yade_clumps" / name, tmp_path / name)
    members = (tmp_path / "members.csv").read_text().splitlines()
    first, second = members[1].split(","), members[2].split(",")
    assert first[1] == second[1]                                     # the first two members: one clump
    lines = (tmp_path / "contacts.csv").read_text().splitlines()
    lines[5] = ",".join([first[0], second[0]] + lines[5].split(",")[2:])
    (tmp_path / "contacts.csv").write_text("\n".join(lines) + "\n")
    rc = main(["convert", str(tmp_path), "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err == (f"{tmp_path / 'contacts.csv'}: line 6: contact {first[0]}-{second[0]}: id2: both "
                               f"parts belong to clump {first[1]} (a rigid body's parts cannot touch each other; "
                               "engines exclude them)"), err


# ------------------------------------------------------------------------------------------------ LIGGGHTS

def check_liggghts(folder, tmp_path, capsys):
    out = tmp_path / "clumps.json"
    files = [str(folder / f"{n}.dump") for n in ("atoms", "contacts", "walls", "bodies")]
    rc = main(["convert", *files, str(SCRIPT), "--out", str(out), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["format"] == "liggghts_multisphere"
    loaded = granstab.io.load(files + [str(SCRIPT)])
    check_clumps(loaded, *liggghts_raw(folder))
    assert report["law"]["k"]["value"] == 2000.0 and report["law"]["mu"]["value"] == 0.5
    assert report["walls"]["gravity"] == [0.0, 0.0, -9.81]
    # quasi-static (kinetic energy ~3e-8 J left, tangential damping): each clump's residual is a few per cent at
    # most of its summed |f|; a wrong arm or a wall's point or gravity left out gives O(1) (measured: force median
    # 5e-3, max 0.034; moment median 3e-3, max 0.031)
    imb = report["imbalance"]
    assert imb["particles"] == 100
    assert imb["force"]["median"] <= 0.02 and imb["force"]["max"] <= 0.1
    assert imb["moment"]["median"] <= 0.02 and imb["moment"]["max"] <= 0.1
    # LIGGGHTS's contactPoint is within 1e-3 of a member radius of the midpoint of the overlap (unequal radii)
    assert report["geometry"]["engine_point_offset_over_radius"]["max"] <= 1e-3
    assert "largest difference" in report["quaternion"]
    np.testing.assert_allclose(np.linalg.norm(loaded.orientation, axis=1), 1.0, rtol=1e-12)
    check_commands(out, tmp_path, capsys)


@pytest.mark.liggghts
def test_liggghts_multisphere_packing_converts_and_balances(liggghts_run, tmp_path, capsys):
    check_liggghts(liggghts_run, tmp_path, capsys)


def test_liggghts_multisphere_fixture_converts_and_balances(tmp_path, capsys):
    check_liggghts(DATA / "liggghts_multisphere", tmp_path, capsys)


def test_gravity_left_out_shows_in_the_balance(tmp_path):
    """Without the script's gravity the top clumps' contact forces cannot balance: the residual is O(1)."""
    script = tmp_path / "in.clumps3d"
    script.write_text(SCRIPT.read_text().replace("fix             gravi all gravity", "# fix gravi all gravity"))
    files = [DATA / "liggghts_multisphere" / f"{n}.dump" for n in ("atoms", "contacts", "walls", "bodies")]
    report = granstab.io.load(files + [script]).report
    assert report["walls"]["gravity"] is None and report["imbalance"]["force"]["max"] > 0.3


def test_liggghts_walls_dump_missing_is_refused_when_the_script_has_walls():
    """The script has mesh walls (fix wall/gran): without wall/gran/local's dump their forces would be lost."""
    files = [DATA / "liggghts_multisphere" / f"{n}.dump" for n in ("atoms", "contacts", "bodies")]
    with pytest.raises(granstab.SceneError, match=r"need the dumps of .* no walls dump"):
        granstab.io.load(files + [SCRIPT])
