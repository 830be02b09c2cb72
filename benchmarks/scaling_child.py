"""One size of the scaling benchmark in a fresh process, so that its peak memory is its own:
`python -m granstab_bench.scaling_child DIM N METHOD` prints one JSON line (times, memory, factor size, residual)."""
from __future__ import annotations

import json
import resource
import sys
import time

from granstab.model import packings
from granstab.solve import sparse


def memory_kb(key: str) -> int:
    """VmRSS / VmHWM of this process in kB (VmHWM is its own peak; ru_maxrss would carry the parent's across
    exec); ru_maxrss where /proc is missing."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key):
                    return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def measure(dim: int, n: int, method: str) -> dict:
    """Build a random packing of n particles, its sparse problem and its 6 lowest modes; time and memory of each."""
    base = memory_kb("VmRSS")
    t0 = time.perf_counter()
    scene = packings.random_packing(dim, n, seed=3)
    t1 = time.perf_counter()
    spb = sparse.sparse_problem(scene)
    t2 = time.perf_counter()
    m = sparse.lowest_modes(spb, k=6, method=method)
    t3 = time.perf_counter()
    return {"dim": dim, "particles": scene.n_particles, "contacts": scene.n_contacts, "dof": scene.n_dof,
            "t_scene": t1 - t0, "t_problem": t2 - t1, "t_modes": t3 - t2, "method": m.method,
            "verified": bool(m.verified), "peak_mb": (memory_kb("VmHWM") - base) / 1024, "nnz_H": int(spb.H.nnz),
            "factor_nnz": m.info.get("lu_nnz"), "lambda_min": float(m.eigenvalues[0]),
            "residual": float(m.residuals.max()), "iterations": m.info.get("iterations")}


if __name__ == "__main__":
    print(json.dumps(measure(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3])))
