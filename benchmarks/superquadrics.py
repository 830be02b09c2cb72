"""Reading LIGGGHTS superquadric dumps (issue 37, "Speed": reading and curvature for 10⁵ superquadric contacts in ≤ 5 s).

Input: pairs of blocky, elongated superquadrics (semi-axes 3 × 2 × 1.5, n1 = n2 = 4, random orientations) in the
exact common-normal configuration: P on p's surface with outward normal ν, Q = P − 2ε ν on q's surface with normal
−ν (the support point of q's dual-norm support function), ε = 1e-3 of the size, the contact point their midpoint,
force −k δ ν + 0.3 k δ t. Written as docs/formats.md says (`atoms.dump`: id type x y z quat1-4 shapex-z
blockiness1-2 radius mass; `contacts.dump`: compute pair/gran/local id force force_normal force_tangential
contactPoint, `%.12g`). Timed: `granstab.io.load` of the two dumps (parse, foot points and curvatures by the
vectorised Newton of model/surface.py, build, checks, report) and, apart, `surface.contact_curvature` alone.
*checked*: every contact kept, each foot-point depth equal to ε within 1e-9 of the size (the printed precision).
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

import granstab.io
from granstab.model import surface

from .converting import median_time, write_rows

QUICK_SIZES = (10_000,)
FULL_SIZES = (10_000, 100_000)
AXES = np.array([3.0, 2.0, 1.5])
N_BLOCK = 4.0
EPSILON = 1e-3 * 3.0


def _quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def _support_point(m):
    """The surface point with outward body normal m (M, 3) of the superquadric AXES, n1 = n2 = N_BLOCK."""
    w = AXES * np.abs(m)
    e = 1.0 / (N_BLOCK - 1.0)
    y = np.sign(m) * AXES * w**e
    return y / (np.sum(w ** (N_BLOCK * e), axis=1) ** (1.0 / N_BLOCK))[:, None]


def write_pairs(folder: Path, contacts: int, seed: int = 1) -> tuple[Path, Path]:
    """atoms.dump and contacts.dump of `contacts` separate pressed pairs (module docstring)."""
    from granstab.model.vec import quaternion_matrix
    rng = np.random.default_rng(seed)
    M = contacts
    qp, qq = _quaternions(rng, M), _quaternions(rng, M)
    Rp, Rq = quaternion_matrix(qp), quaternion_matrix(qq)
    m = rng.normal(size=(M, 3))
    m /= np.linalg.norm(m, axis=1)[:, None]
    sp = _support_point(m)
    _, g = surface.implicit(sp, AXES, np.array([N_BLOCK, N_BLOCK]), order=1)
    nu = np.einsum("mij,mj->mi", Rp, g / np.linalg.norm(g, axis=1)[:, None])
    xp = np.stack([np.arange(M) * 20.0, np.zeros(M), np.zeros(M)], axis=1)
    P = xp + np.einsum("mij,mj->mi", Rp, sp)
    sq = _support_point(np.einsum("mji,mj->mi", Rq, -nu))
    xq = P - 2 * EPSILON * nu - np.einsum("mij,mj->mi", Rq, sq)
    point = P - EPSILON * nu
    t = np.cross(nu, [0.3, 0.5, 0.8])
    t /= np.linalg.norm(t, axis=1)[:, None]
    force = -2 * EPSILON * nu + 0.6 * EPSILON * t
    ids = np.arange(1, 2 * M + 1)
    x = np.concatenate([xp, xq])
    quat = np.concatenate([qp, qq])
    n = 2 * M
    atoms, local = folder / "atoms.dump", folder / "contacts.dump"
    box = "ITEM: BOX BOUNDS ff ff ff\n-10 %.12g\n-10 10\n-10 10\n" % (20.0 * M)
    write_rows(atoms, f"ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n{n}\n{box}ITEM: ATOMS id type x y z quat1 quat2 "
               "quat3 quat4 shapex shapey shapez blockiness1 blockiness2 radius mass\n",
               [ids, np.ones(n), *x.T, *quat.T, *np.tile(AXES, (n, 1)).T, np.full(n, N_BLOCK), np.full(n, N_BLOCK),
                np.full(n, 3.3), np.full(n, 1.0)], ["%d", "%d"] + ["%.12g"] * 14)
    zero = np.zeros(M)
    write_rows(local, f"ITEM: TIMESTEP\n0\nITEM: NUMBER OF ENTRIES\n{M}\n{box}ITEM: ENTRIES " + " ".join(
        f"c_pg[{k}]" for k in range(1, 16)) + "\n",
        [ids[:M], ids[M:], zero, *force.T, *force.T, zero, zero, zero, *point.T], ["%d", "%d", "%d"] + ["%.12g"] * 12)
    return atoms, local


def run(quick: bool = False) -> dict:
    return {"rows": [measure(size) for size in (QUICK_SIZES if quick else FULL_SIZES)]}


def measure(size: int) -> dict:
    """One size: load and curvature medians, and the checks (module docstring)."""
    with tempfile.TemporaryDirectory() as tmp:
        atoms, local = write_pairs(Path(tmp), size)
        seconds, runs, loaded = median_time(lambda: granstab.io.load([atoms, local]), budget=10.0, most=3)
        cpu = time.process_time()
        granstab.io.load([atoms, local])
        cpu = time.process_time() - cpu
    scene = loaded.scene
    rot = _rotations(loaded, scene.p)
    curv_s, _, _ = median_time(lambda: surface.contact_curvature(
        scene.point, scene.x[scene.p], rot, np.tile(AXES, (size, 1)), np.full((size, 2), N_BLOCK), scene.normal),
        budget=10.0, most=3)
    depth = loaded.report["geometry"]["depth_over_size"]
    printed = 1e-11 * np.abs(scene.x).max() / AXES.max()       # %.12g positions far from the origin
    return {"contacts": size, "kept": scene.n_contacts, "load_s": seconds, "load_cpu_s": cpu, "runs": runs,
            "curvature_s": curv_s,
            "depth_max_over_size": depth["max"],
            "checked": bool(scene.n_contacts == size and abs(depth["max"] - EPSILON / AXES.max()) <= printed)}


def _rotations(loaded, index):
    from granstab.model.vec import quaternion_matrix
    return quaternion_matrix(loaded.orientation[index])


def markdown(results: dict) -> str:
    lines = ["## Reading superquadric contacts (issue 37)", "",
             "`granstab.io.load` of a LIGGGHTS superquadric dump pair (docs/formats.md) — parse, foot points and "
             "parallel-surface curvatures of both grains at every contact by the vectorised Newton of "
             "model/surface.py, build, checks, report — and `surface.contact_curvature` alone, on separate pressed "
             "pairs of blocky elongated grains (3 × 2 × 1.5, n = 4, random orientations; benchmarks/superquadrics.py). "
             "Medians of up to 3 runs, wall seconds, and the CPU seconds of one load (process time: what a load "
             "costs whatever the machine's load). Goal: 10⁵ contacts in ≤ 5 s. *checked*: every contact kept, the "
             "foot-point depth equal to the written one. Where a 10⁵ load's time goes (cProfile, 2026-11-29, load ~9): "
             "reading the two dumps (numpy.loadtxt) ~15 %, foot points and curvatures ~55 % (four Newton iterations "
             "over the 2 × 10⁵ grain-contact points, then one shape operator each), building the scene and its "
             "checks ~20 %. Wall time under load is stretched by the load: the CPU column is what the work costs.",
             "",
             "| contacts | load (read + curvature + build) | load, CPU | curvature alone | checked |",
             "|---|---|---|---|---|"]
    for r in results["rows"]:
        lines.append(f"| {r['contacts']:,} | {r['load_s']:.3g} | {r['load_cpu_s']:.3g} | {r['curvature_s']:.3g} | "
                     f"{'yes' if r['checked'] else 'NO'} |")
    return "\n".join(lines) + "\n"
