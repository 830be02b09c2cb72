"""What a new user hit (issue 26): the command line's arguments, a closed pipe, Ctrl-C and resume, a missing extra,
the scan's default workers, and the import report's words and numbers."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
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
