"""MercuryDPM .data + .fstat, in the layout MercuryDPM's writers use (granstab/io/mercury.py): files written here
from known scenes (each contact from both sides, a wall row) read back to the same scene as the generic tables."""
from pathlib import Path

import numpy as np
from helpers import DATA, ROOT  # noqa: E402

from granstab.cli import main
from granstab.io import load

DATA = DATA / "io"
KEYS = ("x", "point", "normal", "curvature_p", "curvature_q", "force", "load", "k", "alpha", "mu")


def write_mercury(path: Path, steps):
    """steps: [(time, x (N, d), radius (N,), p, q, f^pq (M, d), walls [(i, force on i)])] → NAME.data, NAME.fstat."""
    data, fstat = [], []
    for time, x, radius, p, q, f, walls in steps:
        n, d = x.shape
        box = " ".join(["0"] * d + ["10"] * d)
        data.append(f"{n} {time} {box}")
        for k in range(n):
            vel = " ".join(["0"] * d)
            tail = "0 0 0" if d == 2 else "0 0 0 0 0 0 0"
            data.append(" ".join(repr(float(v)) for v in x[k]) + f" {vel} {float(radius[k])!r} {tail}")
        fstat += [f"# {time} 0", f"# {box}", "# 0.5 1 0 0 0 0"]
        for a, b, force in [(p[c], q[c], f[c]) for c in range(len(p))] + [(q[c], p[c], -f[c]) for c in range(len(p))]:
            n_row = (x[a] - x[b]) / np.linalg.norm(x[a] - x[b])          # from j to i
            fn = force @ n_row
            ft_vec = force - fn * n_row
            ft = np.linalg.norm(ft_vec)
            t_row = ft_vec / ft if ft > 0 else 0 * ft_vec
            fstat.append(_row(time, a, b, fn, ft, n_row, t_row))
        for a, force in walls:                                           # MercuryDPM flips n, t on wall rows
            n_row = -force / np.linalg.norm(force)
            fstat.append(_row(time, a, -1, np.linalg.norm(force), 0.0, n_row, 0 * n_row))
    path.with_suffix(".data").write_text("\n".join(data) + "\n")
    path.with_suffix(".fstat").write_text("\n".join(fstat) + "\n")
    return [path.with_suffix(".data"), path.with_suffix(".fstat")]


def _row(time, a, b, fn, ft, n, t):
    pad = lambda v: list(v) + [0.0] * (3 - len(v))  # noqa: E731
    values = [time, int(a), int(b), 0, 0, 0, 0, 0, fn, ft, *pad(n), *pad(t)]
    return " ".join(str(v) if isinstance(v, int) else repr(float(v)) for v in values)


def table_scene():
    return load([DATA / "table" / "particles.csv", DATA / "table" / "contacts.csv"], k=2.0, alpha=0.5, mu=0.4)


def test_2d_frames_read_back_to_the_table_scene(tmp_path):
    ref = table_scene().scene
    x = ref.x
    radius = np.ones(3)
    steps = [(0.5, x + 1.0, radius, ref.p, ref.q, ref.force * 2, []),
             (1.0, x, radius, ref.p, ref.q, ref.force, [(0, np.array([0.0, 0.05]))])]
    files = write_mercury(tmp_path / "run", steps)
    imp = load(files, k=2.0, alpha=0.5, mu=0.4)
    s = imp.scene
    assert imp.frames == [0.5, 1.0] and imp.report["frame"] == 1.0              # default: the last time
    assert s.names == ("0", "1", "2") and np.array_equal(s.p, ref.p) and np.array_equal(s.q, ref.q)
    for key in KEYS:
        assert np.abs(getattr(s, key) - getattr(ref, key)).max() <= 1e-15 * max(np.abs(getattr(ref, key)).max(), 1)
    rep = imp.report
    assert rep["duplicates"]["pairs_listed_twice"] == 3 and rep["duplicates"]["newton_third_law_largest_relative_misfit"] < 1e-15
    assert rep["walls"]["wall_contacts"] == 1 and rep["walls"]["particles_touching"] == 1
    earlier = load(files, timestep=0.5).scene
    assert np.allclose(earlier.x, x + 1.0) and np.allclose(earlier.force, 2 * ref.force)


def test_3d_scene_round_trip(tmp_path):
    ref = load([DATA / "lammps" / "atoms3d.dump", DATA / "lammps" / "contacts3d.dump",
                ROOT / "examples" / "dem" / "in.spheres3d"], timestep=14000, periodic=False).scene   # no cell here
    atoms = np.loadtxt((DATA / "lammps" / "atoms3d.dump").read_text().split("ITEM: TIMESTEP\n14000\n")[1]
                       .split("\n", 7)[7].splitlines())
    radius_of = dict(zip(atoms[:, 0].astype(int), atoms[:, 5]))
    radius = np.array([radius_of[int(n)] for n in ref.names])
    files = write_mercury(tmp_path / "spheres", [(2.0, ref.x, radius, ref.p, ref.q, ref.force, [])])
    s = load(files, k=1000, alpha=0.5, mu=0.5).scene
    assert s.dim == 3 and s.n_contacts == ref.n_contacts and s.state == ref.state
    for key in ("x", "point", "normal", "curvature_p", "force", "load"):
        assert np.abs(getattr(s, key) - getattr(ref, key)).max() <= 1e-12 * max(np.abs(getattr(ref, key)).max(), 1), key


def test_malformed_mercury_files(tmp_path, capsys):
    ref = table_scene().scene
    files = write_mercury(tmp_path / "run", [(1.0, ref.x, np.ones(3), ref.p, ref.q, ref.force, [])])
    fstat = files[1].read_text().splitlines()
    files[1].write_text("\n".join(fstat[:4] + ["1.0 1 7 " + " ".join(["0"] * 13)] + fstat[5:]) + "\n")
    rc = main(["convert", *map(str, files), "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "run.fstat: line 5: j: unknown particle 7 (rows 0..2 of run.data at time 1)" in err
    files[1].write_text("\n".join(fstat) + "\n")
    rc = main(["convert", *map(str, files), "--timestep", "3", "--out", str(tmp_path / "x.json")])
    assert rc == 2 and "run.data: timestep 3: time: not in the file (it has 1)" in capsys.readouterr().err
    files[0].write_text("\n".join(files[0].read_text().splitlines()[:2]) + "\n")
    rc = main(["convert", *map(str, files), "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "run.data: line 2: particles: file ends after 1 of 3 rows of time 1 (truncated?)" in err
