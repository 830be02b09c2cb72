"""The vertex certificate of a stable verdict under a force band (issue 42): exact for few uncertain contacts.

On a loading branch with every contact's state and (2D) sliding sign fixed, sym(𝓗^i) is affine in the contact forces
(mechanics/uncertainty.py; eq:Hg1, eq:equilibrium4, eq:Hg3 linear in f, eq:Hm independent of it, the projection
P^nrr of eq:newstiffnesses geometric), so μ_i(f) = min over unit non-rigid x of xᵀ sym(𝓗^i(f)) x is **concave** in
f (a minimum of affine functions) and its minimum over a convex polytope is at a vertex. Each enumerated contact's
force ball (radius δ_c: a disk in 2D; in 3D a ball of the normal and both tangential components) is cut into cones
over pieces of the unit circle or sphere: a piece spanned by d unit vectors u_i (2D: an arc, 3D: a spherical
triangle) lies, within the ball, inside the simplex (0, R u_1, …, R u_d) once R >= δ_c / h, h the distance of the
plane (line) through the u_i from the origin (2D: cos of half the arc). So a product of pieces lies inside a product
of simplices, whose (d + 1)^K vertices bound μ from below: `analyze` at each vertex (its eigenvalues less their
accuracy bounds, accuracy.py, every branch, the non-rigid ones). The first cover (level 0) and its covering factor
c_0 = max 1/h: 2D 8 arcs (K = 1; 1.082) or 4 (K = 2; √2 = 1.414); 3D the icosahedron's 20 triangles (K = 1; 1.258)
or the octahedron's 8 (K = 2; √3 = 1.732). A piece of level L is cut into 2 arcs (2D) or 4 triangles at its edges'
midpoints (3D: a geodesic grid), and every piece of level L uses R = δ_c c_L, c_L the largest 1/h of the level, so
that neighbouring cells share their vertices (and their analyses). The other contacts enter by Weyl
(e_rest = Σ δ_c β_c). The cell with the lowest bound is cut (its coarsest piece) until every cell's bound exceeds
e_rest (proven) or the budget of analyses is spent (not proven). Exact in the limit for K = every uncertain contact:
a band just inside the threshold is proven once the pieces near the worst direction are fine enough.
"""
from __future__ import annotations

import functools
import heapq
import itertools
from dataclasses import replace

import numpy as np

from .analysis import analyze
from .mechanics.branches import RIGID
from .model.scene import SceneError
from .model.vec import tangent_basis

BUDGET = 64        # analyses the certificate may spend (the data's own included)
CONTACTS = 2       # contacts enumerated (the largest δ_c β_c); the others enter by Weyl
WIDEN = 1.0 + 1e-9     # the vertices' radius rounded up (h, the midpoints and the forces' sums in floating point)
INSIDE = 1.0 - 1e-9    # a probe inside the band: this fraction of each enumerated contact's radius
MOST_DOF = 600         # larger scenes are left to the bound (64 analyses of a packing: minutes)
DEEPEST = 7            # levels of the cover at most (3D: 20·4⁷ triangles for c_L, pieces of about 0.5°)
_GOLD = (1 + 5 ** 0.5) / 2
_ICOSAHEDRON = np.array([[-1, _GOLD, 0], [1, _GOLD, 0], [-1, -_GOLD, 0], [1, -_GOLD, 0], [0, -1, _GOLD],
                         [0, 1, _GOLD], [0, -1, -_GOLD], [0, 1, -_GOLD], [_GOLD, 0, -1], [_GOLD, 0, 1],
                         [-_GOLD, 0, -1], [-_GOLD, 0, 1]]) / np.hypot(1, _GOLD)
_W = _ICOSAHEDRON[0] - np.eye(3)[0]
_ICOSAHEDRON = _ICOSAHEDRON - 2 * np.outer(_ICOSAHEDRON @ _W, _W) / (_W @ _W)    # reflected: vertex 0 on e1
_OCTAHEDRON = np.vstack([np.eye(3), -np.eye(3)])
#: the first cover of the unit circle / sphere by (dimension, enumerated contacts): its vertices and pieces, in
#: each contact's frame (n, t1[, t2]): a vertex along ±n, where a threshold of the normal force lies
COVERS = {
    (2, 1): (np.c_[np.cos(np.arange(8) * np.pi / 4), np.sin(np.arange(8) * np.pi / 4)],
             [(i, (i + 1) % 8) for i in range(8)]),
    (2, 2): (np.array([[1.0, 0], [0, 1], [-1, 0], [0, -1]]), [(i, (i + 1) % 4) for i in range(4)]),
    (3, 1): (_ICOSAHEDRON, [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
                            (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
                            (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]),
    (3, 2): (_OCTAHEDRON, [(a, b, c) for a in (0, 3) for b in (1, 4) for c in (2, 5)]),
}


def eligible(scene, band, mob, ext) -> bool:
    """The certificate applies: at most MOST_DOF dofs on the dense path, no position band, no moment band, every
    branch kept, no contact whose sliding direction can turn (mobilisation: `unbounded`, and `turning`: in 3D every
    contact that may slide and has a band; λ_min is concave in the forces only where the branch's H is affine)."""
    return (scene.n_dof <= MOST_DOF and ext.backend == "dense" and band.position == 0
            and not np.any(band.moment_radius(scene.moment) > 0) and not mob["unbounded"].any()
            and not mob["turning"].any()
            and len(ext.branches) == ext.verdict.n_branches)


def first_cover(dim: int, K: int) -> list:
    """The pieces of level 0 (module docstring): (0, d unit vectors, each a tuple of floats)."""
    points, pieces = COVERS[(dim, K)]
    return [(0, tuple(tuple(map(float, points[i])) for i in piece)) for piece in pieces]


def _midpoint(a: tuple, b: tuple) -> tuple:
    """The unit vector halfway between a and b (the pair sorted: the same bits from either side)."""
    m = np.add(*sorted((a, b)))
    return tuple(map(float, m / np.linalg.norm(m)))


def split(piece) -> list:
    """A piece of level L → its pieces of level L + 1: an arc at its midpoint, a triangle at its edges' midpoints."""
    level, u = piece
    if len(u) == 2:
        m = _midpoint(*u)
        return [(level + 1, (u[0], m)), (level + 1, (m, u[1]))]
    a, b, c = u
    ab, bc, ca = _midpoint(a, b), _midpoint(b, c), _midpoint(c, a)
    return [(level + 1, t) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]


@functools.cache
def covering_factor(dim: int, K: int, level: int) -> float:
    """c_L: the largest 1/h (R/δ of a piece's simplex; h the distance of the plane through its unit vectors from 0)
    over every piece of the level, rounded up by WIDEN (vectorised over the level's pieces)."""
    points, pieces = COVERS[(dim, K)]
    U = points[np.array(pieces)]                                   # (P, d, d): the pieces' vectors as rows
    for _ in range(level):
        if dim == 2:
            m = U.sum(axis=1)
            m /= np.linalg.norm(m, axis=1, keepdims=True)
            U = np.concatenate([np.stack([U[:, 0], m], 1), np.stack([m, U[:, 1]], 1)])
        else:
            mid = [(U[:, i] + U[:, j]) / np.linalg.norm(U[:, i] + U[:, j], axis=1, keepdims=True)
                   for i, j in ((0, 1), (1, 2), (2, 0))]
            ab, bc, ca = mid
            U = np.concatenate([np.stack(t, 1) for t in ((U[:, 0], ab, ca), (ab, U[:, 1], bc), (ca, bc, U[:, 2]),
                                                          (ab, bc, ca))])
    inverse = np.linalg.solve(U, np.ones(U.shape[:2])[..., None])[..., 0]
    return float(np.linalg.norm(inverse, axis=1).max()) * WIDEN


def certify(ext, delta: np.ndarray, weight: np.ndarray, perturbed, *, budget: int = BUDGET,
            contacts: int = CONTACTS) -> dict:
    """Whether every branch of `ext` (an analysis of the scene, contacts of open mobilisation sliding) stays positive
    definite off its rigid modes for every force within δ (M,) of the data (module docstring). weight (M,): δ_c β_c,
    the Weyl bound of each contact; perturbed(scene, forces): the scene with other forces (uncertainty.perturbed).
    Before a cell is cut, the forces at its lowest vertex pulled onto the band's edge (shared by the cells around
    that vertex) are analysed: where they are not proven positive no proof can follow, and they are returned
    (`probe`, (M, d): a candidate counter-example for the search). Returns {"proven", "analyses", "enumerated", "exact", "rest", "lowest", "probe", "cover",
    "finest"} (cover: the first cover's covering factor c_0; finest: the finest cover's c_L)."""
    scene = ext.scene
    chosen = np.argsort(-weight, kind="stable")[:contacts]
    chosen = chosen[delta[chosen] > 0]
    others = np.ones(len(delta), dtype=bool)
    others[chosen] = False
    rest = float(np.sum(weight[others]))
    frozen = replace(scene, state=tuple(np.where(scene.at_yield(), "sliding", "elastic")))
    value = _values(ext, frozen, chosen, perturbed)
    K, d = len(chosen), scene.dim
    radius = functools.partial(_radius, d, K, delta[chosen])
    heap = [(value.lowest(_points(cell, radius)), cell)
            for cell in itertools.product(first_cover(d, K) if K else [], repeat=K)]
    heapq.heapify(heap)
    proven, probe, finest = False, None, 0
    while heap:
        low, cell = heap[0]
        if low > rest:
            proven = True
            break
        worst = min(_points(cell, radius), key=value)          # its lowest vertex, pulled onto the band's edge
        inner = tuple(None if p is None else (p[0], r * INSIDE) for p, r in zip(worst, delta[chosen]))
        j = min(range(K), key=lambda k: cell[k][0]) if K else None
        children = [] if j is None or cell[j][0] >= DEEPEST else [
            cell[:j] + (part,) + cell[j + 1:] for part in split(cell[j])]
        new = {p for child in children for p in _points(child, radius)} | {inner}
        if not children or value.count + len(new - value.cache.keys()) > budget:
            break
        if value(inner) <= rest:                    # a force inside the band not proven: no proof can follow
            probe = value.forces(inner)
            break
        heapq.heappop(heap)
        for child in children:
            heapq.heappush(heap, (value.lowest(_points(child, radius)), child))
        finest = max(finest, cell[j][0] + 1)
    lowest = min((h[0] for h in heap), default=np.inf)
    return {"proven": proven, "analyses": value.count, "enumerated": [int(c) for c in chosen],
            "exact": bool(not others[delta > 0].any()), "rest": rest, "lowest": float(lowest),
            "probe": None if probe is None else probe.tolist(),
            "cover": covering_factor(d, K, 0) if K else 1.0, "finest": covering_factor(d, K, finest) if K else 1.0}


def _radius(dim: int, K: int, delta: np.ndarray, k: int, level: int) -> float:
    """R of enumerated contact k's pieces of `level`: δ_k c_L."""
    return float(delta[k]) * covering_factor(dim, K, level)


def _points(cell, radius) -> list:
    """The (d + 1)^K vertices of the cell's product of simplices (0, R u_1, …, R u_d): per contact None (not moved)
    or (u, R)."""
    options = [(None, *((u, radius(k, level)) for u in vectors)) for k, (level, vectors) in enumerate(cell)]
    return list(itertools.product(*options))


class _values:
    """The vertex values, cached: min over branches and non-rigid eigenvalues of λ − its accuracy bound, for the
    forces of the enumerated contacts moved by R u (None: not moved); −inf where the vertex leaves the affine
    family (a sliding contact's tangential force changes sign or vanishes, the rigid modes or branches differ) or
    `analyze` refuses it."""

    def __init__(self, ext, frozen, chosen, perturbed):
        self.ext, self.frozen, self.chosen, self.perturbed = ext, frozen, chosen, perturbed
        n = frozen.normal[chosen]
        self.frame = np.concatenate([n[:, None, :], np.swapaxes(tangent_basis(n), 1, 2)], axis=1)   # rows n, t
        self.cache, self.count = {}, 0
        self.rigid = [int(np.sum(b.codes == RIGID)) for b in ext.branches]
        self.sliding = frozen.at_yield()
        self.ft = frozen.tangential_force()
        m = ext.metric
        self.options = dict(metric=m.name if m.rotation_length is None else "L", rotation_length=m.rotation_length,
                            max_sliding=max(16, int(self.sliding.sum())), attribution=False, keep="all")

    def __call__(self, point) -> float:
        if point not in self.cache:
            self.count += 1
            self.cache[point] = self._value(point)
        return self.cache[point]

    def lowest(self, points) -> float:
        """min of the values of `points`: the lower bound of μ over a cell."""
        return min(map(self, points))

    def forces(self, point) -> np.ndarray:
        """The forces (M, d) of a point: the enumerated contacts' moved by R u (u in the contact's frame)."""
        force = self.frozen.force.copy()
        for c, p, frame in zip(self.chosen, point, self.frame):
            if p is not None:
                force[c] += p[1] * (np.array(p[0]) @ frame)
        return force

    def _value(self, point) -> float:
        scene = self.perturbed(self.frozen, self.forces(point))
        ft = scene.tangential_force()
        if np.any(self.sliding & ((np.sum(ft * self.ft, axis=1) <= 0) | ~scene.has_sliding_direction())):
            return -np.inf
        try:
            res = analyze(scene, **self.options)
        except (SceneError, ValueError):
            return -np.inf
        if len(res.branches) != len(self.rigid) or any(int(np.sum(b.codes == RIGID)) != r
                                                       for b, r in zip(res.branches, self.rigid)):
            return -np.inf
        return min((float(np.min(b.stability_eigenvalues[b.codes != RIGID] - b.accuracy[b.codes != RIGID],
                                 initial=np.inf)) for b in res.branches), default=np.inf)
