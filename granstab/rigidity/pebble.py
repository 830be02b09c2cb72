"""The (k, k) pebble game on a body-bar multigraph (Lee & Streinu, Discrete Math. 308, 1425 (2008); Jacobs &
Hendrickson, J. Comput. Phys. 137, 346 (1997)): k = d(d+1)/2 pebbles a body (3 in 2D, 6 in 3D), one bar is
accepted (independent) when k + 1 pebbles can be gathered on its two ends. The rigid components are the maximal
sets of bodies spanning k·|V| - k independent bars; for l = k they share no body.

Rigid sets are contracted as they are found (the component pebble game): when k + 1 pebbles cannot be gathered on
a bar's ends, the bodies searched hold no other free pebble, so they span a tight set (Lee & Streinu, Lemma 10),
rigid; tight sets sharing a body have a tight union (l = k). Such a set is one body from then on: its bars inside
are dropped, its free pebbles and outside bars pooled (a tight set holds exactly k pebbles on free or outgoing
bars, as one body does). A later bar inside it is redundant at once, and no search walks through it again, so
the game stays near-linear where a plain game turns quadratic on a large rigid cluster (each failing search
visits all of it). The multigraph is kept as counts per pair of representatives (a union-find by size).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Game:
    """independent (B,) bool per bar, component (N,) int per body (-1: in no rigid component of >= 2 bodies),
    free pebbles left (= the generic number of floppy modes, trivial ones included) and where they sit (on each
    rigid set's representative body)."""

    independent: np.ndarray
    component: np.ndarray
    free: int
    free_per_body: np.ndarray


class _Pebbles:
    def __init__(self, n: int, k: int):
        self.k = k
        self.free = [k] * n
        self.out = [Counter() for _ in range(n)]    # out[u][v]: bars u→v covered by u's pebbles (representatives)
        self.into = [Counter() for _ in range(n)]   # into[v][u]: the same bars seen from v
        self.up = list(range(n))                    # union-find of the contracted rigid sets
        self.size = [1] * n

    def root(self, u: int) -> int:
        while self.up[u] != u:
            self.up[u] = self.up[self.up[u]]
            u = self.up[u]
        return u

    def _move(self, w: int, v: int, to_w: int, to_v: int) -> None:
        """Re-point one bar w→v as to_w→to_v."""
        for table, x, y in ((self.out, w, v), (self.into, v, w)):
            table[x][y] -= 1
            if not table[x][y]:
                del table[x][y]
        self.out[to_w][to_v] += 1
        self.into[to_v][to_w] += 1

    def find(self, start: int, a: int, b: int, seen: set | None = None) -> bool:
        """Move a free pebble found from `start` (never from a or b) back to `start`, reversing the path; on
        failure the bodies searched are added to `seen`."""
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
                        self._move(parent[v], v, v, parent[v])
                        v = parent[v]
                    self.free[start] += 1
                    return True
                stack.append(v)
        if seen is not None:
            seen.update(parent)
        return False

    def gather(self, a: int, b: int, need: int, learn: bool = False) -> bool:
        """Bring `need` pebbles onto a and b together; False when it cannot be done. With `learn`, a failure
        contracts the bodies searched (a tight set)."""
        while self.free[a] + self.free[b] < need:
            seen = {a, b}
            if not (self.find(a, a, b, seen) or self.find(b, a, b, seen)):
                if learn:
                    self.contract(seen)
                return False
        return True

    def contract(self, reps: set) -> int:
        """Make the rigid set of representatives `reps` one body; return its representative."""
        top = max(reps, key=lambda u: self.size[u])
        for s in reps - {top}:
            self.free[top] += self.free[s]
            self.free[s] = 0
            for t, c in list(self.out[s].items()):
                for _ in range(c):
                    self._move(s, t, top, t)
            for t, c in list(self.into[s].items()):
                for _ in range(c):
                    self._move(t, s, t, top)
            self.up[s] = top
            self.size[top] += self.size[s]
        for table in (self.out, self.into):
            table[top].pop(top, None)           # the bars now inside
            for s in reps - {top}:
                table[top].pop(s, None)
        return top

    def add(self, a: int, b: int) -> bool:
        """Play bar a-b (bodies): redundant at once inside one rigid set, else by the pebble search."""
        a, b = self.root(a), self.root(b)
        if a == b or not self.gather(a, b, self.k + 1, learn=True):
            return False
        owner, other = (a, b) if self.free[a] > 0 else (b, a)
        self.free[owner] -= 1
        self.out[owner][other] += 1
        self.into[other][owner] += 1
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
        """The rigid component spanned by an independent bar a-b of two representatives (empty when a and b can
        still move relative to each other: a k+1-th pebble reaches them). With k pebbles locked on a and b,
        Reach(a, b) holds no other free pebble; the component is Reach(a, b) and every body that reaches it but
        no free pebble (Lee & Streinu's component detection)."""
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
    """Play the (k, k) game on bars a[i]-b[i] in their order; then (with `components`) find and contract the
    rigid components the failed searches left out (those without a redundant bar) and label them."""
    game = _Pebbles(n_bodies, k)
    a, b = np.asarray(a).tolist(), np.asarray(b).tolist()
    independent = np.array([game.add(u, v) for u, v in zip(a, b)], bool)
    for i in np.flatnonzero(independent) if components else ():
        u, v = game.root(a[i]), game.root(b[i])
        if u != v:
            members = game.component(u, v)
            if len(members) >= 2:
                game.contract(members)
    roots = np.array([game.root(u) for u in range(n_bodies)], int)
    size = np.bincount(roots, minlength=n_bodies)
    _, label = np.unique(roots, return_inverse=True)
    component = np.where(size[roots] >= 2, label, -1) if components else np.full(n_bodies, -1)
    return Game(independent, component, int(sum(game.free)), np.array(game.free))
