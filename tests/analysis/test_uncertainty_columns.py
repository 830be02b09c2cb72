"""Per-contact force uncertainties read from a table's columns (issue 42; docs/formats.md, docs/uncertainty.md):
f_err, or fn_err and ft_err (the ball around their box), used by `analyze --force-uncertainty file`; bad values are
one-line errors naming the file, the line and the field."""
import json

import numpy as np
import pytest

from granstab.cli import main
from granstab.io import load

ROWS = [(1, 2, -1.0, 0.05), (2, 3, -1.1, -0.02), (4, 5, -0.9, 0.01), (5, 6, -1.0, 0.0), (1, 4, 0.03, -1.0),
        (2, 5, 0.0, -1.2), (3, 6, -0.01, -0.95)]


def write(folder, header="f_err", values=None):
    """A 3×2 grid of unit disks (centres 1.998 apart), seven contacts with the force on id1 and `header` columns."""
    values = values if values is not None else [[0.1 + 0.01 * i] for i in range(len(ROWS))]
    particles = folder / "particles.csv"
    particles.write_text("id,x,y,radius\n" + "".join(f"{i + 1},{1.998 * (i % 3)},{1.998 * (i // 3)},1\n"
                                                     for i in range(6)))
    contacts = folder / "contacts.csv"
    contacts.write_text(f"id1,id2,fx,fy,{header}\n" + "".join(
        ",".join(str(v) for v in (*row, *extra)) + "\n" for row, extra in zip(ROWS, values)))
    return [str(particles), str(contacts)]


def analyze_json(paths, band, capsys) -> dict:
    assert main(["analyze", *paths, "--mu", "0.5", "--metric", "L", "--force-uncertainty", band, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_values_read_are_the_values_used(tmp_path, capsys):
    """f_err as read (in the file's contact order) is the band: a file with every f_err = 0.3 gives the same result,
    bit for bit, as the uniform band --force-uncertainty 0,0.3; fn_err and ft_err give √(fn_err² + ft_err²)."""
    paths = write(tmp_path)
    got = load(paths, mu=0.5)
    assert np.array_equal(got.force_uncertainty, [0.1 + 0.01 * i for i in range(len(ROWS))])
    assert got.report["force_uncertainty"]["source"] == "f_err column"
    even = write(tmp_path, values=[[0.3]] * len(ROWS))
    from_file = analyze_json(even, "file", capsys)["data_uncertainty"]
    uniform = analyze_json(even, "0,0.3", capsys)["data_uncertainty"]
    assert from_file["band"] == "forces ± the file's per-contact uncertainty"
    for key in ("robust", "verdict", "margin", "bound"):
        assert from_file[key] == uniform[key]
    split = write(tmp_path, "fn_err,ft_err", [[0.03 * (i + 1), 0.04 * (i + 1)] for i in range(len(ROWS))])
    assert np.allclose(load(split, mu=0.5).force_uncertainty, 0.05 * np.arange(1, len(ROWS) + 1), rtol=1e-15)


@pytest.mark.parametrize("header, values, field", [
    ("f_err", [[0.1]] * 3 + [[-0.1]] + [[0.1]] * 3, "f_err"),
    ("f_err", [[0.1]] * 3 + [["nan"]] + [[0.1]] * 3, "f_err"),
    ("f_err", [[0.1]] * 3 + [["inf"]] + [[0.1]] * 3, "f_err"),
    ("fn_err,ft_err", [[0.1, 0.1]] * 3 + [[0.1, -1]] + [[0.1, 0.1]] * 3, "ft_err"),
])
def test_a_bad_value_names_file_line_and_field(tmp_path, capsys, header, values, field):
    paths = write(tmp_path, header, values)
    assert main(["analyze", *paths, "--mu", "0.5", "--force-uncertainty", "file"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "contacts.csv: line 5" in err and f"{field}:" in err


def test_missing_columns_and_a_missing_value(tmp_path, capsys):
    paths = write(tmp_path, "fn_err", [[0.1]] * len(ROWS))
    assert main(["analyze", *paths, "--mu", "0.5", "--force-uncertainty", "file"]) == 2
    err = capsys.readouterr().err
    assert "ft_err: missing column" in err and "contacts.csv" in err
    paths = write(tmp_path, "f_err", [[0.1]] * 3 + [[""]] + [[0.1]] * 3)
    assert main(["analyze", *paths, "--mu", "0.5", "--force-uncertainty", "file"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "contacts.csv: line 5" in err and "f_err" in err
    paths = write(tmp_path, "mobilised", [[0]] * len(ROWS))
    assert main(["analyze", *paths, "--mu", "0.5", "--force-uncertainty", "file"]) == 2
    assert "no per-contact uncertainty columns" in capsys.readouterr().err
