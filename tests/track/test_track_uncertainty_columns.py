"""`track --scan --force-uncertainty file` (issue 42): each frame's scan takes that frame's own f_err columns; a
sequence without them is a one-line error naming the file (exit 2)."""
import json
import sys
from pathlib import Path

import numpy as np

from granstab.cli import main
from granstab.scan import read_map

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
from test_uncertainty_columns import ROWS  # noqa: E402


def write_frames(folder, loud, header="f_err"):
    """The 3×2 grid of test_uncertainty_columns in two frames (a `frame` column), the same forces; in frame k the
    contact loud[k] has f_err = 100, the others 0."""
    particles, contacts = folder / "particles.csv", folder / "contacts.csv"
    particles.write_text("frame,id,x,y,radius\n" + "".join(
        f"{k},{i + 1},{1.998 * (i % 3)},{1.998 * (i // 3)},1\n" for k in range(2) for i in range(6)))
    contacts.write_text(f"frame,id1,id2,fx,fy,{header}\n" + "".join(
        f"{k}," + ",".join(str(v) for v in row) + f",{100.0 if c == loud[k] else 0.0}\n"
        for k in range(2) for c, row in enumerate(ROWS)))
    return [str(particles), str(contacts)]


def track_args(paths, out):
    return ["track", *paths, "--mu", "0.5", "--scan", "--boundary", "loads", "--force-uncertainty", "file",
            "--workers", "1", "--no-figures", "--out", str(out)]


def test_each_frame_takes_its_own_columns(tmp_path, capsys):
    """Frame 0: contact 5–6 loud (clusters of 5 and 6, centres 4 and 5, not `holds`); frame 1: contact 1–2 loud
    (clusters of 1 and 2, centres 0 and 1). The rest hold with an infinite margin (zero band). One frame's columns
    used for both would give the same centres twice."""
    paths = write_frames(tmp_path, loud=[3, 0])
    assert main(track_args(paths, tmp_path / "t")) == 0
    capsys.readouterr()
    for frame, loud in ((0, [4, 5]), (1, [0, 1])):
        folder = tmp_path / "t" / "scans" / f"frame-{frame:06d}"
        c = read_map(folder)["clusters"]
        assert set(c["verdict"]) == {"unstable"}
        held = ~np.isin(c["center"], loud)
        assert list(c["data_robust"][held]) == ["holds"] * 4 and np.all(np.isinf(c["robust_margin"][held]))
        assert set(c["data_robust"][~held]) <= {"depends", "undecided"} and np.all(c["robust_margin"][~held] < 1)
        options = json.loads((folder / "summary.json").read_text())["options"]
        assert options["uncertainty"]["per_contact"].startswith("the file's")


def test_frames_without_columns_are_one_line_naming_the_file(tmp_path, capsys):
    paths = write_frames(tmp_path, loud=[3, 0], header="mobilised")
    assert main(track_args(paths, tmp_path / "t")) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "contacts.csv" in err and "no per-contact uncertainty columns" in err
