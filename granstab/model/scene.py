"""Scenes: particles and contact-level data (Sec. 2), built from arrays and validated (the readers: granstab.io).

A `Scene` holds arrays over particles (N) and contacts (M); d = dim, r = 1 (2D) or 3 (3D):
x (N, d), load b (N, d), load_moment w (N, r); per contact p, q (M,), point (M, d),
normal n^pq (M, d), curvature_p/q K (M, d, d) on the tangent plane (2D: κ t⊗t), their sum curvature_sum
K^p + K^q (M, d, d) as formed from the input (2D: (κp + κq) t⊗t from the scalars), force f^pq (M, d),
moment m^pq (M, r), k, alpha, mu (M,), rolling M^pq (M, r, r) and state ("auto" | "elastic" | "sliding").
A periodic scene also has `cell` (d, d), the lattice vectors a_i as rows, and per contact `image` (M, d) integers:
q's copy sits at x^q + Σ_i image_i a_i (`Scene.q_copy`); the branch vector b^pq runs from x^p to that copy and r^qp
is measured from it, so every formula written with r^pq, r^qp holds for seam contacts unchanged.

Every invalid input raises `SceneError` with ONE line: "<file>: <entry>: <field>: <what is wrong>".
Loads default to equilibrium, b^p = -Σ f^pq and w^p = -Σ (r^pq × f^pq + m^pq) (eq:equil1).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .errors import SceneError, first, row_problem
from .periodic import check_cell, check_images, check_points, image_offset
from .tolerances import COORDINATE_RATIO, DEFAULT, MAX_MAGNITUDE, MIN_SCALE, Tolerances
from .vec import cross, norms, rot_dim, sum_at

STATES = ("auto", "elastic", "sliding")
CONTACT_FIELDS = ("p", "q", "point", "normal", "curvature_p", "curvature_q", "curvature_sum", "force", "moment", "k",
                  "alpha", "mu", "rolling", "image")     # the per-contact arrays (state, a tuple, besides): slice them together
LAW_KEYS = ("k", "alpha", "mu", "rolling_stiffness")
LAW_DEFAULTS = {"k": 1.0, "alpha": 1.0, "mu": 0.5, "rolling_stiffness": 0.0}


@dataclass(frozen=True, eq=False)
class Scene:
    """Contact-level description of a cluster: N particles, M contacts, d = dim, r = 1 (2D) or 3 (3D) rotations.

    Attributes
    ----------
    dim : int
        2 or 3.
    names : tuple of str, (N,)
        Particle names, unique.
    x, load, load_moment : ndarray, (N, d), (N, d), (N, r)
        Reference points and the external loads b, w (eq:equil1).
    p, q : ndarray of int, (M,)
        The two particles of each contact (indices into `names`).
    point, normal, force : ndarray, (M, d)
        Contact point, unit normal n^pq from p toward q, force f^pq on p by q (compression: f·n < 0).
    curvature_p, curvature_q : ndarray, (M, d, d)
        Surface curvature tensors K^p, K^q on the tangent plane (2D: κ t⊗t, convex κ < 0).
    curvature_sum : ndarray, (M, d, d)
        K^p + K^q formed from the input data before anything else (eq:rolling inverts it): the readers add the 2D
        scalars, (κp + κq) t⊗t, and a sphere's (κp + κq)(I − n⊗n), so that a nearly conforming sum is rounded
        relative to itself, not to |K| (docs/bounds.md). Default: curvature_p + curvature_q, entrywise (the tensors
        as the data). A scene that replaces curvature_p or curvature_q must replace it too.
    moment : ndarray, (M, r)
        Contact moment m^pq on p by q.
    k, alpha, mu : ndarray, (M,)
        Contact law (eq:ContactF): normal stiffness, tangential/normal ratio, friction coefficient.
    rolling : ndarray, (M, r, r)
        Rolling stiffness M^pq (eq:constitutiveM).
    state : tuple of str, (M,)
        "auto" (the yield test decides), "elastic" or "sliding".
    mass, inertia, fixed : ndarray or None, (N,), (N, r, r), (N,) bool
        Masses and rotational inertia (the inertia metric), and particles held fixed (supports).
    title, source, tol : str, str, Tolerances
        A title, the name errors give the input, the tolerances it was checked with.
    force_err : ndarray or None, (M,)
        The input's per-contact force uncertainty radius (f_err columns: `--force-uncertainty file`, issue 42).
    """

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
    cell: np.ndarray | None = None        # (d, d) lattice vectors as rows; None: not periodic
    image: np.ndarray | None = None       # (M, d) int: q's copy is x^q + image @ cell; None → zeros
    curvature_sum: np.ndarray | None = None   # (M, d, d) K^p + K^q from the input; None → the tensors' sum
    force_err: np.ndarray | None = None       # (M,) the file's per-contact force uncertainty; None: not given

    def __post_init__(self):
        if self.image is None:
            object.__setattr__(self, "image", np.zeros((len(self.p), self.dim), dtype=np.int64))
        if self.curvature_sum is None:
            object.__setattr__(self, "curvature_sum", self.curvature_p + self.curvature_q)
        if self.force_err is not None and len(self.force_err) != len(self.p):     # a stale one after a contact cut
            raise SceneError(f"{self.source}: force_err: {len(self.force_err)} values for {len(self.p)} contacts")

    def without_rattlers(self) -> tuple[Scene, np.ndarray]:
        """The scene without its particles that have no contact (rattlers: nothing to analyse) and the indices of
        those kept. The contacts, their order and the kept particles' loads stay as they are (the one rattler drop:
        the import's default and track's analyses)."""
        touched = np.zeros(self.n_particles, bool)
        touched[self.p] = touched[self.q] = True
        keep = np.flatnonzero(touched)
        if keep.size == self.n_particles:
            return self, keep
        index = np.cumsum(touched) - 1
        fixed = None if self.fixed is None or not self.fixed[keep].any() else self.fixed[keep]
        return replace(self, names=tuple(self.names[i] for i in keep), x=self.x[keep], p=index[self.p],
                       q=index[self.q], load=self.load[keep], load_moment=self.load_moment[keep], fixed=fixed,
                       mass=None if self.mass is None else self.mass[keep],
                       inertia=None if self.inertia is None else self.inertia[keep]), keep

    @property
    def periodic(self) -> bool:
        return self.cell is not None

    @property
    def volume(self) -> float:
        """det(cell): the cell's area (2D) or volume (3D); a scene without a cell has none (ValueError)."""
        if self.cell is None:
            raise ValueError(f"{self.source}: the scene has no cell, so no volume")
        return float(np.linalg.det(self.cell))

    @property
    def offset(self) -> np.ndarray:
        """image @ cell: where q's copy sits relative to x^q, (M, d) (zeros without a cell)."""
        return image_offset(self.image, self.cell)

    @property
    def q_copy(self) -> np.ndarray:
        """x^q + image @ cell: the copy of q each contact touches, (M, d)."""
        return self.x[self.q] + self.offset

    @property
    def branch(self) -> np.ndarray:
        """Branch vectors b^pq = q's copy - x^p, (M, d)."""
        return self.q_copy - self.x[self.p]

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
        """Radial vectors r^qp = contact point - q's copy (x^q + image @ cell), (M, d)."""
        return self.point - self.q_copy

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

    def yield_function(self, ft=None) -> np.ndarray:
        """Q^pq = |f_t| + μ f·n (eq:yield), (M,); `ft`: |f_t| when already formed."""
        fn = np.sum(self.force * self.normal, axis=1)
        return (norms(self.tangential_force()) if ft is None else ft) + self.mu * fn

    def has_sliding_direction(self, ft=None) -> np.ndarray:
        """|f_t| > yield_rtol·|f|: a tangential force that defines h = f_t/|f_t| (eq:Hdirection), (M,).

        A smaller |f_t| is within the yield test's own tolerance of zero and its direction is round-off (a rigid
        rotation of the scene turns an exact 0 into ~1e-16·|f|): treating it as a direction made the
        classification, and so the number of branches and the verdict, depend on the frame. `ft`: |f_t| when
        already formed."""
        ft = norms(self.tangential_force()) if ft is None else ft
        return ft > self.tol.yield_rtol * norms(self.force)

    def at_yield(self) -> np.ndarray:
        """Potentially sliding contacts (Appendix D mask ±1): state "sliding", or "auto" with Q = 0 within
        yield_rtol·|f| and a tangential force to slide along (`has_sliding_direction`). Zero-force and
        frictionless normal contacts have no sliding direction h (eq:Hdirection) and stay elastic."""
        state = np.asarray(self.state)
        scale = norms(self.force)
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



def build_scene(dim, names, x, arrays, loads=None, load_moments=None, *, title="", source="<scene>",
                tol: Tolerances = DEFAULT, entries=None, particle_entries=None, mass=None, inertia=None,
                fixed=None, cell=None, image=None) -> Scene:
    """Assemble a `Scene` from arrays and run the range and physical checks (vectorised).

    Parameters
    ----------
    dim : int
        2 or 3; r = 1 or 3 rotations a particle.
    names, x : sequence of str (N,), array_like (N, dim)
        Particle names and reference points.
    arrays : dict
        The contact fields of `Scene`: ``p``, ``q`` (M,) int, ``point``, ``normal``, ``force`` (M, dim),
        ``curvature_p``, ``curvature_q`` (M, dim, dim), ``moment`` (M, r), ``k``, ``alpha``, ``mu`` (M,),
        ``rolling`` (M, r, r), ``state`` (M,) str; optionally ``curvature_sum`` (M, dim, dim), K^p + K^q as formed
        from the input (it must agree with the tensors' sum to input_rtol·max(|K^p|, |K^q|)).
    loads, load_moments : None, list or (values, given)
        External b (N, dim) and w (N, r): None for the equilibrium values (eq:equil1), a list with None where
        the equilibrium value is meant, or values with a (N,) bool of those given; given ones must balance.
    mass, inertia, fixed : array_like, optional
        (N,) masses and (N, r, r) inertia tensors (the inertia metric); (N,) bool supports (no dofs).
    cell, image : array_like, optional
        (dim, dim) lattice vectors as rows (a periodic scene) and (M, dim) integer images of q per contact (default
        zeros): q's copy is x^q + image @ cell (model/periodic.py checks them and the contact points).
    title, source, tol, entries, particle_entries
        Title; the input's name in errors; tolerances; contact and particle names for error messages (a list or
        a function i → name; default "contacts[i]", "particles[i]").

    Returns
    -------
    Scene
        With equilibrium loads wherever none were given.

    Raises
    ------
    SceneError
        A value out of range, a load that does not balance, an "auto" contact outside the friction cone: one line.
    """
    N = len(names)
    r = rot_dim(dim)
    contact_name = _namer(entries, "contacts")
    particle_name = _namer(particle_entries, None) or (lambda i: f"particles[{i}] ({names[i]!r})")
    cell = check_cell(cell, dim, source, tol)
    image = check_images(image, len(arrays["p"]), dim, cell, source, contact_name)
    base = Scene(dim=dim, names=tuple(names), x=np.asarray(x, float).reshape(N, dim), load=np.zeros((N, dim)),
                 load_moment=np.zeros((N, r)), title=title, source=source, tol=tol, cell=cell, image=image, **arrays)
    given_b, has_b = _given(loads, N, dim)
    given_w, has_w = _given(load_moments, N, r)
    arms = (base.r_pq, base.r_qp)                   # formed once for every check below (10⁶ contacts: 0.3 s each)
    check_ranges(base, contact_name, particle_name, (given_b, given_w), arms)
    _check_curvature_sum(base, contact_name)
    check_points(base, contact_name)
    _check_friction(base, contact_name)
    b_eq, w_eq = equilibrium_loads(base, arms)
    f_scale, m_scale = _load_scales(base, arms)
    for given, has, eq, scale, key, what in ((given_b, has_b, b_eq, f_scale, "load", "|b + Σf|"),
                                             (given_w, has_w, w_eq, m_scale, "moment", "|w + Σ(r×f + m)|")):
        res = norms(given - eq)
        bad = has & (res > tol.input_rtol * (scale + norms(given)))
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
                 source=source, tol=tol, mass=mass, inertia=inertia, fixed=fixed, cell=cell, image=image,
                 **arrays)


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


def check_ranges(scene: Scene, contact_name, particle_name, given=(), arms=None) -> None:
    """Every number finite with |v| <= MAX_MAGNITUDE; k and α >= MIN_SCALE; positions and contact points within
    COORDINATE_RATIO mean contact radii of the origin (beyond it r^pq = point - x loses more than input_rtol to
    rounding). The first offender is named with its entry and field. `arms`: (r^pq, r^qp) when already formed."""
    per_contact = {"point": scene.point, "normal": scene.normal, "curvature_p": scene.curvature_p,
                   "curvature_q": scene.curvature_q, "curvature_sum": scene.curvature_sum, "force": scene.force,
                   "moment": scene.moment, "k": scene.k, "alpha": scene.alpha, "mu": scene.mu,
                   "rolling_stiffness": scene.rolling}
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
    L = mean_contact_radius(scene, arms)
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


def mean_contact_radius(scene: Scene, arms=None) -> float:
    """The mean contact radius over |r^pq| and |r^qp| (1 for a scene without contacts): granstab's length scale.
    `arms`: (r^pq, r^qp) when already formed."""
    if scene.n_contacts == 0:
        return 1.0
    r_pq, r_qp = arms or (scene.r_pq, scene.r_qp)
    L = float(np.concatenate([norms(r_pq), norms(r_qp)]).mean())
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


def _check_curvature_sum(scene: Scene, name) -> None:
    """A given curvature_sum must be K^p + K^q to input_rtol of the larger curvature (the same data, summed first)."""
    M = scene.n_contacts
    kp, kq = _rows(scene.curvature_p, M), _rows(scene.curvature_q, M)
    scale = np.maximum(np.abs(kp).max(axis=1, initial=0.0), np.abs(kq).max(axis=1, initial=0.0))
    off = _rows(scene.curvature_sum, M) - kp                     # in place from here: no (M, d, d) temporaries
    off -= kq
    off = np.abs(off, out=off).max(axis=1, initial=0.0)
    bad = off > scene.tol.input_rtol * scale
    if bad.any():
        c = first(bad)
        raise SceneError(f"{scene.source}: {name(c)}: curvature_sum: differs from curvature_p + curvature_q by "
                         f"{off[c]:.3g} (more than input_rtol of |K| = {scale[c]:.3g})")


def _check_friction(scene: Scene, name) -> None:
    """Forces outside the friction cone ("auto") and "sliding" contacts not at yield are errors."""
    if scene.n_contacts == 0:
        return
    ft = norms(scene.tangential_force())
    Q = scene.yield_function(ft)
    fmag = norms(scene.force)
    state = np.asarray(scene.state)
    tol = scene.tol.yield_rtol * fmag
    outside = np.flatnonzero((state == "auto") & (Q > tol))
    if outside.size:
        c = outside[0]
        raise SceneError(f"{scene.source}: {name(c)}: force: outside the friction cone, Q = {Q[c]:.6g} > 0 "
                         f"(|f_t| = {ft[c]:.6g}, μ|f_n| = {abs(Q[c] - ft[c]):.6g}); set state = \"elastic\" "
                         "for a cohesive contact")
    direction = scene.has_sliding_direction(ft)
    not_at_yield = np.flatnonzero((state == "sliding") & ((np.abs(Q) > tol) | ~direction))
    if not_at_yield.size:
        c = not_at_yield[0]
        why = (f"no tangential force to slide along (|f_t| = {ft[c]:.3g} <= yield_rtol·|f|)" if not direction[c]
               else f"Q = {Q[c]:.6g} ≠ 0")
        raise SceneError(f"{scene.source}: {name(c)}: state: \"sliding\" but not at yield ({why})")


def equilibrium_loads(scene: Scene, arms=None):
    """b^p = -Σ f^pq, w^p = -Σ (r^pq × f^pq + m^pq) over both sides of every contact (eq:equil1); `arms`:
    (r^pq, r^qp) when already formed."""
    N = scene.n_particles
    r_pq, r_qp = arms or (scene.r_pq, scene.r_qp)
    f = scene.force
    side = np.concatenate([scene.p, scene.q])       # p's terms, then q's (sum_at: in this order, as np.add.at)
    b = sum_at(side, np.concatenate([-f, f]), N)
    w = sum_at(side, np.concatenate([-(cross(r_pq, f) + scene.moment), -(cross(r_qp, -f) - scene.moment)]), N)
    return b, w


def _load_scales(scene: Scene, arms):
    """Σ|f| and Σ(|r||f| + |m|) over each particle's contacts: the scale of its load balance."""
    N = scene.n_particles
    r_pq, r_qp = arms
    fmag = norms(scene.force)
    mmag = norms(scene.moment)
    side = np.concatenate([scene.p, scene.q])
    fs = sum_at(side, np.concatenate([fmag, fmag]), N)
    ms = sum_at(side, np.concatenate([norms(r_pq) * fmag + mmag, norms(r_qp) * fmag + mmag]), N)
    return fs, ms


__all__ = ["Scene", "SceneError", "build_scene", "equilibrium_loads"]
