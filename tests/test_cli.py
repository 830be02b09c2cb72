"""The CLI contract: `granstab stiffness` arrays and `granstab analyze --json` keys."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

import granstab
from granstab.cli import main

PRESETS = Path(__file__).parents[1] / "presets"


def test_stiffness_npz(tmp_path, capsys):
    out = tmp_path / "k.npz"
    assert main(["stiffness", str(PRESETS / "two_particle.toml"), "--out", str(out)]) == 0
    data = np.load(out)
    assert set(data.files) == {"H", "Hm", "Hg1", "Hg2", "Hg3", "dofs"}
    assert list(data["dofs"]) == ["p.u1", "p.u2", "p.th3", "q.u1", "q.u2", "q.th3"]
    assert data["H"].dtype == np.float64 and data["H"].shape == (6, 6)
    assert np.abs(data["H"] - (data["Hm"] + data["Hg1"] + data["Hg2"] + data["Hg3"])).max() <= 1e-15
    # rolling entry of the closed form: H[2,2] = k α r² + f(ρ-r)(ρ+r)/(2ρ) with r = 1, ρ = 0.5, f = 0.01
    assert abs(data["H"][2, 2] - (1.0 + 0.01 * (0.5 - 1) * (0.5 + 1) / (2 * 0.5))) <= 1e-15


def test_stiffness_mask_selects_the_sliding_branch(tmp_path, capsys):
    scene = tmp_path / "slide.toml"
    scene.write_text((PRESETS / "two_particle.toml").read_text().replace("force = [-0.01, 0.0]",
                                                                         "force = [-0.01, 0.005]"))
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    assert main(["stiffness", str(scene), "--out", str(a), "--mask", "+1"]) == 0
    assert main(["stiffness", str(scene), "--out", str(b)]) == 0
    Ha, Hb = np.load(a)["Hm"], np.load(b)["Hm"]
    assert np.abs(Ha - Ha.T).max() > 0.1            # sliding makes Hm asymmetric (eq:ContactF)
    assert np.abs(Hb - Hb.T).max() <= 1e-15


def test_analyze_json_contract(capsys):
    assert main(["analyze", str(PRESETS / "two_particle.toml"), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert {"dim", "n_particles", "n_contacts", "n_sliding", "branches", "summary", "errors", "timings"} <= set(d)
    (b,) = d["branches"]
    assert {"mask", "stability_eigenvalues", "n_zero", "consistent", "uniqueness_eigenvalues"} <= set(b)
    assert b["stability_eigenvalues"] == sorted(b["stability_eigenvalues"])
    assert all(len(pair) == 2 for pair in b["uniqueness_eigenvalues"])
    assert all(c["vector_sign"] in (1, -1, 0) for c in b["consistent"])
    assert d["summary"]["verdict"] == "unstable"
    assert abs(min(b["stability_eigenvalues"]) - 0.01 * (0.5 - 1)) <= 1e-15   # λ⁽⁶⁾ = f(ρ - r)/r² · k
    assert d == granstab.analyze(granstab.load_scene(PRESETS / "two_particle.toml")).to_dict() | {
        "timings": d["timings"]}


def test_readable_table_and_module_entry_point():
    proc = subprocess.run([sys.executable, "-m", "granstab", "analyze", str(PRESETS / "two_particle.toml")],
                          capture_output=True, text=True)
    assert proc.returncode == 0
    assert "verdict: UNSTABLE" in proc.stdout and "errors (relative)" in proc.stdout


def test_sparse_method_agrees_with_dense_on_real_data(capsys):
    """`--method sparse` (lowest k eigenpairs, no dense matrices) against the dense spectrum, relative to max|λ|."""
    path = str(PRESETS / "annulus_frame.json")
    assert main(["analyze", path, "--json", "--method", "dense"]) == 0
    dense = json.loads(capsys.readouterr().out)["branches"][0]["stability_eigenvalues"]
    assert main(["analyze", path, "--json", "--method", "sparse", "--k", "5"]) == 0
    out = json.loads(capsys.readouterr().out)
    sparse = sorted(out["branches"][0]["stability_eigenvalues"])
    lowest = [lam for lam in dense if abs(lam) > 1e-12 * max(map(abs, dense))][:5]
    assert np.allclose(sorted(lam for lam in sparse if abs(lam) > 1e-12 * max(map(abs, dense)))[:5], lowest,
                       rtol=0, atol=1e-12 * max(map(abs, dense)))
    assert any("sparse path" in w for w in out["warnings"])


def test_readable_table_lists_the_lowest_eigenvalues_and_counts(capsys):
    """The 143-disk frame (429 eigenvalues): the table shows the lowest TABLE_LOWEST with the counts; --all every
    one. The counts must match the analysis' (4 consistent negative, 3 rigid zeros)."""
    from granstab.cli import TABLE_LOWEST
    path = str(PRESETS / "annulus_frame.json")
    assert main(["analyze", path, "--metric", "L"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "sym(𝓗) eigenvalues" in x)
    assert f"(lowest {TABLE_LOWEST} of 429: 4 negative, 3 zero, 422 positive)" in line
    assert line.count("(±v)") + line.count("(rigid)") == TABLE_LOWEST and "(421 more: --all)" in line
    assert line.index("-0.0015365") < line.index("-0.00146259")                 # ascending, the lowest first
    assert main(["analyze", path, "--metric", "L", "--all"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "sym(𝓗) eigenvalues" in x)
    assert "(all 429: 4 negative, 3 zero, 422 positive)" in line
    assert len(line.split("positive): ")[1].split(", ")) == 429 and "--all)" not in line
