"""Converting DEM output (issue 9, "Speed": reading must not be the bottleneck): `granstab.io.load` (what
`granstab convert` runs) on a LAMMPS per-atom dump + local contact dump (+ its input script) and on the generic
tables (particles.csv + contacts.csv), against numpy.loadtxt of the same contact file, side by side in one run;
saving the converted scene as NPZ; peak memory per contact.

Inputs are random packings (granstab.model.packings.random_packing, 2D and 3D) of about 10⁴…10⁶ contacts written the
way the readers expect them (docs/formats.md, LAMMPS):

- LAMMPS: `atoms.dump` (`id type x y z radius mass`, rows in a shuffled order as LAMMPS writes them), the local
  `contacts.dump` with the 11 columns of docs/formats.md (`c_ends[1] c_ends[2] c_pair[1]` … `c_pair[9]`: ids, the normal part
  of the force on id1, the tangential part, the branch vector), printed with `%.12g` as `dump_modify format float
  %.12g` does, plus one non-touching neighbour pair (zero force) for every ten contacts, as `pair/local` lists
  them; and `in.bench`, the input script that names the columns (`compute property/local`, `compute pair/local`)
  and gives the law (`pair_style granular`, `pair_coeff * * hooke … tangential linear_history …`).
- tables: `particles.csv` (`id,x,y[,z],radius`) and `contacts.csv` (`id1,id2,fx,fy[,fz]`), `%.12g`.

Radii: each particle's is half its longest contact distance times 1.01, so that every listed contact overlaps
(δ > 0: the LAMMPS reader keeps contacts by overlap). The converted scene is checked against the packing: the
same contacts and particles, the same forces and centres to the printed precision, k, α, μ from the script.

Rows (medians over repeats; one run where a run takes seconds):
- `convert`: granstab.io.load(paths): detect the format, read both files, contacts from particles (ids →
  indices, overlap, forces), build the scene (geometry, law, cone, imbalance, checks) and its validation report.
- `numpy.loadtxt`: the contact file alone as a plain numeric table (header lines skipped, no checks): the floor
  for parsing it.
- `save NPZ`: granstab.save_scene of the converted scene.
Memory: tracemalloc's peak while converting, per contact (file rows), at the two smallest sizes.
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import granstab.io
from granstab.io.scenes import save_scene
from granstab.model import packings

from .reading import peak_bytes

QUICK_SIZES = (1_000, 10_000)
FULL_SIZES = (10_000, 100_000, 1_000_000)
CONTACTS_PER_PARTICLE = {2: 2.7, 3: 5.7}     # of the random packings (measured; the tables give actual counts)
APART_PER_CONTACT = 0.1                       # non-touching pairs pair/local lists, per contact
FORMAT = "%.12g"
PRINTED = 5e-12                               # its relative rounding
KN, KT, MU = 1.0, 1.0, 0.5                    # the packings' law (k, alpha = kt/kn, mu)


def median_time(fn, budget: float = 2.0, most: int = 5) -> tuple[float, int, object]:
    """Median wall time of fn(), the number of runs (up to `most`, while the total is under `budget`) and the
    last result."""
    times = []
    while len(times) < most and (not times or sum(times) < budget):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), len(times), out


# ------------------------------------------------------------------------------------------------ inputs

def packing(dim: int, target: int, seed: int = 1):
    """A random packing of about `target` contacts, the radii that make every contact overlap and the order in
    which the atom dump lists the particles."""
    scene = packings.random_packing(dim, int(target / CONTACTS_PER_PARTICLE[dim]), seed=seed)
    d = np.linalg.norm(scene.x[scene.q] - scene.x[scene.p], axis=1)
    longest = np.zeros(scene.n_particles)
    np.maximum.at(longest, scene.p, d)
    np.maximum.at(longest, scene.q, d)
    radius = 0.505 * longest
    return scene, radius


def write_rows(path: Path, head: str, columns: list, fmt: list, mode: str = "w") -> None:
    """Rows of `columns` (arrays of equal length) after `head`, one formatted line each (setup only)."""
    table = np.column_stack(columns)
    with open(path, mode, encoding="utf-8") as fh:
        fh.write(head)
        np.savetxt(fh, table, fmt=fmt, delimiter=" " if "," not in head.splitlines()[-1] else ",")


def apart_pairs(scene, radius, rng) -> np.ndarray:
    """About APART_PER_CONTACT·M particle pairs that do not touch (R_1 + R_2 < d), none of them a contact."""
    N, M = scene.n_particles, scene.n_contacts
    want = int(APART_PER_CONTACT * M)
    i = rng.integers(0, N, 2 * want + 10)
    j = (i + N // 2 + rng.integers(0, max(N // 4, 1), len(i))) % N
    d = np.linalg.norm(scene.x[j] - scene.x[i], axis=1)
    ok = (i != j) & (d > 1.5 * (radius[i] + radius[j]))
    return np.stack([i[ok], j[ok]], axis=1)[:want]


def write_lammps(scene, radius, folder: Path, seed: int = 2) -> list[Path]:
    """atoms.dump, contacts.dump and in.bench in the layout of docs/formats.md (module docstring); the paths."""
    dim, N, M = scene.dim, scene.n_particles, scene.n_contacts
    rng = np.random.default_rng(seed)
    ids = np.arange(1, N + 1)
    x3 = np.zeros((N, 3))
    x3[:, :dim] = scene.x
    lo, hi = x3.min(axis=0) - 2 * radius.max(), x3.max(axis=0) + 2 * radius.max()
    if dim == 2:
        lo[2], hi[2] = -0.5, 0.5
    box = "ITEM: BOX BOUNDS ff ff ff\n" + "".join(f"{a:.16e} {b:.16e}\n" for a, b in zip(lo, hi))
    mass = (np.pi * radius**2) if dim == 2 else (4 / 3 * np.pi * radius**3)
    order = rng.permutation(N)
    atoms, contacts, script = folder / "atoms.dump", folder / "contacts.dump", folder / "in.bench"
    write_rows(atoms, f"ITEM: TIMESTEP\n1000\nITEM: NUMBER OF ATOMS\n{N}\n{box}ITEM: ATOMS id type x y z radius mass\n",
               [ids[order], np.ones(N), x3[order], radius[order], mass[order]],
               ["%d", "%d", FORMAT, FORMAT, FORMAT, FORMAT, FORMAT])
    apart = apart_pairs(scene, radius, rng)
    A = len(apart)
    p = np.concatenate([scene.p, apart[:, 0]])
    q = np.concatenate([scene.q, apart[:, 1]])
    n = scene.normal
    fn_part = np.sum(scene.force * n, axis=1)[:, None] * n
    ft_part = scene.force - fn_part
    pad = lambda a: np.concatenate([np.c_[a, np.zeros((len(a), 3 - dim))], np.zeros((A, 3))])  # noqa: E731
    branch = np.zeros((M + A, 3))
    branch[:, :dim] = scene.x[p] - scene.x[q]           # pair/local p10-p12: x_1 - x_2
    mix = rng.permutation(M + A)                         # pair/local lists pairs in neighbour-list order
    cols = [ids[p][mix], ids[q][mix], pad(fn_part)[mix], pad(ft_part)[mix], branch[mix]]
    head = (f"ITEM: TIMESTEP\n1000\nITEM: NUMBER OF ENTRIES\n{M + A}\n{box}ITEM: ENTRIES c_ends[1] c_ends[2] "
            + " ".join(f"c_pair[{k}]" for k in range(1, 10)) + "\n")
    write_rows(contacts, head, cols, ["%d", "%d"] + [FORMAT] * 9)
    script.write_text(
        f"# granstab bench: a random {dim}D packing written as a LAMMPS run would dump it\n"
        f"units lj\ndimension {dim}\natom_style sphere\nboundary f f f\n"
        f"pair_style granular\npair_coeff * * hooke {KN} 0.0 tangential linear_history {KT} 0.5 {MU}\n"
        "compute ends all property/local patom1 patom2\n"
        "compute pair all pair/local fx fy fz p1 p2 p3 p10 p11 p12\n"
        "dump atoms all custom 1000 atoms.dump id type x y z radius mass\n"
        "dump contacts all local 1000 contacts.dump c_ends[1] c_ends[2] c_pair[1] c_pair[2] c_pair[3] &\n"
        "     c_pair[4] c_pair[5] c_pair[6] c_pair[7] c_pair[8] c_pair[9]\n", encoding="utf-8")
    return [atoms, contacts, script]


def write_tables(scene, radius, folder: Path, seed: int = 2) -> list[Path]:
    """particles.csv and contacts.csv (module docstring); the paths."""
    dim, N = scene.dim, scene.n_particles
    ids = np.arange(1, N + 1)
    axes = ",".join("xyz"[:dim])
    particles, contacts = folder / "particles.csv", folder / "contacts.csv"
    write_rows(particles, f"id,{axes},radius\n", [ids, scene.x, radius], ["%d"] + [FORMAT] * (dim + 1))
    force_names = ",".join("f" + a for a in "xyz"[:dim])
    write_rows(contacts, f"id1,id2,{force_names}\n", [ids[scene.p], ids[scene.q], scene.force],
               ["%d", "%d"] + [FORMAT] * dim)
    return [particles, contacts]


# ------------------------------------------------------------------------------------------------ checks

def agreement(scene, imported) -> dict:
    """The converted scene against the packing: contacts (as id pairs), particles, centres and forces (to the
    printed precision: the force is the sum of two printed parts, each component off by up to PRINTED of it)."""
    out = imported.scene
    N = scene.n_particles
    ids = np.array([int(name) for name in out.names]) - 1          # file ids 1..N → packing indices
    key = lambda a, b: np.minimum(a, b).astype(np.int64) * N + np.maximum(a, b)  # noqa: E731
    want, got = key(scene.p, scene.q), key(ids[out.p], ids[out.q])
    order_w, order_g = np.argsort(want), np.argsort(got)
    same_pairs = len(want) == len(got) and np.array_equal(want[order_w], got[order_g])
    force_err = x_err = float("inf")
    if same_pairs:
        sign = np.where(ids[out.p][order_g] == scene.p[order_w], 1.0, -1.0)[:, None]
        f = scene.force[order_w]
        force_err = float(np.max(np.linalg.norm(out.force[order_g] - sign * f, axis=1) / np.linalg.norm(f, axis=1)))
    if len(ids) == N:
        x_err = float(np.abs(out.x - scene.x[ids]).max() / np.abs(scene.x).max())
    law = all(np.allclose(getattr(out, k), v, rtol=1e-12) for k, v in (("k", KN), ("alpha", KT / KN), ("mu", MU)))
    return {"contacts": out.n_contacts, "particles": out.n_particles, "same_contacts": bool(same_pairs),
            "force_rel_err": force_err, "x_rel_err": x_err, "law": bool(law),
            "ok": bool(same_pairs and out.n_particles == N and force_err <= 4 * PRINTED and x_err <= 2 * PRINTED
                       and law)}


# ------------------------------------------------------------------------------------------------ run

CASES = {"lammps": {"write": write_lammps, "contacts": "contacts.dump", "loadtxt": {"skiprows": 9}},
           "table": {"write": write_tables, "contacts": "contacts.csv", "loadtxt": {"skiprows": 1, "delimiter": ","}}}
TIMED = ("convert", "numpy.loadtxt", "save NPZ")


def one_case(scene, radius, fmt: str, folder: Path, memory: bool) -> dict:
    """Write `scene` in format `fmt` into `folder`, then time converting it, loadtxt of its contact file and
    saving the result as NPZ; check the result against the packing."""
    spec = CASES[fmt]
    paths = spec["write"](scene, radius, folder)
    contacts = folder / spec["contacts"]
    row = {"dim": scene.dim, "format": fmt, "packing_contacts": scene.n_contacts,
           "particles": scene.n_particles, "mb": sum(p.stat().st_size for p in paths) / 1e6,
           "contact_rows": sum(1 for _ in open(contacts, "rb")) - spec["loadtxt"]["skiprows"]}
    seconds, runs, imported = median_time(lambda: granstab.io.load(paths), budget=3.0, most=5)
    row["convert"] = {"seconds": seconds, "runs": runs}
    seconds, runs, table = median_time(lambda: np.loadtxt(contacts, **spec["loadtxt"]), budget=3.0, most=5)
    row["numpy.loadtxt"] = {"seconds": seconds, "runs": runs}
    assert table.shape[0] == row["contact_rows"]
    del table
    npz = folder / "converted.npz"
    seconds, runs, _ = median_time(lambda scene=imported.scene: save_scene(scene, npz), budget=3.0, most=5)
    row["save NPZ"] = {"seconds": seconds, "runs": runs}
    row["npz_mb"] = npz.stat().st_size / 1e6
    row["check"] = agreement(scene, imported)
    row["dropped_non_touching"] = imported.report.get("non_touching_pairs", {}).get("count", 0)
    del imported
    if memory:
        row["peak_bytes_per_contact"] = peak_bytes(lambda: granstab.io.load(paths)) / row["contact_rows"]
    row["convert_over_loadtxt"] = row["convert"]["seconds"] / row["numpy.loadtxt"]["seconds"]
    for p in [*paths, npz]:
        p.unlink()
    return row


def run(quick: bool = False) -> dict:
    sizes = QUICK_SIZES if quick else FULL_SIZES
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for dim in (2, 3):
            for i, target in enumerate(sizes):
                scene, radius = packing(dim, target)
                for fmt in CASES:
                    rows.append(one_case(scene, radius, fmt, Path(tmp), memory=i >= len(sizes) - 2))
                    if not rows[-1]["check"]["ok"]:
                        raise AssertionError(f"converting: {dim}D {fmt} at {target} contacts does not reproduce "
                                             f"the packing: {rows[-1]['check']}")
                del scene, radius
    return {"quick": quick, "rows": rows}


def markdown(results: dict) -> str:
    rows = results["rows"]
    head = ["input", "contacts", "particles", "file rows", "MB", "convert", "numpy.loadtxt (contacts)",
            "convert / loadtxt", "save NPZ", "checked"]
    lines = ["## Converting DEM output", "",
             "`granstab.io.load` (what `granstab convert` runs: detect, parse, contacts from particles, geometry, "
             "law, cone, imbalance, scene checks, validation report) on random packings written as a LAMMPS "
             "per-atom dump + local dump + input script (the 11 columns of docs/formats.md, `%.12g`, one non-touching "
             "`pair/local` pair per ten contacts) and as the generic tables, against `numpy.loadtxt` of the same "
             "contact file without any check (the floor for parsing it), and saving the converted scene as NPZ. "
             "Medians of up to 5 runs (1 where a run takes seconds), seconds. *checked*: the converted scene has "
             "the packing's contacts and particles, its forces and centres to the printed precision and k, α, μ "
             "from the script (benchmarks/converting.py)."
             + (" Quick run: small sizes only." if results["quick"] else ""), "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        check = row["check"]
        cells = [f"{row['dim']}D {row['format']}", f"{check['contacts']:,}", f"{row['particles']:,}",
                 f"{row['contact_rows']:,}", f"{row['mb']:.1f}",
                 *(f"{row[k]['seconds']:.3g}" for k in ("convert", "numpy.loadtxt")),
                 f"{row['convert_over_loadtxt']:.1f}×", f"{row['save NPZ']['seconds']:.3g}",
                 "yes" if check["ok"] else "NO"]
        lines.append("| " + " | ".join(cells) + " |")
    mem = [row for row in rows if "peak_bytes_per_contact" in row]
    lines += ["", "Peak memory while converting (tracemalloc), bytes per contact-file row: "
              + "; ".join(f"{r['dim']}D {r['format']} {r['contact_rows']:,}: {r['peak_bytes_per_contact']:.0f}"
                          for r in mem)
              + " (constant per row as the size grows tenfold: memory O(contacts)).",
              "Largest force error over the contact's force, largest centre error over the packing's extent: "
              + f"{max(r['check']['force_rel_err'] for r in rows):.1e}, {max(r['check']['x_rel_err'] for r in rows):.1e}"
              + " (`%.12g` prints 12 significant digits: 5e-12 relative)."]
    return "\n".join(lines) + "\n"
