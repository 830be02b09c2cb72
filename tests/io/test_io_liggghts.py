"""LIGGGHTS (Debian's liggghts 3.8.0): examples/liggghts/in.spheres3d compresses 200 frictional spheres in a
periodic box and loads them biaxially until contacts slide; a per-atom dump and a `compute pair/gran/local id
force` local dump, converted with the script (columns and the hooke/stiffness law from it) and analysed here. The
engine run is marked `liggghts` and needs the `liggghts` executable (.ci/run installs it): without it the test
fails, it does not skip. tests/data/io/liggghts is that run's output, read without the engine. Both are checked
against the per-atom forces LIGGGHTS wrote (fx fy fz, the sum over each atom's contacts: no gravity, no walls),
which pins the force to the first id of a row."""
import json
import shutil
import subprocess

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402
from io_checks import check_contact_geometry, check_region_analyses

import granstab
from granstab.cli import main

LIGGGHTS = ROOT / "examples" / "liggghts"
FIXTURE = DATA / "io" / "liggghts"
SCRIPT = LIGGGHTS / "in.spheres3d"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    if shutil.which("liggghts") is None:
        pytest.fail("liggghts: executable not found; the `liggghts` tests run Debian's LIGGGHTS (apt-get install -y "
                    "liggghts, as .ci/run does)", pytrace=False)
    out = tmp_path_factory.mktemp("liggghts")
    done = subprocess.run(["bash", str(LIGGGHTS / "run.sh"), str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return out


def rows(path):
    """The one timestep of a dump as numbers (plain text split, independent of granstab's reader)."""
    return np.loadtxt(path.read_text().split("\n", 9)[9].splitlines(), ndmin=2)


def check_liggghts_packing(folder, tmp_path, capsys):
    out = tmp_path / "liggghts.json"
    rc = main(["convert", str(folder / "atoms.dump"), str(folder / "contacts.dump"), str(SCRIPT), "--out", str(out),
               "--json"])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["format"] == "lammps" and report["particles"]["in_file"] == 200
    assert report["cone"]["at_yield"] >= 10 and report["cone"]["outside"]["count"] == 0   # the loading: sliding
    assert report["non_touching_pairs"]["count"] == 0          # pair/gran/local lists touching pairs only
    assert report["geometry"]["gaps"] == 0 and report["contacts"]["cut_around_periodic_cell"] == 0
    assert report["periodic"]["periodic"] and report["periodic"]["seam_contacts"] > 0   # kept with their images
    law = report["law"]
    assert (law["k"]["value"], law["alpha"]["value"], law["mu"]["value"]) == (2000.0, 0.5, 0.5)
    assert "fix property/global kn" in law["k"]["source"]
    assert report["imbalance"]["force"]["median"] < 0.05 and report["imbalance"]["moment"]["median"] < 0.05
    scene = granstab.load_scene(out)
    atoms, contacts = rows(folder / "atoms.dump"), rows(folder / "contacts.dump")
    ids = atoms[:, 0].astype(int)
    index = np.full(ids.max() + 1, -1)
    index[ids] = np.arange(len(ids))
    names = np.array(scene.names).astype(int)
    check_contact_geometry(scene, atoms[index[names], 5])      # unit normals, overlaps, points, third law
    # the file: f on id1, −f on id2 sums to each atom's force (LIGGGHTS' own fx fy fz)
    i, j, f = index[contacts[:, 0].astype(int)], index[contacts[:, 1].astype(int)], contacts[:, 3:6]
    net = np.zeros((len(ids), 3))
    np.add.at(net, i, f)
    np.add.at(net, j, -f)
    scale = np.abs(f).max()
    assert np.abs(net - atoms[:, 7:10]).max() <= 1e-9 * scale
    # the scene: f^pq with p the row's id1, the file's force (sliding ones put on the cone)
    row = {(a, b): k for k, (a, b) in enumerate(contacts[:, :2].astype(int).tolist())}
    pick = np.array([row[(a, b)] for a, b in zip(names[scene.p].tolist(), names[scene.q].tolist())])
    assert np.abs(scene.force - f[pick]).max() <= 1e-5 * scale
    check_region_analyses([folder / "atoms.dump", folder / "contacts.dump", SCRIPT],
                          "box:0.02,0.04,0.02,0.04,0.02,0.04", 6)
    return report


@pytest.mark.liggghts
def test_liggghts_packing_converts_with_sliding_contacts(run, tmp_path, capsys):
    check_liggghts_packing(run, tmp_path, capsys)


def test_liggghts_fixture_converts_with_sliding_contacts(tmp_path, capsys):
    report = check_liggghts_packing(FIXTURE, tmp_path, capsys)
    assert report["contacts"]["in_file"] == 579 and report["cone"]["at_yield"] == 44


@pytest.mark.parametrize("compute, columns", [
    ("id force", "id1 id2 - fx fy fz"),
    ("force id delta", "id1 id2 - fx fy fz delta"),                          # fixed order, not the keywords'
    ("contactPoint force_normal force_tangential id", "id1 id2 - fnx fny fnz ftx fty ftz cx cy cz"),
    ("", "- - - - - - - - - - - - id1 id2 - fx fy fz - - - - - - -"),         # default: ... torque history area
    ("id force history delta contactPoint", "id1 id2 - fx fy fz - - - - - - -"),  # after history: ignored
])
def test_pair_gran_local_columns_follow_liggghts_order(compute, columns):
    from granstab.io.lammps_script import compute_columns
    width = len(columns.split())
    names = compute_columns({"cpg": ("pair/gran/local", compute.split())}, "gran")
    got = [names.get(f"c_cpg[{k}]", names.get("c_cpg[*]")) for k in range(1, width + 1)]
    assert got == columns.split()


def test_liggghts_law_bad_value_is_one_line(tmp_path, capsys):
    script = tmp_path / "in.bad"
    script.write_text(SCRIPT.read_text().replace("kt peratomtypepair 1 1000.0", "kt peratomtypepair 1 1e3x"))
    rc = main(["convert", str(FIXTURE / "atoms.dump"), str(FIXTURE / "contacts.dump"), str(script),
               "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    line = 1 + SCRIPT.read_text().splitlines().index(
        next(t for t in SCRIPT.read_text().splitlines() if " kt peratomtypepair" in t))
    assert rc == 2 and err == f"{script}: line {line}: kt: not a number ('1e3x')", err
