"""A resume knows its inputs (issue 38): `track` and `scan` into a folder that holds a run record each input's size,
modification time and content hash with the options; a changed input or option is a one-line refusal naming the
file (or the option, with both values, only what differs) and saying how to start afresh (--overwrite)."""
import json
import os

import numpy as np
from test_track import write_sequence

import granstab
from granstab.cli import main
from granstab.model.packings import lattice
from granstab.scan.resume import changed_options, fingerprint


def double_forces(path):
    """contacts.csv with every force doubled (same columns, other bytes)."""
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    rows[:, 3:] *= 2
    np.savetxt(path, rows, delimiter=",", header="frame,id1,id2,fx,fy", comments="")


def test_track_refuses_a_resume_on_a_changed_input_and_overwrite_starts_afresh(tmp_path, capsys):
    """The issue's case: every force doubled, the same track command into the same folder printed "3 frames (3
    already in the folder)" and kept the old pressures; now one line naming the file and --overwrite."""
    paths = write_sequence(tmp_path)
    out = tmp_path / "out"
    args = ["track", *map(str, paths), "--out", str(out), "--mu", "0.5", "--workers", "1", "--no-figures", "--json"]
    assert main(args) == 0
    first = json.loads(capsys.readouterr().out)
    before = pressures(out)
    assert main(args) == 0                                   # unchanged: a resume that runs nothing
    assert json.loads(capsys.readouterr().out)["cost"]["resumed"] == 3
    double_forces(paths[1])
    assert main(args) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert captured.out == "" and "\n" not in err
    assert str(paths[1].resolve()) in err and "changed" in err and "--overwrite" in err
    assert main([*args, "--overwrite"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["cost"]["resumed"] == 0 and again["cost"]["frames_this_run"] == 3
    # the pressures follow the doubled forces: twice the first run's (σ is linear in f; round-off of the sums)
    assert first["frames"] == again["frames"] == 3
    np.testing.assert_allclose(pressures(out), 2 * before, rtol=1e-12)


def pressures(out):
    import pyarrow.parquet as pq
    return np.asarray(pq.read_table(out / "frames.parquet").column("pressure"))


def test_a_changed_option_names_only_what_differs_with_both_values(tmp_path, capsys):
    paths = write_sequence(tmp_path)
    out = tmp_path / "out"
    base = ["track", *map(str, paths), "--out", str(out), "--workers", "1", "--no-figures"]
    assert main([*base, "--mu", "0.5"]) == 0
    capsys.readouterr()
    assert main([*base, "--mu", "0.3"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "import.mu: 0.5 → 0.3" in err and "--overwrite" in err
    assert "window" not in err and "event_threshold" not in err          # only what differs, not the whole dict
    assert changed_options({"a": 1, "b": {"c": 2}}, {"a": 1, "b": {"c": 3}}) == ["b.c: 2 → 3"]


def test_the_same_bytes_with_a_new_modification_time_still_resume(tmp_path):
    """Only the contents decide: touching a file (a copy, a checkout) is not a change."""
    path = tmp_path / "a.txt"
    path.write_text("forces")
    before = fingerprint([path])
    os.utime(path, (1, 1))
    after = fingerprint([path])
    key = str(path.resolve())
    assert before[key]["mtime"] != after[key]["mtime"] and before[key]["blake2b"] == after[key]["blake2b"]
    from granstab.scan.resume import changed_input
    assert changed_input(before, after) is None
    path.write_text("forcez")                                          # same size, other bytes
    assert "same size, other contents" in changed_input(before, fingerprint([path]))


def test_scan_refuses_a_resume_on_a_changed_input(tmp_path, capsys):
    scene = lattice(2, size=4, kind="square", n_sliding=2, mu=0.5)
    path = granstab.save_scene(scene, tmp_path / "packing.json")
    out = tmp_path / "scan"
    args = ["scan", str(path), "--out", str(out), "--workers", "1", "--out-format", "csv", "--centers", "every:4"]
    assert main(args) == 0
    capsys.readouterr()
    data = json.loads(path.read_text())
    data["title"] = "another packing"                          # any other bytes: the folder cannot tell what matters
    path.write_text(json.dumps(data))
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(path.resolve()) in err and "--overwrite" in err
    assert main([*args, "--overwrite"]) == 0
    assert json.loads((out / "summary.json").read_text())["resumed"] == 0


def change_one_force(path, step: int, digit: str = "7") -> int:
    """contacts.dump with the first digit of one force (c_pair[1] of the first row) of timestep `step` replaced by
    `digit` (same size), its modification time kept: only the bytes differ. Returns the byte offset changed."""
    raw = bytearray(path.read_bytes())
    st = path.stat()
    block = raw.index(f"ITEM: TIMESTEP\n{step}\n".encode())
    row = raw.index(b"ITEM: ENTRIES", block)
    row = raw.index(b"\n", row) + 1
    at = row + raw[row:].index(b" ") + 1                       # past id1
    at = at + raw[at:].index(b" ") + 1                         # past id2: the first force component
    at += raw[at] == ord("-")
    assert raw[at:at + 1].isdigit() and raw[at:at + 1] != digit.encode()
    raw[at] = ord(digit)
    path.write_bytes(bytes(raw))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    return at


def test_track_resume_names_the_frame_whose_contents_changed(tmp_path, capsys):
    """A 3-frame dump pair (timesteps 0, 100, 200): unchanged, the same track resumes; one force of frame 2
    (timestep 200) changed, same size and modification time, is refused in one line naming contacts.dump and
    timestep 200 (and no other frame); inputs.json holds one hash a frame of each dump, the script hashed whole."""
    from test_io_source import run_of
    paths = run_of(tmp_path / "run", 3)
    out = tmp_path / "out"
    args = ["track", *map(str, paths), "--out", str(out), "--workers", "1", "--no-figures", "--json"]
    assert main(args) == 0
    capsys.readouterr()
    recorded = json.loads((out / "inputs.json").read_text())
    for dump in paths[:2]:
        assert list(recorded[str(dump.resolve())]["frames"]) == ["0", "100", "200"]
    assert "blake2b" in recorded[str(paths[2].resolve())]
    assert main(args) == 0
    assert json.loads(capsys.readouterr().out)["cost"]["resumed"] == 3
    size = paths[1].stat().st_size
    change_one_force(paths[1], 200)
    assert paths[1].stat().st_size == size
    assert main(args) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert captured.out == "" and "\n" not in err
    assert str(paths[1].resolve()) in err and "timestep 200 changed" in err and "--overwrite" in err
    assert "timestep 100" not in err and "timestep 0 " not in err


def test_frame_hashes_follow_only_the_frame_changed(tmp_path):
    """fingerprint with the dump's spans: a byte changed in the frame at timestep 100 changes that frame's hash
    alone; the spans tile the file (each frame from the end of the one before it, header included)."""
    from test_io_source import run_of
    paths = run_of(tmp_path, 3)
    source = granstab.io.open(paths)
    spans = source.spans()
    for path, parts in spans.items():
        assert [t for t, _, _ in parts] == [0, 100, 200]
        assert [lo for _, lo, _ in parts] == [0] + [hi for _, _, hi in parts[:-1]]
        assert parts[-1][2] == path.stat().st_size
    key = str(paths[1].resolve())
    before = fingerprint(paths, spans)[key]["frames"]
    change_one_force(paths[1], 100)
    after = fingerprint(paths, spans)[key]["frames"]
    assert [t for t in before if before[t] != after[t]] == ["100"]
    assert source.spans([200])[paths[1]] == [spans[paths[1]][2]]
