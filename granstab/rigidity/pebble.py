"""The (k, k) pebble game on a body-bar multigraph (Lee & Streinu, Discrete Math. 308, 1425 (2008); Jacobs &
Hendrickson, J. Comput. Phys. 137, 346 (1997)): k = d(d+1)/2 pebbles a body (3 in 2D, 6 in 3D), one bar is
accepted (independent) when k + 1 pebbles can be gathered on its two ends. The rigid components are the maximal
sets of bodies spanning k·|V| - k independent bars; for l = k they share no body.

Each search is a depth-first search along the pebble-directed bars, so a game is near-linear in practice.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Game:
    """independent (B,) bool per bar, component (N,) int per body (-1: in no rigid component of >= 2 bodies),
    free pebbles left (= the generic number of floppy modes, trivial ones included) and where they sit."""

    independent: np.ndarray
    component: np.ndarray
    free: int
    free_per_body: np.ndarray


class _Pebbles:
    def __init__(self, n: int, k: int):
        self.k = k
        self.free = [k] * n
        self.out = [[] for _ in range(n)]          # out[u]: the bodies v of bars u→v that u's pebbles cover
        self.into = [[] for _ in range(n)]         # into[v]: the bodies u of bars u→v

    def _flip(self, w: int, v: int) -> None:
        self.out[w].remove(v)
        self.into[v].remove(w)
        self.out[v].append(w)
        self.into[w].append(v)

    def find(self, start: int, a: int, b: int) -> bool:
        """Move a free pebble found from `start` (never from a or b) back to `start`, reversing the path."""
        parent = {start: -1}
        stack = [start]
        while stack:
            u = stack.pop()
            for v in self.out[u]:
                if v in parent:
                    continue
                parent[v] = u
                if v != a and v != b and self.free[v] > 0:
                    self.free[v] -= 1
                    while parent[v] != -1:
                        self._flip(parent[v], v)
                        v = parent[v]
                    self.free[start] += 1
                    return True
                stack.append(v)
        return False

    def gather(self, a: int, b: int, need: int) -> bool:
        """Bring `need` pebbles onto a and b together; False when it cannot be done."""
        while self.free[a] + self.free[b] < need:
            if not (self.find(a, a, b) or self.find(b, a, b)):
                return False
        return True

    def add(self, a: int, b: int) -> bool:
        if not self.gather(a, b, self.k + 1):
            return False
        owner, other = (a, b) if self.free[a] > 0 else (b, a)
        self.free[owner] -= 1
        self.out[owner].append(other)
        self.into[other].append(owner)
        return True

    def _reach(self, start: list, stop: set) -> tuple[set, bool]:
        """The bodies reachable from `start` along the bars without entering `stop`, and whether a free pebble
        was met (the search stops there)."""
        seen, stack = set(start), list(start)
        while stack:
            u = stack.pop()
            if self.free[u] > 0:
                return seen, True
            for v in self.out[u]:
                if v not in seen and v not in stop:
                    seen.add(v)
                    stack.append(v)
        return seen, False

    def component(self, a: int, b: int) -> set:
        """The rigid component spanned by an independent bar a-b (empty when a and b can still move relative to
        each other: a k+1-th pebble reaches them). With k pebbles locked on a and b, Reach(a, b) holds no other
        free pebble; the component is Reach(a, b) and every body that reaches it but no free pebble (Lee &
        Streinu's component detection)."""
        self.gather(a, b, self.k)
        if self.gather(a, b, self.k + 1):
            return set()
        held = (self.free[a], self.free[b])
        self.free[a] = self.free[b] = 0                     # locked
        comp, _ = self._reach([a, b], set())
        floppy = set()
        todo = [w for v in comp for w in self.into[v] if w not in comp]
        while todo:
            w = todo.pop()
            if w in comp or w in floppy:
                continue
            seen, free = self._reach([w], comp)
            if free or seen & floppy:
                floppy.add(w)
            else:
                comp |= seen
                todo += [u for v in seen for u in self.into[v] if u not in comp]
        self.free[a], self.free[b] = held
        return comp


def pebble_game(n_bodies: int, a: np.ndarray, b: np.ndarray, k: int, components: bool = True) -> Game:
    """Play the (k, k) game on bars a[i]-b[i] in their order; then (with `components`) label the rigid
    components."""
    game = _Pebbles(n_bodies, k)
    a, b = np.asarray(a).tolist(), np.asarray(b).tolist()
    independent = np.array([game.add(u, v) for u, v in zip(a, b)], bool)
    component = np.full(n_bodies, -1)
    label = 0
    for i in np.flatnonzero(independent) if components else ():
        u, v = a[i], b[i]
        if component[u] >= 0 or component[v] >= 0:
            continue                               # components share no body: this bar lies in a known one or none
        members = game.component(u, v)
        if len(members) >= 2:
            component[list(members)] = label
            label += 1
    return Game(independent, component, int(sum(game.free)), np.array(game.free))
