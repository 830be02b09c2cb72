"""What a new user hit (issue 26): the command line's arguments, a closed pipe, Ctrl-C and resume, a missing extra,
the scan's default workers, and the import report's words and numbers."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import granstab
from granstab.cli import main
from granstab.io import load

ROOT = Path(__file__).parents[1]
LAMMPS = ROOT / "tests" / "data" / "io" / "lammps"
TABLE = ROOT / "tests" / "data" / "io" / "table"
LAMMPS_2D = [LAMMPS / "atoms2d.dump", LAMMPS / "contacts2d.dump", ROOT / "examples" / "dem" / "in.disks2d"]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / ".shim"), str(ROOT),
                                                     os.environ.get("PYTHONPATH", "")])}


def granstab_cli(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "granstab", *map(str, args)], capture_output=True, text=True,
                          env=ENV, **kwargs)


# ------------------------------------------------------------------------------------------------ arguments

def test_analyze_takes_a_snapshot_as_several_files_as_convert_does(capsys):
    """`analyze atoms.dump contacts.dump in.disks` (the README's FOLDER_OR_FILES) analyses the scene that
    `granstab.io.load` of those files builds; stiffness, extract and scan take the same inputs."""
    assert main(["analyze", *map(str, LAMMPS_2D), "--metric", "L", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    loaded = load(LAMMPS_2D)
    expected = json.loads(json.dumps(granstab.analyze(loaded.scene, metric="L").to_dict()))
    assert got["n_particles"] == loaded.scene.n_particles == 127 and got["import"]["source"] == loaded.report["source"]
    assert {k: v for k, v in got.items() if k not in ("import", "timings")} == {
        k: v for k, v in expected.items() if k != "timings"}
    assert main(["analyze", str(LAMMPS_2D[0]), "nope.dump", "--metric", "L"]) == 2     # one line, as convert says
    assert capsys.readouterr().err.count("\n") == 1


def test_a_columns_value_beginning_with_a_dash_is_taken_as_written_or_with_equals(tmp_path, capsys):
    """`--columns -,id1,…` (an ignored first column) was refused by argparse ('expected one argument'); now it is
    read as `--columns=-,…` is, and both give the scene of the table without that column."""
    shutil.copy(TABLE / "particles.csv", tmp_path / "particles.csv")
    rows = (TABLE / "contacts.csv").read_text().splitlines()
    (tmp_path / "contacts.csv").write_text("\n".join(["row," + rows[0]] + [f"{i},{r}" for i, r in
                                                                           enumerate(rows[1:])]) + "\n")
    plain = load([TABLE / "particles.csv", TABLE / "contacts.csv"]).scene
    inputs = [str(tmp_path / "particles.csv"), str(tmp_path / "contacts.csv")]
    for i, columns in enumerate([["--columns", "-,id1,id2,fx,fy"], ["--columns=-,id1,id2,fx,fy"]]):
        out = tmp_path / f"scene{i}.json"
        assert main(["convert", *inputs, *columns, "--out", str(out)]) == 0, capsys.readouterr().err
        scene = granstab.load_scene(out)
        assert scene.names == plain.names and np.array_equal(scene.force, plain.force)
    assert main(["stiffness", str(ROOT / "presets" / "two_particle.toml"), "--out", str(tmp_path / "k.npz"),
                 "--mask", "-1"]) == 0          # a mask beginning with a dash, as before
    assert main(["convert", *inputs, "--columns", "--json", "--out", str(tmp_path / "x.json")]) == 2   # no value
    assert "--columns: expected one argument" in capsys.readouterr().err


def test_a_closed_pipe_is_a_quiet_exit():
    """`convert … | head -3`: the reader closes the pipe before granstab writes its report: no 'cannot write Broken
    pipe', nothing on stderr, exit 0 (the scene file was written; the reader chose to stop reading)."""
    out = Path(os.environ.get("TMPDIR", "/tmp")) / f"granstab-pipe-{os.getpid()}.json"
    proc = subprocess.Popen([sys.executable, "-m", "granstab", "convert", *map(str, LAMMPS_2D), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV)
    proc.stdout.close()                                   # the reader has gone before anything was written
    err = proc.stderr.read().decode()
    assert proc.wait() == 0 and err == ""
    assert granstab.load_scene(out).n_particles == 127
    out.unlink()


# ------------------------------------------------------------------------------------------------ import report

def three_disks(tmp_path, radii=(1.0, 1.0, 1.0), header="id1,id2,fx,fy", extra=""):
    """The table fixture's three disks with other radii (and optionally another contact header and first column)."""
    rows = (TABLE / "particles.csv").read_text().splitlines()
    data = [r for r in rows if r and r[0].isdigit()]
    (tmp_path / "particles.csv").write_text("id,x,y,radius\n" + "\n".join(
        ",".join(r.split(",")[:3] + [str(radius)]) for r, radius in zip(data, radii)) + "\n")
    contacts = (TABLE / "contacts.csv").read_text().splitlines()[1:]
    (tmp_path / "contacts.csv").write_text(header + "\n" + "\n".join(
        (f"{i}," if extra else "") + c for i, c in enumerate(contacts)) + "\n")
    return [tmp_path / "particles.csv", tmp_path / "contacts.csv"]


def test_extreme_overlaps_are_warned_with_the_worst_values_and_the_pairs(tmp_path):
    """Radii 1.0, 1.3, 1.0 on the fixture's centres (1.98 and 1.97 apart): two overlaps of 0.28–0.29 of the pairs'
    mean radius, one of 0.03. The warning counts those above 0.1 and gives the largest overlap and the smallest d/(R_p+R_q), both
    computed here from the files, the worst pair first; the fixture as it is (overlap 0.01–0.02) is not warned."""
    radii = np.array([1.0, 1.3, 1.0])
    paths = three_disks(tmp_path, radii)
    x = np.loadtxt(paths[0], delimiter=",", skiprows=1)[:, 1:3]
    pairs = np.loadtxt(paths[1], delimiter=",", skiprows=1)[:, :2].astype(int) - 1
    d = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    total = radii[pairs[:, 0]] + radii[pairs[:, 1]]
    overlap = 2 * (total - d) / total
    assert np.sum(overlap > 0.1) == 2 and overlap.max() > 0.2            # the case is what it claims
    worst = pairs[np.argmax(overlap)] + 1
    (line,) = [w for w in load(paths).warnings if "overlap by more than" in w]
    assert line.startswith(f"2 contact(s) overlap by more than 0.1 of the pair's mean radius (2δ/(R_p+R_q) up to "
                           f"{overlap.max():.3g}; d/(R_p+R_q) down to {(d / total).min():.3g})")
    assert line.endswith(f"({worst[0]}-{worst[1]}, " + line.split(", ")[-1])
    assert not [w for w in load(three_disks(tmp_path)).warnings if "overlap" in w]


def test_the_text_report_shows_the_columns_and_the_pairs_that_do_not_touch(tmp_path):
    """The column mapping and the non-touching pairs were only in --json; now the text says them too."""
    from granstab.io import format_report
    rep = load(LAMMPS_2D).report
    text = format_report(rep)
    assert ("columns of contacts2d.dump (from the input script): c_ends[1] → id1, c_ends[2] → id2, c_pair[1] → fnx"
            in text)
    apart = rep["non_touching_pairs"]
    assert apart["count"] > 0 and (f"non-touching pairs: {apart['count']} listed by the file and dropped, "
                                   f"{apart['with_force']} of them with a force" in text)
    paths = three_disks(tmp_path, header="row,id1,id2,fx,fy", extra="row")
    text = format_report(load(paths, columns="-,id1,id2,fx,fy").report)
    assert "columns of contacts.csv (from --columns): row → ignored, id1 → id1, id2 → id2, fx → fx, fy → fy" in text


@pytest.mark.parametrize("policy, sliding", [("sliding", True), ("project", False)])
def test_the_contact_states_are_said_in_words(tmp_path, policy, sliding):
    """'7 sliding, 0 elastic' said what? With μ = 0.01 the fixture's contacts whose |f_t| > μ f_n (counted here
    from the files) are at the friction limit (policy sliding) or forced elastic (policy project)."""
    from granstab.io import format_report
    paths = three_disks(tmp_path)
    x = np.loadtxt(paths[0], delimiter=",", skiprows=1)[:, 1:3]
    rows = np.loadtxt(paths[1], delimiter=",", skiprows=1)
    p, q = rows[:, 0].astype(int) - 1, rows[:, 1].astype(int) - 1
    n = (x[q] - x[p]) / np.linalg.norm(x[q] - x[p], axis=1)[:, None]
    fn = -np.sum(rows[:, 2:4] * n, axis=1)
    ft = np.linalg.norm(rows[:, 2:4] + fn[:, None] * n, axis=1)
    outside = int(np.sum(ft > 0.01 * fn * (1 + 1e-4)))
    assert 0 < outside < 3
    text = format_report(load(paths, mu=0.01, outside_cone=policy).report)
    at_limit, forced = (outside, 0) if sliding else (0, outside)
    assert (f"{at_limit} at the friction limit (sliding: both of their branches are examined), {forced} forced "
            f"elastic by the input (tension, or outside the cone with --outside-cone project/elastic), "
            f"{3 - outside} inside the cone (sticking)") in text
    assert f"{outside} outside ({100 * outside / 3:.1f} %)" in text        # a share over 10 %: one decimal


@pytest.mark.parametrize("fraction, text", [(0.0005, "0.05 %"), (0.000123, "0.012 %"), (0.012345, "1.2 %"),
                                            (0.0, "0 %"), (1.0, "100 %"), (0.999996, "99.9996 %"),
                                            (4e-7, "4e-05 %"), (0.5, "50.0 %")])
def test_small_shares_keep_their_significant_digits(fraction, text):
    """One helper writes every share of the report: 0.05 % where '{:.1f}' wrote '0.0 %', never 0 % or 100 % for a
    share that is neither."""
    from granstab.io.validation import percent
    assert percent(fraction) == text
