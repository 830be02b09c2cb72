"""MercuryDPM output: `NAME.data` (particles) + `NAME.fstat` (contacts), many time steps each.

Layout as MercuryDPM writes it (DPMBase::outputXBallsData, BaseInteraction::writeToFStat):
- .data: per time step a header `N time xmin ymin [zmin] xmax ymax [zmax]` (6 values: 2D, 8: 3D), then N rows
  `x y [z] vx vy [vz] radius ...` (2D: 8 values, radius 5th; 3D: 14 values, radius 7th). Particles are named by
  their 0-based row, the index the .fstat uses.
- .fstat: per time step three `#` lines (time; box; radii), then one row per contact side:
  `time i j cx cy cz δ δ_t f_n f_t nx ny nz tx ty tz`, with n pointing from j to i and the force on i equal to
  f_n n + f_t t. A particle pair appears twice (once from each side: the listings are compared, Newton's third
  law); a negative j = −(wall index + 1) is a wall, whose row MercuryDPM writes with n and t flipped (its own
  comment: "an old bug"), so the wall's force on i is −(f_n n + f_t t): it becomes an external load.
The contact law is not in these files: give --k --alpha --mu. Periodic ghost particles are not handled.
Written from MercuryDPM's source; the tests use files in this layout, not output of the engine itself.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from .build import Snapshot
from .lines import read_block
from .registry import Format, register

FSTAT_FIELDS = ("time", "i", "j", "cx", "cy", "cz", "delta", "delta_t", "fn", "ft", "nx", "ny", "nz", "tx", "ty",
                "tz")


def is_mercury(paths: list[Path]) -> bool:
    return {p.suffix for p in paths} == {".data", ".fstat"}


def _text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None


def data_steps(path: Path):
    """(time, first row line, N, dim, text of the rows) per time step: one loop per step, not per line."""
    lines = _text(path).splitlines()
    steps, at = [], 0
    while at < len(lines):
        if not lines[at].strip():
            at += 1
            continue
        head = lines[at].split()
        try:
            n, time = int(head[0]), float(head[1])
        except (ValueError, IndexError):
            raise SceneError(f"{path}: line {at + 1}: N time: expected a time-step header `N time xmin ...`, "
                             f"got {lines[at][:40]!r}") from None
        if len(head) not in (6, 8):
            raise SceneError(f"{path}: line {at + 1}: header: {len(head)} values, expected 6 (2D) or 8 (3D)")
        if at + 1 + n > len(lines):
            raise SceneError(f"{path}: line {len(lines)}: particles: file ends after {len(lines) - at - 1} of {n} "
                             f"rows of time {time:g} (truncated?)")
        steps.append((time, at + 2, n, 2 if len(head) == 6 else 3, "\n".join(lines[at + 1:at + 1 + n])))
        at += 1 + n
    if not steps:
        raise SceneError(f"{path}: line 1: header: empty file")
    return steps


def fstat_steps(path: Path):
    """(time, first row line, rows text) per time step, split at the three `#` header lines."""
    text = _text(path)
    heads = list(re.finditer(r"^#([^\n]*)\n#[^\n]*\n#[^\n]*\n", text, re.M))
    if not heads:
        raise SceneError(f"{path}: line 1: header: no `# time` header lines (not a MercuryDPM .fstat)")
    steps = []
    for k, m in enumerate(heads):
        end = heads[k + 1].start() if k + 1 < len(heads) else len(text)
        line = text.count("\n", 0, m.end()) + 1
        try:
            time = float(m.group(1).split()[0])
        except (ValueError, IndexError):
            raise SceneError(f"{path}: line {line - 3}: time: not a number ({m.group(1)[:40]!r})") from None
        steps.append((time, line, text[m.end():end]))
    return steps


def _pick(times, wanted, path):
    times = np.asarray(times)
    if wanted is None:
        return None
    hit = np.flatnonzero(np.isclose(times, wanted, rtol=1e-6, atol=0))
    if not hit.size:
        shown = ", ".join(f"{t:g}" for t in times[:5]) + (", …" if len(times) > 5 else "")
        raise SceneError(f"{path}: timestep {wanted:g}: time: not in the file (it has {shown})")
    return int(hit[0])


def read_mercury(paths: list[Path], timestep=None) -> Snapshot:
    dpath = next(p for p in paths if p.suffix == ".data")
    fpath = next(p for p in paths if p.suffix == ".fstat")
    dsteps, fsteps = data_steps(dpath), fstat_steps(fpath)
    dtimes, ftimes = [s[0] for s in dsteps], [s[0] for s in fsteps]
    if timestep is None:
        common = [t for t in dtimes if np.any(np.isclose(ftimes, t, rtol=1e-6, atol=0))]
        if not common:
            raise SceneError(f"{fpath}: timestep {dtimes[-1]:g}: time: mismatched .data/.fstat times (no time in "
                             "both)")
        timestep = common[-1]
    time, first, n, dim, rows = dsteps[_pick(dtimes, timestep, dpath)]
    _, cfirst, crows = fsteps[_pick(ftimes, timestep, fpath)]
    width = 8 if dim == 2 else 14
    names = (["x", "y", "vx", "vy", "radius"] if dim == 2 else ["x", "y", "z", "vx", "vy", "vz", "radius"])
    names = names + [f"column {k + 1}" for k in range(len(names), width)]
    P = read_block(rows, first, dpath, names, n, "particles")
    x, radius = P[:, :dim], P[:, dim * 2]
    crow_count = len(re.findall(r"^[ \t]*\S", crows, re.M))
    C = read_block(crows, cfirst, fpath, list(FSTAT_FIELDS), crow_count, "contacts") if crow_count else \
        np.zeros((0, 16))
    line_of_row = lambda r: f"{fpath}: line {cfirst + r}"  # noqa: E731
    i, j = C[:, 1].astype(np.int64), C[:, 2].astype(np.int64)
    for k, (name, column) in enumerate((("i", i), ("j", j)), 1):
        bad = np.flatnonzero((column >= n) | (column != C[:, k]) | ((column < 0) & (k == 1)))
        if bad.size:
            raise SceneError(f"{line_of_row(bad[0])}: {name}: unknown particle {C[bad[0], k]:g} "
                             f"(rows 0..{n - 1} of {dpath.name} at time {time:g})")
    n_row, t_row = C[:, 10:10 + dim], C[:, 13:13 + dim]
    force_on_i = C[:, 8:9] * n_row + C[:, 9:10] * t_row
    wall = j < 0
    wall_load = None
    if np.any(wall):
        wall_load = np.zeros((n, dim))
        np.add.at(wall_load, i[wall], -force_on_i[wall])
    rows_pp = np.flatnonzero(~wall)
    p, q, f = i[rows_pp], j[rows_pp], force_on_i[rows_pp]
    key = np.minimum(p, q) * n + np.maximum(p, q)
    _, first_row, counts = np.unique(key, return_index=True, return_counts=True)
    keep = np.sort(first_row)
    misfit = 0.0
    if np.any(counts == 2):
        order = np.argsort(key, kind="stable")
        twin = key[order][1:] == key[order][:-1]
        a, b = order[:-1][twin], order[1:][twin]
        misfit = float(np.max(np.linalg.norm(f[a] + f[b], axis=1) / np.maximum(np.linalg.norm(f[a], axis=1), 1e-300)))
    walls = "none in the file" if wall_load is None else {
        "wall_contacts": int(wall.sum()), "particles_touching": int(np.unique(i[wall]).size),
        "treatment": "wall force −(f_n n + f_t t) of MercuryDPM's wall rows becomes an external load"}
    return Snapshot(source=f"{dpath} + {fpath}", format="mercurydpm", dim=dim, ids=np.arange(n), x=x, radius=radius,
                    p=p[keep], q=q[keep], force=f[keep], wall_load=wall_load, frame=float(time),
                    frames=[float(t) for t in dtimes],
                    notes={"walls": walls, "duplicates": {"pairs_listed_twice": int(np.sum(counts == 2)),
                                                          "pairs_listed_once": int(np.sum(counts == 1)),
                                                          "newton_third_law_largest_relative_misfit": misfit}},
                    particle_line=lambda k: f"{dpath}: line {first + k}",
                    contact_line=lambda c: line_of_row(rows_pp[keep[c]]))


register(Format("mercurydpm", sniff=is_mercury,
                read=lambda paths, request, progress: read_mercury(paths, request.frame)))
