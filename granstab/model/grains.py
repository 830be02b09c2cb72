"""The true shapes of a scene's grains, for drawing (numpy only): superquadrics (model/surface.py), clumps of
spheres and rounded polygons.

A contact-level scene carries the geometry the mechanics needs at its contacts (points, normals, curvatures); the
grains' shapes are what the explorer draws and what a scene file keeps beside it, per particle:

    shape = {kind = "superquadric", a = 3.0, b = 2.0, c = 1.5, n1 = 4.0, n2 = 4.0}   (LIGGGHTS's convention)
    shape = {kind = "clump", spheres = [[x, y, z, r], …]}       (member spheres, centres from the particle's centre)
    shape = {kind = "rounded_polygon", vertices = [[x, y], …], radius = r}         (2D, vertices in order around it)
    orientation = [w, x, y, z]                                   (3D, optional: body → world; default: none)

Offsets and vertices are in body axes (the world's where no orientation is given). Every particle of a scene has a
shape of one kind, or none has; `Grains` holds them as arrays.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import SceneError

KINDS = ("superquadric", "clump", "rounded_polygon")
SUPERQUADRIC = ("a", "b", "c", "n1", "n2")


@dataclass(frozen=True)
class Grains:
    """The shapes of a scene's N particles: `kind` (one of KINDS), `orientation` (N, 4) unit quaternions
    (w, x, y, z), body → world; superquadrics: `shape` (N, 5) a, b, c, n1, n2; clumps and rounded polygons: round
    parts `body` (K,) (the particle of each: member spheres, or a polygon's vertices in order around it), `offset`
    (K, d) from the particle's centre in body axes, `radius` (K,) (a polygon's rounding radius at each vertex)."""

    kind: str
    dim: int
    orientation: np.ndarray
    shape: np.ndarray | None = None
    body: np.ndarray | None = None
    offset: np.ndarray | None = None
    radius: np.ndarray | None = None

    @property
    def n_particles(self) -> int:
        return len(self.orientation)

    def parts_of(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Particle i's parts: offsets (k, d) and radii (k,), in their order."""
        mine = self.body == i
        return self.offset[mine], self.radius[mine]

    def entries(self) -> list[dict]:
        """Per particle, the scene file's `shape` (and, in 3D, `orientation`) entries (module docstring)."""
        out = []
        for i in range(self.n_particles):
            if self.kind == "superquadric":
                shape = {"kind": self.kind, **dict(zip(SUPERQUADRIC, self.shape[i].tolist()))}
            else:
                offset, radius = self.parts_of(i)
                shape = ({"kind": "clump", "spheres": np.column_stack([offset, radius]).tolist()}
                         if self.kind == "clump" else
                         {"kind": self.kind, "vertices": offset.tolist(), "radius": float(radius[0])})
            out.append({"shape": shape, **({"orientation": self.orientation[i].tolist()} if self.dim == 3 else {})})
        return out


def identity(n: int) -> np.ndarray:
    """(n, 4) identity quaternions."""
    return np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))


def from_loaded(loaded) -> Grains | None:
    """The grains of an imported snapshot (io.Loaded: `shape` and `orientation` of superquadrics, `parts` of clumps
    and rounded polygons, offsets in world axes), or None (disks, spheres)."""
    scene = loaded.scene
    if loaded.shape is not None:
        q = np.asarray(loaded.orientation, float)
        return Grains("superquadric", scene.dim, q / np.linalg.norm(q, axis=1)[:, None], shape=np.asarray(loaded.shape))
    parts = loaded.parts
    if parts is None:
        return None
    return Grains(parts["kind"], scene.dim, identity(scene.n_particles), body=np.asarray(parts["body"]),
                  offset=np.asarray(parts["offset"], float), radius=np.asarray(parts["radius"], float))


def from_particles(particles: list, dim: int, source: str) -> Grains | None:
    """The grains of a scene file's `particles` (parsed dicts), checked (one-line SceneError naming the file, the
    entry and the field), or None where no particle has a `shape`."""
    have = [isinstance(p, dict) and "shape" in p for p in particles]
    reader = _Reader(source, particles, dim)
    if not any(have):
        alone = [i for i, p in enumerate(particles) if isinstance(p, dict) and "orientation" in p]
        if alone:
            reader.fail(alone[0], "orientation", "given without a shape (it orients the grain's shape)")
        return None
    for i, p in enumerate(particles):
        if not have[i]:
            reader.fail(i, "shape", "missing (every particle has a shape or none has)")
        reader.read(i, p)
    return reader.grains()


class _Reader:
    """Reads and checks the `shape` and `orientation` entries of the particles, one at a time."""

    def __init__(self, source: str, particles: list, dim: int):
        self.source, self.particles, self.dim = source, particles, dim
        self.kind, self.shape, self.body, self.offset, self.radius, self.q = None, [], [], [], [], []

    def fail(self, i: int, key: str, msg: str):
        name = self.particles[i].get("name") if isinstance(self.particles[i], dict) else None
        raise SceneError(f"{self.source}: particles[{i}]{f' ({name!r})' if name is not None else ''}: {key}: {msg}")

    def numbers(self, i: int, key: str, value, shape: tuple, positive: bool = False) -> np.ndarray:
        try:
            a = np.asarray(value, float)
        except (TypeError, ValueError):
            self.fail(i, key, f"must be numbers of shape {shape}")
        if a.dtype == object or a.ndim != len(shape) or any(s and n != s for s, n in zip(shape, a.shape)):
            self.fail(i, key, f"must be numbers of shape {shape}, got shape {a.shape}")
        if not np.all(np.isfinite(a)) or (positive and not np.all(a > 0)):
            self.fail(i, key, "must be finite" + (" and > 0" if positive else ""))
        return a

    def read(self, i: int, p: dict) -> None:
        s = p["shape"]
        kind = s.get("kind") if isinstance(s, dict) else None
        if kind not in KINDS or (kind == "rounded_polygon") != (self.dim == 2):
            self.fail(i, "shape", f"kind must be one of {', '.join(k for k in KINDS if (k == 'rounded_polygon') == (self.dim == 2))}, "
                      f"got {kind!r}")
        if self.kind not in (None, kind):
            self.fail(i, "shape", f"kind {kind!r}: the other particles are {self.kind!r} (one kind a scene)")
        self.kind = kind
        allowed = {"superquadric": {"kind", *SUPERQUADRIC}, "clump": {"kind", "spheres"},
                   "rounded_polygon": {"kind", "vertices", "radius"}}[kind]
        if set(s) != allowed:
            self.fail(i, "shape", f"a {kind} has the keys {', '.join(sorted(allowed))}, got {', '.join(sorted(s))}")
        if kind == "superquadric":
            value = self.numbers(i, "shape", [s[k] for k in SUPERQUADRIC], (5,), positive=True)
            if value[3] < 2 or value[4] < 2:
                self.fail(i, "shape", "blockiness n1, n2 must be >= 2")
            self.shape.append(value)
        else:
            parts = (self.numbers(i, "shape.spheres", s["spheres"], (0, 4)) if kind == "clump" else
                     np.column_stack([self.numbers(i, "shape.vertices", s["vertices"], (0, 2)),
                                      np.full(len(s["vertices"]), self.numbers(i, "shape.radius", s["radius"], (),
                                                                               positive=True))]))
            if len(parts) < (1 if kind == "clump" else 3) or not np.all(parts[:, -1] > 0):
                self.fail(i, "shape", "a clump needs >= 1 sphere of radius > 0, a polygon >= 3 vertices")
            self.body.append(np.full(len(parts), i))
            self.offset.append(parts[:, :-1])
            self.radius.append(parts[:, -1])
        q = p.get("orientation", [1.0, 0.0, 0.0, 0.0])
        if "orientation" in p and self.dim == 2:
            self.fail(i, "orientation", "3D only (a rounded polygon's vertices are given in the scene's axes)")
        q = self.numbers(i, "orientation", q, (4,))
        if not np.linalg.norm(q) > 0:
            self.fail(i, "orientation", "must be a nonzero quaternion (w, x, y, z)")
        self.q.append(q / np.linalg.norm(q))

    def grains(self) -> Grains:
        q = np.array(self.q)
        if self.kind == "superquadric":
            return Grains(self.kind, self.dim, q, shape=np.array(self.shape))
        return Grains(self.kind, self.dim, q, body=np.concatenate(self.body), offset=np.concatenate(self.offset),
                      radius=np.concatenate(self.radius))


__all__ = ["Grains", "KINDS", "from_loaded", "from_particles"]
