"""Rigidity of a packing: rigid clusters, floppy modes, self-stresses and Maxwell counts (issue 28).

    result = granstab.rigidity.rigidity(scene, model="both", walls="free")
    result["physical"]["clusters"][0]          # the largest rigid cluster: its particles and contacts
    granstab.rigidity.largest_cluster(scene)   # per frame, for track: size_particles, size_contacts, fraction

Two models of the same body-bar frame (bodybar.py: particles as rigid bodies, a sticking contact d constraints, a
sliding one 1, rolling stiffness r more):
- "physical" (physical.py): the rank and null space of the compatibility matrix at the actual geometry, with its
  rank tolerance and singular-value gap; the prestress's second-order verdict on the floppy modes (prestress.py);
- "generic" (pebble.py): the (k, k) pebble game, k = d(d+1)/2, RigidLibrary's (3,3) game in 2D: exact for
  generic geometry, blind to collinear contacts, parallel chains and the periodic cell.
"""
from __future__ import annotations

import time

import numpy as np

from ..model.errors import SceneError
from ..model.scene import Scene, mean_contact_radius
from .bodybar import WALL_NAMES, WALL_OPTIONS, BodyBar, from_scene
from .pebble import pebble_game
from .physical import DENSE_MAX, NEAR_RTOL, TOL_RULE, physical
from .prestress import prestress

MODELS = ("physical", "generic", "both")
CELL_IGNORED = ("periodic cell ignored: seam contacts are bars like any other and the whole may turn, so the game "
                "counts k trivial modes where the fixed cell has d (RigidLibrary treats the cell as a free body); "
                "compare --kind physical, which constrains through the images")
GAME_START_MAX = 5000     # bodies up to which the physical model alone plays the game for its start


def rigidity(scene: Scene, model: str = "physical", walls: str = "free", wall_flags=None,
             second_order: bool = True) -> dict:
    """The rigidity analysis of a scene as a JSON-able dict: one entry per model ("physical", "generic"), and with
    model="both" also "differ" (the contacts whose cluster membership differs); `walls` "free" or "bodies"
    (RigidLibrary's annulus convention, needs `wall_flags`); `second_order` False skips the prestress check."""
    if model not in MODELS:
        raise SceneError(f"--kind: must be one of {', '.join(MODELS)}, got {model!r}")
    bodybar = from_scene(scene, walls, wall_flags)
    out = {"source": scene.source, "dim": scene.dim, "walls": walls, "periodic": scene.periodic,
           "wall_bodies": bodybar.walls}
    game = None
    if model in ("generic", "both"):
        start = time.perf_counter()
        game = play(bodybar)
        out["generic"] = analyse_generic(scene, bodybar, game, time.perf_counter() - start)
    if model in ("physical", "both"):
        out["physical"] = analyse_physical(scene, bodybar, game, second_order)
    if model == "both":
        out["differ"] = differing_contacts(out["physical"], out["generic"])
    return out


def play(bodybar: BodyBar, components: bool = True):
    """The pebble game on the body-bar frame's bars in RigidLibrary's order (one bar of every contact, then the further
    bars)."""
    bars = bodybar.bars
    order = np.r_[np.arange(len(bars)), np.repeat(np.arange(len(bars)), bars - 1)]
    return pebble_game(bodybar.n_bodies, bodybar.p[order], bodybar.q[order], bodybar.per, components=components)


def analyse_generic(scene: Scene, bodybar: BodyBar, game=None, seconds: float = 0.0) -> dict:
    """The generic model's report (the game played here unless given, with the seconds it took)."""
    start = time.perf_counter()
    game = game or play(bodybar)
    k = bodybar.per
    counts = {"dofs": k * bodybar.n_bodies, "constraints": len(game.independent), "rank": int(game.independent.sum()),
              "floppy": game.free, "trivial": k}
    return report(scene, bodybar, game.component, counts, seconds + time.perf_counter() - start,
                  {"method": f"({k},{k}) pebble game on the body-bar graph, rigid sets contracted as found",
                   "trivial_modes_note": CELL_IGNORED if bodybar.periodic else "the game counts k rigid motions of "
                                                                              "the whole"})


def analyse_physical(scene: Scene, bodybar: BodyBar, game=None, second_order: bool = True) -> dict:
    """The physical model's report with its rank tolerance, gap and the prestress's second-order verdict; the
    sparse path starts from `game`'s floppy count (played here up to GAME_START_MAX bodies, where it costs < 1 s;
    beyond, Maxwell's count n - K, whose underestimate the sparse path doubles away)."""
    start = time.perf_counter()
    length = mean_contact_radius(scene)
    if game is None and bodybar.n_bodies <= GAME_START_MAX:
        game = play(bodybar, components=False)
    ph = physical(bodybar, length, game.free_per_body if game is not None else None)
    trivial = bodybar.dim if bodybar.periodic else bodybar.per
    counts = {"dofs": bodybar.per * bodybar.n_bodies, "constraints": int(bodybar.bars.sum()), "rank": ph.rank,
              "floppy": ph.nullity, "trivial": trivial}
    extra = {"method": f"SVD per connected block up to {DENSE_MAX} columns (dense), else inverse iteration on "
                       "CᵀC + δI (one sparse LU), two projection steps and the SVD of C on that subspace",
             "blocks": ph.paths, "rotation_length": length,
             "rank_tolerance": {"rule": f"sigma <= {TOL_RULE:g} * max(rows, cols) * eps * sigma_max_bound",
                                "sigma_max_bound": ph.sigma_max_bound,
                                "sigma_max_bound_is": "sqrt(|C|_1 |C|_inf) >= sigma_max of C",
                                "largest": ph.tolerance,
                                "gap": ph.gap if np.isfinite(ph.gap) else None,
                                "gap_is": "sigma_rank / sigma_rank+1 (smallest non-zero over largest zero), "
                                          "smallest over the blocks (null: no block has both)"},
             "rigid_contact_strain": ph.strain_gap,
             "nearly_floppy": {"count": ph.nearly_floppy, "below": NEAR_RTOL * ph.sigma_max_bound,
                               "note": "singular values above the tolerance but below 1e-6 sigma_max_bound: counted "
                                       "rigid, floppy to a data file's precision (a lower bound on the sparse path)"}}
    result = report(scene, bodybar, ph.component, counts, time.perf_counter() - start, extra)
    t = time.perf_counter()
    result["prestress"] = prestress(scene, ph.null, length) if second_order else {"evaluated": False,
                                                                                  "why": "not asked"}
    result["prestress"]["seconds"] = time.perf_counter() - t
    return result


def rattlers(bodybar: BodyBar) -> np.ndarray:
    """Particles (not walls) left with fewer than 2 contacts when such particles are removed one round after
    another: a frictional disk needs two contacts to be held (bool, N_b)."""
    alive = np.ones(bodybar.n_bodies, bool)
    alive[bodybar.n_particles:] = False
    walls = np.arange(bodybar.n_bodies) >= bodybar.n_particles
    while True:
        use = (alive | walls)[bodybar.p] & (alive | walls)[bodybar.q]
        z = np.bincount(bodybar.p[use], minlength=bodybar.n_bodies) + np.bincount(bodybar.q[use], minlength=bodybar.n_bodies)
        drop = alive & (z < 2)
        if not drop.any():
            return ~alive & ~walls
        alive &= ~drop


def report(scene: Scene, bodybar: BodyBar, component: np.ndarray, counts: dict, seconds: float, extra: dict) -> dict:
    """The JSON contract: contacts [p, q, label], clusters largest first, floppy and trivial modes, rattlers,
    self-stresses and the counts (z, z_iso, Maxwell with its self-stress correction)."""
    names = bodybar.names
    same = (component[bodybar.p] == component[bodybar.q]) & (component[bodybar.p] >= 0)
    raw = np.where(same, component[bodybar.p], -1)
    labels, clusters = _ordered(raw, bodybar)
    rat = rattlers(bodybar)
    m = bodybar.n_contacts
    n_live = int(bodybar.n_particles - rat[:bodybar.n_particles].sum())
    live_contacts = ~rat[bodybar.p[:m]] & ~rat[bodybar.q[:m]]
    bars = bodybar.bars[:m]
    mean_bars = float(bars[live_contacts].mean()) if live_contacts.any() else float("nan")
    self_stresses = counts["constraints"] - counts["rank"]
    return {
        "contacts": [[names[a], names[b], int(c)] for a, b, c in zip(bodybar.p, bodybar.q, labels)],
        "clusters": clusters,
        "floppy_modes": {"count": counts["floppy"] - counts["trivial"], "total_with_trivial": counts["floppy"]},
        "trivial_modes": {"count": counts["trivial"],
                          "kind": "translations (fixed periodic cell)" if bodybar.periodic and "pebble" not in
                          extra["method"] else "rigid motions of the whole (translations and rotations)"},
        "rattlers": [names[i] for i in np.flatnonzero(rat)],
        "self_stresses": self_stresses,
        "counts": {"particles": bodybar.n_particles, "bodies": bodybar.n_bodies, "contacts": len(bodybar.p),
                   "sliding": int(bodybar.sliding.sum()), "z": 2 * m / max(bodybar.n_particles, 1),
                   "z_without_rattlers": 2 * int(live_contacts.sum()) / max(n_live, 1),
                   "z_iso": 2 * bodybar.per / mean_bars if mean_bars else None,
                   "maxwell": {**{k: counts[k] for k in ("dofs", "constraints", "rank")},
                               "self_stresses": self_stresses,
                               "floppy": counts["dofs"] - counts["constraints"] + self_stresses,
                               "formula": "floppy = dofs - constraints + self_stresses"},
                   "largest_cluster_particles": len(clusters[0]["particles"]) if clusters else 0},
        "seconds": seconds, **extra,
    }


def _ordered(raw: np.ndarray, bodybar: BodyBar):
    """Cluster labels renumbered largest first (bodies, then contacts, then the first contact), and the clusters."""
    found = np.unique(raw[raw >= 0])
    members = {c: np.flatnonzero(raw == c) for c in found}
    bodies = {c: np.unique(np.r_[bodybar.p[members[c]], bodybar.q[members[c]]]) for c in found}
    order = sorted(found, key=lambda c: (-len(bodies[c]), -len(members[c]), members[c][0]))
    new = np.full(len(raw), -1)
    clusters = []
    for i, c in enumerate(order):
        new[members[c]] = i
        clusters.append({"label": i, "particles": [bodybar.names[b] for b in bodies[c]],
                         "contacts": members[c].tolist()})
    return new, clusters


def partition(result: dict) -> set:
    """A model's partition of contacts into rigid clusters, as a set of frozensets of contact indices."""
    return {frozenset(c["contacts"]) for c in result["clusters"]}


def differing_contacts(a: dict, b: dict) -> dict:
    """Where two models differ: the contacts rigid (in some cluster) in one model and floppy in the other, and
    whether the partitions of contacts into clusters are the same."""
    la = np.array([c[2] for c in a["contacts"]])
    lb = np.array([c[2] for c in b["contacts"]])
    differ = np.flatnonzero((la >= 0) != (lb >= 0))
    same = partition(a) == partition(b)
    return {"same_partition": same, "count": int(differ.size),
            "contacts": [[*a["contacts"][i][:2], int(la[i]), int(lb[i])] for i in differ],
            "columns": ["p", "q", "label (physical)", "label (generic)"],
            "note": "contacts rigid in one model and floppy in the other"
                    + ("" if same or differ.size else "; the clusters also group the rigid contacts differently")}


def largest_rigid_cluster(result: dict, model: str | None = None) -> dict:
    """The largest rigid cluster of a `rigidity` result: its particles (wall bodies not counted), contacts and
    share of the scene's particles; `model` defaults to the physical one when present."""
    name = model or ("physical" if "physical" in result else "generic")
    r = result[name]
    first = r["clusters"][0] if r["clusters"] else {"particles": [], "contacts": []}
    particles = [p for p in first["particles"] if p not in WALL_NAMES]
    return {"model": name, "size_particles": len(particles), "size_contacts": len(first["contacts"]),
            "fraction": len(particles) / max(r["counts"]["particles"], 1)}


def largest_cluster(scene: Scene, model: str = "generic", walls: str = "free", wall_flags=None) -> dict:
    """One frame's largest rigid cluster for `track`: {model, size_particles, size_contacts, fraction, seconds}.
    The generic model (default) costs one pebble game, near-linear (10⁴ disks in ~3 s); "physical" adds the
    sparse rank (~8 s there) but no prestress check."""
    if model not in ("physical", "generic"):
        raise SceneError(f"model: must be physical or generic, got {model!r}")
    start = time.perf_counter()
    result = rigidity(scene, model, walls, wall_flags, second_order=False)
    return {**largest_rigid_cluster(result, model), "seconds": time.perf_counter() - start}


__all__ = ["MODELS", "WALL_OPTIONS", "largest_cluster", "largest_rigid_cluster", "partition", "rigidity"]
