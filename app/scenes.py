"""Scene models: what the sliders and drags act on, and how a Scene is made from them (no viser).

Three kinds, each with `params_used`, `initial_params()`, `build(params) -> Scene` and `bodies(params)` (what to draw):
- TwoParticleModel: the symmetric pair of Sec. 4.1, driven by ρ/r and f/(kr) directly. The contact-level data are
  the paper's (radii along e1, normal e1, curvature -1/ρ on both sides, force f^pq = [-f, ±m μ f]), so the numbers
  are exactly those of eq:exampleH; the drawn particles are ellipses of semi-axis r along e1 and tip radius of
  curvature ρ (ρ = b²/a, so b = √(ρ r)): the shape follows the ρ/r slider.
- ShapeModel: disks/ellipses/spheres/ellipsoids at poses; contacts, normals, curvatures and forces come from the
  geometry (granstab.model.shapes); dragging changes the poses.
- ContactModel: a contact-level scene file; the law parameters (μ, α, k, rolling) can be overridden, the geometry
  is fixed (particles are drawn as disks/spheres through their contact points; in 2D with a socket at a concave side).
"""
from __future__ import annotations

import functools
import itertools
import json
import re
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import granstab
from granstab.io import shapefile
from granstab.model import grains, shapes
from granstab.model.outline import tip_ellipse

from .params import defaults
from .protocols import SceneModel


@dataclass(frozen=True)
class Body:
    """A particle to draw: kind "ellipse"|"disk" (2D) or "ellipsoid"|"sphere" (3D), semi-axes, pose x (d,), R (d, d);
    2D `sockets`: its concave contact sides (contact_sockets), cut into the drawn outline (app.meshes.outline).
    A grain with a true shape (granstab.model.grains; `grain_bodies`): kind "superquadric", "clump" or
    "rounded_polygon", `grain` its shape in body axes (hashable: ("superquadric", a, b, c, n1, n2), ("clump",
    ((x, y, z, r), …)), ("rounded_polygon", ((x, y), …), r)), axes its semi-axes or bounding radius."""

    name: str
    kind: str
    axes: tuple
    x: np.ndarray
    R: np.ndarray
    sockets: tuple = ()
    grain: tuple = ()


# ------------------------------------------------------------------------------------------------ the pair

def contact_shape(rho_r: float) -> str:
    """What the pair's contact is called (Fig. 5): sharp tips (ρ < r, rolls off), circular (ρ = r, neutral), flat
    (ρ > r, rocks back)."""
    return "sharp" if rho_r < 1.0 else "circular" if rho_r == 1.0 else "flat"


@dataclass
class TwoParticleModel(SceneModel):
    """The symmetric two-particle example (Sec. 4.1, Appendix C), driven by ρ/r and f/(kr)."""

    r: float = 1.0
    start: dict = field(default_factory=dict)
    title: str = "two particles"

    kind = "two_particle"
    params_used = ("rho_r", "f_kr", "mu", "mobilised", "alpha", "k", "rolling")
    draggable = True   # a drag turns the pair into a ShapeModel of the same ellipses (see Session.move)

    def field_scale(self) -> float:
        return self.r

    def initial_params(self) -> dict:
        return {**defaults(), **self.start}

    def scene_dict(self, P: dict) -> dict:
        r, k = self.r, P["k"]
        f = P["f_kr"] * k * r
        rho = P["rho_r"] * r
        ft = P["mobilised"] * P["mu"] * f if f > 0 else 0.0
        contact = {"p": "p", "q": "q", "point": [r, 0.0], "normal": [1.0, 0.0],
                   "curvature_p": -1.0 / rho, "curvature_q": -1.0 / rho, "force": [-f, -ft],
                   "k": k, "alpha": P["alpha"], "mu": P["mu"], "rolling_stiffness": P["rolling"] * k * r * r,
                   # a tensile (cohesive) force lies outside the friction cone: the contact is elastic then
                   "state": "auto" if f >= 0 else "elastic"}
        return {"dim": 2, "title": f"{self.title}, {contact_shape(P['rho_r'])} contact "
                                    f"(ρ/r = {P['rho_r']:g}, f/(kr) = {P['f_kr']:g})",
                "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [2 * r, 0.0]}],
                "contacts": [contact]}

    def build(self, P: dict) -> granstab.Scene:
        return granstab.scene_from_dict(self.scene_dict(P), source="two-particle pair")

    def bodies(self, P: dict) -> list[Body]:
        r = self.r
        axes = tip_ellipse(r, P["rho_r"] * r)           # the tip's radius of curvature is ρ: the curvature drawn
        return [Body("p", "ellipse", axes, np.array([0.0, 0.0]), np.eye(2)),
                Body("q", "ellipse", axes, np.array([2 * r, 0.0]), np.eye(2))]

    def to_shapes(self, P: dict) -> ShapeModel:
        """The same two ellipses as a shape model (what a drag turns the pair into): q sits at 2r - δ with the
        penalty overlap δ = f/k, so the pair keeps its force (a tensile force cannot be kept: δ = 0 then)."""
        a, b = self.bodies(P)[0].axes
        delta = max(P["f_kr"], 0.0) * self.r
        ellipse = shapes.Ellipse(a, b)
        particles = [("p", ellipse, (np.array([0.0, 0.0]), 0.0)), ("q", ellipse, (np.array([2 * self.r - delta, 0.0]), 0.0))]
        start = {key: P[key] for key in ShapeModel.params_used}
        return ShapeModel(dim=2, particles=particles, start=start, title=f"{self.title} (dragged)", length=self.r)

    @classmethod
    def from_scene(cls, scene: granstab.Scene) -> TwoParticleModel | None:
        """The pair if `scene` is the symmetric collinear two-particle example (else None), with its parameters."""
        if scene.dim != 2 or scene.n_particles != 2 or scene.n_contacts != 1:
            return None
        xp, xq = scene.x[scene.p[0]], scene.x[scene.q[0]]
        L = float(np.linalg.norm(xq - xp))
        n, c = scene.normal[0], scene.point[0]
        tol = 1e-9 * max(L, 1e-300)
        if L == 0 or np.linalg.norm(n - (xq - xp) / L) > 1e-9 or np.linalg.norm(c - 0.5 * (xp + xq)) > tol:
            return None
        t = np.array([-n[1], n[0]])
        kp, kq = float(t @ scene.curvature_p[0] @ t), float(t @ scene.curvature_q[0] @ t)
        if kp >= 0 or abs(kp - kq) > 1e-9 * abs(kp) or scene.has_moments:
            return None
        r = L / 2
        k = float(scene.k[0])
        fn = -float(scene.force[0] @ n)
        ft = float(np.linalg.norm(scene.tangential_force()[0]))
        mu = float(scene.mu[0])
        start = {"rho_r": -1.0 / kp / r, "f_kr": fn / (k * r), "mu": mu, "alpha": float(scene.alpha[0]), "k": k,
                 "mobilised": ft / (mu * fn) if fn > 0 and mu > 0 else 0.0,
                 "rolling": float(scene.rolling[0, 0, 0]) / (k * r * r)}
        base = scene.title.split("(")[0].split(",")[0].strip()     # the contact word follows ρ/r (contact_shape)
        return cls(r=r, start=start, title=base or "two particles")


# ------------------------------------------------------------------------------------------------ shapes

@dataclass
class ShapeModel(SceneModel):
    """Particles with shapes at poses; every contact quantity is derived from the geometry (granstab.model.shapes)."""

    dim: int
    particles: list            # [(name, shape, (x, orientation))] as granstab.model.shapes.scene_from_shapes takes them
    start: dict = field(default_factory=dict)
    title: str = "shapes"
    length: float = 0.0        # the r of rolling stiffness/(kr²); default: mean bounding radius
    shear: object = None       # 3D tangential-force direction (granstab.model.shapes.tangent_directions)
    poses0: list = field(default_factory=list)

    kind = "shapes"
    params_used = ("mu", "mobilised", "alpha", "k", "rolling")
    draggable = True

    def dimension(self) -> int:
        return self.dim

    def __post_init__(self):
        self.poses0 = self.poses0 or [pose for _, _, pose in self.particles]
        self.length = self.length or float(np.mean([shapes.bounding_radius(s) for _, s, _ in self.particles]))

    def initial_params(self) -> dict:
        return {**defaults(), **self.start}

    def _law(self, P: dict) -> dict:
        return {"k": P["k"], "alpha": P["alpha"], "mu": P["mu"], "mobilised": P["mobilised"],
                "rolling_stiffness": P["rolling"] * P["k"] * self.length ** 2, "shear": self.shear, "title": self.title}

    def build(self, P: dict) -> granstab.Scene:
        try:
            scene = shapes.scene_from_shapes(self.dim, self.particles, source="shapes", **self._law(P))
            return replace(scene, title=shape_title(scene.title, scene))
        except granstab.SceneError:
            raise
        except (ValueError, RuntimeError) as exc:
            raise granstab.SceneError(" ".join(str(exc).split())) from None

    def to_dict(self, P: dict) -> dict:
        """The shape scene file (granstab.model.shapes format) of the current poses and parameters."""
        return shapefile.shape_scene_to_dict(self.dim, self.particles, **self._law(P))

    def bodies(self, P: dict) -> list[Body]:
        out = []
        for name, shape, (x, orientation) in self.particles:
            kind = ({2: "disk", 3: "sphere"} if shapes.is_round(shape) else {2: "ellipse", 3: "ellipsoid"})[self.dim]
            out.append(Body(name, kind, tuple(map(float, shape.semi_axes)), np.asarray(x, float).copy(),
                            shapes.rotation_matrix(self.dim, orientation)))
        return out

    def set_pose(self, name: str, x, R) -> None:
        """Move particle `name` to position x (d,) and orientation R (d, d)."""
        R = np.asarray(R, float)
        orientation = float(np.arctan2(R[1, 0], R[0, 0])) if self.dim == 2 else R
        for i, (n, shape, _) in enumerate(self.particles):
            if n == name:
                self.particles[i] = (n, shape, (np.asarray(x, float)[:self.dim].copy(), orientation))
                return
        raise KeyError(name)

    def reset_poses(self) -> None:
        self.particles = [(n, s, p) for (n, s, _), p in zip(self.particles, self.poses0)]

    @classmethod
    def from_dict(cls, data: dict, source: str) -> ShapeModel:
        """Read the shape format; validation (one-line SceneError) is granstab.io.shapefile.shape_scene_from_dict's."""
        spec = shapefile.read_shape_file(data, source=source)
        law = {**spec.law, "mobilised": spec.mobilised}
        start = {key: float(law[key]) for key in ("mu", "alpha", "k", "mobilised")}
        model = cls(dim=spec.dim, particles=spec.particles, title=spec.title, shear=spec.shear)
        rolling = spec.law["rolling_stiffness"]
        if np.allclose(rolling, rolling.flat[0] * np.eye(len(rolling))):
            start["rolling"] = float(rolling.flat[0]) / (start["k"] * model.length ** 2)
        model.start = start
        return model


# ------------------------------------------------------------------------------------------------ contact level

LAW_PARAMS = {"mu": "mu", "alpha": "alpha", "k": "k", "rolling": "rolling_stiffness"}


@dataclass
class ContactModel(SceneModel):
    """A contact-level scene (file); uniform law parameters may be overridden, the geometry is fixed."""

    scene: granstab.Scene
    report: str = ""           # an imported snapshot's validation report (granstab.io.format_report)
    frames: list | None = None # the frames its input holds (None: one)
    frame: object = None       # the frame shown
    path: str = ""             # where it was read from (to read another frame)
    grains: object = None     # the particles' true shapes (granstab.model.grains.Grains), drawn as they are; None
    kind = "contacts"
    draggable = False

    @property
    def params_used(self) -> tuple:
        """The law parameters that are uniform over the contacts (only those can be set by one slider)."""
        s = self.scene
        if s.n_contacts == 0:
            return ()
        used = []
        for key, arr in (("mu", s.mu), ("alpha", s.alpha), ("k", s.k)):
            if np.ptp(arr) == 0:
                used.append(key)
        if s.dim == 2 and np.ptp(s.rolling.reshape(-1)) == 0:
            used.append("rolling")
        return tuple(used)

    @property
    def length(self) -> float:
        s = self.scene
        return float(np.linalg.norm(s.r_pq, axis=1).mean()) if s.n_contacts else 1.0

    def initial_params(self) -> dict:
        s = self.scene
        P = defaults()
        if s.n_contacts:
            P.update(mu=float(s.mu[0]), alpha=float(s.alpha[0]), k=float(s.k[0]),
                     rolling=float(s.rolling.reshape(s.n_contacts, -1)[0, 0]) / (float(s.k[0]) * self.length ** 2))
        return P

    def build(self, P: dict) -> granstab.Scene:
        """The file's scene with the sliders' law parameters. A new μ keeps the contacts at the friction limit there
        (onto_cone: sliding ones, and those the smaller cone would leave outside), their loads following from the
        forces; the title's "μ = …" follows the slider."""
        start = self.initial_params()
        changed = [key for key in self.params_used if P[key] != start[key]]
        if not changed:
            return self.scene
        data = granstab.scene_to_dict(self.scene)
        for c in data["contacts"]:
            for key in changed:
                c[LAW_PARAMS[key]] = P[key] if key != "rolling" else P[key] * P["k"] * self.length ** 2
        if "mu" in changed:
            force, state, moved = onto_cone(self.scene, P["mu"])
            if moved.any():
                for c, f, st in zip(data["contacts"], force.tolist(), state):
                    c["force"], c["state"] = f, st
                for particle in data["particles"]:           # equilibrium loads of the new forces
                    particle.pop("load", None)
                    particle.pop("moment", None)
            data["title"] = re.sub(r"μ = [0-9.]+", f"μ = {P['mu']:g}", data.get("title", ""))
        return granstab.scene_from_dict(data, source=self.scene.source)

    def adjustments(self, P: dict) -> str:
        if self.scene.n_contacts == 0 or "mu" not in self.params_used or P["mu"] == self.initial_params()["mu"]:
            return ""
        _, _, moved = onto_cone(self.scene, P["mu"])
        if not moved.any():
            return ""
        return (f"μ = {P['mu']:g}: {int(moved.sum())} contact(s) at the friction limit keep sliding: their tangential "
                f"force is scaled onto the new cone (|f_t| = μ f_n{', none at μ = 0' if P['mu'] == 0 else ''}), "
                "and the loads follow from the forces.")

    def bodies(self, P: dict) -> list[Body]:
        """The grains as they are (`grain_bodies`), else disks (spheres) of radius the smallest distance from the
        centre to one of the particle's contact points."""
        s = self.scene
        if self.grains is not None:
            return grain_bodies(s, self.grains)
        radius = np.full(s.n_particles, np.inf)
        if s.n_contacts:
            np.minimum.at(radius, s.p, np.linalg.norm(s.r_pq, axis=1))
            np.minimum.at(radius, s.q, np.linalg.norm(s.r_qp, axis=1))
        fallback = np.median(radius[np.isfinite(radius)]) if np.isfinite(radius).any() else 1.0
        radius = np.where(np.isfinite(radius) & (radius > 0), radius, fallback)
        kind = "disk" if s.dim == 2 else "sphere"
        sockets = contact_sockets(s) if s.dim == 2 else {}
        return [Body(name, kind, (float(radius[i]),) * s.dim, s.x[i].copy(), np.eye(s.dim), sockets.get(i, ()))
                for i, name in enumerate(s.names)]


def grain_bodies(scene: granstab.Scene, grains) -> list[Body]:
    """The bodies of a scene's grains (granstab.model.grains.Grains, in the scene's particle order): superquadrics
    with their semi-axes, clumps and rounded polygons with their parts and bounding radius, each at its centre and
    orientation."""
    from granstab.io.bodies import rotation
    R = rotation(grains.orientation)[:, :scene.dim, :scene.dim]
    out = []
    for i, name in enumerate(scene.names):
        if grains.kind == "superquadric":
            a, b, c, n1, n2 = map(float, grains.shape[i])
            axes, grain = (a, b, c), ("superquadric", a, b, c, n1, n2)
        else:
            offset, radius = grains.parts_of(i)
            bound = float(np.max(np.linalg.norm(offset, axis=1) + radius))
            axes = (bound,) * scene.dim
            grain = (("clump", tuple(map(tuple, np.column_stack([offset, radius]).tolist())))
                     if grains.kind == "clump" else
                     ("rounded_polygon", tuple(map(tuple, offset.tolist())), float(radius[0])))
        out.append(Body(name, grains.kind, axes, scene.x[i].copy(), R[i], grain=grain))
    return out


def shape_title(title: str, scene: granstab.Scene) -> str:
    """A 2D shape scene's title with its contact words from the geometry now ("sharp tips" where every contact's ρ,
    the radius of curvature of p there, is below r, its distance to p's centre; "flat sides" above; "ρ/r = …" of a
    single contact): an ellipse turned to its flat side no longer says "sharp tips touching"."""
    if scene.dim != 2 or scene.n_contacts == 0:
        return title
    t = np.stack([-scene.normal[:, 1], scene.normal[:, 0]], axis=1)
    kappa = np.einsum("mi,mij,mj->m", t, scene.curvature_p, t)
    if np.any(kappa >= 0):                                     # a flat or concave side: no word to say
        return title
    rho_r = -1.0 / kappa / np.linalg.norm(scene.r_pq, axis=1)
    words = "sharp tips" if np.all(rho_r < 1) else "flat sides" if np.all(rho_r > 1) else None
    if words:
        title = re.sub(r"sharp tips|flat flanks|flat sides", words, title)
    return re.sub(r"ρ/r = [0-9.]+", f"ρ/r = {rho_r[0]:.2g}", title) if scene.n_contacts == 1 else title


def onto_cone(scene: granstab.Scene, mu: float) -> tuple[np.ndarray, tuple, np.ndarray]:
    """Contact forces (M, d) and states for friction coefficient `mu`: every compressive contact at the friction limit
    now (Scene.at_yield) or outside the new cone (|f_t| > μ f_n, not "elastic") gets |f_t| = μ f_n along its own
    tangential direction and the state "sliding" (eq:yield: Q = 0); at μ = 0 no tangential force and the state
    "auto" (a frictionless contact has no sliding direction, eq:Hdirection). Returns (force, state, moved (M,))."""
    fdotn = np.sum(scene.force * scene.normal, axis=1)            # < 0: compressive
    ft = scene.tangential_force()
    size = np.linalg.norm(ft, axis=1)
    state = np.asarray(scene.state, dtype=object)
    outside = (state == "auto") & (size > mu * -fdotn * (1 + scene.tol.yield_rtol))
    moved = (fdotn < 0) & (size > 0) & (scene.at_yield() | outside)
    scale = np.where(moved, mu * -fdotn / np.where(size > 0, size, 1.0), 1.0)
    force = fdotn[:, None] * scene.normal + scale[:, None] * ft
    state = np.where(moved, "sliding" if mu > 0 else "auto", state)
    return force, tuple(state), moved


def contact_sockets(scene: granstab.Scene) -> dict[int, tuple]:
    """The concave sides of a 2D scene's contacts, by particle index: for each, (cx, cy, ρ, angle) — the circle of
    curvature of its surface at the contact, radius ρ = 1/κ about a centre outside the particle (relative to the
    particle's centre), and the direction (angle) from that centre to the contact point. κ = t·K·t along the contact
    tangent t: < 0 convex, > 0 concave (as in app.meshes.circle_data); sides flatter than ρ = 10⁶ × the contact's
    distance from the particle's centre are drawn flat. Vectorised over contacts: a packing has thousands."""
    t = np.stack([-scene.normal[:, 1], scene.normal[:, 0]], axis=1)
    out: dict[int, list] = {}
    for index, K, r, sign in ((scene.p, scene.curvature_p, scene.r_pq, -1.0),
                              (scene.q, scene.curvature_q, scene.r_qp, 1.0)):
        kappa = np.einsum("ci,cij,cj->c", t, K, t)
        for c in np.flatnonzero(kappa * np.linalg.norm(r, axis=1) > 1e-6):
            rho = 1.0 / kappa[c]
            centre = scene.point[c] - sign * rho * scene.normal[c] - scene.x[index[c]]
            angle = np.arctan2(sign * scene.normal[c, 1], sign * scene.normal[c, 0])
            out.setdefault(int(index[c]), []).append((float(centre[0]), float(centre[1]), float(rho), float(angle)))
    return {i: tuple(v) for i, v in out.items()}


def cell_edges(scene: granstab.Scene) -> np.ndarray | None:
    """The periodic cell's outline as segments (E, 2, d): the parallelogram (2D, 4 edges) or parallelepiped (3D, 12)
    spanned by the lattice vectors, centred on the particles' centroid (a packing whose positions fill one period
    sits in it); None for a scene without a cell."""
    if scene.cell is None:
        return None
    corners = np.array(list(itertools.product((0, 1), repeat=scene.dim)))
    pairs = [(i, j) for i in range(len(corners)) for j in range(i + 1, len(corners))
             if np.abs(corners[i] - corners[j]).sum() == 1]
    points = scene.x.mean(axis=0) - 0.5 * scene.cell.sum(axis=0) + corners @ scene.cell
    return np.array([[points[i], points[j]] for i, j in pairs])


IMAGE_REACH = 2.0      # periodic images are drawn for particles within this many sizes (Session.size) of a face


def periodic_images(scene: granstab.Scene, reach: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The periodic images drawn beside the cell: every particle within `reach` of a face of the outline
    (cell_edges), copied across to the opposite side by the lattice shift n @ cell, n in {-1, 0, 1}^d other than 0
    (near a corner: a copy across each face, edge and corner it is near). Returns (index (G,), shift (G, d)): ghost g is
    x[index[g]] + shift[g] (ghost_positions); None for a scene without a cell."""
    if scene.cell is None:
        return None
    inv = np.linalg.inv(scene.cell)
    frac = (scene.x - scene.x.mean(axis=0) + 0.5 * scene.cell.sum(axis=0)) @ inv     # fractional, outline = [0, 1]^d
    margin = reach * np.linalg.norm(inv, axis=0)            # reach in fractions: face i is 1/|column i of inv| apart
    near = {1: frac < margin, -1: frac > 1 - margin}        # copied by +a_i (near face 0) or -a_i (near face 1)
    index, shift = [], []
    for n in itertools.product((-1, 0, 1), repeat=scene.dim):
        if not any(n):
            continue
        chosen = np.all([near[ni][:, i] for i, ni in enumerate(n) if ni], axis=0)
        index.append(np.flatnonzero(chosen))
        shift.append(np.broadcast_to(np.asarray(n, float) @ scene.cell, (int(chosen.sum()), scene.dim)))
    return np.concatenate(index), np.concatenate(shift)


def ghost_positions(x: np.ndarray, images: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The ghosts' positions (G, d) for particle positions x (N, d): a displaced packing's ghosts move with their
    particles (a periodic mode moves every copy of a particle alike)."""
    index, shift = images
    return x[index] + shift


def model_for_scene(scene: granstab.Scene, grains=None):
    """The two-particle model if the scene is the symmetric pair (of disks), else a contact-level model (drawn with
    its `grains`' true shapes where given)."""
    if grains is not None:
        return ContactModel(scene, grains=grains)
    return TwoParticleModel.from_scene(scene) or ContactModel(scene)


def read_scene_file(path) -> dict:
    """Parse a TOML or JSON scene file into a dict (one-line SceneError naming the file on failure)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise granstab.SceneError(f"{path}: cannot read file ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        return json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise granstab.SceneError(f"{path}: malformed {path.suffix.lstrip('.').upper() or 'TOML'}: "
                                  + " ".join(str(exc).split())) from None


def model_from_dict(data, source: str):
    """The model of a parsed scene file: shape format → ShapeModel, contact level → pair or ContactModel."""
    if shapefile.is_shape_scene(data):
        return ShapeModel.from_dict(data, source)
    scene = granstab.scene_from_dict(data, source=source)
    return model_for_scene(scene, grains.from_particles(data["particles"], scene.dim, source))


def _opened(path):
    """granstab.io.open of `path`, kept while its files are unchanged: another frame is one read, not a re-index."""
    import os
    files = [e.path for e in os.scandir(path) if e.is_file()] if os.path.isdir(path) else [path]
    stamp = tuple((f, s.st_mtime_ns, s.st_size) for f in files if (s := os.stat(f) if os.path.exists(f) else None))
    return _open_cached(os.fspath(path), stamp)


@functools.lru_cache(maxsize=4)
def _open_cached(path: str, stamp: tuple):
    from granstab.io import open as open_input
    return open_input(path)


def load_model(path, frame=None):
    """The model of a scene file (TOML/JSON, shape or contact format; NPZ) or of anything else `granstab.load_scene`
    reads (DEM snapshots, RigidLibrary folders: granstab.io.load, with its validation report and frames);
    raises SceneError with one line."""
    from granstab.io import format_report, is_snapshot
    if is_snapshot(path):
        imported = _opened(path).read(frame)           # indexed once per file version (granstab.io.open)
        frames = list(imported.frames) if imported.frames else None
        return ContactModel(imported.scene, report=format_report(imported.report), frames=frames,
                            frame=imported.report.get("frame"), path=str(path), grains=grains.from_loaded(imported))
    if Path(path).suffix.lower() == ".npz":           # a binary scene (save_scene), with its grains' shapes
        binary = granstab.io.load(path)
        return model_for_scene(binary.scene, binary.grains)
    return model_from_dict(read_scene_file(path), str(path))


__all__ = [
    "Body",
    "ContactModel",
    "IMAGE_REACH",
    "ShapeModel",
    "TwoParticleModel",
    "cell_edges",
    "contact_sockets",
    "ghost_positions",
    "grain_bodies",
    "load_model",
    "model_for_scene",
    "model_from_dict",
    "periodic_images",
    "read_scene_file",
]
