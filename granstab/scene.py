"""Scenes: particles and contact-level data (Sec. 2), read from a parsed TOML/JSON file (files.py) and validated.

A `Scene` holds arrays over particles (N) and contacts (M); d = dim, r = 1 (2D) or 3 (3D):
x (N, d), load b (N, d), load_moment w (N, r); per contact p, q (M,), point (M, d),
normal n^pq (M, d), curvature_p/q K (M, d, d) on the tangent plane (2D: κ t⊗t), force f^pq (M, d),
moment m^pq (M, r), k, alpha, mu (M,), rolling M^pq (M, r, r) and state ("auto" | "elastic" | "sliding").

Every invalid input raises `SceneError` with ONE line: "<file>: <entry>: <field>: <what is wrong>".
Loads default to equilibrium, b^p = -Σ f^pq and w^p = -Σ (r^pq × f^pq + m^pq) (eq:equil1).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .reading import Reader, SceneError, read_law
from .tolerances import DEFAULT, Tolerances
from .vec import cross, rot_dim, tangent_basis

STATES = ("auto", "elastic", "sliding")
LAW_KEYS = ("k", "alpha", "mu", "rolling_stiffness")
TOP_KEYS = {"dim", "title", "defaults", "particles", "contacts"}
PARTICLE_KEYS = {"name", "x", "load", "moment", "mass", "inertia"}
CONTACT_KEYS = {"p", "q", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "state", *LAW_KEYS}
LAW_DEFAULTS = {"k": 1.0, "alpha": 1.0, "mu": 0.5, "rolling_stiffness": 0.0}


@dataclass(frozen=True, eq=False)
class Scene:
    """Contact-level description of a cluster (see module docstring for shapes)."""

    dim: int
    names: tuple
    x: np.ndarray
    p: np.ndarray
    q: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    curvature_p: np.ndarray
    curvature_q: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    k: np.ndarray
    alpha: np.ndarray
    mu: np.ndarray
    rolling: np.ndarray
    state: tuple
    load: np.ndarray
    load_moment: np.ndarray
    title: str = ""
    source: str = "<scene>"
    tol: Tolerances = field(default=DEFAULT)
    mass: np.ndarray | None = None        # (N,) masses, for the inertia metric (metric.py); None: not known
    inertia: np.ndarray | None = None     # (N, r, r) rotational inertia in the global frame

    @property
    def n_particles(self) -> int:
        return len(self.names)

    @property
    def n_contacts(self) -> int:
        return len(self.p)

    @property
    def dof_per_particle(self) -> int:
        return self.dim + rot_dim(self.dim)

    @property
    def n_dof(self) -> int:
        return self.n_particles * self.dof_per_particle

    @property
    def r_pq(self) -> np.ndarray:
        """Radial vectors r^pq = contact point - x^p, (M, d)."""
        return self.point - self.x[self.p]

    @property
    def r_qp(self) -> np.ndarray:
        return self.point - self.x[self.q]

    @property
    def has_moments(self) -> bool:
        return bool(np.any(self.moment != 0.0))

    @property
    def has_rolling(self) -> bool:
        return bool(np.any(self.rolling != 0.0))

    def tangential_force(self) -> np.ndarray:
        """f^pq - (n·f^pq) n, (M, d)."""
        fn = np.sum(self.force * self.normal, axis=1)
        return self.force - fn[:, None] * self.normal

    def yield_function(self) -> np.ndarray:
        """Q^pq = |f_t| + μ f·n (eq:yield), (M,)."""
        fn = np.sum(self.force * self.normal, axis=1)
        return np.linalg.norm(self.tangential_force(), axis=1) + self.mu * fn

    def at_yield(self) -> np.ndarray:
        """Potentially sliding contacts (Appendix D mask ±1): state "sliding", or "auto" with Q = 0 within
        yield_rtol·|f| and a tangential force to slide along. Zero-force and frictionless normal contacts
        have no sliding direction h (eq:Hdirection) and stay elastic."""
        state = np.asarray(self.state)
        ft = np.linalg.norm(self.tangential_force(), axis=1)
        scale = np.linalg.norm(self.force, axis=1)
        auto = (state == "auto") & (self.yield_function() >= -self.tol.yield_rtol * scale) & (ft > 0)
        return (state == "sliding") | auto

    def dofs(self) -> list[str]:
        """Dof labels: particles in file order, translations then rotations (p.u1, p.u2, p.th3 …)."""
        rot = ["th3"] if self.dim == 2 else ["th1", "th2", "th3"]
        labels = [f"u{i + 1}" for i in range(self.dim)] + rot
        return [f"{name}.{lab}" for name in self.names for lab in labels]

    def to_dict(self) -> dict:
        """The scene in the file format (contact level); `scene_from_dict` reads it back to the same arrays."""
        def scalar_or_list(a):
            a = np.asarray(a)
            return float(a.reshape(-1)[0]) if a.size == 1 else a.tolist()

        def curvature(K, n):
            if self.dim == 2:
                t = tangent_basis(n)[:, 0]
                return float(t @ K @ t)
            return K.tolist()

        particles = []
        for i, name in enumerate(self.names):
            particles.append({"name": name, "x": self.x[i].tolist(), "load": self.load[i].tolist(),
                              "moment": scalar_or_list(self.load_moment[i])})
            if self.mass is not None:
                particles[-1].update(mass=float(self.mass[i]), inertia=scalar_or_list(self.inertia[i]))
        contacts = []
        for c in range(self.n_contacts):
            contacts.append({
                "p": self.names[self.p[c]], "q": self.names[self.q[c]],
                "point": self.point[c].tolist(), "normal": self.normal[c].tolist(),
                "curvature_p": curvature(self.curvature_p[c], self.normal[c]),
                "curvature_q": curvature(self.curvature_q[c], self.normal[c]),
                "force": self.force[c].tolist(), "moment": scalar_or_list(self.moment[c]),
                "k": float(self.k[c]), "alpha": float(self.alpha[c]), "mu": float(self.mu[c]),
                "rolling_stiffness": scalar_or_list(self.rolling[c]), "state": self.state[c],
            })
        return {"dim": self.dim, "title": self.title, "particles": particles, "contacts": contacts}


# ----------------------------------------------------------------------------------------------- reading

def contact_scene_from_dict(data, source: str = "<scene>", tol: Tolerances = DEFAULT) -> Scene:
    """Build and validate a Scene from the parsed contact-level file format (a dict); files.py dispatches."""
    top, dim, title = read_header(data, source, TOP_KEYS)
    r = rot_dim(dim)
    base_law = {**LAW_DEFAULTS, "rolling_stiffness": np.zeros((r, r))}
    law = read_law(Reader(source, "defaults", data.get("defaults", {}), set(LAW_KEYS)), dim, base_law)

    def read_particle(rd: Reader, name: str):
        load = rd.array("load", (dim,)) if rd.has("load") else None
        moment = rd.array("moment", () if dim == 2 else (3,)) if rd.has("moment") else None
        return name, rd.array("x", (dim,)), load, moment, _read_mass(rd, dim, tol)

    names, x, loads, load_moments, masses = zip(*read_particles(top, data, PARTICLE_KEYS, read_particle))
    mass, inertia = _collect_masses(source, names, masses)
    index = {name: i for i, name in enumerate(names)}

    contacts = data.get("contacts", [])
    if not isinstance(contacts, list):
        top.fail("contacts", "must be an array of tables")
    cols = {key: [] for key in ("p", "q", "point", "normal", "curvature_p", "curvature_q", "force", "moment",
                                "k", "alpha", "mu", "rolling", "state")}
    entries = []
    seen = {}
    for c, item in enumerate(contacts):
        rd = Reader(source, f"contacts[{c}]", item, CONTACT_KEYS)
        pn, qn = rd.text("p"), rd.text("q")
        rd.entry = f"contacts[{c}] ({pn}-{qn})"
        for key, name in (("p", pn), ("q", qn)):
            if name not in index:
                rd.fail(key, f"unknown particle {name!r}")
        if pn == qn:
            rd.fail("q", "a particle cannot touch itself (p = q)")
        pair = frozenset((pn, qn))
        if pair in seen:
            rd.fail("q", f"duplicate contact between {pn!r} and {qn!r} (also contacts[{seen[pair]}])")
        seen[pair] = c
        entries.append(rd.entry)
        cols["p"].append(index[pn])
        cols["q"].append(index[qn])
        cols["point"].append(rd.array("point", (dim,)))
        normal = rd.array("normal", (dim,))
        norm = float(np.linalg.norm(normal))
        if abs(norm - 1.0) > tol.input_rtol:
            rd.fail("normal", f"must be a unit vector, |n| = {norm:.9g}")
        cols["normal"].append(normal)
        for key in ("curvature_p", "curvature_q"):
            cols[key].append(_read_curvature(rd, key, dim, normal, tol))
        cols["force"].append(rd.array("force", (dim,)))
        cols["moment"].append(rd.array("moment", (r,), 0.0) if dim == 3 else rd.array("moment", (), 0.0).reshape(1))
        own = read_law(rd, dim, law)
        for key in ("k", "alpha", "mu"):
            cols[key].append(own[key])
        cols["rolling"].append(own["rolling_stiffness"])
        state = rd.text("state", "auto")
        if state not in STATES:
            rd.fail("state", f"must be one of {', '.join(STATES)}, got {state!r}")
        cols["state"].append(state)

    M = len(entries)
    arrays = {
        "p": np.array(cols["p"], dtype=np.intp), "q": np.array(cols["q"], dtype=np.intp),
        "point": np.array(cols["point"]).reshape(M, dim), "normal": np.array(cols["normal"]).reshape(M, dim),
        "curvature_p": np.array(cols["curvature_p"]).reshape(M, dim, dim),
        "curvature_q": np.array(cols["curvature_q"]).reshape(M, dim, dim),
        "force": np.array(cols["force"]).reshape(M, dim), "moment": np.array(cols["moment"]).reshape(M, r),
        "k": np.array(cols["k"]).reshape(M), "alpha": np.array(cols["alpha"]).reshape(M),
        "mu": np.array(cols["mu"]).reshape(M), "rolling": np.array(cols["rolling"]).reshape(M, r, r),
        "state": tuple(cols["state"]),
    }
    return build_scene(dim, list(names), np.array(x).reshape(-1, dim), arrays, list(loads), list(load_moments),
                       title=title, source=source, tol=tol, entries=entries, mass=mass, inertia=inertia)


def _read_mass(rd: Reader, dim: int, tol: Tolerances):
    """Optional `mass` (> 0) and `inertia` (2D: a number > 0; 3D: a symmetric positive definite 3x3 tensor in the
    global frame), both or neither: (mass, inertia) or None."""
    if not (rd.has("mass") or rd.has("inertia")):
        return None
    for key in ("mass", "inertia"):
        if not rd.has(key):
            rd.fail(key, "missing: the inertia metric needs both mass and inertia")
    mass = float(rd.number("mass"))
    if not mass > 0:
        rd.fail("mass", f"must be positive, got {mass:g}")
    if dim == 2:
        J = rd.array("inertia", ())
        if not J > 0:
            rd.fail("inertia", f"must be positive, got {float(J):g}")
        return mass, np.asarray(J, float).reshape(1, 1)
    J = rd.array("inertia", (3, 3))
    if np.abs(J - J.T).max() > tol.input_rtol * np.abs(J).max():
        rd.fail("inertia", "must be a symmetric 3x3 tensor")
    if np.linalg.eigvalsh(0.5 * (J + J.T)).min() <= 0:
        rd.fail("inertia", "must be positive definite")
    return mass, 0.5 * (J + J.T)


def _collect_masses(source: str, names, masses):
    """Masses of every particle or of none (a scene cannot mix): (mass (N,), inertia (N, r, r)) or (None, None)."""
    given = [m is not None for m in masses]
    if not any(given):
        return None, None
    if not all(given):
        i = given.index(False)
        raise SceneError(f"{source}: particles[{i}] ({names[i]!r}): mass: missing (other particles have masses: "
                         "give every particle mass and inertia, or none)")
    return np.array([m for m, _ in masses]), np.array([J for _, J in masses])


def read_header(data, source: str, allowed: set):
    """The top-level table: its reader, dim (2 or 3, required) and title (optional)."""
    top = Reader(source, "scene", data, allowed)
    if "dim" not in data:
        top.fail("dim", "missing (2 or 3)")
    dim = data["dim"]
    if dim not in (2, 3) or isinstance(dim, bool):
        top.fail("dim", f"must be 2 or 3, got {dim!r}")
    return top, dim, top.text("title", "") if "title" in data else ""


def read_particles(top: Reader, data: dict, allowed: set, read) -> list:
    """The `particles` array: one table each, with a unique name; `read(rd, name)` returns an entry's data."""
    particles = data.get("particles")
    if not isinstance(particles, list) or not particles:
        top.fail("particles", "must be a non-empty array of tables")
    out, index = [], {}
    for i, item in enumerate(particles):
        rd = Reader(top.source, f"particles[{i}]", item, allowed)
        name = rd.text("name")
        rd.entry = f"particles[{i}] ({name!r})"
        if name in index:
            rd.fail("name", f"duplicate particle name (also particles[{index[name]}])")
        index[name] = i
        out.append(read(rd, name))
    return out


def _read_curvature(rd: Reader, key: str, dim: int, normal: np.ndarray, tol: Tolerances) -> np.ndarray:
    """2D: scalar κ along t (convex < 0, κ = -1/ρ) → κ t⊗t; 3D: symmetric 3x3 with K·n = 0."""
    if dim == 2:
        kappa = float(rd.array(key, ()))
        t = tangent_basis(normal)[:, 0]
        return kappa * np.outer(t, t)
    K = rd.array(key, (3, 3))
    scale = max(float(np.abs(K).max()), 1e-300)
    if np.abs(K - K.T).max() > tol.input_rtol * scale:
        rd.fail(key, "curvature tensor must be symmetric")
    n = normal / np.linalg.norm(normal)
    if np.linalg.norm(K @ n) > tol.input_rtol * scale:
        rd.fail(key, f"curvature tensor must be tangent (K·n = 0), |K·n| = {np.linalg.norm(K @ n):.3g}")
    return K


def build_scene(dim, names, x, arrays, loads=None, load_moments=None, *, title="", source="<scene>",
                tol: Tolerances = DEFAULT, entries=None, mass=None, inertia=None) -> Scene:
    """Assemble a Scene from arrays (programmatic use: presets, studies, the app) and run the physical checks.

    `loads`/`load_moments` are lists with None where the equilibrium value is to be used (or None for all).
    `entries` names each contact for error messages (default "contacts[c]").
    """
    N = len(names)
    r = rot_dim(dim)
    M = len(arrays["p"])
    entries = entries or [f"contacts[{c}]" for c in range(M)]
    base = Scene(dim=dim, names=tuple(names), x=np.asarray(x, float).reshape(N, dim), load=np.zeros((N, dim)),
                 load_moment=np.zeros((N, r)), title=title, source=source, tol=tol, **arrays)
    _check_friction(base, entries)
    b_eq, w_eq = equilibrium_loads(base)
    load = b_eq.copy()
    load_moment = w_eq.copy()
    f_scale, m_scale = _load_scales(base)
    for i in range(N):
        entry = f"particles[{i}] ({names[i]!r})"
        if loads is not None and loads[i] is not None:
            res = float(np.linalg.norm(loads[i] - b_eq[i]))
            if res > tol.input_rtol * (f_scale[i] + np.linalg.norm(loads[i])):
                raise SceneError(f"{source}: {entry}: load: does not balance the contact forces "
                                 f"(residual |b + Σf| = {res:.3g}, expected {_fmt(b_eq[i])})")
            load[i] = loads[i]
        if load_moments is not None and load_moments[i] is not None:
            given = np.asarray(load_moments[i], float).reshape(r)
            res = float(np.linalg.norm(given - w_eq[i]))
            if res > tol.input_rtol * (m_scale[i] + np.linalg.norm(given)):
                raise SceneError(f"{source}: {entry}: moment: does not balance the contact moments "
                                 f"(residual |w + Σ(r×f + m)| = {res:.3g}, expected {_fmt(w_eq[i])})")
            load_moment[i] = given
    if mass is not None:
        mass = np.asarray(mass, float).reshape(N)
        inertia = np.asarray(inertia, float).reshape(N, r, r)
    return Scene(dim=dim, names=tuple(names), x=base.x, load=load, load_moment=load_moment, title=title,
                 source=source, tol=tol, mass=mass, inertia=inertia, **arrays)


def _fmt(v) -> str:
    v = np.asarray(v).reshape(-1)
    return "[" + ", ".join(f"{a:.6g}" for a in v) + "]" if v.size > 1 else f"{v[0]:.6g}"


def _check_friction(scene: Scene, entries) -> None:
    """Forces outside the friction cone ("auto") and "sliding" contacts not at yield are errors."""
    if scene.n_contacts == 0:
        return
    Q = scene.yield_function()
    fmag = np.linalg.norm(scene.force, axis=1)
    ft = np.linalg.norm(scene.tangential_force(), axis=1)
    state = np.asarray(scene.state)
    tol = scene.tol.yield_rtol * fmag
    outside = np.flatnonzero((state == "auto") & (Q > tol))
    if outside.size:
        c = outside[0]
        raise SceneError(f"{scene.source}: {entries[c]}: force: outside the friction cone, Q = {Q[c]:.6g} > 0 "
                         f"(|f_t| = {ft[c]:.6g}, μ|f_n| = {abs(Q[c] - ft[c]):.6g}); set state = \"elastic\" "
                         "for a cohesive contact")
    not_at_yield = np.flatnonzero((state == "sliding") & ((np.abs(Q) > tol) | (ft == 0)))
    if not_at_yield.size:
        c = not_at_yield[0]
        why = "no tangential force to slide along" if ft[c] == 0 else f"Q = {Q[c]:.6g} ≠ 0"
        raise SceneError(f"{scene.source}: {entries[c]}: state: \"sliding\" but not at yield ({why})")


def equilibrium_loads(scene: Scene):
    """b^p = -Σ f^pq, w^p = -Σ (r^pq × f^pq + m^pq) over both sides of every contact (eq:equil1)."""
    N, d, r = scene.n_particles, scene.dim, rot_dim(scene.dim)
    b = np.zeros((N, d))
    w = np.zeros((N, r))
    f = scene.force
    np.add.at(b, scene.p, -f)
    np.add.at(b, scene.q, f)
    np.add.at(w, scene.p, -(cross(scene.r_pq, f) + scene.moment))
    np.add.at(w, scene.q, -(cross(scene.r_qp, -f) - scene.moment))
    return b, w


def _load_scales(scene: Scene):
    """Σ|f| and Σ(|r||f| + |m|) over each particle's contacts: the scale of its load balance."""
    N = scene.n_particles
    fmag = np.linalg.norm(scene.force, axis=1)
    mmag = np.linalg.norm(scene.moment, axis=1)
    fs = np.zeros(N)
    ms = np.zeros(N)
    for side, rr in ((scene.p, scene.r_pq), (scene.q, scene.r_qp)):
        np.add.at(fs, side, fmag)
        np.add.at(ms, side, np.linalg.norm(rr, axis=1) * fmag + mmag)
    return fs, ms


__all__ = ["Scene", "SceneError", "contact_scene_from_dict", "build_scene", "equilibrium_loads"]
