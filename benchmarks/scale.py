"""The held-out check `scale` (issue 41): a 2·10⁵-disk periodic packing written here, as a user's writer would write
it (the JSON contact-level scene of docs/formats.md, not through granstab), `granstab analyze FILE --json --metric L
--timeout T` run on it in a fresh process (T = RUN_TIMEOUT, so that the answer is checked however long a loaded
machine takes; the 120 s goal is checked on the wall time), and its answer checked against a solve made here:

- the exact rigid zero count: a periodic scene's only rigid motions are the d translations, so every branch reports
  n_zero = d, its first d eigenvalues exact zeros, and the count of eigenvalues below σ proven (total) and 0;
- the lowest eigenvalue against this module's own shift-invert solve (scipy's SuperLU of Hs - σI in its own
  minimum-degree order and ARPACK, none of granstab's solvers: multifrontal.py, krylov.py, ritz.py), to REL_TOL;
- the reported bounds: every reported eigenvalue within its `accuracy` of the reference's;
- the wall time within SECONDS (reading, checks and the analysis: the whole command), and its peak memory.

The matrix both solve is granstab's assembled sym(H) in the metric L (`solve.assembled.sparse_problem`): what is
checked here is the solver at scale, not the assembly (tested against the paper's closed forms and finite
differences elsewhere). The packing (`packing`): a jittered triangular lattice of polydisperse disks closing on
itself in the cell, every contact compressive with a tangential force at most TANGENTIAL of the cone (no contact at
yield: one branch), the loads left to balance them (docs/formats.md). Run `python -m granstab_bench.scale N` for one
size alone."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

from .formatting import table

PARTICLES = 200_000      # the check's size (issue 41)
QUICK_PARTICLES = 3_000  # above the dense limit still: the sparse path
SECONDS = 120.0          # the check's time limit for the whole command
REL_TOL = 1e-8           # λ_min against the reference solve, relative
TANGENTIAL = 0.5         # |f_t| ≤ this · μ |f_n|: inside the cone
K_LOWEST = 6


def packing(n: int, seed: int = 41) -> dict:
    """About n disks on a jittered triangular lattice in a periodic cell (rows even so that it closes on itself),
    radii 0.5(1 ± 0.15) of the spacing 1, every lattice bond a contact: its point on the branch at the share of the
    radii, its normal along the branch, curvatures -1/distance to the point, forces compressive (f·n < 0) with a
    tangential part inside the cone. Plain arrays: `write_json` writes them as the scene format."""
    rows = max(4, 2 * int(round(np.sqrt(2 * n / np.sqrt(3)) / 2)))
    cols = max(3, int(round(n / rows)))
    i, j = np.meshgrid(np.arange(cols), np.arange(rows), indexing="ij")
    sites = np.stack([i.ravel() + 0.5 * (j.ravel() % 2), j.ravel() * np.sqrt(3) / 2], axis=1)
    box = np.array([cols, rows * np.sqrt(3) / 2])
    pairs = cKDTree(sites, boxsize=box).query_pairs(1.0 + 1e-6, output_type="ndarray")
    p, q = pairs[:, 0], pairs[:, 1]
    image = -np.round((sites[q] - sites[p]) / box).astype(np.int64)
    rng = np.random.default_rng(seed)
    x = sites + 0.08 * rng.uniform(-0.5, 0.5, sites.shape)
    radius = 0.5 * (1 + 0.15 * rng.uniform(-1, 1, len(x)))
    branch = x[q] + image * box - x[p]
    length = np.linalg.norm(branch, axis=1)
    normal = branch / length[:, None]
    share = radius[p] / (radius[p] + radius[q])
    point = x[p] + branch * share[:, None]
    f_n = 1e-3 * rng.uniform(0.5, 1.5, len(p))
    tangent = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
    f_t = TANGENTIAL * 0.5 * f_n * rng.uniform(-1, 1, len(p))        # μ = 0.5
    force = -f_n[:, None] * normal + f_t[:, None] * tangent
    return {"x": x, "cell": np.diag(box), "p": p, "q": q, "image": image, "point": point, "normal": normal,
            "curvature_p": -1 / (length * share), "curvature_q": -1 / (length * (1 - share)), "force": force}


def write_json(path: Path, pk: dict) -> None:
    """The packing as a contact-level JSON scene (docs/formats.md), k = α = 1, μ = 0.5."""
    def rows(a):
        return np.asarray(a).tolist()
    names = [f"d{i}" for i in range(len(pk["x"]))]
    contacts = [{"p": names[a], "q": names[b], "image": im, "point": pt, "normal": nm, "curvature_p": cp,
                 "curvature_q": cq, "force": f}
                for a, b, im, pt, nm, cp, cq, f in zip(pk["p"].tolist(), pk["q"].tolist(), rows(pk["image"]),
                                                       rows(pk["point"]), rows(pk["normal"]), rows(pk["curvature_p"]),
                                                       rows(pk["curvature_q"]), rows(pk["force"]))]
    scene = {"dim": 2, "title": f"scale check, {len(names)} disks", "cell": rows(pk["cell"]),
             "defaults": {"k": 1.0, "alpha": 1.0, "mu": 0.5},
             "particles": [{"name": nm, "x": xy} for nm, xy in zip(names, rows(pk["x"]))], "contacts": contacts}
    path.write_text(json.dumps(scene), encoding="utf-8")


def reference(path: Path, k: int = K_LOWEST) -> dict:
    """The k + d eigenvalues of sym(H) nearest σ = -1e-6 ‖H‖₁ by scipy alone: SuperLU of Hs - σI (minimum degree on
    Aᵀ + A) and shift-invert ARPACK; the d translations are the d eigenvalues nearest 0."""
    import granstab
    from granstab.solve.assembled import sparse_problem
    t = time.perf_counter()
    Hs = sparse_problem(granstab.load_scene(path)).Hs.tocsc()
    Hs = 0.5 * (Hs + Hs.T)
    sigma = -1e-6 * float(abs(Hs).sum(axis=0).max())
    lu = spla.splu((Hs - sigma * sp.identity(Hs.shape[0], format="csc")).tocsc(), permc_spec="MMD_AT_PLUS_A")
    op = spla.LinearOperator(Hs.shape, matvec=lu.solve, dtype=float)
    lam = spla.eigsh(Hs, k=k + 2, sigma=sigma, OPinv=op, which="LM", tol=0, return_eigenvectors=False)
    return {"eigenvalues": np.sort(lam).tolist(), "seconds": time.perf_counter() - t, "lu_nnz": int(lu.nnz)}


RUN_TIMEOUT = 20 * SECONDS   # the command's --timeout here: a shared machine's load stretches the wall time, and the
                             # answer is checked whatever it took (`time_ok` says whether it took more than SECONDS)


def run_cli(path: Path, timeout: float = RUN_TIMEOUT) -> dict:
    """`granstab analyze FILE --json --metric L --timeout T` in a fresh process: its JSON, wall time, CPU time and
    peak resident memory (wait4), and the 1-minute load average before and after."""
    load = os.getloadavg()[0]
    cmd = [sys.executable, "-m", "granstab", "analyze", str(path), "--json", "--metric", "L", "--timeout",
           f"{timeout:g}"]
    t = time.perf_counter()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(cmd, stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read().decode(), err.read().decode()
    rc = os.waitstatus_to_exitcode(status)
    return {"rc": rc, "wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "peak_mb": usage.ru_maxrss / 1024,
            "load": [load, os.getloadavg()[0]], "result": json.loads(stdout) if rc == 0 else None,
            "stderr": stderr.strip().splitlines()[-1:] if rc else []}


def verdicts(answer: dict, ref: dict, dim: int = 2) -> dict:
    """The check's items (module docstring), each True or False, with the numbers they compare."""
    if answer["result"] is None:
        return {"ran": False, "ok": False, "why": answer["stderr"][0] if answer["stderr"] else "no output"}
    result = answer["result"]
    branches = result["branches"]
    lam = np.array(branches[0]["stability_eigenvalues"])
    bound = np.array(branches[0]["accuracy"])
    expect = np.array(ref["eigenvalues"])
    zeros = all(b["n_zero"] == dim and not np.any(b["stability_eigenvalues"][:dim]) for b in branches)
    counted = all(b["negative_count"]["total"] and b["negative_count"]["count"] == 0 for b in branches)
    low = lam[dim]
    rel = abs(low - expect[dim]) / abs(expect[dim])
    within = np.abs(lam[:len(expect)] - expect[:len(lam)]) <= bound[:len(expect)]
    out = {"ran": True, "rigid_zeros": zeros, "counts": counted, "lambda_min": float(low),
           "reference": float(expect[dim]), "rel_error": float(rel), "rel_ok": bool(rel <= REL_TOL),
           "bounds_ok": bool(within.all()), "worst_over_bound": float(np.max(np.abs(lam[:len(expect)] -
                                                                                    expect[:len(lam)]) /
                                                                             np.maximum(bound[:len(expect)], 1e-300))),
           "time_ok": answer["wall"] <= SECONDS}
    out["ok"] = all(out[key] for key in ("rigid_zeros", "counts", "rel_ok", "bounds_ok", "time_ok"))
    return out


def check(n: int, folder: Path | None = None) -> dict:
    """Write the packing (JSON), run the command, solve the reference, compare (module docstring)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(folder or tmp) / f"scale_{n}.json"
        t = time.perf_counter()
        pk = packing(n)
        write_json(path, pk)
        written = time.perf_counter() - t
        answer = run_cli(path)
        ref = reference(path)
        size = path.stat().st_size
    return {"particles": len(pk["x"]), "contacts": len(pk["p"]), "file_mb": size / 2 ** 20, "t_write": written,
            **{key: answer[key] for key in ("rc", "wall", "cpu", "peak_mb", "load")},
            "timings": (answer["result"] or {}).get("timings"), "t_reference": ref["seconds"],
            "reference_lu_nnz": ref["lu_nnz"], "check": verdicts(answer, ref)}


def run(quick: bool = False) -> dict:
    return {"cases": [check(QUICK_PARTICLES if quick else PARTICLES)], "seconds": SECONDS, "rel_tol": REL_TOL}


def markdown(results: dict) -> str:
    rows = []
    for d in results["cases"]:
        c = d["check"]
        if not c["ran"]:
            rows.append([f"{d['particles']:,}", f"{d['contacts']:,}", f"{d['file_mb']:.0f}", "—", "—", "—",
                         "{:.1f} → {:.1f}".format(*d["load"]), "failed: " + c["why"], "", "", "**no**"])
            continue
        t = d["timings"] or {}
        rows.append([f"{d['particles']:,}", f"{d['contacts']:,}", f"{d['file_mb']:.0f}", f"{d['wall']:.1f} s",
                     f"{d['cpu']:.1f} s", f"{d['peak_mb']:.0f} MB", "{:.1f} → {:.1f}".format(*d["load"]),
                     f"{c['lambda_min']:.10g} / {c['reference']:.10g}: {c['rel_error']:.1e}",
                     f"{'yes' if c['bounds_ok'] else 'no'} (worst {c['worst_over_bound']:.2g} of its bound)",
                     f"rigid zeros {'exact' if c['rigid_zeros'] else 'WRONG'}, count below σ "
                     f"{'proven 0' if c['counts'] else 'not proven'}; analysis {t.get('total', 0):.1f} s",
                     "**yes**" if c["ok"] else "**no**" + ("" if c["time_ok"] else " (time)")])
    return "\n".join([
        "## The held-out check `scale` (issue 41)",
        "",
        " ".join(__doc__.split("\n\n")[0].split()),
        "",
        "\n".join("- " + " ".join(item.split()) for item in ("\n" + __doc__.split("\n\n")[1]).split("\n- ")[1:]),
        "",
        f"Goal: the whole command within {results['seconds']:g} s, λ_min within {results['rel_tol']:g} relative of "
        "the reference, every reported eigenvalue within its bound. *wall*, *CPU*, *peak*: the command's process "
        "(wait4); *load*: the 1-minute load average before and after it, on 2 cores shared with other work (wall "
        "times above a load of 2 are stretched by it; the CPU time is what the work costs).",
        "",
        table(["particles", "contacts", "JSON MB", "wall", "CPU", "peak", "load", "λ_min / reference: rel. error",
               "bounds hold", "counts", "passes"], rows),
    ])


if __name__ == "__main__":
    print(json.dumps(check(int(sys.argv[1]) if len(sys.argv) > 1 else PARTICLES), default=float))
