"""The true shapes of a scene's grains, for drawing (numpy only): superquadrics (model/surface.py), clumps of
spheres and rounded polygons.

A contact-level scene carries the geometry the mechanics needs at its contacts (points, normals, curvatures); the
grains' shapes are what the explorer draws and what a scene file keeps beside it, per particle:

    shape = {kind = "superquadric", a = 3.0, b = 2.0, c = 1.5, n1 = 4.0, n2 = 4.0}   (LIGGGHTS's convention)
    shape = {kind = "clump", spheres = [[x, y, z, r], …]}       (member spheres, centres from the particle's centre)
    shape = {kind = "rounded_polygon", vertices = [[x, y], …], radius = r}         (2D, vertices in order around it)
    orientation = [w, x, y, z]                                   (3D, optional: body → world; default: none)

Offsets and vertices are in body axes (the world's where no orientation is given). Every particle of a scene has a
shape of one kind, or none has; `Grains` holds them as arrays, which are also their NPZ form (`Grains.arrays`,
`from_arrays`: a scan folder's packing.npz keeps them). Text and NPZ are checked by the same rules (`_checked`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .errors import SceneError

KINDS = ("superquadric", "clump", "rounded_polygon")
SUPERQUADRIC = ("a", "b", "c", "n1", "n2")
PREFIX = "grains/"          # the NPZ arrays' names: grains/kind, grains/orientation, grains/shape or body/offset/radius
PART_ARRAYS = ("body", "offset", "radius")


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

    def arrays(self) -> dict:
        """The NPZ form: `grains/kind` (0-d string), `grains/orientation` (N, 4) (3D only: a 2D grain's vertices are
        in the scene's axes), then `grains/shape` (N, 5) of superquadrics, or `grains/body` (K,) 0-based particle
        indices, `grains/offset` (K, d) and `grains/radius` (K,) of clumps' spheres and polygons' vertices."""
        out = {PREFIX + "kind": np.array(self.kind)}
        if self.dim == 3:
            out[PREFIX + "orientation"] = self.orientation
        if self.kind == "superquadric":
            return {**out, PREFIX + "shape": self.shape}
        return {**out, **{PREFIX + key: getattr(self, key) for key in PART_ARRAYS}}

    def take(self, index) -> Grains:
        """The grains of particles `index` (in that order): a cluster's, cut from its packing."""
        index = np.asarray(index, dtype=np.int64)
        if self.kind == "superquadric":
            return replace(self, orientation=self.orientation[index], shape=self.shape[index])
        new = np.full(self.n_particles, -1)
        new[index] = np.arange(len(index))
        keep = new[self.body] >= 0
        return replace(self, orientation=self.orientation[index], body=new[self.body[keep]],
                       offset=self.offset[keep], radius=self.radius[keep])


def cut(grains: Grains | None, scene, sub) -> Grains | None:
    """The grains of `sub`, a scene cut from `scene` (a cluster, an extract: its particles found by name)."""
    if grains is None:
        return None
    index = {name: i for i, name in enumerate(scene.names)}
    return grains.take([index[name] for name in sub.names])


def identity(n: int) -> np.ndarray:
    """(n, 4) identity quaternions."""
    return np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))


def from_loaded(loaded) -> Grains | None:
    """The grains of an import (io.Loaded): a scene file's own (`grains`: its `shape` entries or `grains/…` arrays),
    or a snapshot's (`shape` and `orientation` of superquadrics, `parts` of clumps and rounded polygons, offsets in
    world axes); None for disks and spheres."""
    scene = loaded.scene
    if getattr(loaded, "grains", None) is not None:
        return loaded.grains
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


def from_arrays(arrays: dict, dim: int, names, source: str) -> Grains | None:
    """The grains of an NPZ scene's `grains/…` arrays (`Grains.arrays`) for its particles `names`, checked as the
    text form is (one-line SceneError naming the file, the array and the particle), or None where it has none."""
    given = {key[len(PREFIX):] for key in arrays if key.startswith(PREFIX)}
    if not given:
        return None
    n = len(names)

    def fail(i, key: str, msg: str):
        where = f"[{i}] (particle {names[i]!r})" if i is not None else ""
        raise SceneError(f"{source}: {PREFIX}{key}{where}: {msg}")

    kind = arrays.get(PREFIX + "kind")
    allowed = [k for k in KINDS if (k == "rounded_polygon") == (dim == 2)]
    if kind is None or kind.shape != () or kind.dtype.kind != "U" or kind.item() not in allowed:
        fail(None, "kind", f"must be one of {', '.join(allowed)} (a 0-d string)")
    kind = str(kind.item())
    wanted = {"kind", *(("orientation",) if dim == 3 else ()), *(("shape",) if kind == "superquadric" else PART_ARRAYS)}
    if given != wanted:
        odd = sorted(given ^ wanted)[0]
        fail(None, odd, f"{'missing' if odd in wanted else 'not an array'} of a {kind} scene (it has "
             f"{', '.join(PREFIX + k for k in sorted(wanted))})")

    def numbers(key: str, shape: tuple) -> np.ndarray:
        a = arrays[PREFIX + key]
        if a.dtype.kind not in "fiu" or a.ndim != len(shape) or any(s and m != s for s, m in zip(shape, a.shape)):
            fail(None, key, f"must be numbers of shape {tuple(s or 'K' for s in shape)}, got {a.dtype} {a.shape}")
        return a.astype(float)

    q = numbers("orientation", (n, 4)) if dim == 3 else identity(n)
    if kind == "superquadric":
        return _checked(Grains(kind, dim, q, shape=numbers("shape", (n, 5))), fail)
    body = arrays[PREFIX + "body"]
    if body.dtype.kind not in "iu" or body.ndim != 1:
        fail(None, "body", f"must be integer particle indices (K,), got {body.dtype} {body.shape}")
    outside = (body < 0) | (body >= n)
    if outside.any():
        fail(None, "body", f"particle index {body[np.argmax(outside)]} is not in 0..{n - 1}")
    offset, radius = numbers("offset", (len(body), dim)), numbers("radius", (len(body),))
    return _checked(Grains(kind, dim, q, body=body.astype(np.int64), offset=offset, radius=radius), fail)


def _checked(g: Grains, fail) -> Grains:
    """The rules of every grain, vectorised (text and NPZ alike): finite numbers, positive sizes, blockiness ≥ 2, at
    least one sphere a clump and three vertices a polygon, one rounding radius a polygon, a nonzero quaternion
    (normalised where it is not a unit one already). `fail(i, field, msg)` raises naming particle i's entry."""
    norm = np.linalg.norm(g.orientation, axis=1)
    bad = ~np.isfinite(g.orientation).all(axis=1) | ~(norm > 0)
    if bad.any():
        fail(int(np.argmax(bad)), "orientation", "must be a finite nonzero quaternion (w, x, y, z)")
    unit = np.abs(norm - 1.0) <= 4 * np.finfo(float).eps         # unit to round-off: kept as given (exact round trip)
    g = replace(g, orientation=g.orientation / np.where(unit, 1.0, norm)[:, None])
    if g.kind == "superquadric":
        bad = ~(np.isfinite(g.shape).all(axis=1) & (g.shape > 0).all(axis=1))
        if bad.any():
            fail(int(np.argmax(bad)), "shape", "a, b, c, n1, n2 must be finite and > 0")
        bad = (g.shape[:, 3:] < 2).any(axis=1)
        if bad.any():
            fail(int(np.argmax(bad)), "shape", "blockiness n1, n2 must be >= 2")
        return g
    part = (np.isfinite(g.offset).all(axis=1) & np.isfinite(g.radius)) & (g.radius > 0)
    if not part.all():
        fail(int(g.body[np.argmax(~part)]), "shape", "parts must be finite numbers, radius > 0")
    count = np.bincount(g.body, minlength=g.n_particles)
    least = 1 if g.kind == "clump" else 3
    if (count < least).any():
        fail(int(np.argmax(count < least)), "shape", "a clump needs >= 1 sphere, a polygon >= 3 vertices")
    if g.kind == "rounded_polygon":
        first = np.full(g.n_particles, np.nan)
        first[g.body[::-1]] = g.radius[::-1]
        uneven = first[g.body] != g.radius
        if uneven.any():
            fail(int(g.body[np.argmax(uneven)]), "shape", "a rounded polygon has one rounding radius")
    return g


class _Reader:
    """Reads the `shape` and `orientation` entries of the particles, one at a time (their structure: kind, keys,
    numbers of the right shape); `grains` checks the values (`_checked`)."""

    def __init__(self, source: str, particles: list, dim: int):
        self.source, self.particles, self.dim = source, particles, dim
        self.kind, self.shape, self.body, self.offset, self.radius, self.q = None, [], [], [], [], []

    def fail(self, i: int, key: str, msg: str):
        name = self.particles[i].get("name") if isinstance(self.particles[i], dict) else None
        raise SceneError(f"{self.source}: particles[{i}]{f' ({name!r})' if name is not None else ''}: {key}: {msg}")

    def numbers(self, i: int, key: str, value, shape: tuple) -> np.ndarray:
        try:
            a = np.asarray(value, float)
        except (TypeError, ValueError):
            self.fail(i, key, f"must be numbers of shape {shape}")
        if a.dtype == object or a.ndim != len(shape) or any(s and n != s for s, n in zip(shape, a.shape)):
            self.fail(i, key, f"must be numbers of shape {shape}, got shape {a.shape}")
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
            self.shape.append(self.numbers(i, "shape", [s[k] for k in SUPERQUADRIC], (5,)))
        else:
            parts = (self.numbers(i, "shape.spheres", s["spheres"], (0, 4)) if kind == "clump" else
                     np.column_stack([self.numbers(i, "shape.vertices", s["vertices"], (0, 2)),
                                      np.full(len(s["vertices"]), self.numbers(i, "shape.radius", s["radius"], ()))]))
            self.body.append(np.full(len(parts), i))
            self.offset.append(parts[:, :-1])
            self.radius.append(parts[:, -1])
        if "orientation" in p and self.dim == 2:
            self.fail(i, "orientation", "3D only (a rounded polygon's vertices are given in the scene's axes)")
        self.q.append(self.numbers(i, "orientation", p.get("orientation", [1.0, 0.0, 0.0, 0.0]), (4,)))

    def grains(self) -> Grains:
        q = np.array(self.q)
        if self.kind == "superquadric":
            return _checked(Grains(self.kind, self.dim, q, shape=np.array(self.shape)), self.fail)
        return _checked(Grains(self.kind, self.dim, q, body=np.concatenate(self.body),
                               offset=np.concatenate(self.offset), radius=np.concatenate(self.radius)), self.fail)


__all__ = ["Grains", "KINDS", "cut", "from_arrays", "from_loaded", "from_particles"]
