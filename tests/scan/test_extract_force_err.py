"""`granstab extract` keeps the cluster's per-contact force uncertainty (issue 42): the scene format's optional
contact field `force_err` (docs/formats.md) is written and read back, so that an extracted cluster analysed alone
with `--force-uncertainty file` keeps its band; a partial or negative `force_err` is a one-line error."""
import json
import sys
from pathlib import Path

import numpy as np
import pytest

import granstab
from granstab.cli import main
from granstab.io import load

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
from test_uncertainty_columns import ROWS, write  # noqa: E402

LOUD = 3          # ROWS[3] is the contact of particles 5 and 6


def test_extracted_cluster_keeps_its_band(tmp_path, capsys):
    """The cluster of particle 5 (rings 1, loads): the written scene's force_err are its contacts' f_err from the
    file, by particle pair; `analyze --force-uncertainty file` of the extracted scene gives the same data_robust,
    margin and bound as the scan's row of that cluster (the band travelled with it), and the loud contact still
    unsettles it (not holds)."""
    values = [100.0 if i == LOUD else 0.01 * (i + 1) for i in range(len(ROWS))]
    paths = write(tmp_path, values=[[v] for v in values])
    out = tmp_path / "c5.json"
    assert main(["extract", *paths, "--mu", "0.5", "--center", "5", "--out", str(out)]) == 0
    capsys.readouterr()
    written = json.loads(out.read_text())
    by_pair = {frozenset(map(str, row[:2])): v for row, v in zip(ROWS, values)}
    want = [by_pair[frozenset((c["p"], c["q"]))] for c in written["contacts"]]
    assert [c["force_err"] for c in written["contacts"]] == want and 100.0 in want
    assert np.array_equal(granstab.load_scene(str(out)).force_err, want)
    assert main(["analyze", str(out), "--metric", "L", "--force-uncertainty", "file", "--json"]) == 0
    alone = json.loads(capsys.readouterr().out)["data_uncertainty"]
    whole = load(paths, mu=0.5).scene
    from granstab.scan import extract
    from granstab.uncertainty import Band, data_robustness
    sub = extract(whole, "5", rings=1, boundary="loads")
    direct = data_robustness(sub, Band(per_contact=sub.force_err)).to_dict()
    assert alone["robust"] == direct["robust"] != "holds"
    assert alone["bound"] == pytest.approx(direct["bound"], rel=1e-12) and alone["bound"] > 0
    assert main(["convert", str(out), "--out", str(tmp_path / "c5.npz")]) == 0
    assert np.array_equal(granstab.load_scene(str(tmp_path / "c5.npz")).force_err, want)


@pytest.mark.parametrize("edit, message", [(lambda c: c[1].pop("force_err"), "contacts[1] (5-6): force_err: missing"),
                                           (lambda c: c[0].update(force_err=-1.0), "force_err: must be >= 0"),
                                           (lambda c: c[0].update(force_err="x"), "force_err")])
def test_bad_force_err_is_one_line(tmp_path, capsys, edit, message):
    paths = write(tmp_path, values=[[0.1]] * len(ROWS))
    out = tmp_path / "c.json"
    assert main(["extract", *paths, "--mu", "0.5", "--center", "5", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    edit(data["contacts"])
    out.write_text(json.dumps(data))
    capsys.readouterr()
    assert main(["analyze", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "c.json" in err and message in err
