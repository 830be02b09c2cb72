"""The frames of the shaped-grain readers accounted for as every reader's are (issues 37, 38): LIGGGHTS multisphere
(four dumps), LAMMPS rounded polygons (two dumps, data file, script) and LIGGGHTS superquadrics are indexed once
(registry `index`): the timesteps all dumps have are the frames, timesteps in some dumps only are named in one
line, a truncated last timestep is left out with a warning naming its file, dumps of different runs are refused.
Each run's committed one-timestep fixture is made a run of several timesteps by repeating its timestep."""
import re
from pathlib import Path

import pytest
from helpers import DATA, ROOT  # noqa: E402

import granstab
from granstab.cli import main
from granstab.io.registry import get

EXAMPLES = ROOT / "examples"
CASES = {   # format: (fixture folder, dump names, other inputs)
    "liggghts_multisphere": (DATA / "io" / "liggghts_multisphere", ("atoms", "contacts", "walls", "bodies"),
                             [EXAMPLES / "liggghts_multisphere" / "in.clumps3d"]),
    "lammps_polygons": (DATA / "io" / "lammps_polygons", ("atoms", "vertices"),
                        [EXAMPLES / "lammps_body" / "data.polygons", EXAMPLES / "lammps_body" / "in.polygons2d"]),
    "liggghts-superquadric": (DATA / "liggghts_superquadric", ("atoms", "contacts"),
                              [DATA / "liggghts_superquadric" / "in.settle"]),
}
STRIDE = 100


def repeated(text: str, n: int, shift: int = 0) -> str:
    """The dump's one timestep T written n times, as timesteps T + shift, T + shift + STRIDE, ..."""
    step = int(re.search(r"ITEM: TIMESTEP\n(\d+)\n", text).group(1))
    return "".join(text.replace(f"ITEM: TIMESTEP\n{step}\n", f"ITEM: TIMESTEP\n{step + shift + k * STRIDE}\n", 1)
                   for k in range(n))


def run_of(tmp_path: Path, fmt: str, frames: dict, shift: dict = None) -> tuple[list, int]:
    """The fixture's dumps repeated (frames: dump name → count, default 2) into tmp_path; (paths, first step)."""
    folder, names, others = CASES[fmt]
    paths = []
    for name in names:
        text = (folder / f"{name}.dump").read_text()
        out = tmp_path / f"{name}.dump"
        out.write_text(repeated(text, frames.get(name, 2), (shift or {}).get(name, 0)))
        paths.append(out)
    first = int(re.search(r"ITEM: TIMESTEP\n(\d+)\n", (folder / f"{names[0]}.dump").read_text()).group(1))
    return paths + others, first


@pytest.mark.parametrize("fmt", CASES)
def test_every_timestep_of_a_shaped_run_is_a_frame_read_alone(tmp_path, fmt):
    paths, first = run_of(tmp_path, fmt, {})
    assert get(fmt).index is not None
    source = granstab.io.open(paths)
    assert source.format == fmt and source.frames == [first, first + STRIDE] and source.warnings == []
    a, b = source.read(first), source.read(first + STRIDE)
    assert a.report["frame"] == first and b.report["frame"] == first + STRIDE
    assert a.scene.n_contacts == b.scene.n_contacts > 0


@pytest.mark.parametrize("fmt", CASES)
def test_a_truncated_last_timestep_is_left_out_with_a_warning_naming_it(tmp_path, fmt):
    paths, first = run_of(tmp_path, fmt, {})
    cut = paths[1]                                   # the contacts (vertices) dump loses its last rows
    lines = cut.read_text().splitlines(keepends=True)
    cut.write_text("".join(lines[:-3]))
    source = granstab.io.open(paths)
    assert source.frames == [first]
    assert len(source.warnings) == 1 and cut.name in source.warnings[0] and "cut short" in source.warnings[0]
    loaded = source.read()
    assert loaded.report["frame"] == first and loaded.report["frames_left_out"] == source.warnings


@pytest.mark.parametrize("fmt", CASES)
def test_timesteps_in_some_dumps_only_are_named_in_one_line(tmp_path, fmt, capsys):
    first_name = CASES[fmt][1][0]
    paths, first = run_of(tmp_path, fmt, {first_name: 4})
    source = granstab.io.open(paths)
    assert source.frames == [first, first + STRIDE]
    extra = f"2 in {first_name}.dump only ({first + 2 * STRIDE}, {first + 3 * STRIDE})"
    assert len(source.warnings) == 1 and extra in source.warnings[0]
    assert main(["convert", *map(str, paths), "--out", str(tmp_path / "s.json")]) == 0
    assert capsys.readouterr().out.count(extra) == 1


@pytest.mark.parametrize("fmt", CASES)
def test_dumps_of_different_runs_are_refused_in_one_line(tmp_path, fmt, capsys):
    last = CASES[fmt][1][-1]
    paths, _ = run_of(tmp_path, fmt, {}, shift={last: 7})
    assert main(["convert", *map(str, paths), "--out", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"{last}.dump" in err and "none in common" in err and "different runs" in err, err
