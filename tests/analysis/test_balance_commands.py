"""`--balance least-squares` on scan and track (issue 42, docs/uncertainty.md): the forces they analyse are the ones
`analyze --balance least-squares` analyses, bit for bit (one function, granstab.uncertainty.balance_least_squares),
and the folders say which balance was used."""
import json

import numpy as np
import pytest

import granstab
import granstab.cli as cli
from granstab.cli import main
from granstab.model.packings import lattice
from granstab.scan import read_packing
from granstab.uncertainty import perturbed


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """A 4×4 square lattice, its rim fixed, forces with 5 % noise (they no longer balance the inner particles)."""
    scene = lattice(2, size=4, kind="square")
    rng = np.random.default_rng(7)
    noisy = perturbed(scene, scene.force * (1 + 0.05 * rng.standard_normal(scene.force.shape)))
    data = granstab.scene_to_dict(noisy)
    rim = np.any((scene.x <= scene.x.min(axis=0) + 1e-9) | (scene.x >= scene.x.max(axis=0) - 1e-9), axis=1)
    for particle, fixed in zip(data["particles"], rim):
        particle["fixed"] = bool(fixed)
    path = tmp_path_factory.mktemp("balance") / "noisy.json"
    path.write_text(json.dumps(data))
    return path, granstab.load_scene(path)


def analysed_forces(path, monkeypatch, capsys) -> tuple[np.ndarray, dict]:
    """The forces `analyze --balance least-squares --force-uncertainty 0.1` analyses, and its JSON balance report."""
    seen = []
    real = cli.analyze

    def spy(scene, **options):
        seen.append(scene.force.copy())
        return real(scene, **options)

    monkeypatch.setattr(cli, "analyze", spy)
    assert main(["analyze", str(path), "--metric", "L", "--balance", "least-squares", "--force-uncertainty", "0.1",
                 "--json"]) == 0
    return seen[0], json.loads(capsys.readouterr().out)["balance"]


def test_scan_and_track_balance_as_analyze_does(measured, tmp_path, monkeypatch, capsys):
    path, scene = measured
    forces, report = analysed_forces(path, monkeypatch, capsys)
    assert report["method"] == "least-squares" and report["imbalance_after"] <= 1e-12 < report["imbalance_before"]
    moved = np.linalg.norm(forces - scene.force, axis=1)
    assert moved.max() > 1e-3 * np.abs(scene.force).max()                 # the balance changed the forces
    assert main(["scan", str(path), "--out", str(tmp_path / "s"), "--workers", "1", "--balance", "least-squares",
                 "--force-uncertainty", "0.1", "--centers", "every:8"]) == 0
    assert np.array_equal(read_packing(tmp_path / "s").force, forces)      # bit-identical
    summary = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert summary["options"]["balance"] == "least-squares"
    assert summary["balance"]["largest_correction_over_band"] == pytest.approx(report["largest_correction_over_band"],
                                                                            rel=0, abs=0)
    assert main(["track", str(path), "--out", str(tmp_path / "t"), "--workers", "1", "--scan", "--balance",
                 "least-squares", "--force-uncertainty", "0.1", "--no-figures"]) == 0
    folder = next((tmp_path / "t" / "scans").iterdir())
    assert np.array_equal(read_packing(folder).force, forces)
    import pyarrow.parquet as pq
    row = pq.read_table(tmp_path / "t" / "frames.parquet").to_pydict()
    assert json.loads(row["balance"][0])["method"] == "least-squares"


def test_default_scan_keeps_the_measured_forces(measured, tmp_path):
    path, scene = measured
    assert main(["scan", str(path), "--out", str(tmp_path / "s"), "--workers", "1", "--centers", "every:8"]) == 0
    assert np.array_equal(read_packing(tmp_path / "s").force, scene.force)
    assert "balance" not in json.loads((tmp_path / "s" / "summary.json").read_text())
