"""One kernel for every shape with a smooth surface function F(y) = 1 in body coordinates (numpy only).

Superquadrics in LIGGGHTS's convention (semi-axes a, b, c along the body axes, blockiness n1, n2 ≥ 2):

    F(y) = (|y1/a|^n2 + |y2/b|^n2)^(n1/n2) + |y3/c|^n1,

an ellipsoid for n1 = n2 = 2, a sphere for equal axes too; in 2D the superellipse |y1/a|^n + |y2/b|^n (n = n2,
n1 ignored), the ellipse for n = 2. Every function is vectorised over contacts (leading axis M) and works on
φ = F^(1/n1), which is homogeneous of degree 1 (φ(λy) = λφ(y)): it is evaluated at y/s with s the largest
|y_i|/a_i (no overflow for blocky n or far points, whatever the length scale), and its surface φ = 1 and the
shape operator W = P ∇∇F P / |∇F| = P ∇∇φ P / |∇φ| (P = I − ν⊗ν, ν the outward unit normal) are F's.

The curvature at a contact, in the project's convention (docs/errata.md: the curvature of each grain's parallel
surface through the contact point, ρ = R − δ/2 for spheres): the foot point s is the point of the surface
nearest to the contact point y (`foot_points`, vectorised Newton), y = s − depth·ν (depth > 0 inside); the
parallel surface through y has the shape operator W (I − depth·W)⁻¹, and the contact stores it on the contact's
tangent plane (normal n) with the paper's sign (eq:rolling, eq:Dnpq: convex ⇒ negative eigenvalues):

    K = −P_n W (I − depth·W)⁻¹ P_n,   P_n = I − n⊗n      (`contact_curvature`).

For a sphere that is −(I − n⊗n)/(R − depth); shapes.py's ellipses and ellipsoids give the same tensor from
their support functions (tests/model/test_surface.py checks the two agree). `mesh` and `outline` give one shared
triangle mesh (or polyline) per shape for drawing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar

import numpy as np

MAX_NEWTON = 100          # foot-point Newton iterations (3-8 are typical from the radial start)
STEP_CONVERGED = 1e-13    # a full step below this fraction of the body size ends the iteration (error ~ step²)
MAX_STEP = 0.25           # largest foot-point step, fraction of the body size
DEEP = 0.05               # inside points deeper than this fraction of the smallest semi-axis get extra starts
EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Superquadric:
    """3D superquadric, LIGGGHTS's convention (module docstring): semi-axes a, b, c, blockiness n1, n2 ≥ 2."""

    a: float
    b: float
    c: float
    n1: float = 2.0
    n2: float = 2.0
    dim: ClassVar[int] = 3
    kind: ClassVar[str] = "superquadric"

    def __post_init__(self):
        for key in ("a", "b", "c", "n1", "n2"):
            value = getattr(self, key)
            low = 2.0 if key.startswith("n") else 0.0
            if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value)
                    and (value >= low if low else value > 0)):
                raise ValueError(f"superquadric: {key} must be a finite number {'>= 2' if low else '> 0'}, "
                                 f"got {value!r}")

    @property
    def semi_axes(self) -> tuple:
        return (self.a, self.b, self.c)

    def to_dict(self) -> dict:
        return {"kind": self.kind, **{k: float(getattr(self, k)) for k in ("a", "b", "c", "n1", "n2")}}


def parameters(shape) -> tuple[np.ndarray, np.ndarray]:
    """(semi-axes (d,), blockiness (2,)) of a Superquadric, Ellipsoid, Sphere, Ellipse or Disk (n1 = n2 = 2)."""
    n = (shape.n1, shape.n2) if hasattr(shape, "n1") else (2.0, 2.0)
    return np.asarray(shape.semi_axes, float), np.asarray(n, float)


# ------------------------------------------------------------------------------------------ the surface

def _pow(t, n):
    """t^n for t ≥ 0 with 0^0 = 1 (numpy's convention, the limit that n = 2 needs)."""
    return np.power(t, n)


def _below(t, tn1, n):
    """t^(n−2) from t^(n−1) (t ≥ 0): their quotient, and 0^(n−2) (1 for n = 2, 0 above, inf below) at t = 0."""
    zero = np.where(n > 2, 0.0, np.where(n == 2, 1.0, np.inf))
    return np.where(t > 0, tn1 / np.where(t > 0, t, 1.0), zero)


def implicit(y, axes, blockiness, order: int = 2):
    """φ = F^(1/n1) at body points y (M, d) (order 0: alone), with ∇φ (M, d) (order 1) and ∇∇φ (M, d, d) (order 2).

    axes (M, d), blockiness (M, 2) (broadcast). φ is 1-homogeneous: computed at y/s (s = max |y_i|/a_i, so every
    power is ≤ 1), then ∇φ(y) = ∇φ(y/s) and ∇∇φ(y) = ∇∇φ(y/s)/s. Points at the centre (y = 0) give NaN."""
    y = np.asarray(y, float)
    M, d = y.shape
    axes = np.broadcast_to(np.asarray(axes, float), (M, d))
    nb = np.broadcast_to(np.asarray(blockiness, float), (M, 2))
    n1 = nb[:, 0] if d == 3 else nb[:, 1]
    n2 = nb[:, 1]
    sign = np.where(y < 0, -1.0, 1.0)
    t = np.abs(y) / axes
    s = t.max(axis=1)
    t = t / s[:, None]
    k = n1 / n2
    # five powers in all (the rest by products: t^n = t^(n−1)·t, u^(k−1) = u^k/u, A^(1/n1−1) = φ/A, ...)
    tq = [_pow(t[:, i], n2 - 1.0) for i in range(d)] if d == 2 else \
        [_pow(t[:, 0], n2 - 1.0), _pow(t[:, 1], n2 - 1.0), _pow(t[:, 2], n1 - 1.0)]
    u = tq[0] * t[:, 0] + tq[1] * t[:, 1]               # ≥ 1 unless the largest ratio is along y3
    u_safe = np.where(u > 0, u, 1.0)
    uk = _pow(u, k)
    A = uk + (tq[2] * t[:, 2] if d == 3 else 0.0)       # ≥ 1: the largest ratio t_i is 1
    phi = _pow(A, 1.0 / n1)
    if order == 0:
        return s * phi
    # ∂A/∂y_i (times a_i s, sign restored below), in t
    gA = np.empty((M, d))
    uk1 = np.where(u > 0, uk / u_safe, 0.0)
    for i in range(2):
        gA[:, i] = k * uk1 * n2 * tq[i]
    if d == 3:
        gA[:, 2] = n1 * tq[2]
    c1 = phi / A / n1
    grad = c1[:, None] * gA * sign / axes
    if order < 2:
        return s * phi, grad
    hA = np.zeros((M, d, d))
    uk2 = uk1 / u_safe
    du = [n2 * tq[i] for i in range(2)]
    for i in range(2):
        for j in range(2):
            hA[:, i, j] = k * (k - 1.0) * uk2 * du[i] * du[j]
        hA[:, i, i] += k * uk1 * n2 * (n2 - 1.0) * _below(t[:, i], tq[i], n2)
    if d == 3:
        hA[:, 2, 2] = n1 * (n1 - 1.0) * _below(t[:, 2], tq[2], n1)
    c2 = (1.0 / n1) * (1.0 / n1 - 1.0) * phi / (A * A)
    sa = sign / axes
    hess = (c1[:, None, None] * hA + c2[:, None, None] * gA[:, :, None] * gA[:, None, :]) * sa[:, :, None] * sa[:, None, :]
    return s * phi, grad, hess / s[:, None, None]


def shape_operator(grad, hess):
    """W = P ∇∇φ P / |∇φ| (M, d, d) and the outward unit normal ν (M, d): positive on convex surfaces."""
    g = np.linalg.norm(grad, axis=1)
    nu = grad / g[:, None]
    Hn = np.einsum("mij,mj->mi", hess, nu)                       # P H P = H − ν(Hν)ᵀ − (Hν)νᵀ + (νᵀHν) ν⊗ν
    nHn = np.sum(Hn * nu, axis=1)
    W = (hess - nu[:, :, None] * Hn[:, None, :] - Hn[:, :, None] * nu[:, None, :]
         + nHn[:, None, None] * nu[:, :, None] * nu[:, None, :]) / g[:, None, None]
    return 0.5 * (W + np.swapaxes(W, 1, 2)), nu


# ------------------------------------------------------------------------------------------ foot points

def foot_points(y, axes, blockiness):
    """The nearest surface point s (M, d) to each body point y (M, d), its outward unit normal ν and the signed
    distance (y − s)·ν (M,) (> 0 outside). In units of the body size L = max a_i (scale-free): Riemannian Newton
    on D(s) = ½|s − y|² over the surface, from the radial projection y/φ(y); steps in the tangent plane on the
    Hessian I − ((s − y)·ν) W (shifted to be positive definite where it is not), capped at L/4, the iterate pulled
    back onto the surface radially (φ is 1-homogeneous), halved until D does not grow. Points deeper than
    DEEP·(smallest semi-axis) also start from the surface points straight above and below them along each body
    axis, and keep the nearest local minimum. Raises RuntimeError if an iteration does not converge."""
    y = np.asarray(y, float)
    M, d = y.shape
    axes = np.broadcast_to(np.asarray(axes, float), (M, d))
    nb = np.broadcast_to(np.asarray(blockiness, float), (M, 2))
    L = axes.max(axis=1)
    yn, an = y / L[:, None], axes / L[:, None]          # unit body size: the iteration is scale-free
    s = _foot(yn, an, nb)
    _, g = implicit(s, an, nb, order=1)
    nu = g / np.linalg.norm(g, axis=1)[:, None]
    return s * L[:, None], nu, np.sum((yn - s) * nu, axis=1) * L


def _foot(yn, an, nb):
    """`foot_points`' nearest surface points (M, d) in units of the body size (module docstring)."""
    d = yn.shape[1]
    phi = implicit(yn, an, nb, order=0)
    s = _descend(yn, yn / phi[:, None], an, nb)
    deep = np.flatnonzero((phi < 1) & (np.linalg.norm(s - yn, axis=1) > DEEP * an.min(axis=1)))
    if deep.size:
        best = np.linalg.norm(s[deep] - yn[deep], axis=1)
        for axis in range(d):
            for side in (-1.0, 1.0):
                start = yn[deep].copy()
                start[:, axis] = side * an[deep, axis]
                trial = _descend(yn[deep], start / implicit(start, an[deep], nb[deep], order=0)[:, None],
                                 an[deep], nb[deep])
                dist = np.linalg.norm(trial - yn[deep], axis=1)
                better = dist < best
                s[deep[better]], best[better] = trial[better], dist[better]
    return s


def _descend(y, s, axes, nb):
    """Riemannian Newton for the nearest surface point from starts s (on the surface), unit body size."""
    M, d = y.shape
    s = s.copy()
    active = np.arange(M)
    for _ in range(MAX_NEWTON):
        if active.size == 0:
            return s
        ya, sa, aa, na = y[active], s[active], axes[active], nb[active]
        _, g, h = implicit(sa, aa, na)
        gnorm = np.linalg.norm(g, axis=1)
        nu = g / gnorm[:, None]
        T = _tangent_basis(nu)
        diff = sa - ya
        gt = np.einsum("mki,mk->mi", T, diff)
        Wt = np.swapaxes(T, 1, 2) @ h @ T / gnorm[:, None, None]          # Tᵀ W T = Tᵀ ∇∇φ T / |∇φ| (P T = T)
        Ht = np.eye(d - 1) - np.sum(diff * nu, axis=1)[:, None, None] * Wt
        shift = np.maximum(0.1 - _lowest_eigenvalue(Ht), 0.0)          # keeps the step a descent direction
        step = -_solve_small(Ht + shift[:, None, None] * np.eye(d - 1), gt)
        length = np.linalg.norm(step, axis=1)
        step *= np.minimum(1.0, MAX_STEP / np.maximum(length, 1e-300))[:, None]
        D0 = np.sum(diff * diff, axis=1)
        floor = 16 * EPS * (np.sum(ya * ya, axis=1) + 1.0)
        t = np.ones(len(active))
        for _ in range(50):
            trial = sa + np.einsum("mki,mi->mk", T, t[:, None] * step)
            trial /= implicit(trial, aa, na, order=0)[:, None]
            worse = np.sum((trial - ya) ** 2, axis=1) > D0 + floor
            if not worse.any():
                break
            t[worse] *= 0.5
        s[active] = trial
        done = (t == 1.0) & (length <= np.maximum(STEP_CONVERGED, 1e3 * EPS * np.sqrt(D0)))
        active = active[~done & (t * length > 0)]
    if active.size:
        raise RuntimeError(f"foot point: Newton did not converge for {active.size} point(s), e.g. body point "
                           f"{y[active[0]].tolist()} (unit body size)")
    return s


def _lowest_eigenvalue(A):
    """Lowest eigenvalue (M,) of symmetric (M, k, k): closed forms for k = 1, 2 (eigvalsh costs ~10× more)."""
    if A.shape[1] == 1:
        return A[:, 0, 0]
    if A.shape[1] == 2:
        mean = 0.5 * (A[:, 0, 0] + A[:, 1, 1])
        return mean - np.hypot(0.5 * (A[:, 0, 0] - A[:, 1, 1]), 0.5 * (A[:, 0, 1] + A[:, 1, 0]))
    return np.linalg.eigvalsh(A)[:, 0]


def _solve_small(A, b):
    """x (M, k) with A x = b for A (M, k, k): closed forms for k = 1, 2 (batched linalg.solve costs ~10× more)."""
    if A.shape[1] == 1:
        return b / A[:, 0]
    if A.shape[1] == 2:
        det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
        return np.stack([A[:, 1, 1] * b[:, 0] - A[:, 0, 1] * b[:, 1],
                         A[:, 0, 0] * b[:, 1] - A[:, 1, 0] * b[:, 0]], axis=1) / det[:, None]
    return np.linalg.solve(A, b[..., None])[..., 0]


def _tangent_basis(nu):
    """(M, d, d−1) orthonormal basis of the tangent plane (2D: e3 × ν)."""
    if nu.shape[1] == 2:
        return np.stack([-nu[:, 1], nu[:, 0]], axis=-1)[..., None]
    pick = np.argmin(np.abs(nu), axis=1)
    e = np.zeros_like(nu)
    e[np.arange(len(nu)), pick] = 1.0
    t1 = e - np.sum(e * nu, axis=1)[:, None] * nu
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return np.stack([t1, np.cross(nu, t1)], axis=-1)


# ------------------------------------------------------------------------------------------ curvature

def parallel_operator(W, nu, depth):
    """W (I − depth·W)⁻¹ (M, d, d) on the tangent plane of ν: the shape operator of the parallel surface at
    inward offset `depth` (M,). Raises ValueError where depth reaches a radius of curvature (I − depth·W singular
    on the tangent plane: the parallel surface is degenerate)."""
    M, d = nu.shape
    T = _tangent_basis(nu)
    Tt = np.swapaxes(T, 1, 2)
    Wt = Tt @ W @ T
    Bt = np.eye(d - 1) - depth[:, None, None] * Wt
    Bt = 0.5 * (Bt + np.swapaxes(Bt, 1, 2))
    bad = np.flatnonzero(~(_lowest_eigenvalue(Bt) > 0))
    if bad.size:
        raise ValueError(f"contact {bad[0]}: the depth {depth[bad[0]]:.6g} reaches a radius of curvature "
                         "(the parallel surface is degenerate)")
    if d == 3:                                                   # the 2×2 inverse in closed form
        det = Bt[:, 0, 0] * Bt[:, 1, 1] - Bt[:, 0, 1] * Bt[:, 1, 0]
        inv = np.stack([np.stack([Bt[:, 1, 1], -Bt[:, 0, 1]], -1), np.stack([-Bt[:, 1, 0], Bt[:, 0, 0]], -1)], -2)
        inv /= det[:, None, None]
    else:
        inv = 1.0 / Bt
    V = T @ (Wt @ inv) @ Tt
    return 0.5 * (V + np.swapaxes(V, 1, 2))


def parallel_curvature(points, centres, rotations, axes, blockiness):
    """The shape operators V = W (I − depth·W)⁻¹ (M, d, d), world axes, of each grain's parallel surface through
    `points` (module docstring), the foot points' outward unit normals ν (M, d, world) and the depths (M,) (> 0: the
    point is inside the grain). points, centres (M, d); rotations (M, d, d) body → world; axes (M, d); blockiness
    (M, 2)."""
    y = np.einsum("mji,mj->mi", rotations, points - centres)          # Rᵀ (x − c)
    L = np.max(axes, axis=1)
    yn, an = y / L[:, None], axes / L[:, None]
    s = _foot(yn, an, np.broadcast_to(np.asarray(blockiness, float), (len(y), 2)))
    _, g, h = implicit(s, an, blockiness)
    W_b, nu_b = shape_operator(g, h)
    depth = np.sum((s - yn) * nu_b, axis=1) * L
    V = rotations @ (parallel_operator(W_b, nu_b, depth / L) / L[:, None, None]) @ np.swapaxes(rotations, 1, 2)
    return V, np.einsum("mij,mj->mi", rotations, nu_b), depth


def tangent_curvature(V, normal):
    """K = −P_n V P_n (M, d, d), P_n = I − n⊗n: a parallel surface's shape operator on the contact's tangent plane,
    with the paper's sign (convex < 0)."""
    P = np.eye(normal.shape[1]) - normal[:, :, None] * normal[:, None, :]
    K = -(P @ V @ P)
    return 0.5 * (K + np.swapaxes(K, 1, 2))


def contact_curvature(points, centres, rotations, axes, blockiness, normal):
    """Curvature tensors K (M, d, d) of each grain's parallel surface through the contact points on the tangent
    plane of the contact normals `normal` (M, d) (`parallel_curvature` then `tangent_curvature`), with the foot
    points' outward normals ν (M, d) and the depths (M,)."""
    V, nu, depth = parallel_curvature(points, centres, rotations, axes, blockiness)
    return tangent_curvature(V, normal), nu, depth


# ------------------------------------------------------------------------------------------ drawing

@lru_cache(maxsize=256)
def _mesh(a, b, c, n1, n2, resolution):
    eta = np.linspace(-np.pi / 2, np.pi / 2, resolution + 1)
    omega = np.linspace(-np.pi, np.pi, 2 * resolution, endpoint=False)
    E, Om = np.meshgrid(eta, omega, indexing="ij")

    def spow(v, e):
        return np.sign(v) * np.abs(v) ** e

    ce = spow(np.cos(E), 2.0 / n1)
    verts = np.stack([a * ce * spow(np.cos(Om), 2.0 / n2), b * ce * spow(np.sin(Om), 2.0 / n2),
                      c * spow(np.sin(E), 2.0 / n1)], axis=-1).reshape(-1, 3)
    m = 2 * resolution
    i, j = np.meshgrid(np.arange(resolution), np.arange(m), indexing="ij")
    v00 = i * m + j
    v01 = i * m + (j + 1) % m
    v10 = v00 + m
    v11 = v01 + m
    faces = np.concatenate([np.stack([v00, v01, v11], -1).reshape(-1, 3),
                            np.stack([v00, v11, v10], -1).reshape(-1, 3)])
    verts.flags.writeable = False
    faces.flags.writeable = False
    return verts, faces


def mesh(shape, resolution: int = 16):
    """One shared triangle mesh of a 3D shape in body axes (read-only, cached per shape): vertices (V, 3) and
    faces (F, 3) of the parametric surface (signed powers 2/n1, 2/n2 of cos, sin), outward-wound. The poles
    repeat vertices (degenerate triangles there are harmless to draw)."""
    axes, n = parameters(shape)
    return _mesh(*map(float, axes), float(n[0]), float(n[1]), int(resolution))


def outline(shape, points: int = 64) -> np.ndarray:
    """Closed outline (points, 2) of a 2D shape (ellipse, disk, or a superquadric's a-b section) in body axes."""
    axes, n = parameters(shape)
    t = np.linspace(0.0, 2 * np.pi, points, endpoint=False)
    e = 2.0 / n[1]
    return np.stack([axes[0] * np.sign(np.cos(t)) * np.abs(np.cos(t)) ** e,
                     axes[1] * np.sign(np.sin(t)) * np.abs(np.sin(t)) ** e], axis=1)


# ------------------------------------------------------------------------------------------ mass

def _beta(x, y):
    return math.exp(math.lgamma(x) + math.lgamma(y) - math.lgamma(x + y))


def mass_properties(shape) -> tuple[float, np.ndarray]:
    """Volume and the inertia tensor per unit mass (3, 3), body axes, of a uniform solid superquadric (closed form
    with beta functions, Jaklič, Leonardis & Solina 2000, Sec. 2.5, with ε1 = 2/n1, ε2 = 2/n2)."""
    (a, b, c), (n1, n2) = parameters(shape)
    e1, e2 = 2.0 / n1, 2.0 / n2
    volume = 2 * a * b * c * e1 * e2 * _beta(e1 / 2 + 1, e1) * _beta(e2 / 2, e2 / 2)
    k = 0.5 * a * b * c * e1 * e2
    plane = _beta(1.5 * e2, e2 / 2) * _beta(e1 / 2, 2 * e1 + 1)
    axial = 4 * c * c * _beta(e2 / 2, e2 / 2 + 1) * _beta(1.5 * e1, e1 + 1)
    inertia = k * np.array([b * b * plane + axial, a * a * plane + axial, (a * a + b * b) * plane])
    return volume, np.diag(inertia / volume)


__all__ = ["Superquadric", "contact_curvature", "foot_points", "implicit", "mass_properties", "mesh", "outline",
           "parallel_curvature", "parallel_operator", "tangent_curvature",
           "parameters", "shape_operator"]
