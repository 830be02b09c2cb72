"""The vertex certificate of a stable verdict under a force band (issue 42): exact for few uncertain contacts.

On a loading branch with every contact's state and (2D) sliding sign fixed, sym(𝓗^i) is affine in the contact forces
(mechanics/uncertainty.py; eq:Hg1, eq:equilibrium4, eq:Hg3 linear in f, eq:Hm independent of it, the projection
P^nrr of eq:newstiffnesses geometric), so μ_i(f) = min over unit non-rigid x of xᵀ sym(𝓗^i(f)) x is **concave** in
f (a minimum of affine functions) and its minimum over a convex polytope is at a vertex. Each enumerated contact's
force disk (2D, radius δ_c) is cut into angular sectors; a sector [a, b] lies inside the triangle
(0, R e(a), R e(b)), R = δ_c / cos((b − a)/2), so a product of sectors lies inside the product of triangles, whose
3^K vertices bound μ from below: `analyze` at each vertex (its eigenvalues less their accuracy bounds, accuracy.py,
every branch, the non-rigid ones). The other contacts enter by Weyl (e_rest = Σ δ_c β_c). The cell with the lowest
bound is bisected until every cell's bound exceeds e_rest (proven) or the budget of analyses is spent (not proven).
Exact in the limit for K = every uncertain contact: a band just inside the threshold is proven once the sectors
near the worst direction are fine enough.
"""
from __future__ import annotations

import heapq
import itertools
from dataclasses import replace

import numpy as np

from .analysis import analyze
from .mechanics.branches import RIGID
from .model.scene import SceneError

BUDGET = 64        # analyses the certificate may spend (the data's own included)
CONTACTS = 2       # contacts enumerated (the largest δ_c β_c); the others enter by Weyl
FIRST = {1: 8, 2: 4}   # sectors per enumerated contact at the start
WIDEN = 1.0 + 1e-9     # the vertices' radius rounded up (cos and the forces' sums in floating point)
INSIDE = 1.0 - 1e-9    # a probe inside the band: this fraction of each enumerated contact's radius
MOST_DOF = 600         # larger scenes are left to the bound (64 analyses of a packing: minutes)


def eligible(scene, band, mob, ext) -> bool:
    """The certificate applies: 2D, at most MOST_DOF dofs on the dense path, no position band, no moment band, every
    branch kept, no contact whose sliding direction can turn (mobilisation: `unbounded`)."""
    return (scene.dim == 2 and scene.n_dof <= MOST_DOF and ext.backend == "dense" and band.position == 0
            and not np.any(band.moment_radius(scene.moment) > 0) and not mob["unbounded"].any()
            and len(ext.branches) == ext.verdict.n_branches)


def certify(ext, delta: np.ndarray, weight: np.ndarray, perturbed, *, budget: int = BUDGET,
            contacts: int = CONTACTS) -> dict:
    """Whether every branch of `ext` (an analysis of the scene, contacts of open mobilisation sliding) stays positive
    definite off its rigid modes for every force within δ (M,) of the data (module docstring). weight (M,): δ_c β_c,
    the Weyl bound of each contact; perturbed(scene, forces): the scene with other forces (uncertainty.perturbed).
    Before a cell is bisected, the forces at its sectors' middles on the band's edge
    are analysed: where they are not proven positive no proof can follow, and they are returned (`probe`, (M, d): a
    candidate counter-example for the search). Returns {"proven", "analyses", "enumerated", "exact", "rest",
    "lowest", "probe"}."""
    scene = ext.scene
    chosen = np.argsort(-weight, kind="stable")[:contacts]
    chosen = chosen[delta[chosen] > 0]
    others = np.ones(len(delta), dtype=bool)
    others[chosen] = False
    rest = float(np.sum(weight[others]))
    frozen = replace(scene, state=tuple(np.where(scene.at_yield(), "sliding", "elastic")))
    value = _values(ext, frozen, chosen, perturbed)
    K = len(chosen)
    first = FIRST.get(K, 2)
    edges = np.linspace(0.0, 2 * np.pi, first + 1)
    heap = []
    for cell in itertools.product(list(zip(edges[:-1], edges[1:])), repeat=K):
        heapq.heappush(heap, (_lower(value, cell, delta[chosen]), cell))
    proven, probe = False, None
    while heap:
        low, cell = heap[0]
        if low > rest:
            proven = True
            break
        if value.count + 3 ** K + 1 > budget:       # a bisection adds at most 3^K vertices and the probe
            break
        inner = tuple((0.5 * (a + b), d * INSIDE) for (a, b), d in zip(cell, delta[chosen]))
        if value(inner) <= rest:                    # a force inside the band not proven: no proof can follow
            probe = value.forces(inner)
            break
        heapq.heappop(heap)
        j = int(np.argmax([b - a for a, b in cell]))
        a, b = cell[j]
        for half in ((a, 0.5 * (a + b)), (0.5 * (a + b), b)):
            part = cell[:j] + (half,) + cell[j + 1:]
            heapq.heappush(heap, (_lower(value, part, delta[chosen]), part))
    lowest = min((h[0] for h in heap), default=np.inf)
    return {"proven": proven, "analyses": value.count, "enumerated": [int(c) for c in chosen],
            "exact": bool(not others[delta > 0].any()), "rest": rest, "lowest": float(lowest),
            "probe": None if probe is None else probe.tolist()}


def _lower(value, cell, delta) -> float:
    """min over the 3^K vertices of the cell's product of triangles (0, R e(a), R e(b)) of the vertex value."""
    options = []
    for (a, b), d in zip(cell, delta):
        R = d / np.cos(0.5 * (b - a)) * WIDEN
        options.append((None, (a, R), (b, R)))
    return min(value(point) for point in itertools.product(*options))


class _values:
    """The vertex values, cached: min over branches and non-rigid eigenvalues of λ − its accuracy bound, for the
    forces of the enumerated contacts moved by R e(θ) (None: not moved); −inf where the vertex leaves the affine
    family (a sliding contact's tangential force changes sign or vanishes, the rigid modes or branches differ) or
    `analyze` refuses it."""

    def __init__(self, ext, frozen, chosen, perturbed):
        self.ext, self.frozen, self.chosen, self.perturbed = ext, frozen, chosen, perturbed
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

    def forces(self, point) -> np.ndarray:
        """The forces (M, d) of a point: the enumerated contacts' moved by R e(θ)."""
        force = self.frozen.force.copy()
        for c, p in zip(self.chosen, point):
            if p is not None:
                force[c] += p[1] * np.array([np.cos(p[0]), np.sin(p[0])])
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
