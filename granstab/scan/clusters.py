"""Local clusters of a packing (the paper's Sec. 5: "clusters within larger systems").

The cluster of a centre particle c with N rings is c, every particle within N contact hops of c, and every contact
between two of them. Its loads are the scene format's equilibrium defaults (b^p = -Σ f^pq, w^p = -Σ (r×f + m)),
so the forces of the contacts cut at its rim act as external loads: the paper's isolated cluster.

In a periodic packing (a scene with a cell) a cluster at the seam keeps every contact with its minimum-image
geometry: its particles are unwrapped along its contacts from the centre (`unwrap`: each particle moved by a
lattice vector to sit next to the copy its contact names), so that the cluster is an ordinary scene, without a
cell. A scan's chunk stays periodic (`cut`); its batch unwraps each cluster with the same `unwrap`.
"""
from __future__ import annotations

from dataclasses import replace
from operator import itemgetter

import numpy as np
import scipy.sparse as sp

from ..model.scene import Scene, SceneError, equilibrium_loads
from ..model.vec import rot_dim

CONTACT_FIELDS = ("point", "normal", "curvature_p", "curvature_q", "curvature_sum", "force", "moment", "k", "alpha", "mu",
                  "rolling")


def adjacency(scene: Scene) -> sp.csr_matrix:
    """Boolean contact graph with self-loops (n, n): one product with it adds one ring."""
    n = scene.n_particles
    ones = np.ones(scene.n_contacts, dtype=bool)
    A = sp.coo_matrix((ones, (scene.p, scene.q)), shape=(n, n))
    return (A + A.T + sp.identity(n, dtype=bool, format="coo")).tocsr().astype(bool)


def members(scene: Scene, centers: np.ndarray, rings: int, graph: sp.csr_matrix | None = None) -> list[np.ndarray]:
    """Sorted particle indices of the cluster of every centre (indices), all centres at once by sparse products."""
    X = _reach(scene, centers, rings, graph)
    X.sort_indices()
    return np.split(X.indices.astype(np.int64), X.indptr[1:-1])


def union(scene: Scene, centers: np.ndarray, rings: int, graph: sp.csr_matrix | None = None) -> np.ndarray:
    """Sorted particle indices of the clusters of `centers` together (a scan chunk's particles), without the
    per-cluster lists."""
    return _distinct(_reach(scene, centers, rings, graph).indices, scene.n_particles)


def _distinct(indices: np.ndarray, n: int) -> np.ndarray:
    """Sorted distinct values of `indices` (all in range(n)): a mark per value, no sort (a scan's client cuts every
    chunk with it)."""
    mark = np.zeros(n, dtype=bool)
    mark[indices] = True
    return np.flatnonzero(mark)


MORTON_BITS = 16    # bits per axis of the Z-order curve: 65,536 cells an axis, far finer than a packing's grains


def spatial_order(x: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """`indices` in the order of a Z-order (Morton) curve through their positions x[indices]: consecutive ones are
    near in space, so that a scan chunk of consecutive centres shares most of its clusters' particles (its scene, its
    contact blocks and the task Dask ships are then about the chunk's size, not clusters × cluster size). Ties keep
    their order; the rows do not depend on it (each is the same bits however the scan is chunked)."""
    indices = np.asarray(indices, dtype=np.int64)
    if indices.size < 2:
        return indices
    pos = x[indices]
    lo, span = pos.min(axis=0), np.ptp(pos, axis=0)
    cells = np.floor((pos - lo) / np.where(span > 0, span, 1.0) * (2 ** MORTON_BITS - 1)).astype(np.int64)
    key = np.zeros(len(indices), dtype=np.int64)
    for bit in range(MORTON_BITS):          # interleave the axes' bits, the lowest first
        for axis in range(x.shape[1]):
            key |= ((cells[:, axis] >> bit) & 1) << (bit * x.shape[1] + axis)
    return indices[np.argsort(key, kind="stable")]


def particle_shares(flat: np.ndarray, sizes: np.ndarray, n: int, *flags: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per particle of `n`, from clusters given by their members (`flat`: every cluster's member indices in turn,
    `sizes`: how many each has): the number of clusters containing it, then for each (G,) bool `flags` over the
    clusters the share of those containing it that are flagged (NaN: in no cluster). The map's unstable fraction,
    its split by mechanism and track's per-particle predictors all count this way."""
    contains = np.bincount(flat, minlength=n).astype(float)
    shares = []
    for flag in flags:
        count = np.bincount(flat, weights=np.repeat(flag, sizes).astype(float), minlength=n)
        with np.errstate(invalid="ignore", divide="ignore"):
            shares.append(np.where(contains > 0, count / np.maximum(contains, 1), np.nan))
    return (contains, *shares)


def _reach(scene, centers, rings, graph) -> sp.csr_matrix:
    """(len(centers), n) boolean: row i marks the particles within `rings` contact hops of centres[i]."""
    graph = adjacency(scene) if graph is None else graph
    centers = np.asarray(centers, dtype=np.int64)
    X = sp.csr_matrix((np.ones(len(centers), dtype=bool), (np.arange(len(centers)), centers)),
                      shape=(len(centers), scene.n_particles))
    for _ in range(rings):                 # one row a centre: the product's work is the clusters', not the packing's
        X = (X @ graph).astype(bool)
    return X


def incidence(scene: Scene) -> sp.csr_matrix:
    """Particle × contact incidence (n, M), boolean: row i lists the contacts of particle i."""
    M = scene.n_contacts
    return sp.csr_matrix((np.ones(2 * M, dtype=bool), (np.r_[scene.p, scene.q], np.r_[np.arange(M), np.arange(M)])),
                         shape=(scene.n_particles, M))


def subscene(scene: Scene, keep: np.ndarray, title: str = "", hold: np.ndarray | None = None,
             center: int | None = None) -> Scene:
    """The sub-scene of the particles `keep` (indices) and every contact between two of them, with equilibrium loads.

    hold: further particles (indices) held fixed around them (`--boundary fixed`): the contacts between a kept and a
    held particle are added, those between two held ones are not (they would act on no dof). In a periodic scene the
    cluster is unwrapped from `center` (an index; default keep[0]) and has no cell (module docstring)."""
    fields = cut(scene, keep, title, hold)
    if scene.cell is not None:
        every = np.sort(np.concatenate([keep, [] if hold is None else hold])).astype(np.int64)
        fields = unwrapped(fields, scene.cell, int(np.searchsorted(every, keep[0] if center is None else center)))
    return piece(fields)


def unwrap(n: int, p: np.ndarray, q: np.ndarray, image: np.ndarray, roots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integer lattice shifts s (n, d) that put every particle reachable from `roots` next to its neighbours along
    the contacts p → q's copy (x^q + image @ cell): s_q = s_p + image, breadth first (the first contact of the
    contact order that reaches a particle places it). Also the contacts that close a loop around the cell
    (image + s_p − s_q ≠ 0: the cluster wraps around it). Any number of clusters at once (roots: one a cluster,
    particles numbered across them)."""
    shift = np.zeros((n, image.shape[1]), dtype=np.int64)
    known = np.zeros(n, dtype=bool)
    known[roots] = True
    while True:
        forward, backward = known[p] & ~known[q], known[q] & ~known[p]
        if not (forward.any() or backward.any()):
            break
        target = np.concatenate([q[forward], p[backward]])
        value = np.concatenate([shift[p[forward]] + image[forward], shift[q[backward]] - image[backward]])
        order = np.concatenate([np.flatnonzero(forward), np.flatnonzero(backward)])
        first = np.lexsort((order, target))
        placed = first[np.r_[True, target[first][1:] != target[first][:-1]]]
        shift[target[placed]] = value[placed]
        known[target[placed]] = True
    loops = np.any(image + shift[p] - shift[q] != 0, axis=1)
    return shift, loops


def lattice_offset(shift: np.ndarray, cell: np.ndarray) -> np.ndarray:
    """shift @ cell, (n, d), written out term by term: the same bits for a particle however many are shifted
    together (a matrix product's kernel, and so its rounding, may change with the row count)."""
    offset = np.zeros((len(shift), cell.shape[1]))
    for i in range(cell.shape[0]):
        offset = offset + shift[:, i:i + 1] * cell[i]
    return offset


def unwrapped(fields: dict, cell: np.ndarray, root: int) -> dict:
    """`cut`'s fields of one cluster of a periodic scene as a cluster without a cell: positions and contact points
    moved by the lattice shifts of `unwrap` from particle `root` (a local index), images zero. A cluster that wraps
    around the cell (a contact closing a loop) is a one-line error."""
    shift, loops = unwrap(len(fields["x"]), fields["p"], fields["q"], fields["image"], np.array([root]))
    if loops.any():
        c = int(np.flatnonzero(loops)[0])
        names = fields["names"]
        raise SceneError(f"{fields['source']}: cluster of {names[root]}: contact {names[fields['p'][c]]}-"
                         f"{names[fields['q'][c]]}: image: the cluster wraps around the periodic cell (the contact "
                         "closes a loop around it): use fewer rings")
    offset = lattice_offset(shift, cell)
    return {**fields, "x": fields["x"] + offset, "point": fields["point"] + offset[fields["p"]],
            "image": np.zeros_like(fields["image"]), "cell": None}


def piece(fields: dict) -> Scene:
    """The Scene of `cut`'s fields with its loads at equilibrium (eq:equil1: the forces of the cut contacts act as
    loads). Not checked again: every value is a slice of a scene that was checked where it was read."""
    n, r = len(fields["names"]), rot_dim(fields["dim"])
    bare = Scene(**fields, load=np.zeros((n, fields["dim"])), load_moment=np.zeros((n, r)))
    load, load_moment = equilibrium_loads(bare)
    return replace(bare, load=load, load_moment=load_moment)


def cut(scene: Scene, keep: np.ndarray, title: str = "", hold: np.ndarray | None = None,
        contacts_of: sp.csr_matrix | None = None) -> dict:
    """The fields of `subscene(scene, keep, title, hold)` but its loads (`piece` makes the scene): slices of the
    scene's arrays only, so that a scan's client cuts a chunk cheaply and ships arrays. contacts_of:
    `incidence(scene)`, if at hand (then the work is of the size of the cut, not of the scene)."""
    hold = np.zeros(0, dtype=np.int64) if hold is None else np.asarray(hold, dtype=np.int64)
    every = np.sort(np.concatenate([keep, hold]))
    contacts_of = incidence(scene) if contacts_of is None else contacts_of
    touching = _distinct(contacts_of[every].indices, scene.n_contacts)
    p, q = np.searchsorted(every, scene.p[touching]), np.searchsorted(every, scene.q[touching])
    free = np.isin(every, keep) if hold.size else np.ones(len(every), dtype=bool)
    inside_p = every[np.minimum(p, len(every) - 1)] == scene.p[touching]
    inside_q = every[np.minimum(q, len(every) - 1)] == scene.q[touching]
    within = inside_p & inside_q
    within[within] &= free[p[within]] | free[q[within]]
    c = touching[within]
    fields = {name: getattr(scene, name)[c] for name in CONTACT_FIELDS + ("image",)}
    names = itemgetter(*every)(scene.names) if len(every) > 1 else (scene.names[every[0]],)
    fixed = ~free | (False if scene.fixed is None else scene.fixed[every])
    fields.update(p=p[within], q=q[within], dim=scene.dim, names=tuple(names), x=scene.x[every], title=title,
                  cell=scene.cell,
                  state=tuple(itemgetter(*c)(scene.state)) if len(c) > 1 else tuple(scene.state[i] for i in c),
                  source=scene.source, tol=scene.tol, fixed=fixed if fixed.any() else None,
                  mass=None if scene.mass is None else scene.mass[every],
                  inertia=None if scene.inertia is None else scene.inertia[every])
    if scene.force_err is not None:                 # the file's per-contact uncertainty (issue 42): its contacts'
        fields["force_err"] = scene.force_err[c]
    return fields


def boundary_ring(scene: Scene, center: int, rings: int, graph: sp.csr_matrix | None = None):
    """The cluster of `center` (indices, sorted) and the particles one contact beyond it (the ring `--boundary fixed`
    holds)."""
    inner, outer = members(scene, [center], rings, graph)[0], members(scene, [center], rings + 1, graph)[0]
    return inner, np.setdiff1d(outer, inner)


BOUNDARIES = ("loads", "fixed", "embedded")
DEFAULT_BOUNDARY = "embedded:1"   # the scan's default: docs/attribution.md#the-default (why)


def boundary_rings(boundary: str) -> tuple[str, int]:
    """("loads" | "fixed" | "embedded", R) of a --boundary value: "embedded[:R]" (R rings, default 2); a one-line
    SceneError for anything else."""
    kind, _, rings = boundary.partition(":")
    if kind not in BOUNDARIES or (rings and (kind != "embedded" or not rings.isdigit())):
        raise SceneError(f"--boundary: one of loads, fixed, embedded[:R] (R a whole number of rings), got {boundary!r}")
    return kind, int(rings) if rings else (2 if kind == "embedded" else 0)


def embedded(scene: Scene, center: int, rings: int, R: int, title: str = "", graph=None) -> Scene:
    """The cluster of `center` embedded in its next R rings (--boundary embedded:R): those particles free with their
    contacts elastic at their current state (only contacts between two of the cluster's own particles may slide),
    the ring beyond them held fixed."""
    inner = members(scene, [center], rings, graph)[0]
    within, ring = boundary_ring(scene, center, rings + R, graph)
    sub = subscene(scene, within, title=title, hold=ring)
    own = np.isin(np.asarray(sub.names, dtype=object), np.asarray(scene.names, dtype=object)[inner])
    elastic = ~(own[sub.p] & own[sub.q])
    return replace(sub, state=tuple("elastic" if e else st for e, st in zip(elastic, sub.state)))


RIM_LOAD = 0.5     # a load above this share of a particle's largest contact force marks a cut contact (rim)


def loaded(scene: Scene) -> np.ndarray:
    """(N,) bool: particles whose load in the packing is like a contact force (|b| above RIM_LOAD of their largest
    contact force): contacts cut before the scan saw the packing — across a periodic cell's seam, at a region's
    edge — or measured forces that do not balance. They are on the rim of any cluster holding them."""
    largest = np.zeros(scene.n_particles)
    size = np.linalg.norm(scene.force, axis=1)
    np.maximum.at(largest, scene.p, size)
    np.maximum.at(largest, scene.q, size)
    return np.linalg.norm(scene.load, axis=1) > RIM_LOAD * largest


def control_scene(scene: Scene, center: int, rings: int, boundary: str, control: str, graph=None) -> Scene:
    """A control of the cluster of `center` (mechanics/attribution.py): "elastic", the cluster as `boundary` cuts it
    with every contact elastic; "rim", the cluster alone with its rim (particles with contacts outside it, or with a
    packing load like a contact force: `loaded`) held."""
    if control == "elastic":
        sub = cluster(scene, center, rings, boundary, graph=graph)
        return replace(sub, state=("elastic",) * sub.n_contacts)
    inner = members(scene, [center], rings, graph)[0]
    sub = subscene(scene, inner)
    outside = np.setdiff1d(members(scene, [center], rings + 1, graph)[0], inner)
    graph = adjacency(scene) if graph is None else graph
    rim = (np.asarray(graph[inner][:, outside].sum(axis=1)).ravel() > 0) | loaded(scene)[inner]
    held = rim if sub.fixed is None else rim | sub.fixed
    return replace(sub, fixed=held if held.any() else None)


def cluster(scene: Scene, center: int, rings: int = 1, boundary: str = "loads", title: str = "",
            graph: sp.csr_matrix | None = None) -> Scene:
    """The cluster of particle `center` (an index) with `rings` contact hops, as a scene of its own: the one cluster
    function of the scan, `extract` and the app.

    boundary "loads" (the paper's isolated cluster, Sec. 5): the forces of the cut contacts act as dead loads and
    the rigid-rotation projection applies (eq:newstiffnesses) — can the cluster, pushed as its neighbours push it
    now, deform unstably? "fixed": the next ring of particles is held fixed (supports, no rigid modes, no
    projection) — can it deform unstably while its surroundings do not move (a stiffer, sufficient question)?
    "embedded:R" (`embedded`): the next R rings free and elastic, the ring beyond held. graph: adjacency(scene), if
    at hand."""
    if rings < 1:
        raise SceneError(f"{scene.source}: rings must be >= 1, got {rings}")
    kind, R = boundary_rings(boundary)
    if kind == "embedded":
        return embedded(scene, center, rings, R, title=title, graph=graph)
    if boundary == "fixed":
        inner, ring = boundary_ring(scene, center, rings, graph)
        return subscene(scene, inner, title=title, hold=ring, center=center)
    return subscene(scene, members(scene, [center], rings, graph)[0], title=title, center=center)


def particle_index(scene: Scene, name: str) -> int:
    """Index of the particle called `name` (one-line SceneError when there is none)."""
    try:
        return scene.names.index(str(name))
    except ValueError:
        raise SceneError(f"{scene.source}: no particle named {name!r} (names are as in the scene)") from None


def extract(scene: Scene, center: str, rings: int = 1, boundary: str = "loads") -> Scene:
    """The cluster of particle `center` as a scene of its own (`granstab extract`).

    Parameters
    ----------
    scene : Scene
        The packing.
    center : str
        The centre particle's name.
    rings : int
        Contact hops from the centre (>= 1); the cluster keeps every contact between two of its particles.
    boundary : {"loads", "fixed"}
        "loads" (the paper's isolated cluster, Sec. 5): the forces of the cut contacts act as dead loads and the
        rigid-rotation projection applies (eq:newstiffnesses) — can the cluster, pushed as its neighbours push it
        now, deform unstably? "fixed": the next ring of particles is held fixed (supports, no rigid modes, no
        projection) — can it deform unstably while its surroundings do not move (a stiffer question)?

    Returns
    -------
    Scene
        Its particles and contacts in the packing's order, with ``fixed`` (N_c,) set for "fixed".
    """
    title = f"cluster of {center} ({rings} ring{'s' * (rings > 1)}, boundary {boundary}) in {scene.source}"
    return cluster(scene, particle_index(scene, center), rings, boundary, title=title)
