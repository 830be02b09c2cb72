"""Per-contact force uncertainties in LAMMPS local dumps (issue 42; docs/formats.md): an extra column named f_err (or
fn_err and ft_err) through --columns gives each touching contact its band, the same values as the file's rows; a bad
value is a one-line error naming the file, the line and the field; `analyze --force-uncertainty file` uses them."""
import json
import re

import numpy as np
import pytest
from helpers import DATA

from granstab.cli import main
from granstab.io import load

LAMMPS = DATA / "io" / "lammps"
COLUMNS = "id1,id2,fnx,fny,fnz,ftx,fty,ftz,delx,dely,delz"


def err_of(id1, id2):
    """A value per particle pair, the same either way round (1e-4 force units and up: every one distinct)."""
    return 1e-4 * (id1 + id2) + 1e-7 * id1 * id2


def with_err_columns(dst, extra=("f_err",), bad_row=None, constant=None):
    """contacts2d.dump with `extra` columns appended to every entry (err_of its pair; fn_err/ft_err split it as
    0.6/0.8 so that their hypot is err_of; `constant`: that value instead); `bad_row`: that entry's first extra
    value made negative. Returns the
    1-based line of the bad entry."""
    lines = (LAMMPS / "contacts2d.dump").read_text().splitlines()
    out, inside, row, bad_line = [], False, 0, None
    for line in lines:
        if line.startswith("ITEM: ENTRIES"):
            out.append(line + "".join(f" c_err[{k}]" for k in range(len(extra))))
            inside = True
            continue
        if line.startswith("ITEM:"):
            inside = False
        if inside and line.strip():
            ids = line.split()[:2]
            e = err_of(float(ids[0]), float(ids[1])) if constant is None else constant
            values = [e] if len(extra) == 1 else [0.6 * e, 0.8 * e]
            if row == bad_row:
                values[0], bad_line = -values[0], len(out) + 1
            line = line + "".join(f" {v:.17g}" for v in values)
            row += 1
        out.append(line)
    dst.write_text("\n".join(out) + "\n")
    return bad_line


@pytest.mark.parametrize("extra", [("f_err",), ("fn_err", "ft_err")])
def test_force_err_columns_of_a_local_dump(tmp_path, extra):
    """Every touching contact's force_err is its pair's value (fn_err, ft_err: their hypot, to 1e-15 relative);
    the report names the columns."""
    contacts = tmp_path / "contacts2d.dump"
    with_err_columns(contacts, extra)
    got = load([LAMMPS / "atoms2d.dump", contacts], timestep=18000, columns=COLUMNS + "," + ",".join(extra),
               k=1000, alpha=0.5, mu=0.5)
    s = got.scene
    want = err_of(np.array(s.names, dtype=float)[s.p], np.array(s.names, dtype=float)[s.q])
    assert s.n_contacts > 10 and np.allclose(s.force_err, want, rtol=1e-15, atol=0)
    assert got.report["force_uncertainty"]["source"] == " and ".join(extra) + (" columns" if len(extra) > 1
                                                                               else " column")


def test_a_negative_force_err_names_the_line(tmp_path, capsys):
    contacts = tmp_path / "contacts2d.dump"
    line = with_err_columns(contacts, bad_row=3)
    rc = main(["analyze", str(LAMMPS / "atoms2d.dump"), str(contacts), "--timestep", "18000", "--columns",
               COLUMNS + ",f_err", "--k", "1000", "--alpha", "0.5", "--mu", "0.5", "--force-uncertainty", "file"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert re.search(rf"contacts2d\.dump: line {line}: f_err: the force uncertainty must be finite and >= 0", err)


def test_scan_takes_the_band_from_the_dump(tmp_path, capsys):
    """`scan --force-uncertainty file` of the dump with every f_err = 0.15 (about 1 % of the forces): the same
    data_robust and robust_margin, bit for bit, as the uniform band --force-uncertainty 0,0.15, and the summary names
    the column."""
    from granstab.scan import read_map
    contacts = tmp_path / "contacts2d.dump"
    with_err_columns(contacts, constant=0.15)
    args = [str(LAMMPS / "atoms2d.dump"), str(contacts), "--timestep", "18000", "--columns", COLUMNS + ",f_err",
            "--k", "1000", "--alpha", "0.5", "--mu", "0.5", "--centers", "every:32", "--workers", "1",
            "--no-attribution"]
    rows = {}
    for name, band in (("file", "file"), ("uniform", "0,0.15")):
        assert main(["scan", *args, "--out", str(tmp_path / name), "--force-uncertainty", band]) == 0
        rows[name] = read_map(tmp_path / name)["clusters"]
    capsys.readouterr()
    assert len(rows["file"]["data_robust"]) >= 4 and "holds" in list(rows["file"]["data_robust"])
    assert list(rows["file"]["data_robust"]) == list(rows["uniform"]["data_robust"])
    assert np.array_equal(rows["file"]["robust_margin"], rows["uniform"]["robust_margin"])
    summary = json.loads((tmp_path / "file" / "summary.json").read_text())
    assert "f_err" in summary["options"]["uncertainty"]["per_contact"]
