"""`scan --force-uncertainty file` (issue 42, docs/uncertainty.md): each cluster's band is its own contacts' f_err,
sliced with the contacts from the packing (Scene.force_err through clusters.cut); a file without the columns is a
one-line error naming it (exit 2)."""
import json
import sys
from pathlib import Path

import numpy as np

from granstab.cli import main
from granstab.scan import read_map

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
from test_uncertainty_columns import ROWS, write  # noqa: E402

LOUD = 3          # ROWS[3] is the contact of particles 5 and 6: in the clusters of 5 and 6 only (rings 1, loads)


def scan_clusters(paths, out, band, capsys) -> tuple[dict, dict]:
    args = ["scan", *paths, "--mu", "0.5", "--metric", "L", "--boundary", "loads", "--force-uncertainty", band,
            "--out", str(out), "--json"]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    return read_map(out)["clusters"], summary


def test_a_loud_contact_unsettles_only_the_clusters_that_hold_it(tmp_path, capsys):
    """f_err = 100 on the contact 5–6 (forces ~1) and 0 elsewhere: the clusters of 5 and 6 (centres 4, 5) are not
    `holds` (a finite margin < 1), the four others hold with an infinite margin (a zero band). Taking the first
    entries of the array instead of the cluster's own contacts would move the loud one elsewhere."""
    paths = write(tmp_path, values=[[100.0] if i == LOUD else [0.0] for i in range(len(ROWS))])
    c, summary = scan_clusters(paths, tmp_path / "s", "file", capsys)
    assert list(c["center"]) == list(range(6)) and set(c["verdict"]) == {"unstable"}
    loud = np.isin(c["center"], [4, 5])
    assert list(c["data_robust"][~loud]) == ["holds"] * 4 and np.all(np.isinf(c["robust_margin"][~loud]))
    assert set(c["data_robust"][loud]) <= {"depends", "undecided"} and np.all(c["robust_margin"][loud] < 1)
    assert summary["options"]["uncertainty"]["per_contact"] == "the file's f_err column"


def test_an_even_file_band_is_the_uniform_band(tmp_path, capsys):
    """Every f_err = 0.3: the same data_robust and robust_margin, bit for bit, as --force-uncertainty 0,0.3."""
    paths = write(tmp_path, values=[[0.3]] * len(ROWS))
    from_file, _ = scan_clusters(paths, tmp_path / "f", "file", capsys)
    uniform, _ = scan_clusters(paths, tmp_path / "u", "0,0.3", capsys)
    assert list(from_file["data_robust"]) == list(uniform["data_robust"])
    assert np.array_equal(from_file["robust_margin"], uniform["robust_margin"])


def test_no_columns_is_one_line_naming_the_file(tmp_path, capsys):
    paths = write(tmp_path, "mobilised", [[0]] * len(ROWS))
    assert main(["scan", *paths, "--mu", "0.5", "--force-uncertainty", "file", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "contacts.csv" in err and "no per-contact uncertainty columns" in err
    assert not (tmp_path / "s").exists()



def test_a_cluster_takes_its_own_contacts_entries(tmp_path):
    """Every cluster (loads boundary, and with the held ring of `fixed`) carries the f_err of exactly its contacts,
    looked up here by their particle pair in the file (all seven values distinct)."""
    from granstab.io import load
    from granstab.scan import extract
    values = [0.1 + 0.01 * i for i in range(len(ROWS))]
    by_pair = {frozenset(map(str, row[:2])): v for row, v in zip(ROWS, values)}
    scene = load(write(tmp_path, values=[[v] for v in values]), mu=0.5).scene
    for center in map(str, range(1, 7)):
        for boundary in ("loads", "fixed"):
            sub = extract(scene, center, rings=1, boundary=boundary)
            want = [by_pair[frozenset((sub.names[a], sub.names[b]))] for a, b in zip(sub.p, sub.q)]
            assert sub.n_contacts > 0 and np.array_equal(sub.force_err, want)


def test_least_squares_balance_moves_only_the_contacts_with_a_band(tmp_path, capsys):
    """--balance least-squares weighted by the file's f_err: contacts with f_err = 0 keep their forces bit for bit,
    the loud one moves, and the report's largest correction over the band is finite (0/0 is a contact held exactly,
    not an infinite ratio: the summary was not valid JSON before)."""
    from granstab.io import load
    from granstab.uncertainty import balance_scene
    paths = write(tmp_path, values=[[100.0] if i == LOUD else [0.0] for i in range(len(ROWS))])
    scene = load(paths, mu=0.5).scene
    out, report = balance_scene(scene, {"per_contact": "the file's f_err column"}, "least-squares")
    quiet = np.arange(len(ROWS)) != LOUD
    assert np.array_equal(out.force[quiet], scene.force[quiet]) and np.linalg.norm(out.force - scene.force) > 0
    assert 0 < report["largest_correction_over_band"] < 1 and report["inside_band"] is True
    assert main(["scan", *paths, "--mu", "0.5", "--force-uncertainty", "file", "--balance", "least-squares",
                 "--out", str(tmp_path / "s")]) == 0
    assert json.loads((tmp_path / "s" / "summary.json").read_text())["balance"]["inside_band"] is True
