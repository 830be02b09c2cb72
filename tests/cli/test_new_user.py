"""What a new user hit (issue 26): the command line's arguments, a closed pipe, Ctrl-C and resume, a missing extra,
the scan's default workers, and the import report's words and numbers."""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from contextlib import suppress
from pathlib import Path

import numpy as np
import pytest
from helpers import (
    ROOT,  # noqa: E402
    result_part,
)

import granstab
from granstab.cli import main
from granstab.io import load

LAMMPS = ROOT / "tests" / "data" / "io" / "lammps"
TABLE = ROOT / "tests" / "data" / "io" / "table"
LAMMPS_2D = [LAMMPS / "atoms2d.dump", LAMMPS / "contacts2d.dump", ROOT / "examples" / "dem" / "in.disks2d"]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / ".shim"), str(ROOT),
                                                     os.environ.get("PYTHONPATH", "")])}


def granstab_cli(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "granstab", *map(str, args)], capture_output=True, text=True,
                          env=ENV, **kwargs)


# ------------------------------------------------------------------------------------------------ arguments

def test_analyze_takes_a_snapshot_as_several_files_as_convert_does(tmp_path, capsys):
    """`analyze atoms.dump contacts.dump in.disks` (the README's FOLDER_OR_FILES) was refused ('unrecognized
    arguments'). On the two tables of the three-disk fixture the whole result is `analyze` of what
    `granstab.io.load` builds from them; `extract` of the LAMMPS trio (the user's case; analysing all of its 127
    disks would take seconds here) is the cluster of the scene `load` builds from those files."""
    tables = [TABLE / "particles.csv", TABLE / "contacts.csv"]
    assert main(["analyze", *map(str, tables), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    expected = json.loads(json.dumps(granstab.analyze(load(tables).scene).to_dict()))
    assert got["import"] == json.loads(json.dumps(load(tables).report)) and got["n_particles"] == 3
    assert result_part(got) == result_part(expected)
    from granstab.scan import extract
    assert main(["extract", *map(str, LAMMPS_2D), "--center", "25", "--out", str(tmp_path / "c.json")]) == 0
    direct = extract(load(LAMMPS_2D).scene, "25")
    assert granstab.load_scene(tmp_path / "c.json").names == direct.names and len(direct.names) > 3
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


def test_a_closed_pipe_is_a_quiet_exit(tmp_path):
    """`convert … | head -3`: the reader closes the pipe before granstab writes its report: no 'cannot write Broken
    pipe', nothing on stderr, exit 0 (the scene file was written; the reader chose to stop reading)."""
    out = tmp_path / "scene.json"
    tables = [TABLE / "particles.csv", TABLE / "contacts.csv"]
    proc = subprocess.Popen([sys.executable, "-m", "granstab", "convert", *map(str, tables), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV)
    proc.stdout.close()                                   # the reader has gone before anything was written
    err = proc.stderr.read().decode()
    assert proc.wait() == 0 and err == ""
    assert granstab.load_scene(out).n_particles == 3


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
    first, second = pairs[np.argsort(-overlap)[:2]] + 1
    (line,) = [w for w in load(paths).warnings if "overlap by more than" in w]
    assert line.startswith(f"2 contact(s) overlap by more than 0.1 of the pair's mean radius (2δ/(R_p+R_q) up to "
                           f"{overlap.max():.3g}; d/(R_p+R_q) down to {(d / total).min():.3g})")
    assert line.endswith(f"({first[0]}-{first[1]}, {second[0]}-{second[1]})")             # worst first
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


# ------------------------------------------------------------------------------------------------ Ctrl-C, resume

def packing_file(tmp_path, n: int, n_sliding: int, seed: int = 1) -> Path:
    from granstab.io.scenes import save_scene
    from granstab.model import packings
    path = tmp_path / f"packing{n}.npz"
    save_scene(packings.random_packing(2, n, n_sliding=n_sliding, seed=seed), path)
    return path


def interrupt_when(proc, ready, timeout: float = 300) -> tuple[str, str]:
    """Ctrl-C as a terminal sends it (SIGINT to the process group: the command and any workers it started) once
    `ready()` holds; then the command's (stdout, stderr). Never before: this sent it when its wait (120 s) ran out
    too, and a scan on Dask workers slowed by a loaded machine (its first part took over 13 s at load 8 here) then
    said, rightly, "0 of 2000 clusters kept", and the test found no part to compare with that line ("need at least
    one array to concatenate"). Now such a run fails saying the machine was too busy."""
    deadline = time.monotonic() + timeout
    while not ready() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert proc.poll() is None, "the command finished before it could be interrupted: make its work larger"
    if not ready():
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise AssertionError(f"not ready to interrupt after {timeout:g} s: the machine is too busy for this test")
    os.killpg(proc.pid, signal.SIGINT)
    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)          # never leave it running: it did not stop on Ctrl-C
        proc.communicate()
        raise AssertionError(f"still running {timeout:g} s after Ctrl-C") from None


def started(*args) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "granstab", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV, start_new_session=True)


def one_interrupt_line(err: str, what: str) -> str:
    """The interruption's line: the last on stderr, no traceback; any other line is a progress bar's."""
    lines = [x for x in err.replace("\r", "\n").splitlines() if x.strip()]
    assert "Traceback" not in err and "Error" not in err, err
    assert lines and lines[-1].startswith(f"granstab {what}: interrupted (Ctrl-C)"), err
    assert [x for x in lines if "%|" not in x] == lines[-1:], err      # text mode reads a bar's \r as \n
    return lines[-1]


@pytest.mark.slow
@pytest.mark.serial                     # Ctrl-C sent while the work runs: timing
def test_ctrl_c_in_a_scan_says_what_was_kept_and_the_rerun_resumes_to_the_uninterrupted_result(tmp_path):
    """A scan in this process (the default for small work), Ctrl-C once its first chunk is on disk: one line saying
    how many clusters were kept and how to resume, exit 130; the same command again says it resumed from that many
    and its tables equal those of a scan never interrupted (every column but the time taken)."""
    from granstab.scan import read_map, scan
    scene_file, out = packing_file(tmp_path, 200, 20), tmp_path / "scan"      # ~1.5 s of work at rest
    proc = started("scan", scene_file, "--out", out, "--metric", "family", "--out-format", "csv")
    _, err = interrupt_when(proc, lambda: any((out / "parts").glob("*.arrow")) if (out / "parts").is_dir() else False)
    line = one_interrupt_line(err, "scan")
    assert proc.returncode == 130
    kept = int(line.split("interrupted (Ctrl-C): ")[1].split(" of ")[0])
    total = granstab.load_scene(scene_file).n_particles
    assert 0 < kept < total and f"of {total} clusters kept in {out}" in line and "resumes" in line
    assert kept == len(np.unique(np.concatenate([_centers(f) for f in (out / "parts").glob("*.arrow")])))
    again = granstab_cli("scan", scene_file, "--out", out, "--metric", "family", "--out-format", "csv")
    assert again.returncode == 0 and again.stderr == ""
    assert f"(resumed: {kept} already in the folder, {total - kept} analysed now)" in again.stdout.splitlines()[0]
    scan(granstab.load_scene(scene_file), tmp_path / "whole", metric="family", fmt="csv", workers=1, figures=False)
    a, b = read_map(out)["clusters"], read_map(tmp_path / "whole")["clusters"]
    assert set(a) == set(b)
    for key in a:
        if key != "seconds":
            assert [str(v) for v in a[key]] == [str(v) for v in b[key]], key


def _centers(part: Path) -> np.ndarray:
    import pyarrow.feather as feather
    return feather.read_table(part).column("center").to_numpy()


@pytest.mark.slow
@pytest.mark.serial                     # Ctrl-C sent while the work runs: timing
def test_ctrl_c_in_a_scan_on_dask_workers_is_one_line(tmp_path):
    """Two local Dask workers get Ctrl-C too (the terminal's process group): they printed 28–59 lines of
    KeyboardInterrupt and CancelledError tracebacks. Now: one line, exit 130, what is kept stays on disk. Dask's
    port 8787 is held meanwhile (as by another cluster on the machine: CI once printed distributed's "Port 8787 is
    already in use" warning above the line)."""
    scene_file, out = packing_file(tmp_path, 2000, 200), tmp_path / "scan"
    with socket.socket() as taken:
        with suppress(OSError):                   # already taken by someone else: the case under test all the same
            taken.bind(("0.0.0.0", 8787))
            taken.listen()
        proc = started("scan", scene_file, "--out", out, "--metric", "family", "--workers", "2")
        _, err = interrupt_when(proc, lambda: any((out / "parts").glob("*.arrow")) if (out / "parts").is_dir()
                                else False)
    line = one_interrupt_line(err, "scan")
    assert proc.returncode == 130 and " clusters kept in " in line
    kept = int(line.split("interrupted (Ctrl-C): ")[1].split(" of ")[0])
    assert kept == len(np.unique(np.concatenate([_centers(f) for f in (out / "parts").glob("*.arrow")])))


@pytest.mark.slow
@pytest.mark.serial                     # Ctrl-C sent while the work runs: timing
def test_ctrl_c_while_the_dask_workers_start_stops_the_scan(tmp_path):
    """Ctrl-C once the first Dask worker's process exists (the cluster takes 3-8 s to start): it was lost (SIGINT was
    ignored meanwhile, so that the workers inherit it ignored) and the scan ran on to its end, exit 0. Now it is held
    while they start (workers.sigint_held): one line, exit 130, as many clusters kept as are on disk."""
    import psutil
    scene_file, out = packing_file(tmp_path, 2000, 200), tmp_path / "scan"
    proc = started("scan", scene_file, "--out", out, "--metric", "family", "--workers", "2")
    me = psutil.Process(proc.pid)

    def a_worker_starts():
        with suppress(psutil.Error):
            return any("spawn_main" in " ".join(c.cmdline()) for c in me.children())
        return False

    _, err = interrupt_when(proc, a_worker_starts)
    line = one_interrupt_line(err, "scan")
    assert proc.returncode == 130 and " clusters kept in " in line
    kept = int(line.split("interrupted (Ctrl-C): ")[1].split(" of ")[0])
    parts = list((out / "parts").glob("*.arrow")) if (out / "parts").is_dir() else []
    assert kept == len(np.unique(np.concatenate([_centers(f) for f in parts] + [np.zeros(0, int)])))


@pytest.mark.serial                     # Ctrl-C sent while the work runs: timing
def test_ctrl_c_while_granstab_loads_is_one_line():
    """Ctrl-C in a command's first second, while granstab's modules load (numpy loaded, scipy and the rest not yet:
    Python's -X importtime lines say where it is): it printed a traceback of imports. Now one line, exit 130."""
    proc = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "granstab", "analyze", "x.json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV,
                            start_new_session=True)
    seen = []
    while not (seen and seen[-1].split("|")[-1].strip() == "numpy") and proc.poll() is None:
        seen.append(proc.stderr.readline())
    assert not any("granstab.cli" in line for line in seen), "granstab loaded before the Ctrl-C could be sent"
    _, err = interrupt_when(proc, lambda: True)
    lines = [x for x in err.splitlines() if not x.startswith("import time:")]
    assert lines == ["granstab: interrupted (Ctrl-C) while starting; nothing was done"], err[-3000:]
    assert proc.returncode == 130


def test_importing_granstab_leaves_the_programs_excepthook_alone():
    """The start-up hook above answers a Ctrl-C only while granstab's modules load; once loaded, a program that
    imports granstab keeps its own sys.excepthook (a library must not take it over)."""
    code = ("import sys; mine = lambda *a: None; sys.excepthook = mine; import granstab; "
            "print(sys.excepthook is mine)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, timeout=120)
    assert out.stdout.strip() == "True", out.stderr[-2000:]


@pytest.mark.serial                     # Ctrl-C sent while the work runs: timing
def test_ctrl_c_in_analyze_is_one_line(tmp_path):
    """analyze of 4,096 branches (--timeout: above the 10 s a run takes without it), Ctrl-C once its progress bar
    shows: one line (after the bar), exit 130."""
    scene_file = packing_file(tmp_path, 60, 12, seed=3)
    proc = started("analyze", scene_file, "--metric", "L", "--max-sliding", "20", "--progress", "--timeout", "600")
    first = proc.stderr.read(1)                   # the bar has started: granstab is at work
    time.sleep(0.2)
    out, err = interrupt_when(proc, lambda: True)
    one_interrupt_line(first + err, "analyze")
    assert proc.returncode == 130 and out == ""


# ------------------------------------------------------------------------------------------------ missing extras

BLOCK = "import sys; sys.modules.update({{name: None for name in {names!r}}}); from granstab.cli import main; " \
        "sys.exit(main({argv!r}))"


@pytest.mark.parametrize("missing, options, extra", [
    (["pyarrow"], [], "scan"),
    (["dask", "dask.distributed", "distributed"], ["--workers", "2"], "scan"),
    (["matplotlib"], [], "scan")])
def test_a_missing_extra_is_one_line_naming_it_before_any_folder_is_made(tmp_path, missing, options, extra):
    """`pip install -e ".[app]"` then `granstab scan` ended in ModuleNotFoundError: No module named 'dask' and a
    half-made folder. Each package a scan needs, made unimportable: one line saying what to install, exit 2,
    no output folder."""
    out = tmp_path / "scan"
    argv = ["scan", str(ROOT / "presets" / "annulus_frame.json"), "--out", str(out), *options]
    proc = subprocess.run([sys.executable, "-c", BLOCK.format(names=missing, argv=argv)], capture_output=True,
                          text=True, env=ENV)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"granstab: {missing[0]} is needed for ")
    assert f" and is not installed: pip install \"granstab[{extra}]\"" in proc.stderr
    assert not out.exists()


def test_without_dask_a_default_scan_runs_in_this_process_and_says_so(tmp_path):
    """Dask is needed only for parallel workers: a default scan without it runs and says where it ran."""
    out = tmp_path / "scan"
    argv = ["scan", str(ROOT / "presets" / "annulus_frame.json"), "--out", str(out), "--json"]
    proc = subprocess.run([sys.executable, "-c", BLOCK.format(names=["dask", "distributed"], argv=argv)],
                          capture_output=True, text=True, env=ENV)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["workers"]["where"] == "in this process" and summary["clusters"] == 143


def test_the_app_install_brings_what_the_tour_uses():
    """The README's install (`.[app]`) runs the tour, whose step 9 scans: the app extra holds the scan extra."""
    import tomllib
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert set(extras["scan"]) <= set(extras["app"])


# ------------------------------------------------------------------------------------------------ default workers

@pytest.mark.parametrize("seconds, cores, load, dask, workers", [
    (300.0, 2, 6.0, True, 1),      # the busy 2-core machine of the issue: --workers 1 was 2-20x faster
    (300.0, 2, 1.0, True, 1),      # one core taken by another process: no idle core for a second worker
    (300.0, 2, 0.2, True, 2),
    (3.0, 16, 0.0, True, 1),       # little work: Dask's start does not pay
    (12.0, 16, 0.0, True, 3),      # 12 s of work: workers of at least 5 s each
    (1000.0, 16, 4.4, True, 12),   # the idle cores, rounded
    (300.0, 2, 0.0, False, 1)])    # no Dask: in this process, said so
def test_the_default_workers_follow_the_stated_rule(seconds, cores, load, dask, workers):
    from granstab.scan.workers import PARALLEL_SECONDS, WORKER_SECONDS, default_workers
    assert (PARALLEL_SECONDS, WORKER_SECONDS) == (10.0, 5.0)             # the rule docs/scan.md states
    n, why = default_workers(seconds, cores, load, dask)
    assert n == workers and why


def test_a_scan_says_where_it_ran_and_why(tmp_path, monkeypatch, capsys):
    """On a busy machine (2 cores at load 6, as monkeypatched) a scan whose work counts as large stays in this
    process and says so, in summary.json and in its output."""
    from granstab.scan import run, workers
    monkeypatch.setattr(workers, "PARALLEL_SECONDS", 0.0)                 # any work counts as large here
    monkeypatch.setattr(run, "machine", lambda: (2, 6.0))
    assert main(["scan", str(ROOT / "presets" / "annulus_frame.json"), "--out", str(tmp_path / "s")]) == 0
    why = "default: 2 core(s) here at load 6.0: none idle for a second worker"
    summary = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert summary["workers"] == {"count": 1, "where": "in this process", "why": why}
    assert capsys.readouterr().out.splitlines()[1] == f"ran in this process ({why})"
