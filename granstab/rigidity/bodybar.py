"""The body-bar frame a rigidity analysis works on: the scene's particles as rigid bodies and its contacts as
constraints, plus, with `--walls bodies`, an annulus's two walls as two more bodies (RigidLibrary's convention).

walls = "bodies" (RigidLibrary's `AddBoundaryContacts`): every particle flagged at a wall (-1 inner, +1 outer)
gets a sticking contact with that wall, and the two walls are joined by one sliding contact. Geometry for the
physical model: the walls are circles about the centre c of the annulus (an algebraic least-squares circle fit of
the flagged particles' centres, Kåsa's); a particle's wall contact sits on its surface along the radial line,
normal radial; the walls' own sliding contact is a normal constraint along e1 at c (any one direction does: it
removes one relative translation, as RigidLibrary's single bar does).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.errors import SceneError
from ..model.scene import Scene
from ..scan.figure import particle_radii

WALL_NAMES = ("inner_wall", "outer_wall")
WALL_OPTIONS = ("free", "bodies")


@dataclass(frozen=True, eq=False)
class BodyBar:
    """Bodies (N_b, the scene's N first) and contacts (M_b, the scene's M first) of a rigidity analysis.

    r_pq, r_qp: contact point minus each body's reference point (q's periodic copy for r_qp); branch: q's copy
    minus x^p; sliding: a normal constraint only; rolling: the relative rotation constrained too; periodic: the
    cell is fixed, so only translations are trivial. A frictionless contact (μ = 0) constrains its normal only,
    as a sliding one."""

    dim: int
    names: tuple
    x: np.ndarray
    p: np.ndarray
    q: np.ndarray
    r_pq: np.ndarray
    r_qp: np.ndarray
    branch: np.ndarray
    normal: np.ndarray
    sliding: np.ndarray
    rolling: np.ndarray
    periodic: bool
    n_particles: int
    n_contacts: int
    walls: dict | None = None       # centre, radii of the wall bodies (the figure draws them)

    @property
    def n_bodies(self) -> int:
        return len(self.names)

    @property
    def per(self) -> int:
        return self.dim + (1 if self.dim == 2 else 3)

    @property
    def bars(self) -> np.ndarray:
        """Bars of each contact in the body-bar graph: d sticking, 1 sliding, + r with rolling stiffness."""
        r = self.per - self.dim
        return np.where(self.sliding, 1, self.dim) + np.where(self.rolling, r, 0)


def from_scene(scene: Scene, walls: str = "free", wall_flags=None) -> BodyBar:
    """The frame of a scene; walls "bodies" needs `wall_flags` (N,), nonzero for particles at a wall."""
    if walls not in WALL_OPTIONS:
        raise SceneError(f"--walls: must be one of {', '.join(WALL_OPTIONS)}, got {walls!r}")
    rolling = np.any(scene.rolling != 0.0, axis=(1, 2))
    base = dict(dim=scene.dim, names=tuple(scene.names), x=scene.x, p=scene.p, q=scene.q, r_pq=scene.r_pq,
                r_qp=scene.r_qp, branch=scene.branch, normal=scene.normal, sliding=scene.at_yield() | (scene.mu == 0), rolling=rolling,
                periodic=scene.periodic, n_particles=scene.n_particles, n_contacts=scene.n_contacts)
    if walls == "free":
        return BodyBar(**base)
    if scene.dim != 2 or scene.periodic or wall_flags is None or not np.any(wall_flags):
        raise SceneError(f"{scene.source}: --walls bodies: needs a 2D annulus frame whose particles are flagged at "
                         "its walls (RigidLibrary's particle_positions.txt edge column); this input has none")
    return _with_walls(scene, base, np.asarray(wall_flags))


def circle_fit(points: np.ndarray) -> np.ndarray:
    """Kåsa's algebraic fit: the centre c minimising Σ(|x - c|² - R²)², a linear least-squares problem."""
    A = np.c_[2 * points, np.ones(len(points))]
    sol = np.linalg.lstsq(A, np.sum(points ** 2, axis=1), rcond=None)[0]
    return sol[:2]


def _with_walls(scene: Scene, base: dict, flags: np.ndarray) -> BodyBar:
    N = scene.n_particles
    flagged = np.flatnonzero(flags != 0)
    centre = circle_fit(scene.x[flagged])
    radius = particle_radii(scene)
    out = scene.x[flagged] - centre
    e = out / np.linalg.norm(out, axis=1)[:, None]
    toward = np.where(flags[flagged, None] < 0, -e, e)                 # from the particle toward its wall
    point = scene.x[flagged] + radius[flagged, None] * toward
    wall = np.where(flags[flagged] < 0, N, N + 1)
    x = np.r_[scene.x, [centre, centre]]
    p = np.r_[scene.p, flagged, N]
    q = np.r_[scene.q, wall, N + 1]
    r_pq = np.r_[base["r_pq"], point - scene.x[flagged], np.zeros((1, 2))]
    r_qp = np.r_[base["r_qp"], point - centre, np.zeros((1, 2))]
    normal = np.r_[scene.normal, toward, [[1.0, 0.0]]]
    k = len(flagged)
    dist = np.linalg.norm(point - centre, axis=1)
    walls = {"centre": centre.tolist(), "inner_radius": float(np.mean(dist[flags[flagged] < 0])) if np.any(flags < 0) else None,
             "outer_radius": float(np.mean(dist[flags[flagged] > 0])) if np.any(flags > 0) else None,
             "contacts": k + 1, "convention": "RigidLibrary AddBoundaryContacts: flagged particles stick to their "
                                              "wall, the walls share one sliding contact"}
    return BodyBar(dim=2, names=tuple(scene.names) + WALL_NAMES, x=x, p=p, q=q, r_pq=r_pq, r_qp=r_qp,
                 branch=x[q] - x[p], normal=normal, sliding=np.r_[base["sliding"], np.zeros(k, bool), True],
                 rolling=np.r_[base["rolling"], np.zeros(k + 1, bool)], periodic=False, n_particles=N,
                 n_contacts=scene.n_contacts, walls=walls)
