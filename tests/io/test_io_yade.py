"""YADE (Debian's yade 2023.02a): examples/yade/make_packing.py compresses 200 frictional spheres in a box of six
walls and loads them triaxially until contacts slide; its exporter (examples/yade/export_granstab.py) writes the
generic tables, converted and analysed here. The engine run is marked `yade` and needs the `yade` executable
(.ci/run installs it): without it the test fails, it does not skip. tests/data/io/yade is that script's output
(made by real YADE), read without the engine. Both are checked against YADE's own per-body force and torque sums
(yade_resultants.json: O.forces after the export step), which pins the exporter's sign conventions."""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402
from io_checks import check_contact_geometry, check_region_analyses

import granstab
from granstab.cli import main

YADE = ROOT / "examples" / "yade"
FIXTURE = DATA / "io" / "yade"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    if shutil.which("yade") is None:
        pytest.fail("yade: executable not found; the `yade` tests run Debian's YADE (apt-get install -y yade, "
                    "as .ci/run does)", pytrace=False)
    out = tmp_path_factory.mktemp("yade")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}  # yade's own python3
    done = subprocess.run(["yade", "-n", "-x", str(YADE / "make_packing.py"), str(out)], cwd=out, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return out


def check_yade_packing(folder, tmp_path, capsys):
    out = tmp_path / "yade.json"
    rc = main(["convert", str(folder), "--out", str(out), "--json"])          # the folder: both tables
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["format"] == "table" and report["particles"]["in_file"] == 200
    assert report["cone"]["at_yield"] >= 10 and report["cone"]["outside"]["count"] == 0   # sliding: on the cone
    assert report["geometry"]["gaps"] == 0
    assert report["geometry"]["normal_to_centre_line_deg_max"] < 1e-4      # YADE's normal (file) is p → q
    assert report["walls"]["walls"] == 6 and report["walls"]["wall_contacts"] > 50
    assert report["law"]["k"]["source"] == "contacts.csv column kn" and report["law"]["mu"]["value"] == pytest.approx(
        np.tan(np.radians(30)), rel=1e-12)
    imbalance = report["imbalance"]                                         # quasi-static, not static
    assert imbalance["force"]["median"] < 0.02 and imbalance["moment"]["median"] < 0.02
    scene = granstab.load_scene(out)
    assert scene.dim == 3 and scene.state.count("sliding") == report["cone"]["at_yield"]
    P = np.genfromtxt(folder / "particles.csv", delimiter=",", names=True)
    C = np.genfromtxt(folder / "contacts.csv", delimiter=",", names=True)
    ids = P["id"].astype(int)
    index = np.full(ids.max() + 1, -1)
    index[ids] = np.arange(len(ids))
    names = np.array(scene.names).astype(int)
    check_contact_geometry(scene, P["radius"][index[names]])               # unit normals, overlaps, points, 3rd law
    # YADE's sums over each sphere's interactions vs the contacts: f^pq on p, −f^pq on q (Newton's third law),
    # walls on the sphere, torques (x_c − x) × f about the centre (frictionless walls: none)
    yade = json.loads((folder / "yade_resultants.json").read_text())
    F, T = np.zeros((len(ids), 3)), np.zeros((len(ids), 3))
    F[index[yade["id"]]], T[index[yade["id"]]] = yade["force"], yade["torque"]
    f = np.column_stack([C["fx"], C["fy"], C["fz"]])
    wall = C["id2"] < 0
    a, b = index[C["id1"].astype(int)], index[np.where(wall, ids[0], C["id2"]).astype(int)]
    net = np.zeros((len(ids), 3))
    np.add.at(net, a, f)
    np.add.at(net, b[~wall], -f[~wall])
    scale = np.abs(f).max()
    assert np.abs(net - F).max() <= 1e-12 * scale                          # the tables, as written
    walls = np.zeros((len(ids), 3))
    np.add.at(walls, a[wall], f[wall])
    net, torque = np.zeros((scene.n_particles, 3)), np.zeros((scene.n_particles, 3))
    for side, sign in ((scene.p, 1.0), (scene.q, -1.0)):
        np.add.at(net, side, sign * scene.force)
        np.add.at(torque, side, np.cross(scene.point - scene.x[side], sign * scene.force))
    rows = index[names]
    assert np.abs(net + walls[rows] - F[rows]).max() <= 1e-5 * scale      # the scene: sliding forces put on the cone
    assert np.abs(torque - T[rows]).max() <= 1e-5 * scale * P["radius"].max()
    assert np.abs(scene.load + net).max() <= 1e-12 * scale                 # loads close the balance
    # a cluster in the middle of the box, analysed
    check_region_analyses(folder, "box:0.3,0.5,0.3,0.5,0.3,0.5", 8)
    return report


@pytest.mark.yade
def test_yade_packing_converts_with_sliding_contacts_and_balances(run, tmp_path, capsys):
    check_yade_packing(run, tmp_path, capsys)


def test_yade_fixture_converts_with_sliding_contacts_and_balances(tmp_path, capsys):
    report = check_yade_packing(FIXTURE, tmp_path, capsys)
    assert report["contacts"]["in_scene"] == 370 and report["cone"]["at_yield"] == 48


def test_yade_table_bad_field_is_one_line(tmp_path, capsys):
    for name in ("particles.csv", "contacts.csv"):
        shutil.copy(FIXTURE / name, tmp_path / name)
    lines = (tmp_path / "contacts.csv").read_text().splitlines()
    lines[4] = ",".join(lines[4].split(",")[:3] + ["1.5e"] + lines[4].split(",")[4:])
    (tmp_path / "contacts.csv").write_text("\n".join(lines) + "\n")
    rc = main(["convert", str(tmp_path), "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err == f"{tmp_path / 'contacts.csv'}: line 5: fy: not a number ('1.5e')", err


# ------------------------------------------------------------------------------------------------ periodic cells

PERIODIC = DATA / "io" / "yade_periodic"


@pytest.fixture(scope="module")
def periodic_run(tmp_path_factory):
    if shutil.which("yade") is None:
        pytest.fail("yade: executable not found (apt-get install -y yade, as .ci/run does)", pytrace=False)
    out = tmp_path_factory.mktemp("yade_periodic")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    done = subprocess.run(["yade", "-n", "-x", str(YADE / "make_periodic.py"), str(out)], cwd=out, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return out


def check_periodic_yade(folder):
    """YADE's periodic cell through the exporter: the scene is periodic with YADE's cell (the columns of hSize as
    rows), every interaction a contact, and YADE's own per-body forces and torques are the scene's sums, torques
    taken about each centre with r^qp from q's copy x^q + image·cell: a wrong image would put that arm a cell away."""
    imp = granstab.load(folder)
    scene, report = imp.scene, imp.report
    yade = json.loads((folder / "yade_resultants.json").read_text())
    C = np.genfromtxt(folder / "contacts.csv", delimiter=",", names=True)
    P = np.genfromtxt(folder / "particles.csv", delimiter=",", names=True, skip_header=1)   # after the # cell: line
    assert report["periodic"]["periodic"] and report["contacts"]["cut_around_periodic_cell"] == 0
    assert np.array_equal(scene.cell, np.array(yade["hSize"]).T)
    assert scene.n_contacts == len(C) and report["periodic"]["seam_contacts"] >= 10
    ids = P["id"].astype(int)
    index = np.full(ids.max() + 1, -1)
    index[ids] = np.arange(len(ids))
    names = np.array(scene.names).astype(int)
    check_contact_geometry(scene, P["radius"][index[names]])
    F, T = np.zeros((len(ids), 3)), np.zeros((len(ids), 3))
    F[index[yade["id"]]], T[index[yade["id"]]] = yade["force"], yade["torque"]
    net, torque = np.zeros((scene.n_particles, 3)), np.zeros((scene.n_particles, 3))
    for side, sign, arm in ((scene.p, 1.0, scene.r_pq), (scene.q, -1.0, scene.r_qp)):
        np.add.at(net, side, sign * scene.force)
        np.add.at(torque, side, np.cross(arm, sign * scene.force))
    rows = index[names]
    scale = np.abs(scene.force).max()
    assert np.abs(net - F[rows]).max() <= 1e-5 * scale              # sliding forces put on the cone: 1e-4 of |f|
    assert np.abs(torque - T[rows]).max() <= 1e-5 * scale * P["radius"].max()
    return scene


@pytest.mark.yade
def test_yade_periodic_cell_converts_with_every_contact(periodic_run):
    check_periodic_yade(periodic_run)


def test_yade_periodic_fixture_converts_with_every_contact():
    scene = check_periodic_yade(PERIODIC)
    assert scene.cell[1, 0] > 0.01 * scene.cell[1, 1]                  # sheared: the second vector tilted along x
