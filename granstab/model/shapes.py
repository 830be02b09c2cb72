"""Exact contact geometry of smooth convex shapes, and scenes built from shapes (Sec. 2.1-2.3).

Shapes: `Disk`, `Ellipse` (2D) and `Sphere`, `Ellipsoid` (3D), semi-axes along the body axes. A pose is
(position (d,), orientation): a 2D angle (radians) or a 3D rotation matrix (body → world); None is identity.

Every shape is described by its support function h(n) = sqrt(nᵀ S n), S = R diag(semi-axes²) Rᵀ: the surface
point with outward normal n is x + S n / h(n), and ∇²h(n) = S/h - (S n)(S n)ᵀ/h³ is the tangent-plane tensor
of the principal radii of curvature there. For two bodies p, q with d = x^q - x^p the gap along a direction n,

    g(n) = d·n - h_p(n) - h_q(-n),         ∇g = Q - P,

has the common-normal pairs (P on p with normal n, Q on q with normal -n) as its stationary points on the unit
sphere; its maximum is the separation distance (g > 0) or minus the overlap δ (g ≤ 0). `contact_geometry`
maximises g by Newton's method on the sphere, started from the best of a fixed set of sampled directions.

Curvatures follow docs/errata.md ("Where the curvature is evaluated"): the contact point is the midpoint (P+Q)/2 and
each particle's curvature is that of its parallel curve/surface through it, principal radii ρ_i - δ/2 with
unchanged principal directions. Sign convention of the paper (eq:rolling, eq:Dnpq): convex ⇒ negative
eigenvalues, K = -Σ (1/(ρ_i - δ/2)) t_i⊗t_i, with K·n = 0; in 2D that is κ t⊗t with t = e3 × n.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from .scene import build_scene
from .tolerances import DEFAULT, EPS, Tolerances
from .vec import rot_dim, tangent_basis

MAX_NEWTON = 100          # Newton iterations on the sphere (4-8 are typical)
STEP_CONVERGED = 1e-11    # a full Newton step shorter than this (radians) leaves an error ~ step² ≪ eps
MAX_TURN = 0.5            # largest change of the normal per Newton step (radians)


# ------------------------------------------------------------------------------------------------ shapes

def _positive(name: str, **sizes) -> None:
    for key, value in sizes.items():
        if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: {key} must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class _Shape:
    """What the four shapes share: their sizes (the fields, in order) checked finite and > 0, the semi-axes along
    the body axes (a radius repeated), the dict form of the scene files."""

    dim: ClassVar[int]
    kind: ClassVar[str]

    def __post_init__(self):
        _positive(self.kind, **self._sizes())

    def _sizes(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def semi_axes(self) -> tuple:
        sizes = tuple(self._sizes().values())
        return sizes * self.dim if len(sizes) == 1 else sizes

    def to_dict(self) -> dict:
        return {"kind": self.kind, **{key: float(value) for key, value in self._sizes().items()}}


@dataclass(frozen=True)
class Disk(_Shape):
    """2D disk of radius `radius`."""
    radius: float
    dim, kind = 2, "disk"         # class attributes (not annotated: no fields)


@dataclass(frozen=True)
class Sphere(_Shape):
    """3D sphere of radius `radius`."""
    radius: float
    dim, kind = 3, "sphere"


@dataclass(frozen=True)
class Ellipse(_Shape):
    """2D ellipse with semi-axes a (body e1) and b (body e2)."""
    a: float
    b: float
    dim, kind = 2, "ellipse"


@dataclass(frozen=True)
class Ellipsoid(_Shape):
    """3D ellipsoid with semi-axes a, b, c along the body axes e1, e2, e3."""
    a: float
    b: float
    c: float
    dim, kind = 3, "ellipsoid"


SHAPES = {cls.kind: cls for cls in (Disk, Ellipse, Sphere, Ellipsoid)}
SHAPE_FIELDS = {"disk": ("radius",), "ellipse": ("a", "b"), "sphere": ("radius",), "ellipsoid": ("a", "b", "c")}


def bounding_radius(shape) -> float:
    """Radius of the smallest ball about the centre that holds the shape."""
    return float(max(shape.semi_axes))


def is_round(shape) -> bool:
    """Disks, spheres and ellipses/ellipsoids with equal axes: the common normal is the line of centres."""
    axes = shape.semi_axes
    return all(s == axes[0] for s in axes)


def rotation_matrix(dim: int, orientation) -> np.ndarray:
    """Body → world rotation: 2D from an angle (radians), 3D the given 3x3 matrix; None is the identity."""
    if orientation is None:
        return np.eye(dim)
    if dim == 2:
        c, s = np.cos(float(orientation)), np.sin(float(orientation))
        return np.array([[c, -s], [s, c]])
    R = np.asarray(orientation, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"3D orientation must be a 3x3 rotation matrix, got shape {R.shape}")
    return R


def mass_properties(shape, orientation, density: float = 1.0):
    """Mass and rotational inertia (global frame) of a uniform solid: 2D (m, [[I]]) per unit thickness, ellipse
    I = m(a² + b²)/4; 3D ellipsoid I_body = m/5 diag(b² + c², a² + c², a² + b²), rotated by the orientation."""
    axes = np.asarray(shape.semi_axes, float)
    if shape.dim == 2:
        m = density * np.pi * axes.prod()
        return m, np.array([[m * (axes ** 2).sum() / 4.0]])
    m = density * 4.0 / 3.0 * np.pi * axes.prod()
    R = rotation_matrix(3, orientation)
    return m, R @ np.diag(m / 5.0 * ((axes ** 2).sum() - axes ** 2)) @ R.T


def shape_tensor(shape, orientation) -> np.ndarray:
    """S = R diag(semi-axes²) Rᵀ, so that h(n) = sqrt(nᵀ S n) is the support function (d, d)."""
    R = rotation_matrix(shape.dim, orientation)
    return (R * np.square(shape.semi_axes)) @ R.T


# ------------------------------------------------------------------------------------- support geometry

def _quad(S: np.ndarray, n: np.ndarray) -> np.ndarray:
    """nᵀ S n over leading axes."""
    return np.einsum("...i,...ij,...j->...", n, S, n)


def radius_tensor(S: np.ndarray, n: np.ndarray) -> np.ndarray:
    """∇²h(n) = S/h - (S n)(S n)ᵀ/h³: principal radii of curvature on the tangent plane at the point with
    outward normal n (symmetric, W·n = 0), (…, d, d)."""
    h = np.sqrt(_quad(S, n))[..., None, None]
    Sn = np.einsum("...ij,...j->...i", S, n)
    return S / h - Sn[..., :, None] * Sn[..., None, :] / h**3


def curvature_from_radii(W: np.ndarray, n: np.ndarray, offset=0.0) -> np.ndarray:
    """Curvature tensor K (…, d, d) of the parallel surface at inward `offset` from a surface whose radius
    tensor at normal n is W: radii ρ_i - offset, same principal directions, K = -T (TᵀWT - offset I)⁻¹ Tᵀ
    (paper's sign convention, eq:rolling: convex < 0). Raises ValueError if offset reaches a radius."""
    T = tangent_basis(n)
    Tt = np.swapaxes(T, -1, -2)
    Wt = Tt @ W @ T
    Wt = 0.5 * (Wt + np.swapaxes(Wt, -1, -2)) - np.asarray(offset, float)[..., None, None] * np.eye(T.shape[-1])
    bad = np.flatnonzero(np.linalg.eigvalsh(Wt).reshape(-1, T.shape[-1]).min(axis=1) <= 0)
    if bad.size:
        raise ValueError(f"the overlap reaches twice a radius of curvature at contact {bad[0]}: "
                         "the parallel surface is degenerate")
    K = -T @ np.linalg.inv(Wt) @ Tt
    return 0.5 * (K + np.swapaxes(K, -1, -2))


def surface_normal_at(shape, pose, point) -> np.ndarray:
    """Outward unit normal of the surface through `point` (the point is projected radially if off the surface:
    the normal of the homothetic ellipse/ellipsoid through it)."""
    x, orientation = pose
    R = rotation_matrix(shape.dim, orientation)
    y = R.T @ (np.asarray(point, float) - np.asarray(x, float))
    m = R @ (y / np.square(shape.semi_axes))
    return m / np.linalg.norm(m)


def surface_curvature_at(shape, pose, point, offset=0.0) -> np.ndarray:
    """Curvature tensor (d, d), world axes, of the surface at `point` — or, with `offset` > 0, of the parallel
    surface at that inward offset along the same normal (docs/errata.md: offset δ/2 at a contact)."""
    n = surface_normal_at(shape, pose, point)
    S = shape_tensor(shape, pose[1])
    return curvature_from_radii(radius_tensor(S, n), n, offset)


# ------------------------------------------------------------------------------------ common normal

def _sample_directions(dim: int) -> np.ndarray:
    """Fixed start directions: 72 angles in 2D, a 400-point Fibonacci sphere in 3D."""
    if dim == 2:
        a = np.linspace(0.0, 2 * np.pi, 72, endpoint=False)
        return np.stack([np.cos(a), np.sin(a)], axis=1)
    k = np.arange(400) + 0.5
    z = 1.0 - 2.0 * k / 400
    phi = np.pi * (1.0 + 5**0.5) * k
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def _gap(d, Sp, Sq, n):
    """g(n) = d·n - h_p(n) - h_q(n) (S_q is even in n), its gradient Q - P and Hessian, batched (M, …)."""
    hp = np.sqrt(_quad(Sp, n))
    hq = np.sqrt(_quad(Sq, n))
    g = np.sum(d * n, axis=-1) - hp - hq
    grad = d - np.einsum("mij,mj->mi", Sp, n) / hp[:, None] - np.einsum("mij,mj->mi", Sq, n) / hq[:, None]
    hess = -radius_tensor(Sp, n) - radius_tensor(Sq, n)
    return g, grad, hess


def _size(S):
    """sqrt(trace S) = |semi-axes|: the length scale of a body (M,)."""
    return np.sqrt(np.trace(S, axis1=-2, axis2=-1))


def _normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _newton_on_sphere(d, Sp, Sq, n):
    """Maximise g on the unit sphere from starts n (M, d): Newton steps in the tangent plane on the Riemannian
    Hessian Tᵀ∇²g T - g I (negative definite for overlaps below the radii-of-curvature sum), shifted to be
    negative definite where it is not, with turns capped at MAX_TURN and backtracking until g does not decrease.
    Converged when a full, unshifted step is below STEP_CONVERGED or its round-off floor."""
    M, dim = d.shape
    scale = np.linalg.norm(d, axis=1) + _size(Sp) + _size(Sq)
    active = np.ones(M, bool)
    for _ in range(MAX_NEWTON):
        if not active.any():
            return n
        idx = np.flatnonzero(active)
        da, Spa, Sqa, na = d[idx], Sp[idx], Sq[idx], n[idx]
        g, grad, hess = _gap(da, Spa, Sqa, na)
        T = tangent_basis(na)
        Tt = np.swapaxes(T, 1, 2)
        gt = np.einsum("mki,mk->mi", T, grad)
        Ht = Tt @ hess @ T - g[:, None, None] * np.eye(dim - 1)
        Ht = 0.5 * (Ht + np.swapaxes(Ht, 1, 2))
        lam = np.linalg.eigvalsh(Ht)
        floor = 1e-3 * np.abs(lam).max(axis=1) + EPS * scale[idx]
        shift = np.maximum(lam[:, -1] + floor, 0.0)
        step = np.linalg.solve(Ht - shift[:, None, None] * np.eye(dim - 1), -gt[..., None])[..., 0]
        length = np.linalg.norm(step, axis=1)
        step *= np.minimum(1.0, MAX_TURN / np.maximum(length, 1e-300))[:, None]
        full = (shift == 0) & (length <= MAX_TURN)
        t = np.ones(len(idx))
        for _ in range(60):
            trial = _normalize(na + np.einsum("mki,mi->mk", T, t[:, None] * step))
            worse = _gap(da, Spa, Sqa, trial)[0] < g - 8 * EPS * scale[idx]
            if not worse.any():
                break
            t[worse] *= 0.5
        n[idx] = trial
        noise = 64 * EPS * scale[idx] / np.abs(lam[:, -1])            # round-off floor of the step
        active[idx[full & (t == 1.0) & (length <= np.maximum(STEP_CONVERGED, noise))]] = False
    raise RuntimeError("common-normal Newton iteration did not converge")


def common_normals(d: np.ndarray, Sp: np.ndarray, Sq: np.ndarray, round_pair: np.ndarray) -> np.ndarray:
    """Unit n (M, d) maximising g(n) for centre offsets d = x^q - x^p (M, d) and shape tensors (M, d, d);
    pairs flagged `round_pair` (both bodies round) take the closed form n = d/|d|."""
    n = np.empty_like(d)
    dist = np.linalg.norm(d, axis=1)
    if np.any(round_pair & (dist == 0)):
        raise ValueError("coincident centres of two round bodies: the contact normal is undefined")
    n[round_pair] = d[round_pair] / dist[round_pair, None]
    rest = ~round_pair
    if rest.any():
        dim = d.shape[1]
        dirs = _sample_directions(dim)
        outer = (dirs[:, :, None] * dirs[:, None, :]).reshape(len(dirs), dim * dim).T   # nᵀSn as a matmul
        g = (d[rest] @ dirs.T - np.sqrt(Sp[rest].reshape(-1, dim * dim) @ outer)
             - np.sqrt(Sq[rest].reshape(-1, dim * dim) @ outer))
        n[rest] = _newton_on_sphere(d[rest], Sp[rest], Sq[rest], dirs[np.argmax(g, axis=1)].copy())
    return n


# ------------------------------------------------------------------------------------------ contacts

@dataclass(frozen=True, eq=False)
class ContactGeometry:
    """Common-normal contact of two overlapping convex bodies p, q (arrays in world axes).

    normal n^pq (outward from p), overlap δ = (P - Q)·n >= 0, point = (P + Q)/2, point_p = P on p's surface,
    point_q = Q on q's surface, curvature_p/q: parallel-surface curvature tensors through the point (docs/errata.md).
    """

    normal: np.ndarray
    overlap: float
    point: np.ndarray
    point_p: np.ndarray
    point_q: np.ndarray
    curvature_p: np.ndarray
    curvature_q: np.ndarray


def _contacts(x_p, x_q, Sp, Sq, round_pair):
    """Batched narrow phase: n, g (max gap), P, Q, and the radius tensors W_p, W_q at the contact."""
    d = x_q - x_p
    n = common_normals(d, Sp, Sq, round_pair)
    hp = np.sqrt(_quad(Sp, n))
    hq = np.sqrt(_quad(Sq, n))
    P = x_p + np.einsum("mij,mj->mi", Sp, n) / hp[:, None]
    Q = x_q - np.einsum("mij,mj->mi", Sq, n) / hq[:, None]
    g = np.sum(d * n, axis=1) - hp - hq
    return n, g, P, Q, radius_tensor(Sp, n), radius_tensor(Sq, n)


def _touch_tol(x_p, x_q, Sp, Sq):
    """Gaps within round-off of the gap function count as touching: 16 eps (|d| + h_p + h_q)."""
    return 16 * EPS * (np.linalg.norm(x_q - x_p, axis=1) + _size(Sp) + _size(Sq))


def contact_geometry(shape_p, pose_p, shape_q, pose_q) -> ContactGeometry | None:
    """Common-normal contact of two shapes, None when separated (gap above round-off, see `_touch_tol`).

    Curvatures are those of the parallel curves/surfaces through the midpoint (radii ρ - δ/2, docs/errata.md)."""
    if shape_p.dim != shape_q.dim:
        raise ValueError("shapes of different dimension")
    x_p = np.asarray(pose_p[0], float).reshape(1, -1)
    x_q = np.asarray(pose_q[0], float).reshape(1, -1)
    Sp = shape_tensor(shape_p, pose_p[1])[None]
    Sq = shape_tensor(shape_q, pose_q[1])[None]
    n, g, P, Q, Wp, Wq = _contacts(x_p, x_q, Sp, Sq, np.array([is_round(shape_p) and is_round(shape_q)]))
    if g[0] > _touch_tol(x_p, x_q, Sp, Sq)[0]:
        return None
    delta = max(-float(g[0]), 0.0)
    return ContactGeometry(normal=n[0], overlap=delta, point=0.5 * (P[0] + Q[0]), point_p=P[0], point_q=Q[0],
                           curvature_p=curvature_from_radii(Wp[0], n[0], 0.5 * delta),
                           curvature_q=curvature_from_radii(Wq[0], n[0], 0.5 * delta))


def tangent_directions(n: np.ndarray, shear=None) -> np.ndarray:
    """Unit tangential-force directions (M, d): 2D t = e3 × n; 3D the projection of `shear` (default e1) onto
    the tangent plane, or tangent_basis(n)[:, 0] where that projection is shorter than 1e-6 |shear|."""
    if n.shape[1] == 2:
        return tangent_basis(n)[:, :, 0]
    s = np.array([1.0, 0.0, 0.0]) if shear is None else np.asarray(shear, float)
    s = s / np.linalg.norm(s)
    t = s - (n @ s)[:, None] * n
    norm = np.linalg.norm(t, axis=1)
    fallback = norm < 1e-6
    t[~fallback] /= norm[~fallback, None]
    t[fallback] = tangent_basis(n[fallback])[:, :, 0]
    return t


def candidate_pairs(x: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Broad phase: pairs (K, 2), p < q, sorted, whose bounding balls overlap or touch (cKDTree)."""
    if len(x) < 2:
        return np.zeros((0, 2), np.intp)
    pairs = cKDTree(x).query_pairs(r=2.0 * float(radii.max()), output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), np.intp)
    pairs = np.sort(pairs, axis=1)
    reach = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1) <= radii[pairs[:, 0]] + radii[pairs[:, 1]]
    pairs = pairs[reach]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def scene_from_shapes(dim, particles, *, k=1.0, alpha=1.0, mu=0.5, mobilised=0.0, rolling_stiffness=0.0,
                      shear=None, title="", source="<shapes>", tol: Tolerances = DEFAULT, density: float = 1.0):
    """A granstab Scene from shapes: every overlapping (or touching) pair is a contact.

    particles: list of (name, shape, pose), pose = (position, orientation). Contact p < q in particle order,
    normal n^pq from `contact_geometry`; force f^pq = -kδ n + mobilised·μ·kδ t (compressive normal force from
    the overlap δ, tangential force along `tangent_directions(n, shear)`); no contact moments; rolling
    stiffness `rolling_stiffness` (scalar × I or an (r, r) matrix). State "sliding" when mobilised = 1 and the
    contact carries friction (|f_t| > yield_rtol·|f|), else "auto". Loads are the equilibrium defaults (eq:equil1).
    Raises ValueError for invalid shapes/poses or degenerate contacts (see `common_normals`, `curvature_from_radii`).
    """
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    if not 0.0 <= mobilised <= 1.0:
        raise ValueError(f"mobilised must be in [0, 1], got {mobilised}")
    names = [name for name, _, _ in particles]
    shapes = [shape for _, shape, _ in particles]
    if any(shape.dim != dim for shape in shapes):
        raise ValueError(f"every shape must be {dim}D")
    x = np.array([np.asarray(pose[0], float).reshape(dim) for _, _, pose in particles]).reshape(-1, dim)
    S = np.array([shape_tensor(shape, pose[1]) for _, shape, pose in particles]).reshape(-1, dim, dim)
    radii = np.array([bounding_radius(shape) for shape in shapes])
    rnd = np.array([is_round(shape) for shape in shapes], bool)

    pairs = candidate_pairs(x, radii)
    p, q = pairs[:, 0], pairs[:, 1]
    n, g, P, Q, Wp, Wq = _contacts(x[p], x[q], S[p], S[q], rnd[p] & rnd[q])
    keep = g <= _touch_tol(x[p], x[q], S[p], S[q])
    p, q, n, g, P, Q, Wp, Wq = (a[keep] for a in (p, q, n, g, P, Q, Wp, Wq))
    M, r = len(p), rot_dim(dim)
    delta = np.maximum(-g, 0.0)
    for W in (Wp, Wq):
        radii = np.linalg.eigvalsh(W)[:, 1:] - 0.5 * delta[:, None]      # the zero eigenvalue (normal) first
        bad = np.flatnonzero(radii.min(axis=1, initial=np.inf) <= 0)
        if bad.size:
            c = bad[0]
            raise ValueError(f"{names[p[c]]}-{names[q[c]]}: overlap {delta[c]:.6g} reaches twice a radius of "
                             "curvature (the parallel surface is degenerate)")
    Kp = curvature_from_radii(Wp, n, 0.5 * delta)
    Kq = curvature_from_radii(Wq, n, 0.5 * delta)
    fn = k * delta
    force = -fn[:, None] * n + (mobilised * mu * fn)[:, None] * tangent_directions(n, shear)
    rolling = np.asarray(rolling_stiffness, float)
    rolling = rolling * np.eye(r) if rolling.ndim == 0 else rolling.reshape(r, r)
    sliding = (mobilised == 1.0) & (mu * fn > tol.yield_rtol * fn * np.hypot(1.0, mu))   # |f_t| > yield_rtol·|f|
    arrays = {
        "p": p.astype(np.intp), "q": q.astype(np.intp), "point": 0.5 * (P + Q), "normal": n,
        "curvature_p": Kp.reshape(M, dim, dim), "curvature_q": Kq.reshape(M, dim, dim), "force": force,
        "moment": np.zeros((M, r)), "k": np.full(M, float(k)), "alpha": np.full(M, float(alpha)),
        "mu": np.full(M, float(mu)), "rolling": np.broadcast_to(rolling, (M, r, r)).copy(),
        "state": tuple("sliding" if s else "auto" for s in sliding),
    }
    entries = [f"contact {names[a]}-{names[b]}" for a, b in zip(p, q)]
    mass, inertia = zip(*(mass_properties(shape, pose[1], density) for _, shape, pose in particles))
    return build_scene(dim, names, x, arrays, title=title, source=source, tol=tol, entries=entries, mass=mass,
                       inertia=inertia)


# ----------------------------------------------------------------------------------------- file format


__all__ = ["mass_properties", "Disk", "Ellipse", "Sphere", "Ellipsoid", "ContactGeometry", "contact_geometry", "scene_from_shapes",
           "surface_curvature_at", "surface_normal_at", "shape_tensor", "rotation_matrix",
           "tangent_directions", "curvature_from_radii",
           "radius_tensor", "bounding_radius", "candidate_pairs", "common_normals"]
