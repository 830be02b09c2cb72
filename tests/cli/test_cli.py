"""The CLI contract: `granstab stiffness` arrays and `granstab analyze --json` keys."""
import json
import subprocess
import sys

import numpy as np
from helpers import DATA, ROOT, result_part  # noqa: E402

import granstab
from granstab.cli import main

PRESETS = ROOT / "presets"


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
    assert d["import"] == {"source": str(PRESETS / "two_particle.toml"), "format": "scene-toml",
                           "read_as": "scene file", "warnings": []}       # a scene file: read as written
    assert result_part(d) == result_part(granstab.analyze(granstab.load_scene(PRESETS / "two_particle.toml")).to_dict())
    assert d["cost"]["estimated_s"] > 0 and set(d["cost"]) >= {"path", "left_out", "paths"}


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
    from granstab.cli_text import TABLE_LOWEST
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


ANNULUS = DATA / "io" / "annulus"       # two frames cut from RigidLibrary's DataAnnulus
DATASIM = ROOT.parent / "shared" / "data" / "rigidlibrary" / "DataSim"


def annulus_rattlers(frame: int = 1) -> list[int]:
    """The particles of the frame that no contact touches, read from the files without granstab."""
    pos = np.loadtxt(ANNULUS / "particle_positions.txt", delimiter=",", ndmin=2)
    adj = np.loadtxt(ANNULUS / "Adjacency_list.txt", delimiter=",", ndmin=2)
    touched = set(adj[adj[:, 0] == frame, 1:3].astype(int).ravel())
    return sorted(set(pos[pos[:, 0] == frame, 1].astype(int)) - touched)


def test_analyze_of_a_snapshot_keeps_the_import_report(capsys):
    """A real snapshot (RigidLibrary annulus frames): the table ends with the import's warnings (the rattlers it
    dropped, counted here from the files), the JSON carries its report under "import" beside the analysis' keys,
    unchanged; a scene file's table has no import warning."""
    rattlers = annulus_rattlers()
    loaded = granstab.load(ANNULUS)
    assert main(["analyze", str(ANNULUS), "--metric", "L"]) == 0
    lines = capsys.readouterr().out.splitlines()
    imported = [x for x in lines if x.startswith("warning: import: ")]
    assert imported == [f"warning: import: {w}" for w in loaded.warnings] and lines[-len(imported):] == imported
    assert any(x.startswith(f"warning: import: {len(rattlers)} particle(s) without contacts (rattlers) dropped "
                            f"({rattlers[0]}, {rattlers[1]},") for x in imported)
    assert main(["analyze", str(ANNULUS), "--metric", "L", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["import"] == json.loads(json.dumps(loaded.report))
    assert d["import"]["particles"]["dropped"] == [str(i) for i in rattlers]
    assert any(w.startswith(f"{len(rattlers)} particle(s) without contacts") for w in d["import"]["warnings"])
    expected = granstab.analyze(loaded.scene, metric="L").to_dict()
    assert result_part(d) == result_part(json.loads(json.dumps(expected)))
    assert main(["analyze", str(PRESETS / "two_particle.toml")]) == 0
    assert "import" not in capsys.readouterr().out


def test_every_command_that_reads_an_input_prints_the_import_warnings(tmp_path, capsys):
    """stiffness, extract and scan read what analyze reads and print its import warnings after their own line;
    scan --json adds the report as "import". DataSim (RigidLibrary's sheared periodic snapshot): rattlers dropped
    (counted here from the files) and, with --no-periodic, contacts cut at the seam of the cell."""
    warned = [f"warning: import: {w}" for w in granstab.load(ANNULUS).warnings]
    assert main(["stiffness", str(ANNULUS), "--out", str(tmp_path / "k.npz")]) == 0
    assert capsys.readouterr().out.splitlines()[1:] == warned
    assert main(["scan", str(ANNULUS), "--out", str(tmp_path / "scan"), "--workers", "1"]) == 0
    assert capsys.readouterr().out.splitlines()[2:] == warned           # after the counts and where it ran
    assert main(["scan", str(ANNULUS), "--out", str(tmp_path / "scan"), "--workers", "1", "--json"]) == 0   # resumed
    summary = json.loads(capsys.readouterr().out)
    assert summary["import"]["warnings"] == [w.removeprefix("warning: import: ") for w in warned]
    assert summary["clusters"] == granstab.load(ANNULUS).scene.n_particles
    assert main(["stiffness", str(PRESETS / "two_particle.toml"), "--out", str(tmp_path / "k2.npz")]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 1                     # a scene file: no warning
    contacts = np.loadtxt(DATASIM / "Contact5000.dat", ndmin=2)
    n_particles = len(np.loadtxt(DATASIM / "posinit.dat", ndmin=2))
    rattlers = n_particles - len(np.unique(contacts[:, :2]))
    assert main(["extract", str(DATASIM), "--center", "500", "--out", str(tmp_path / "c.json")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith(f"wrote {tmp_path / 'c.json'}: ")
    assert any(x.startswith(f"warning: import: {rattlers} particle(s) without contacts (rattlers) dropped")
               for x in lines[1:])
    assert not any("closing a loop around the periodic cell" in x for x in lines[1:])   # periodic: none cut
    assert main(["extract", str(DATASIM), "--center", "500", "--out", str(tmp_path / "c.json"), "--no-periodic"]) == 0
    lines = capsys.readouterr().out.splitlines()
    cut = granstab.load(DATASIM, periodic=False).report["contacts"]["cut_around_periodic_cell"]
    assert cut > 0 and any(x.startswith(f"warning: import: {cut} contact(s) closing a loop around the periodic "
                                        "cell cut") for x in lines[1:])


def test_analyze_and_scan_take_converts_import_options(tmp_path, capsys):
    """analyze and scan read an annulus folder with convert's import options (issue 28): --frame 2 and --mu 0.05
    (the file gives no μ; the default 0.5 leaves every contact inside the cone, 0.05 puts 3 at yield). analyze's
    JSON is the analysis of the scene loaded with those options; scan's summary
    reports the same import; analyze's --k stays its eigenpair count (the stiffness is --contact-k there)."""
    options = {"frame": 2, "mu": 0.05}
    loaded = granstab.load(ANNULUS, **options)
    assert loaded.report["contacts"]["sliding"] == 3 and granstab.load(ANNULUS, frame=2).report["contacts"]["sliding"] == 0
    assert main(["analyze", str(ANNULUS), "--frame", "2", "--mu", "0.05", "--metric", "L", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["import"]["frame"] == 2 and d["import"]["contacts"]["sliding"] == 3
    expected = granstab.analyze(loaded.scene, metric="L").to_dict()
    assert result_part(d) == result_part(json.loads(json.dumps(expected)))
    assert main(["scan", str(ANNULUS), "--out", str(tmp_path / "s"), "--workers", "1", "--frame", "2", "--mu", "0.05",
                 "--format", "auto", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["import"]["frame"] == 2 and summary["import"]["contacts"]["sliding"] == 3
    assert main(["analyze", str(ANNULUS), "--contact-k", "-1"]) == 2
    assert "k" in capsys.readouterr().err


def parser_flags() -> dict[str, set[str]]:
    """Every long flag of the `granstab` parser → the commands that take it."""
    import argparse

    from granstab.cli import RUNS
    from granstab.cli_options import build_parser
    sub = next(a for a in build_parser(RUNS)._actions if isinstance(a, argparse._SubParsersAction))
    flags: dict[str, set[str]] = {}
    for name, parser in sub.choices.items():
        for action in parser._actions:
            for flag in action.option_strings:
                if flag.startswith("--") and flag != "--help":
                    flags.setdefault(flag, set()).add(name)
    return flags


def test_the_table_of_flags_in_docs_is_the_parsers():
    """docs/cli.md's table (flag, meaning, commands) lists every flag with exactly the commands that take it
    ("readers": every command that reads a file; "a / b" rows: flags of two commands each)."""
    import re
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    readers = {"stiffness", "analyze", "moduli", "convert", "extract", "scan", "rigidity", "track", "export"}
    table: dict[str, set[str]] = {}
    for flags, commands in re.findall(r"^\| (`--.*?) \| .*? \| ([a-z, /]+) \|$", text, flags=re.M):
        names = re.findall(r"`(--[a-z0-9-]+)`", flags)
        groups = [g.strip() for g in commands.split("/")] if "/" in commands else [commands] * len(names)
        for name, group in zip(names, groups):
            table[name] = readers if group == "readers" else {c.strip() for c in group.split(",")}
    flags = parser_flags()
    assert len(flags) > 50
    diff = {n: (table.get(n), flags.get(n)) for n in set(table) | set(flags) if table.get(n) != flags.get(n)}
    assert not diff, diff   # flag: (commands in the docs table, commands in the parser)


def test_a_command_that_reads_a_file_takes_every_import_option(tmp_path, capsys):
    """stiffness, extract, moduli and export (before: no --mu, --frame, ...) read with convert's options: the annulus
    frame 2 at μ = 0.05 puts 3 contacts at yield, as `load` reads it."""
    loaded = granstab.load(ANNULUS, frame=2, mu=0.05)
    options = ["--frame", "2", "--mu", "0.05", "--contact-k", "3"]
    assert main(["stiffness", str(ANNULUS), "--out", str(tmp_path / "k.npz"), *options]) == 0
    K = granstab.stiffness(granstab.load(ANNULUS, frame=2, mu=0.05, k=3.0).scene)
    assert np.array_equal(np.load(tmp_path / "k.npz")["H"], K.H) and loaded.report["contacts"]["sliding"] == 3
    name = str(loaded.scene.names[0])
    assert main(["extract", str(ANNULUS), "--center", name, "--out", str(tmp_path / "c.json"), *options]) == 0
    sub = granstab.load_scene(tmp_path / "c.json")
    assert np.allclose(sub.k, 3.0) and np.allclose(sub.mu, 0.05)
    capsys.readouterr()
    assert main(["export", str(ANNULUS), "--out", str(tmp_path / "x"), "--out-format", "xyz", *options]) == 0
    assert "frame(s) as xyz" in capsys.readouterr().out
    assert set(parser_flags()["--mu"]) == {"stiffness", "analyze", "moduli", "convert", "extract", "scan", "rigidity",
                                           "track", "export"}


def test_old_spellings_are_accepted_with_a_one_line_note(tmp_path, capsys):
    """For one release: convert's --k is --contact-k, scan's --input-format is --format and its --format csv is
    --out-format, export's --format xyz is --out-format and --scan DIR is --scan-dir; each says so in one line on
    stderr and gives the new spelling's result."""
    scene = str(PRESETS / "four_disk.toml")
    assert main(["convert", str(ANNULUS), "--out", str(tmp_path / "old.json"), "--k", "7"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["granstab convert: --k is now --contact-k (the old spelling is accepted until the next release; "
                   "docs/cli.md)"]
    assert main(["convert", str(ANNULUS), "--out", str(tmp_path / "new.json"), "--contact-k=7"]) == 0
    assert capsys.readouterr().err == ""
    assert (tmp_path / "old.json").read_text() == (tmp_path / "new.json").read_text()
    assert main(["scan", scene, "--out", str(tmp_path / "s"), "--workers", "1", "--input-format", "auto",
                 "--format=csv"]) == 0
    err = capsys.readouterr().err
    assert "scan: --input-format is now --format" in err and "scan: --format csv is now --out-format" in err
    assert (tmp_path / "s" / "clusters.csv").exists() and not (tmp_path / "s" / "clusters.parquet").exists()
    assert main(["export", scene, "--out", str(tmp_path / "e"), "--format", "xyz", "--scan", str(tmp_path / "s")]) == 0
    err = capsys.readouterr().err
    assert "export: --format xyz is now --out-format" in err and "export: --scan is now --scan-dir" in err
    assert list((tmp_path / "e").glob("*.xyz"))
    assert main(["analyze", scene, "--k", "3", "--method", "sparse", "--json"]) == 0   # analyze's --k: eigenpairs
    assert capsys.readouterr().err == ""


def test_track_and_export_frames_name_the_same_frames(tmp_path, capsys):
    """--frames has one meaning: the input's frames as --frame names them (the annulus: 1 and 2), A:B inclusive."""
    assert main(["track", str(ANNULUS), "--out", str(tmp_path / "t"), "--frames", "2:2", "--workers", "1",
                 "--no-figures", "--json"]) == 0
    out = capsys.readouterr()
    assert json.loads(out.out)["frames"] == 1 and "no longer 0-based positions" in out.err
    import pyarrow.parquet as pq
    assert pq.read_table(tmp_path / "t" / "frames.parquet").column("step").to_pylist() == [2.0]
    assert main(["export", str(ANNULUS), "--out", str(tmp_path / "e"), "--out-format", "xyz", "--frames", "2:2"]) == 0
    assert "wrote 1 frame(s)" in capsys.readouterr().out
