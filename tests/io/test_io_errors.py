"""Malformed inputs to every granstab.io reader: exit 2 with one line naming the file, the line (or frame /
timestep) and the field; never a traceback (issue 9, issue 12). Fixtures: tests/data/io/."""
import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from granstab.cli import main

DATA = DATA / "io"
DATASIM = ROOT.parent / "shared" / "data" / "rigidlibrary" / "DataSim"


def convert(capsys, *args):
    """Run `granstab convert`; the exit status and stderr (asserted to be at most one line)."""
    rc = main(["convert", *map(str, args)])
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return rc, err


def garble(path: Path, cut: float, junk: bytes, at: float, cut_below: float = 0.5):
    """Truncate `path` at `cut` of its length (when cut < cut_below) and splice `junk` in at `at`."""
    data = path.read_bytes()
    data = data[: int(cut * len(data))] if cut < cut_below else data
    i = int(at * len(data))
    path.write_bytes(data[:i] + junk + data[i:])


def exits_cleanly(rc: int, err: str):
    """Success with nothing on stderr, or exit 2 with one line (convert() checked it is one line)."""
    assert rc in (0, 2)
    assert (rc == 0) == (err == ""), err


def copy(tmp_path, name):
    dest = tmp_path / name
    shutil.copytree(DATA / name if (DATA / name).exists() else DATASIM, dest)
    return dest


def edit(path: Path, line: int, text: str | None):
    """Replace 1-based `line` of `path` by `text` (None: delete it)."""
    lines = path.read_text().splitlines(keepends=True)
    if text is None:
        del lines[line - 1]
    else:
        lines[line - 1] = text
    path.write_text("".join(lines))


def field(path: Path, line: int, col: int, value: str, sep=","):
    cells = path.read_text().splitlines()[line - 1].split(sep)
    cells[col] = value
    edit(path, line, sep.join(cells) + "\n")


ANNULUS_CASES = {
    # name: (edit, expected pieces of the message)
    "truncated": (lambda d: (d / "Adjacency_list.txt").write_text(
        (d / "Adjacency_list.txt").read_text()[:-12]), ["Adjacency_list.txt", "line 126", "columns"]),
    "missing column": (lambda d: edit(d / "particle_positions.txt", 3, "1,17,2575,5954,44\n"),
                       ["particle_positions.txt", "line 3", "edge", "5 columns"]),
    "not a number": (lambda d: field(d / "particle_positions.txt", 4, 2, "12O5.5"),
                     ["particle_positions.txt", "line 4", "x", "not a number"]),
    "nan": (lambda d: field(d / "Adjacency_list.txt", 5, 4, "nan"),
            ["Adjacency_list.txt", "line 5", "normal", "not a finite number"]),
    "unknown id": (lambda d: field(d / "Adjacency_list.txt", 7, 2, "99999"),
                   ["Adjacency_list.txt", "line 7", "id2", "unknown particle id 99999"]),
    "negative radius": (lambda d: field(d / "particle_positions.txt", 2, 4, "-44"),
                        ["particle_positions.txt", "line 2", "radius", "> 0"]),
    "fractional id": (lambda d: field(d / "particle_positions.txt", 6, 1, "12.5"),
                      ["particle_positions.txt", "line 6", "id", "not an integer"]),
    "mismatched frames": (lambda d: field(d / "Adjacency_list.txt", 1, 0, "3"),
                          ["Adjacency_list.txt", "frame 3", "frame", "not in particle_positions.txt"]),
    "duplicate particle": (lambda d: edit(d / "particle_positions.txt", 2,
                                          (d / "particle_positions.txt").read_text().splitlines()[0] + "\n"),
                           ["particle_positions.txt", "line 2", "id", "listed twice"]),
}


@pytest.mark.parametrize("case", sorted(ANNULUS_CASES))
def test_malformed_annulus_input(tmp_path, capsys, case):
    folder = copy(tmp_path, "annulus")
    change, pieces = ANNULUS_CASES[case]
    change(folder)
    rc, err = convert(capsys, folder, "--frame", "1", "--out", tmp_path / "x.json")
    assert rc == 2
    for piece in pieces:
        assert piece in err, (piece, err)


def test_coincident_centres_name_the_contact_line(tmp_path, capsys):
    folder = copy(tmp_path, "annulus")
    adj = (folder / "Adjacency_list.txt").read_text().splitlines()
    first = adj[0].split(",")
    pos = (folder / "particle_positions.txt").read_text().splitlines()
    rows = {line.split(",")[1]: i for i, line in enumerate(pos) if line.startswith("1,")}
    a, b = pos[rows[first[1]]].split(","), pos[rows[first[2]]].split(",")
    b[2:4] = a[2:4]
    edit(folder / "particle_positions.txt", rows[first[2]] + 1, ",".join(b) + "\n")
    rc, err = convert(capsys, folder, "--frame", "1", "--out", tmp_path / "x.json")
    assert rc == 2 and "Adjacency_list.txt: line" in err and "x: the two centres coincide" in err


def test_missing_frame(tmp_path, capsys):
    rc, err = convert(capsys, DATA / "annulus", "--frame", "7", "--out", tmp_path / "x.json")
    assert rc == 2 and "frame 7: frame: not in the file" in err and "particle_positions.txt" in err


def test_missing_input_and_unknown_format(tmp_path, capsys):
    rc, err = convert(capsys, tmp_path / "nothing", "--out", tmp_path / "x.json")
    assert rc == 2 and "nothing: cannot read file" in err
    (tmp_path / "odd.dat").write_text("1 2 3\n")
    rc, err = convert(capsys, tmp_path / "odd.dat", "--out", tmp_path / "x.json")
    assert rc == 2 and "odd.dat: format: not recognised" in err


DATASIM_CASES = {
    "unknown particle": (lambda d: field(d / "Contact5000.dat", 9, 1, "5000", sep="           "),
                         ["Contact5000.dat", "line 9", "j", "unknown particle 5000"]),
    "particle count": (lambda d: edit(d / "PosVel5000.dat", 1024, None),
                       ["PosVel5000.dat", "x", "np = 1024"]),
    "missing contact file": (lambda d: (d / "Contact5000.dat").unlink(),
                             ["Contact5000.dat", "frame 5000", "missing"]),
    "negative radius": (lambda d: field(d / "posinit.dat", 12, 3, "-1.0", sep="           "),
                        ["posinit.dat", "line 12", "radius"]),
    "missing parameter": (lambda d: (d / "Parameters_final.dat").write_text(
        (d / "Parameters_final.dat").read_text().replace("k_rep", "k_xyz")), ["Parameters_final.dat", "k_rep"]),
}


@pytest.mark.parametrize("case", sorted(DATASIM_CASES))
def test_malformed_datasim_input(tmp_path, capsys, case):
    folder = copy(tmp_path, "DataSim")
    change, pieces = DATASIM_CASES[case]
    change(folder)
    rc, err = convert(capsys, folder, "--out", tmp_path / "x.json")
    assert rc == 2
    for piece in pieces:
        assert piece in err, (piece, err)


def test_missing_timestep_datasim(tmp_path, capsys):
    rc, err = convert(capsys, DATASIM, "--timestep", "4000", "--out", tmp_path / "x.json")
    assert rc == 2 and "frame 4000" in err and "PosVel4000.dat" in err


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(["particle_positions.txt", "Adjacency_list.txt"]),
       cut=st.floats(0.0, 1.0), junk=st.binary(max_size=40), at=st.floats(0.0, 1.0))
def test_garbled_annulus_files_never_raise(tmp_path_factory, capsys, which, cut, junk, at):
    """Truncate a file anywhere and splice random bytes in: success or exit 2 with one line, nothing else."""
    folder = tmp_path_factory.mktemp("fuzz") / "annulus"
    shutil.copytree(DATA / "annulus", folder)
    path = folder / which
    garble(path, cut, junk, at, 0.5)
    rc, err = convert(capsys, folder, "--frame", "1", "--out", folder / "x.json")
    exits_cleanly(rc, err)


LAMMPS = DATA / "lammps"
SCRIPT2 = ROOT / "examples" / "dem" / "in.disks2d"


def lammps_copy(tmp_path):
    for name in ("atoms2d.dump", "contacts2d.dump"):
        shutil.copy(LAMMPS / name, tmp_path / name)
    return tmp_path / "atoms2d.dump", tmp_path / "contacts2d.dump"


def last_block_line(path: Path, offset: int) -> int:
    """1-based line `offset` lines after the last ITEM: ENTRIES/ATOMS header (offset 1 = first row)."""
    lines = path.read_text().splitlines()
    header = max(i for i, text in enumerate(lines) if text.startswith(("ITEM: ENTRIES", "ITEM: ATOMS")))
    return header + 1 + offset


def set_cell(path: Path, line: int, col: int, value: str):
    field(path, line, col, value, sep=" ")


LAMMPS_CASES = {    # a truncated last timestep and timesteps in one dump only: tests/io/test_io_source.py
    "short row": (lambda a, c: edit(c, last_block_line(c, 3), "25 800 1.0\n"), ["contacts2d.dump", "line",
                                                                                 "columns"]),
    "unknown id": (lambda a, c: set_cell(c, last_block_line(c, 2), 1, "99999"),
                   ["contacts2d.dump", "id2", "unknown particle id 99999", "timestep 21000"]),
    "nan": (lambda a, c: set_cell(a, last_block_line(a, 4), 2, "nan"), ["atoms2d.dump", "x", "not a finite number"]),
    "negative radius": (lambda a, c: set_cell(a, last_block_line(a, 5), 5, "-0.5"),
                        ["atoms2d.dump", "radius", "must be > 0"]),
    "garbled header": (lambda a, c: c.write_text(c.read_text().replace("NUMBER OF ENTRIES\n266", "NUMBER OF ENTRIES\nabc")),
                       ["contacts2d.dump", "line 4", "number of rows", "not a number"]),
}


@pytest.mark.parametrize("case", sorted(LAMMPS_CASES))
def test_malformed_lammps_input(tmp_path, capsys, case):
    atoms, contacts = lammps_copy(tmp_path)
    change, pieces = LAMMPS_CASES[case]
    change(atoms, contacts)
    rc, err = convert(capsys, atoms, contacts, SCRIPT2, "--out", tmp_path / "x.json")
    assert rc == 2
    for piece in pieces:
        assert piece in err, (piece, err)


def test_lammps_line_numbers_point_at_the_bad_value(tmp_path, capsys):
    atoms, contacts = lammps_copy(tmp_path)
    line = last_block_line(atoms, 7)
    set_cell(atoms, line, 3, "1e999")
    rc, err = convert(capsys, atoms, contacts, SCRIPT2, "--out", tmp_path / "x.json")
    assert rc == 2 and f"atoms2d.dump: line {line}: y: not a finite number" in err


def test_lammps_coincident_centres(tmp_path, capsys):
    atoms, contacts = lammps_copy(tmp_path)
    pair = contacts.read_text().splitlines()[last_block_line(contacts, 1) - 1].split()[:2]
    rows = atoms.read_text().splitlines()
    start = last_block_line(atoms, 1)
    where = {r.split()[0]: k for k, r in enumerate(rows[start - 1:], start)}
    a, b = rows[where[pair[0]] - 1].split(), rows[where[pair[1]] - 1].split()
    b[2:5] = a[2:5]
    edit(atoms, where[pair[1]], " ".join(b) + "\n")
    rc, err = convert(capsys, atoms, contacts, SCRIPT2, "--out", tmp_path / "x.json")
    assert rc == 2 and "contacts2d.dump: line" in err and f"contact {pair[0]}-{pair[1]}: x: the two centres coincide" in err


def test_lammps_missing_timestep_and_bad_columns(tmp_path, capsys):
    atoms, contacts = lammps_copy(tmp_path)
    rc, err = convert(capsys, atoms, contacts, SCRIPT2, "--timestep", "999", "--out", tmp_path / "x.json")
    assert rc == 2 and "atoms2d.dump: timestep 999: timestep: not in the file (it has 18000, 21000)" in err
    rc, err = convert(capsys, atoms, contacts, "--columns", "id1,id2,fx", "--out", tmp_path / "x.json")
    assert rc == 2 and "--columns: 3 names for the 11 columns" in err
    rc, err = convert(capsys, atoms, contacts, "--columns", "id1,id2,force,-,-,-,-,-,-,-,-", "--out", tmp_path / "x")
    assert rc == 2 and "--columns: unknown name 'force'" in err
    rc, err = convert(capsys, atoms, "--out", tmp_path / "x.json")
    assert rc == 2 and "need one per-atom dump (ITEM: ATOMS) and one local dump (ITEM: ENTRIES), got 1 and 0" in err


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(["atoms2d.dump", "contacts2d.dump"]), cut=st.floats(0.0, 1.0),
       junk=st.binary(max_size=40), at=st.floats(0.0, 1.0))
def test_garbled_lammps_dumps_never_raise(tmp_path_factory, capsys, which, cut, junk, at):
    folder = tmp_path_factory.mktemp("fuzz")
    atoms, contacts = lammps_copy(folder)
    path = folder / which
    garble(path, cut, junk, at, 0.5)
    rc, err = convert(capsys, atoms, contacts, SCRIPT2, "--out", folder / "x.json")
    exits_cleanly(rc, err)


TABLE_CASES = {
    "unknown id": (lambda p, c: edit(c, 3, "2,9,0.0095,-0.0170\n"), ["contacts.csv", "line 3", "id2", "unknown particle id 9"]),
    "nan": (lambda p, c: edit(c, 2, "1,2,nan,0.001\n"), ["contacts.csv", "line 2", "fx", "not a finite number"]),
    "missing radius": (lambda p, c: p.write_text("id,x,y\n1,0,0\n2,1.98,0\n3,0.99,1.7\n"),
                       ["particles.csv", "line 1", "radius", "missing column"]),
    "negative radius": (lambda p, c: edit(p, 5, "3,0.99,1.70,-1.0\n"), ["particles.csv", "line 5", "radius", "> 0"]),
    "short row": (lambda p, c: edit(c, 4, "3,1\n"), ["contacts.csv", "line 4", "fx", "columns"]),
    "duplicate id": (lambda p, c: edit(p, 5, "2,0.99,1.70,1.0\n"), ["particles.csv", "line 5", "id", "listed twice"]),
    "coincident centres": (lambda p, c: edit(p, 4, "2,0.0,0.0,1.0\n"), ["contacts.csv", "line 2", "1-2",
                                                                        "x: the two centres coincide"]),
}


@pytest.mark.parametrize("case", sorted(TABLE_CASES))
def test_malformed_table_input(tmp_path, capsys, case):
    p, c = tmp_path / "particles.csv", tmp_path / "contacts.csv"
    shutil.copy(DATA / "table" / "particles.csv", p)
    shutil.copy(DATA / "table" / "contacts.csv", c)
    change, pieces = TABLE_CASES[case]
    change(p, c)
    rc, err = convert(capsys, p, c, "--out", tmp_path / "x.json")
    assert rc == 2
    for piece in pieces:
        assert piece in err, (piece, err)


def test_table_frames_missing_and_mismatched(tmp_path, capsys):
    p, c = tmp_path / "particles.csv", tmp_path / "contacts.csv"
    p.write_text("frame,id,x,y,radius\n1,1,0,0,1\n1,2,1.98,0,1\n")
    c.write_text("frame,id1,id2,fx,fy\n1,1,2,-0.02,0\n")
    rc, err = convert(capsys, p, c, "--frame", "4", "--out", tmp_path / "x.json")
    assert rc == 2 and "particles.csv: frame 4: frame: not in the file" in err
    c.write_text("frame,id1,id2,fx,fy\n1,1,2,-0.02,0\n3,1,2,-0.02,0\n")
    rc, err = convert(capsys, p, c, "--out", tmp_path / "x.json")
    assert rc == 2 and "contacts.csv: frame 3: frame: not in particles.csv (mismatched files)" in err


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(["particles.csv", "contacts.csv"]), junk=st.binary(max_size=30), at=st.floats(0, 1))
def test_garbled_tables_never_raise(tmp_path_factory, capsys, which, junk, at):
    folder = tmp_path_factory.mktemp("fuzz")
    for name in ("particles.csv", "contacts.csv"):
        shutil.copy(DATA / "table" / name, folder / name)
    garble(folder / which, 1.0, junk, at)
    rc, err = convert(capsys, folder / "particles.csv", folder / "contacts.csv", "--format", "table",
                      "--out", folder / "x.json")
    exits_cleanly(rc, err)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(["Contact5000.dat", "PosVel5000.dat", "posinit.dat", "Parameters_final.dat"]),
       cut=st.floats(0.0, 1.0), junk=st.binary(max_size=30), at=st.floats(0.0, 1.0))
def test_garbled_datasim_files_never_raise(tmp_path_factory, capsys, which, cut, junk, at):
    folder = tmp_path_factory.mktemp("fuzz") / "DataSim"
    shutil.copytree(DATASIM, folder)
    path = folder / which
    garble(path, cut, junk, at, 0.3)
    rc, err = convert(capsys, folder, "--out", folder / "x.json")
    exits_cleanly(rc, err)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from([".data", ".fstat"]), cut=st.floats(0.0, 1.0), junk=st.binary(max_size=30),
       at=st.floats(0.0, 1.0))
def test_garbled_mercury_files_never_raise(tmp_path_factory, capsys, which, cut, junk, at):
    from test_io_mercury import table_scene, write_mercury

    folder = tmp_path_factory.mktemp("fuzz")
    ref = table_scene().scene
    files = write_mercury(folder / "run", [(1.0, ref.x, np.ones(3), ref.p, ref.q, ref.force, [])])
    path = folder / f"run{which}"
    garble(path, cut, junk, at, 0.5)
    rc, err = convert(capsys, *files, "--out", folder / "x.json")
    exits_cleanly(rc, err)
