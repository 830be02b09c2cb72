"""One frame of a sequence, the unit of work of `track` (serial or a Dask task): read it, and compute its row of
frames.parquet and its rows of particles.parquet, without what needs the next frame (run.py adds D²min and the
contact changes).

The frame is read with every particle (rattlers kept: they can rearrange too); the analyses (`--whole`, `--scan`,
`--rigidity`) run on the particles that have a contact, which is the scene `granstab.load` gives of that frame
with the same import options (rattlers dropped, the default): each equals `analyze`/`scan`/`rigidity` of the frame
taken alone.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..analysis import analyze
from ..mechanics.branches import RIGID
from ..model.grains import cut, from_loaded
from ..model.scene import Scene, SceneError
from ..scan.clusters import particle_shares
from ..solve.threads import blas_threads
from ..uncertainty import balance_scene
from . import softspots
from .motion import contact_keys
from .quantities import macroscopic, per_particle

PREDICTORS = ("unstable_fraction", "unstable_fraction_nonboundary", "cluster_lambda_min", "soft_participation",
              "in_largest_rigid_cluster", "soft_spots_branch", "soft_spots_frictionless")          # NaN where the stage that computes them was not asked for
WHOLE = {"metric": "L", "max_sliding": 0, "sample_branches": 0, "keep": "all", "attribution": False,
         "uniqueness": False, "estimate": False}
# the whole packing: its all-loading and all-unloading branches only (sample_masks), in the scan's metric L, their
# stability only: no metric family or robustness, no attribution, no ℍ^i (uniqueness, Type-2), none of which the
# row uses (on 300 spheres ℍ^i's eig and SVDs were most of a frame's time), no time estimate (the frame's is measured)


def core_scene(scene: Scene, wall_flags):
    """The scene without its particles that have no contact (`Scene.without_rattlers`, what `load` keeps by
    default), its wall flags and the kept particles' indices."""
    core, keep = scene.without_rattlers()
    return core, None if wall_flags is None or core is scene else np.asarray(wall_flags)[keep], keep


def whole(core: Scene, soft_modes: int) -> tuple[dict, dict]:
    """The whole-packing analysis (WHOLE): λ_min (non-rigid) and the consistent negative count of the all-unloading
    and all-loading branches, and per particle the soft-spot participations (softspots.participation):
    `soft_participation` in the `soft_modes` lowest consistent modes (both branches pooled; where none is
    consistent, the lowest non-rigid modes of the all-unloading branch, said in `soft_modes_from`),
    `soft_spots_branch` in the lowest 1 % of the all-unloading branch's non-rigid modes, `soft_spots_frictionless`
    in the lowest 1 % of the frictionless dynamical matrix's (softspots.frictionless)."""
    n_branch = softspots.lowest_count(core.n_dof)
    res = analyze(core, k=max(6, soft_modes, n_branch), **WHOLE)
    sliding = np.flatnonzero(core.at_yield()) if core.n_contacts else np.zeros(0, int)
    row, modes, elastic = {}, [], []
    for name, sign in (("unloading", -1), ("loading", 1)):
        branch = next((b for b in res.branches if np.all(b.mask[sliding] == sign)), None)
        if branch is None:
            row[f"lambda_min_{name}"], row[f"n_negative_{name}"] = float("nan"), -1
            continue
        lam, V = branch.stability_eigenvalues, np.asarray(branch.stability_vectors)   # once (lowrank.LazyVectors)
        nonrigid = np.flatnonzero(branch.codes != RIGID)
        row[f"lambda_min_{name}"] = float(lam[nonrigid].min()) if nonrigid.size else float("nan")
        consistent = branch.consistent()
        row[f"n_negative_{name}"] = int(sum(c["eigenvalue"] < -branch.accuracy[c["index"]] for c in consistent))
        modes += [(c["eigenvalue"], V[:, c["index"]]) for c in consistent]
        if sign == -1:
            elastic = sorted(((lam[j], V[:, j]) for j in nonrigid), key=lambda m: m[0])
    row.update(whole_row(res))
    row["soft_modes_from"] = "consistent modes, both branches" if modes else \
        "no consistent mode: the lowest non-rigid modes of the all-unloading branch"
    lowest = sorted(modes or elastic, key=lambda m: m[0])[:soft_modes]
    row["soft_modes"] = len(lowest)
    row["soft_spots_branch_count"] = min(n_branch, len(elastic))
    frictionless_row, frictionless_share = softspots.frictionless(core)
    row.update(frictionless_row)
    return row, {"soft_participation": translation_shares(res, core, lowest),
                 "soft_spots_branch": translation_shares(res, core, elastic[:n_branch]),
                 "soft_spots_frictionless": frictionless_share}


def translation_shares(res, core: Scene, modes: list) -> np.ndarray:
    """softspots.participation of the (eigenvalue, vector) `modes` of an analysis (NaN without modes)."""
    if not modes:
        return np.full(core.n_particles, np.nan)
    motions = np.stack([res.motion(v).reshape(core.n_particles, core.dof_per_particle)[:, :core.dim]
                        for _, v in modes])
    return softspots.participation(motions)


def whole_row(res) -> dict:
    """The whole packing's verdict as a frame row: the word, its reason (`not determined because …` where it is not
    a proof, with the named gaps), whether it is proven, whether it hinges on an S within the tolerance."""
    v = res.verdict
    reason = v.reason if v.sufficient else \
        f"not determined because {', '.join(v.insufficient_because)}: {v.reason}"
    return {"whole_verdict": v.verdict, "whole_method": res.backend, "whole_reason": reason,
            "whole_proven": int(v.sufficient), "whole_hinges_on_tolerance": int(v.hinges_on_tolerance)}


def scan_map(core: Scene, folder: Path, scan_options: dict, shapes=None) -> tuple[dict, dict]:
    """The local scan of the frame (granstab.scan.scan, serial, into `folder`: it resumes there; with the grains'
    `shapes` where they have them) → the frame's scan summary and per particle: the unstable fraction of the
    clusters containing it, the same counting only unstable clusters whose mechanism is not `boundary`
    (docs/attribution.md), the lowest λ_min of those clusters."""
    from ..scan import read_map, scan
    scan(core, folder, workers=1, figures=False, progress=False, shapes=shapes, **scan_options)
    got = read_map(folder)
    c = got["clusters"]
    sizes = np.array([len(m) for m in c["members"]], dtype=np.int64)
    flat = np.concatenate(list(c["members"])).astype(np.int64) if len(sizes) else np.zeros(0, np.int64)
    unstable = c["verdict"] == "unstable"
    own = unstable & (c["mechanism"] != "boundary")
    N = core.n_particles
    nonboundary = particle_shares(flat, sizes, N, own)[1]
    lam = np.full(N, np.inf)
    np.fmin.at(lam, flat, np.repeat(np.asarray(c["lambda_min"], float), sizes))   # a cluster without λ_min: skipped
    per = {"unstable_fraction": np.asarray(got["particles"]["unstable_fraction"], float),
           "unstable_fraction_nonboundary": nonboundary, "cluster_lambda_min": np.where(np.isinf(lam), np.nan, lam)}
    verdicts = got["summary"]["verdicts"]
    row = {"scan_clusters": int(len(sizes)), "scan_unstable": int(unstable.sum()),
           "scan_unstable_nonboundary": int(own.sum()), "scan_verdicts": json.dumps(verdicts)}
    return row, per


def rigid(core: Scene, wall_flags) -> tuple[dict, np.ndarray]:
    """The largest rigid cluster (granstab.rigidity, physical model, walls free) and per particle whether it is in
    it (1.0 / 0.0)."""
    from ..rigidity import largest_rigid_cluster, rigidity
    result = rigidity(core, "physical", "free", wall_flags, second_order=False)    # no prestress: not a column
    largest = largest_rigid_cluster(result)
    clusters = result["physical"]["clusters"]
    inside = np.isin(np.asarray(core.names, dtype=object), clusters[0]["particles"] if clusters else [])
    return {"rigid_largest_particles": largest["size_particles"], "rigid_largest_fraction": largest["fraction"]}, \
        inside.astype(float)


def frame_task(spec: dict, position: int, key) -> dict:
    """Frame `position` (key `key`, the reader's frame) of the input in `spec` (run.py; spec["source"]: the input
    opened once, granstab.io.open) → its parts in
    spec["out"]/parts: the particle rows, the contacts (for the changes between frames) and, last, the frame row
    (JSON: its presence marks the frame done). Returns the frame row."""
    times = {}
    start = time.perf_counter()
    loaded = spec["source"].read(key)                # granstab.io.Source: this frame's rows only
    scene, balanced = balance_scene(loaded.scene, spec["scan_options"].get("uncertainty"),
                                    spec.get("balance", "loads"),
                                    None if loaded.wall_flags is None else np.asarray(loaded.wall_flags) != 0)
    times["read"] = time.perf_counter() - start
    core, walls, index = core_scene(scene, loaded.wall_flags)
    row = {"frame": position, "step": float("nan") if key is None else float(key), **macroscopic(scene),
           "n_rattlers": scene.n_particles - core.n_particles, "dim": scene.dim,
           "cell": [] if scene.cell is None else scene.cell.ravel().tolist(),
           "import_warnings": list(loaded.warnings), "import_report": json.dumps(loaded.report, default=str),
           **({"balance": json.dumps(balanced)} if balanced is not None else {})}
    part = {"frame": np.full(scene.n_particles, position, np.int64), "name": np.asarray(scene.names, dtype=object),
            **{a: scene.x[:, k] for k, a in enumerate("xyz"[:scene.dim])}, **per_particle(scene),
            "random": np.random.default_rng([spec["seed"], position]).random(scene.n_particles)}
    part.update({name: np.full(scene.n_particles, np.nan) for name in PREDICTORS})
    times["frame"] = time.perf_counter() - start - times["read"]
    for stage, run in (("whole", lambda: whole(core, spec["soft_modes"])),
                       ("scan", lambda: scan_map(core, Path(spec["out"]) / "scans" / f"frame-{position:06d}",
                                                 spec["scan_options"], cut(from_loaded(loaded), scene, core))),
                       ("rigidity", lambda: rigid(core, walls))):
        if not spec[stage]:
            continue
        begun = time.perf_counter()
        try:
            with blas_threads(1):
                got, values = run()
        except SceneError as exc:                    # which frame and stage, then what failed: one line
            raise SceneError(f"frame {position} (step {key}): --{stage}: {exc}") from None
        row.update(got)
        for name, column in (values.items() if isinstance(values, dict) else
                             [("soft_participation" if stage == "whole" else "in_largest_rigid_cluster", values)]):
            part[name][index] = column
        times[stage] = time.perf_counter() - begun
    row["seconds"] = times
    write_parts(Path(spec["out"]) / "parts", position, part, scene, row)
    return row


def write_parts(parts: Path, position: int, particles: dict, scene: Scene, row: dict) -> None:
    """The frame's particle rows and contacts (Arrow IPC), then its row (JSON), each written whole then renamed:
    an interrupted run leaves no torn part, and a frame counts as done only once its JSON is there."""
    import pyarrow as pa
    import pyarrow.feather as feather
    names = np.asarray(scene.names, dtype=object)
    contacts = {"key": contact_keys(names, scene.p, scene.q), "a": names[scene.p].astype(str),
                "b": names[scene.q].astype(str), "sliding": scene.at_yield()}
    stem = f"frame-{position:06d}"
    for suffix, table in (("particles", particles), ("contacts", contacts)):
        tmp = parts / f"{stem}.{suffix}.tmp"
        feather.write_feather(pa.table({k: pa.array(v) for k, v in table.items()}), tmp, compression="uncompressed")
        tmp.rename(parts / f"{stem}.{suffix}.arrow")
    tmp = parts / f"{stem}.json.tmp"
    tmp.write_text(json.dumps(row, allow_nan=True), encoding="utf-8")
    tmp.rename(parts / f"{stem}.json")
