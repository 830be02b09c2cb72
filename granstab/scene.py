"""Scenes: particles and contact-level data (Sec. 2), read from a parsed file (files.py) and validated.

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

from .fileformat import paused_gc
from .reading import Reader, SceneError, describe, first, read_law, row_problem
from .tables import ArrayTable, TextTable
from .tolerances import COORDINATE_RATIO, DEFAULT, MAX_MAGNITUDE, MIN_SCALE, Tolerances
from .vec import cross, rot_dim, sum_at, tangent_basis

STATES = ("auto", "elastic", "sliding")
LAW_KEYS = ("k", "alpha", "mu", "rolling_stiffness")
TOP_KEYS = {"dim", "title", "defaults", "particles", "contacts"}
PARTICLE_KEYS = {"name", "x", "load", "moment", "mass", "inertia", "fixed"}
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
    fixed: np.ndarray | None = None       # (N,) bool: particles held fixed (supports: no dofs, no rigid modes)

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

    def has_sliding_direction(self) -> np.ndarray:
        """|f_t| > yield_rtol·|f|: a tangential force that defines h = f_t/|f_t| (eq:Hdirection), (M,).

        A smaller |f_t| is within the yield test's own tolerance of zero and its direction is round-off (a rigid
        rotation of the scene turns an exact 0 into ~1e-16·|f|): treating it as a direction made the
        classification, and so the number of branches and the verdict, depend on the frame."""
        ft = np.linalg.norm(self.tangential_force(), axis=1)
        return ft > self.tol.yield_rtol * np.linalg.norm(self.force, axis=1)

    def at_yield(self) -> np.ndarray:
        """Potentially sliding contacts (Appendix D mask ±1): state "sliding", or "auto" with Q = 0 within
        yield_rtol·|f| and a tangential force to slide along (`has_sliding_direction`). Zero-force and
        frictionless normal contacts have no sliding direction h (eq:Hdirection) and stay elastic."""
        state = np.asarray(self.state)
        scale = np.linalg.norm(self.force, axis=1)
        auto = ((state == "auto") & (self.yield_function() >= -self.tol.yield_rtol * scale)
                & self.has_sliding_direction())
        return (state == "sliding") | auto

    @property
    def free_dofs(self) -> np.ndarray | None:
        """Indices of the dofs of the particles not held fixed; None when no particle is fixed."""
        if self.fixed is None:
            return None
        per = self.dof_per_particle
        return (np.flatnonzero(~self.fixed)[:, None] * per + np.arange(per)).ravel()

    def dofs(self) -> list[str]:
        """Dof labels: particles in file order, translations then rotations (p.u1, p.u2, p.th3 …)."""
        rot = ["th3"] if self.dim == 2 else ["th1", "th2", "th3"]
        labels = [f"u{i + 1}" for i in range(self.dim)] + rot
        return [f"{name}.{lab}" for name in self.names for lab in labels]

    def to_dict(self) -> dict:
        """The scene in the file format (contact level); `scene_from_dict` reads it back to the same arrays.
        Built column-wise from `scene_arrays` (numpy's tolist, then one zip per entry)."""
        cols = scene_arrays(self)
        names = cols["particles/name"]
        cols["contacts/p"], cols["contacts/q"] = names[self.p], names[self.q]      # the text format names them

        def rows(prefix: str, keys: tuple) -> list:
            return [dict(zip(keys, values)) for values in zip(*(cols[f"{prefix}/{k}"].tolist() for k in keys))]

        particle_keys = (("name", "x", "load", "moment") + (("mass", "inertia") if self.mass is not None else ())
                         + (("fixed",) if self.fixed is not None else ()))
        with paused_gc():
            return {"dim": self.dim, "title": self.title,
                    "particles": rows("particles", particle_keys),
                    "contacts": rows("contacts", ("p", "q", "point", "normal", "curvature_p", "curvature_q",
                                                  "force", "moment", "k", "alpha", "mu", "rolling_stiffness",
                                                  "state"))}


# ----------------------------------------------------------------------------------------------- reading

def contact_scene_from_dict(data, source: str = "<scene>", tol: Tolerances = DEFAULT) -> Scene:
    """Build and validate a Scene from the parsed contact-level file format (a dict); files.py dispatches."""
    top, dim, title = read_header(data, source, TOP_KEYS)
    law = read_law(Reader(source, "defaults", data.get("defaults", {}), set(LAW_KEYS)), dim, _base_law(dim))
    if not isinstance(data.get("particles"), list) or not data["particles"]:
        top.fail("particles", "must be a non-empty array of tables")
    particles = TextTable(source, "particles", data["particles"], PARTICLE_KEYS)
    contacts = TextTable(source, "contacts", data.get("contacts", []), CONTACT_KEYS)
    return _scene_from_tables(dim, title, law, particles, contacts, source, tol)


NPZ_META = ("dim", "title")


def scene_arrays(scene: Scene) -> dict:
    """The file format as whole arrays (NPZ): `particles/<field>` and `contacts/<field>` over the entries, the
    same fields and units as the text format (2D curvatures and moments as scalars; p, q as 0-based particle
    indices, which scene_from_arrays also accepts as names)."""
    names = np.array(scene.names, dtype=str)
    scalar = scene.dim == 2
    out = {"dim": np.array(scene.dim), "title": np.array(scene.title, dtype=str),
           "particles/name": names, "particles/x": scene.x, "particles/load": scene.load,
           "particles/moment": scene.load_moment[:, 0] if scalar else scene.load_moment,
           "contacts/p": scene.p, "contacts/q": scene.q, "contacts/point": scene.point,
           "contacts/normal": scene.normal, "contacts/force": scene.force,
           "contacts/moment": scene.moment[:, 0] if scalar else scene.moment,
           "contacts/k": scene.k, "contacts/alpha": scene.alpha, "contacts/mu": scene.mu,
           "contacts/rolling_stiffness": scene.rolling[:, 0, 0] if scalar else scene.rolling,
           "contacts/state": np.array(scene.state, dtype=str).reshape(scene.n_contacts)}
    for key in ("curvature_p", "curvature_q"):
        K = getattr(scene, key)
        out[f"contacts/{key}"] = _kappa(K, scene.normal) if scalar else K
    if scene.fixed is not None:
        out["particles/fixed"] = scene.fixed
    if scene.mass is not None:
        out["particles/mass"] = scene.mass
        out["particles/inertia"] = scene.inertia[:, 0, 0] if scalar else scene.inertia
    return out


def _kappa(K: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """2D curvature tensors κ t⊗t back to κ = tᵀKt (M,)."""
    t = tangent_basis(normal)[:, :, 0]
    return np.einsum("mi,mij,mj->m", t, K, t)


def scene_from_arrays(arrays: dict, source: str = "<scene>", tol: Tolerances = DEFAULT) -> Scene:
    """Build and validate a Scene from `scene_arrays`' dict (an .npz file): the same checks as the text format."""
    allowed = {*NPZ_META, *(f"particles/{k}" for k in PARTICLE_KEYS), *(f"contacts/{k}" for k in CONTACT_KEYS)}
    unknown = sorted(set(arrays) - allowed)
    if unknown:
        raise SceneError(f"{source}: {unknown[0]}: unknown array (allowed: {', '.join(sorted(allowed))})")
    meta = {}
    for key in NPZ_META:
        value = arrays.get(key)
        if value is not None and value.shape != ():
            raise SceneError(f"{source}: {key}: must be a single value, got shape {value.shape}")
        if value is not None:
            meta[key] = value.item()
    top, dim, title = read_header(meta, source, set(NPZ_META))

    def table(prefix: str) -> ArrayTable:
        cols = {key.split("/", 1)[1]: value for key, value in arrays.items() if key.startswith(prefix + "/")}
        lengths = {key: len(value) if value.ndim else -1 for key, value in cols.items()}
        n = lengths.get("name" if prefix == "particles" else "p", 0)
        wrong = next((key for key, m in lengths.items() if m != n), None)
        if wrong is not None:
            raise SceneError(f"{source}: {prefix}/{wrong}: has {lengths[wrong]} rows, expected {n}")
        return ArrayTable(source, prefix, cols, n)

    particles, contacts = table("particles"), table("contacts")
    if not len(particles):
        top.fail("particles", "must be a non-empty array")
    return _scene_from_tables(dim, title, _base_law(dim), particles, contacts, source, tol)


def _base_law(dim: int) -> dict:
    r = rot_dim(dim)
    return {**LAW_DEFAULTS, "rolling_stiffness": np.zeros((r, r))}


def _scene_from_tables(dim, title, law, particles, contacts, source, tol) -> Scene:
    """The schema, column by column (vectorised): particles' names, positions and optional loads; contacts'
    particles, geometry, forces, law and state. Errors name the first bad entry and its field."""
    r = rot_dim(dim)
    names = particles.strings("name")
    index = dict(zip(names, range(len(names))))
    if len(index) != len(names):
        seen = {}
        for i, name in enumerate(names):
            if name in seen:
                particles.label = lambda j: f"particles[{j}] ({names[j]!r})"
                particles.fail(i, "name", f"duplicate particle name (also particles[{seen[name]}])")
            seen[name] = i
    particles.label = lambda j: f"particles[{j}] ({names[j]!r})"
    x = particles.numbers("x", (dim,))
    moment_shape = () if dim == 2 else (3,)
    loads = (particles.numbers("load", (dim,), 0.0), particles.present("load"))
    moments = (particles.numbers("moment", moment_shape, 0.0).reshape(-1, r), particles.present("moment"))
    mass, inertia = _mass_columns(particles, dim, tol)
    fixed = _fixed_column(particles)

    M = len(contacts)
    p, q = _particle_column(contacts, "p", names, index), _particle_column(contacts, "q", names, index)
    contacts.label = lambda c: f"contacts[{c}] ({names[p[c]]}-{names[q[c]]})"
    if np.any(p == q):
        contacts.fail(first(p == q), "q", "a particle cannot touch itself (p = q)")
    _check_unique_pairs(contacts, p, q, names)
    normal = contacts.numbers("normal", (dim,))
    norm = np.linalg.norm(normal, axis=1)
    bad = np.abs(norm - 1.0) > tol.input_rtol
    if bad.any():
        c = first(bad)
        contacts.fail(c, "normal", f"must be a unit vector, |n| = {norm[c]:.9g}")
    arrays = {"p": p, "q": q, "point": contacts.numbers("point", (dim,)), "normal": normal,
              "curvature_p": _curvature_column(contacts, "curvature_p", dim, normal, tol),
              "curvature_q": _curvature_column(contacts, "curvature_q", dim, normal, tol),
              "force": contacts.numbers("force", (dim,)),
              "moment": contacts.numbers("moment", moment_shape, 0.0).reshape(M, r)}
    for key, low, strict in (("k", 0.0, True), ("alpha", 0.0, True), ("mu", 0.0, False)):
        values = contacts.numbers(key, (), law[key])
        bad = values <= low if strict else values < low
        if bad.any():
            c = first(bad)
            contacts.fail(c, key, f"must be {'>' if strict else '>='} 0, got {values[c]}")
        arrays[key] = values
    arrays["rolling"] = _rolling_column(contacts, dim, law["rolling_stiffness"])
    state = contacts.strings("state", "auto")
    wrong = set(state) - set(STATES)
    if wrong:
        c = state.index(sorted(wrong)[0])
        contacts.fail(c, "state", f"must be one of {', '.join(STATES)}, got {state[c]!r}")
    arrays["state"] = tuple(state)
    return build_scene(dim, names, x, arrays, loads, moments, title=title, source=source, tol=tol,
                       entries=contacts.label, particle_entries=particles.label, mass=mass, inertia=inertia,
                       fixed=fixed)


def _fixed_column(particles) -> np.ndarray | None:
    """Optional `fixed` (true/false) of each particle: a support with no dofs (absent: false). None if none is."""
    values, have = particles.raw("fixed")
    flags = np.zeros(len(particles), bool)
    if not have.any():
        return None
    given = np.asarray(values)
    if given.dtype != bool or given.shape != (int(have.sum()),):
        j = next((j for j, v in enumerate(values) if not isinstance(v, (bool, np.bool_))), 0)
        particles.fail(int(np.flatnonzero(have)[j]), "fixed", f"must be true or false, got {describe(values[j])}")
    flags[have] = given
    if flags.all():
        particles.fail(0, "fixed", "every particle is fixed: at least one must be free to move")
    return flags if flags.any() else None


def _particle_column(table, key: str, names: list, index: dict) -> np.ndarray:
    """Particle indices of a contact's p or q: names (text and NPZ) or, in NPZ, 0-based indices into the particles
    (what save_scene writes: no string work for 10⁶ contacts). An unknown particle names the contact."""
    given, _ = table.raw(key)
    if isinstance(given, np.ndarray) and given.dtype.kind in "iu":
        if given.shape != (len(table),):
            table.fail(None, key, f"must have shape ({len(table)},), got {given.shape}")
        bad = (given < 0) | (given >= len(names))
        if bad.any():
            table.fail(first(bad), key, f"particle index {given[first(bad)]} is not in 0..{len(names) - 1}")
        return given.astype(np.intp)
    labels = table.strings(key)
    found = list(map(index.get, labels))
    if None in found:
        c = found.index(None)
        table.label = lambda i: f"{table.name}[{i}]"
        table.fail(c, key, f"unknown particle {labels[c]!r}")
    return np.array(found, dtype=np.intp).reshape(len(labels))


def _check_unique_pairs(table, p: np.ndarray, q: np.ndarray, names: list) -> None:
    """One contact per unordered pair: the first repeat (in file order) is an error naming both entries."""
    if len(p) < 2:
        return
    key = np.minimum(p, q).astype(np.int64) * (max(p.max(), q.max()) + 1) + np.maximum(p, q)
    order = np.argsort(key, kind="stable")
    same = key[order][1:] == key[order][:-1]
    if same.any():
        later = order[1:][same]
        c = int(later.min())
        j = int(order[:-1][same][np.argmin(later)])
        table.fail(c, "q", f"duplicate contact between {names[p[c]]!r} and {names[q[c]]!r} (also contacts[{j}])")


def _curvature_column(table, key: str, dim: int, normal: np.ndarray, tol: Tolerances) -> np.ndarray:
    """2D: scalar κ along t (convex < 0, κ = -1/ρ) → κ t⊗t; 3D: symmetric 3x3 with K·n = 0 (input_rtol·|K|)."""
    if dim == 2:
        t = tangent_basis(normal)[:, :, 0]
        return table.numbers(key, ())[:, None, None] * (t[:, :, None] * t[:, None, :])
    K = table.numbers(key, (3, 3))
    scale = np.maximum(np.abs(K).max(axis=(1, 2), initial=0.0), 1e-300)
    asym = np.abs(K - np.swapaxes(K, 1, 2)).max(axis=(1, 2), initial=0.0)
    if np.any(asym > tol.input_rtol * scale):
        table.fail(first(asym > tol.input_rtol * scale), key, "curvature tensor must be symmetric")
    n = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    Kn = np.linalg.norm(np.einsum("mij,mj->mi", K, n), axis=1)
    if np.any(Kn > tol.input_rtol * scale):
        c = first(Kn > tol.input_rtol * scale)
        table.fail(c, key, f"curvature tensor must be tangent (K·n = 0), |K·n| = {Kn[c]:.3g}")
    return K


def _rolling_column(table, dim: int, default: np.ndarray) -> np.ndarray:
    """M^pq per contact: a scalar (× I; >= 0) in 2D, a scalar or a 3x3 matrix in 3D; the defaults elsewhere."""
    r = rot_dim(dim)
    key = "rolling_stiffness"
    matrix = table.matrix_form(key) if dim == 3 else np.zeros(len(table), bool)
    scalar = table.present(key) & ~matrix
    out = np.broadcast_to(default, (len(table), r, r)).copy()
    if scalar.any():
        value = table.numbers(key, (), 0.0, where=scalar)
        if np.any(value < 0):
            table.fail(first(value < 0), key, f"must be >= 0, got {value[first(value < 0)]}")
        out[scalar] = value[scalar, None, None] * np.eye(r)
    if matrix.any():
        out[matrix] = table.numbers(key, (3, 3), 0.0, where=matrix)[matrix]
    return out


def _mass_columns(table, dim: int, tol: Tolerances):
    """Optional `mass` (> 0) and `inertia` (2D: a number > 0; 3D: a symmetric positive definite 3x3 tensor in the
    global frame) of every particle, or of none: (mass (N,), inertia (N, r, r)) or (None, None)."""
    has_m, has_j = table.present("mass"), table.present("inertia")
    if not (has_m.any() or has_j.any()):
        return None, None
    both = has_m & has_j
    if not both.all():
        i = first(~both)
        table.fail(i, "mass" if not has_m[i] else "inertia",
                   "missing: the inertia metric needs mass and inertia for every particle (or for none)")
    mass = table.numbers("mass", ())
    if np.any(mass <= 0):
        table.fail(first(mass <= 0), "mass", f"must be positive, got {mass[first(mass <= 0)]:g}")
    if dim == 2:
        J = table.numbers("inertia", ())
        if np.any(J <= 0):
            table.fail(first(J <= 0), "inertia", f"must be positive, got {J[first(J <= 0)]:g}")
        return mass, J.reshape(-1, 1, 1)
    J = table.numbers("inertia", (3, 3))
    asym = np.abs(J - np.swapaxes(J, 1, 2)).max(axis=(1, 2))
    bad = asym > tol.input_rtol * np.abs(J).max(axis=(1, 2))
    if bad.any():
        table.fail(first(bad), "inertia", "must be a symmetric 3x3 tensor")
    J = 0.5 * (J + np.swapaxes(J, 1, 2))
    bad = np.linalg.eigvalsh(J).min(axis=1) <= 0
    if bad.any():
        table.fail(first(bad), "inertia", "must be positive definite")
    return mass, J


def read_header(data, source: str, allowed: set):
    """The top-level table: its reader, dim (the integer 2 or 3, required) and title (optional)."""
    top = Reader(source, "scene", data, allowed)
    if "dim" not in data:
        top.fail("dim", "missing (2 or 3)")
    dim = data["dim"]
    if type(dim) is not int or dim not in (2, 3):
        top.fail("dim", f"must be the integer 2 or 3, got {describe(dim)}")
    title = data.get("title", "")
    if not isinstance(title, str):
        top.fail("title", f"must be a string, got {describe(title)}")
    return top, int(dim), title


def read_particles(top: Reader, data: dict, allowed: set, read) -> list:
    """The `particles` array of a shape scene (small): one table each, with a unique name; `read(rd, name)`
    returns an entry's data."""
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


def build_scene(dim, names, x, arrays, loads=None, load_moments=None, *, title="", source="<scene>",
                tol: Tolerances = DEFAULT, entries=None, particle_entries=None, mass=None, inertia=None,
                fixed=None) -> Scene:
    """Assemble a Scene from arrays (programmatic use: presets, studies, the app) and run the range and
    physical checks (vectorised); `mass` (N,) and `inertia` (N, r, r) are optional (the inertia metric); `fixed`
    (N,) bool marks supports (particles without dofs).

    `loads`/`load_moments`: None (equilibrium values for all), a list with None where the equilibrium value is
    to be used, or a pair (values (N, ·), given (N,) bool). `entries` names contacts in error messages: a list
    or a function c → name (default "contacts[c]"); `particle_entries` likewise for particles.
    """
    N = len(names)
    r = rot_dim(dim)
    contact_name = _namer(entries, "contacts")
    particle_name = _namer(particle_entries, None) or (lambda i: f"particles[{i}] ({names[i]!r})")
    base = Scene(dim=dim, names=tuple(names), x=np.asarray(x, float).reshape(N, dim), load=np.zeros((N, dim)),
                 load_moment=np.zeros((N, r)), title=title, source=source, tol=tol, **arrays)
    given_b, has_b = _given(loads, N, dim)
    given_w, has_w = _given(load_moments, N, r)
    check_ranges(base, contact_name, particle_name, (given_b, given_w))
    _check_friction(base, contact_name)
    b_eq, w_eq = equilibrium_loads(base)
    f_scale, m_scale = _load_scales(base)
    for given, has, eq, scale, key, what in ((given_b, has_b, b_eq, f_scale, "load", "|b + Σf|"),
                                             (given_w, has_w, w_eq, m_scale, "moment", "|w + Σ(r×f + m)|")):
        res = np.linalg.norm(given - eq, axis=1)
        bad = has & (res > tol.input_rtol * (scale + np.linalg.norm(given, axis=1)))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise SceneError(f"{source}: {particle_name(i)}: {key}: does not balance the contact "
                             f"{'forces' if key == 'load' else 'moments'} (residual {what} = {res[i]:.3g}, "
                             f"expected {_fmt(eq[i])})")
    load = np.where(has_b[:, None], given_b, b_eq)
    load_moment = np.where(has_w[:, None], given_w, w_eq)
    if mass is not None:
        mass = np.asarray(mass, float).reshape(N)
        inertia = np.asarray(inertia, float).reshape(N, r, r)
    fixed = None if fixed is None or not np.any(fixed) else np.asarray(fixed, bool).reshape(N)
    return Scene(dim=dim, names=tuple(names), x=base.x, load=load, load_moment=load_moment, title=title,
                 source=source, tol=tol, mass=mass, inertia=inertia, fixed=fixed, **arrays)


def _namer(entries, prefix):
    if callable(entries):
        return entries
    if entries is not None:
        return entries.__getitem__
    return (lambda c: f"{prefix}[{c}]") if prefix else None


def _given(values, N: int, width: int):
    """Optional per-particle loads as (values (N, width), given (N,) bool) from None, a list with None, or a pair."""
    if values is None:
        return np.zeros((N, width)), np.zeros(N, bool)
    if isinstance(values, tuple) and len(values) == 2 and isinstance(values[1], np.ndarray):
        return np.asarray(values[0], float).reshape(N, width), np.asarray(values[1], bool).reshape(N)
    has = np.array([v is not None for v in values], bool).reshape(N)
    out = np.zeros((N, width))
    for i in np.flatnonzero(has):
        out[i] = np.asarray(values[i], float).reshape(width)
    return out, has


def check_ranges(scene: Scene, contact_name, particle_name, given=()) -> None:
    """Every number finite with |v| <= MAX_MAGNITUDE; k and α >= MIN_SCALE; positions and contact points within
    COORDINATE_RATIO mean contact radii of the origin (beyond it r^pq = point - x loses more than input_rtol to
    rounding). The first offender is named with its entry and field."""
    per_contact = {"point": scene.point, "normal": scene.normal, "curvature_p": scene.curvature_p,
                   "curvature_q": scene.curvature_q, "force": scene.force, "moment": scene.moment, "k": scene.k,
                   "alpha": scene.alpha, "mu": scene.mu, "rolling_stiffness": scene.rolling}
    M = scene.n_contacts
    for key, arr in per_contact.items():
        _check_magnitude(_rows(arr, M), scene.source, contact_name, key)
    for key, arr in (("x", scene.x), ("load", given[0] if given else None), ("moment", given[1] if given else None)):
        if arr is not None:
            _check_magnitude(_rows(arr, scene.n_particles), scene.source, particle_name, key)
    for key, arr in (("k", scene.k), ("alpha", scene.alpha)):
        small = (arr != 0) & (np.abs(arr) < MIN_SCALE)     # 0 is exact (alpha = 0: frictionless)
        if small.any():
            c = first(small)
            raise SceneError(f"{scene.source}: {contact_name(c)}: {key}: {arr[c]:.3g} is below {MIN_SCALE:.0e} "
                             "(change units: products with it underflow float64)")
    if M == 0:
        return
    L = mean_contact_radius(scene)
    if not MIN_SCALE <= L <= MAX_MAGNITUDE:
        raise SceneError(f"{scene.source}: contacts: point: the mean contact radius {L:.3g} is outside "
                         f"[{MIN_SCALE:.0e}, {MAX_MAGNITUDE:.0e}] (change units)")
    limit = COORDINATE_RATIO * L
    for key, arr, name in (("x", scene.x, particle_name), ("point", scene.point, contact_name)):
        far = np.abs(arr).max(axis=1) > limit
        if far.any():
            i = first(far)
            raise SceneError(f"{scene.source}: {name(i)}: {key}: {np.abs(arr[i]).max():.3g} is more than "
                             f"{COORDINATE_RATIO:.0e} mean contact radii ({L:.3g}) from the origin: rounding "
                             f"would cost r^pq = point - x more than input_rtol; move the scene near the origin")


def mean_contact_radius(scene: Scene) -> float:
    """The mean contact radius over |r^pq| and |r^qp| (1 for a scene without contacts): granstab's length scale."""
    if scene.n_contacts == 0:
        return 1.0
    radii = np.concatenate([np.linalg.norm(scene.r_pq, axis=1), np.linalg.norm(scene.r_qp, axis=1)])
    L = float(radii.mean())
    return L if L > 0 else 1.0


def _rows(arr, n: int) -> np.ndarray:
    arr = np.asarray(arr, float)
    return arr.reshape(n, int(np.prod(arr.shape[1:])))


def _check_magnitude(arr: np.ndarray, source: str, name, key: str) -> None:
    bad = row_problem(arr)
    if bad is not None:
        raise SceneError(f"{source}: {name(bad[0])}: {key}: {bad[1]}")


def _fmt(v) -> str:
    v = np.asarray(v).reshape(-1)
    return "[" + ", ".join(f"{a:.6g}" for a in v) + "]" if v.size > 1 else f"{v[0]:.6g}"


def _check_friction(scene: Scene, name) -> None:
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
        raise SceneError(f"{scene.source}: {name(c)}: force: outside the friction cone, Q = {Q[c]:.6g} > 0 "
                         f"(|f_t| = {ft[c]:.6g}, μ|f_n| = {abs(Q[c] - ft[c]):.6g}); set state = \"elastic\" "
                         "for a cohesive contact")
    direction = scene.has_sliding_direction()
    not_at_yield = np.flatnonzero((state == "sliding") & ((np.abs(Q) > tol) | ~direction))
    if not_at_yield.size:
        c = not_at_yield[0]
        why = (f"no tangential force to slide along (|f_t| = {ft[c]:.3g} <= yield_rtol·|f|)" if not direction[c]
               else f"Q = {Q[c]:.6g} ≠ 0")
        raise SceneError(f"{scene.source}: {name(c)}: state: \"sliding\" but not at yield ({why})")


def equilibrium_loads(scene: Scene):
    """b^p = -Σ f^pq, w^p = -Σ (r^pq × f^pq + m^pq) over both sides of every contact (eq:equil1)."""
    N = scene.n_particles
    f = scene.force
    side = np.concatenate([scene.p, scene.q])       # p's terms, then q's (sum_at: in this order, as np.add.at)
    b = sum_at(side, np.concatenate([-f, f]), N)
    w = sum_at(side, np.concatenate([-(cross(scene.r_pq, f) + scene.moment),
                                     -(cross(scene.r_qp, -f) - scene.moment)]), N)
    return b, w


def _load_scales(scene: Scene):
    """Σ|f| and Σ(|r||f| + |m|) over each particle's contacts: the scale of its load balance."""
    N = scene.n_particles
    fmag = np.linalg.norm(scene.force, axis=1)
    mmag = np.linalg.norm(scene.moment, axis=1)
    side = np.concatenate([scene.p, scene.q])
    fs = sum_at(side, np.concatenate([fmag, fmag]), N)
    ms = sum_at(side, np.concatenate([np.linalg.norm(scene.r_pq, axis=1) * fmag + mmag,
                                      np.linalg.norm(scene.r_qp, axis=1) * fmag + mmag]), N)
    return fs, ms


__all__ = ["Scene", "SceneError", "build_scene", "contact_scene_from_dict", "equilibrium_loads", "scene_arrays",
           "scene_from_arrays"]
