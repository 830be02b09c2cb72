"""One case of the periodic benchmark in a fresh process, so that its peak memory is its own:
`python -m granstab_bench.periodic_child analyze|moduli N SLIDING` prints one JSON line (times, peak memory, what
the result says and how accurate it is).

The packing (`periodic_packing`): N frictional disks on a jittered triangular lattice that closes on itself in a
periodic cell (the seam contacts carry their images), radii r(1 ± 0.2), forces f/(kr) ~ 1e-3 with tangential
forces up to half the cone and SLIDING contacts exactly at yield; a valid periodic contact network, not a relaxed
packing (the loads b = -Σf balance it, as in packings.random_packing)."""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

import granstab
from granstab.mechanics.branches import RIGID
from granstab.model.packings import _arrays
from granstab.model.scene import build_scene

from .scaling_child import memory_kb


def periodic_packing(n: int, n_sliding: int = 0, seed: int = 3, radius: float = 1.0):
    """About n disks on a triangular lattice of c columns and an even number of rows in the cell
    [[c, 0], [0, rows·√3/2]]·2r (see the module docstring)."""
    rows = max(4, 2 * int(round(np.sqrt(2 * n / np.sqrt(3)) / 2)))     # even: the rows' offsets close on themselves
    cols = max(3, int(round(n / rows)))                              # a nearly square cell
    i, j = np.meshgrid(np.arange(cols), np.arange(rows), indexing="ij")
    sites = np.stack([i.ravel() + 0.5 * (j.ravel() % 2), j.ravel() * np.sqrt(3) / 2], axis=1)
    box = np.array([cols, rows * np.sqrt(3) / 2])
    pairs = cKDTree(sites, boxsize=box).query_pairs(1.0 + 1e-6, output_type="ndarray")
    p, q = pairs[:, 0], pairs[:, 1]
    raw = sites[q] - sites[p]
    image = -np.round(raw / box).astype(np.int64)                 # q's copy at x_q + image·cell: a unit bond
    rng = np.random.default_rng(seed)
    cell = np.diag(box) * 2 * radius
    x = (sites + 0.1 * rng.uniform(-0.5, 0.5, sites.shape)) * 2 * radius
    R = radius * (1 + 0.2 * rng.uniform(-1, 1, len(x)))
    copies = np.concatenate([x, x[q] + image @ cell])             # _arrays takes branches as x[q'] - x[p]
    frac = R[p] / (R[p] + R[q])
    f_n = 1e-3 * radius * rng.uniform(0.5, 1.5, len(p))
    arrays = _arrays(2, copies, p, len(x) + np.arange(len(p)), frac, 1.0, f_n, rng, 0.5, 1.0, 1.0, 0.5, n_sliding,
                     0.0, 0.0)
    arrays["q"] = q.astype(np.intp)
    names = [f"p{k}" for k in range(len(x))]
    title = f"periodic triangular packing, {len(x)} disks, {len(p)} contacts"
    return build_scene(2, names, x, arrays, title=title, source=title, cell=cell, image=image)


def measure(kind: str, n: int, n_sliding: int) -> dict:
    """Build the packing, then `granstab.analyze` (the whole packing: the sparse path above the dense limit) or
    `granstab.moduli`; time and peak resident memory above the interpreter's baseline of each step."""
    base = memory_kb("VmRSS")
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    scene = periodic_packing(n, n_sliding)
    t1, c1 = time.perf_counter(), time.process_time()
    out = {"kind": kind, "particles": scene.n_particles, "contacts": scene.n_contacts, "dof": scene.n_dof,
           "sliding": n_sliding, "seam": int(np.sum(np.any(scene.image != 0, axis=1))), "t_scene": t1 - t0}
    if kind == "analyze":
        r = granstab.analyze(scene, k=6, metric="L")
        lowest = r.branches[0]
        out.update(backend=r.backend, branches=len(r.branches), verdict=r.summary["verdict"],
                   rigid=int(np.sum(lowest.codes == RIGID)), lambda_min=float(min(b.stability_eigenvalues[b.codes != RIGID].min() for b in r.branches)),
                   exact_counts=all(b.negative_count["total"] for b in r.branches),
                   error=float(max(r.errors.values())))
    else:
        m = granstab.moduli(scene)
        out.update(branches=len(m.branches), bulk=m.bulk, shear=m.shear, residual=m.errors["residual"],
                   symmetry_defect=m.errors["symmetry_defect"])
    out.update(t_run=time.perf_counter() - t1, cpu_run=time.process_time() - c1,
               peak_mb=(memory_kb("VmHWM") - base) / 1024, load=[load, os.getloadavg()[0]])
    return out


if __name__ == "__main__":
    print(json.dumps(measure(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))))
