"""Rigidity (issue 28): the pebble game and the physical rank on random 2D packings up to 10⁴ particles and on
RigidLibrary's annulus frame, against the obvious alternative for the physical rank (one dense SVD of the whole
compatibility matrix, where it fits)."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import scipy.linalg as la

from granstab.io import load
from granstab.mechanics.compatibility import compatibility_matrix
from granstab.model import packings
from granstab.model.scene import mean_contact_radius
from granstab.rigidity import partition, rigidity
from granstab.rigidity.bodybar import from_scene

QUICK = {"sizes": (1000,), "dense_max": 1000, "annulus": False}
FULL = {"sizes": (1000, 3000, 10_000), "dense_max": 1000, "annulus": True}
ANNULUS = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "rigidlibrary" / "DataAnnulus" / "10"


def packing(n: int):
    """A random 2D packing with a third of its contacts at yield (floppy regions and several clusters)."""
    return packings.random_packing(2, n, n_sliding=n, mobilised=1.0, seed=3)


def measure(scene, walls="free", flags=None, dense_max=0) -> dict:
    t = time.perf_counter()
    r = rigidity(scene, "both", walls, flags)
    total = time.perf_counter() - t
    ph, ge = r["physical"], r["generic"]
    row = {"particles": scene.n_particles, "contacts": scene.n_contacts, "sliding": ph["counts"]["sliding"],
           "generic_s": ge["seconds"], "physical_s": ph["seconds"], "prestress_s": ph["prestress"]["seconds"],
           "both_s": total, "floppy_physical": ph["floppy_modes"]["count"], "floppy_generic": ge["floppy_modes"]["count"],
           "same_partition": partition(ph) == partition(ge), "largest": ph["counts"]["largest_cluster_particles"],
           "gap": ph["rank_tolerance"]["gap"]}
    t = time.perf_counter()
    alone = rigidity(scene, "physical", walls, flags, second_order=False)["physical"]
    row["physical_alone_s"] = time.perf_counter() - t
    assert partition(alone) == partition(ph)
    if scene.n_particles <= dense_max:
        frame = from_scene(scene, walls, flags)
        C, _ = compatibility_matrix(frame.p, frame.q, frame.r_pq, frame.r_qp, frame.normal, frame.sliding,
                                    frame.rolling, frame.n_bodies, mean_contact_radius(scene))
        t = time.perf_counter()
        s = la.svd(C.toarray(), compute_uv=False)
        row["dense_svd_s"] = time.perf_counter() - t
        row["dense_nullity"] = int(C.shape[1] - np.sum(s > max(C.shape) * np.finfo(float).eps * s[0]))
        row["nullity"] = ph["floppy_modes"]["total_with_trivial"]
    return row


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    rows = [{"name": "random 2D", **measure(packing(n), dense_max=cfg["dense_max"])} for n in cfg["sizes"]]
    if cfg["annulus"]:
        loaded = load(ANNULUS, frame=1, mu=0.3, keep_rattlers=True)
        rows.append({"name": "annulus 10 frame 1, walls bodies", **measure(loaded.scene, "bodies", loaded.wall_flags)})
    return {"rows": rows}


def markdown(results: dict) -> str:
    lines = ["## Rigidity: pebble game and physical rank (issue 28)", "",
             "`granstab.rigidity.rigidity(scene, \"both\")`: the (3,3) pebble game with rigid sets contracted as "
             "found (*generic*) and the physical model (rank and null space of the compatibility matrix per "
             "connected component: dense SVD up to 600 columns, else inverse iteration on CᵀC + δI with one sparse "
             "LU, two projection steps and the SVD of C on that subspace; then each contact's strain; its time "
             "includes the game's floppy count it starts from) with the prestress's second-order check on the "
             "floppy modes (*prestress*). *gap*: σ_rank/σ_rank+1 of the physical rank. Random 2D packings "
             "(`packings.random_packing`, a third of the contacts at yield) and RigidLibrary's annulus frame with "
             "its walls as bodies. *dense SVD*: the obvious alternative, one SVD of the whole matrix (singular "
             "values only), with its nullity beside ours. Goal: 10⁴ particles in 10 s.", "",
             "| input | particles | contacts (sliding) | generic | physical | prestress | both, total | floppy "
             "(physical / generic) | same partition | largest cluster | gap | dense SVD (nullity vs ours) | physical alone, "
             "no prestress (the default command's work) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        dense = (f"{r['dense_svd_s']:.2f} s ({r['dense_nullity']} vs {r['nullity']})" if "dense_svd_s" in r
                 else "—")
        gap = "full rank" if r["gap"] is None else f"{r['gap']:.3g}"
        lines.append(f"| {r['name']} | {r['particles']:,} | {r['contacts']:,} ({r['sliding']:,}) | "
                     f"{r['generic_s']:.2f} s | {r['physical_s']:.2f} s | {r['prestress_s']:.2f} s | "
                     f"**{r['both_s']:.2f} s** | {r['floppy_physical']} / {r['floppy_generic']} | "
                     f"{'yes' if r['same_partition'] else 'no'} | {r['largest']} | {gap} | {dense} | "
                     f"**{r['physical_alone_s']:.2f} s** |")
    return "\n".join(lines) + "\n"
