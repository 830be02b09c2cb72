"""Test support: exact nonlinear statics of rigid ellipses/ellipsoids with compliant contacts, differentiated.

Independent of granstab's stiffness code. The model is the one the paper linearises (Sec. 2.2-2.3):

* every contact (p, q) has the exact common normal n^pq of the two rigid shapes (maximiser of the gap
  g(n) = (x^q - x^p)·n - h_p(n) - h_q(-n), h the support function), surface points P, Q, overlap
  δ = (P - Q)·n and contact point c = (P + Q)/2;
* force on p:  f^pq = -k δ n + αk (I - n⊗n)(a_q - a_p), a tangential spring between material anchors that
  move rigidly with their bodies, placed in the reference configuration at c ∓ s/2 with s = f_t/(αk). Its
  linearisation is 𝔡f = F δu_def (eq:ContactF, elastic), the tilt f × (dn × n) and the twirl
  -½((dθ^p + dθ^q)·n) f × n of eq:delfpq (P_t(ω × s) = -(ω·n) s × n for s ⊥ n);
* optional rotational spring m^pq = k_r (θ^q - θ^p) (exact for the one-body perturbations used here);
* loads that hold each rigid body in equilibrium (eq:equil1): b^p = -Σ f^pq, w^p = -Σ (r^pq × f^pq + m^pq),
  r^pq = c - x^p.

H_exact = ∂[b, w]/∂[u, θ] with x^p → x^p + u^p and R^p → expm([θ^p]×) R^p (spatial rotation increment), dof
order per particle (u, θ). Derivatives by the complex step, ∂L/∂y_j = Im L(y + i h e_j)/h with h = 1e-30:
no subtractive cancellation, so H_exact is exact to round-off in double precision (every operation below is
complex-analytic: bilinear dot products, no abs/conj). `central_difference` gives the same matrix by
Richardson-extrapolated central differences in real arithmetic, to validate the complex-step machinery.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from granstab.model import shapes as gshapes

CSTEP = 1e-30
NEWTON_ITERS = 6   # from the converged reference normal: quadratic convergence, 2-3 iterations reach round-off


# ---------------------------------------------------------------------------------- complex-analytic algebra

def dot(a, b):
    """Bilinear a·b over the last axis (no conjugation)."""
    return np.sum(a * b, axis=-1)


def mv(A, v):
    return np.einsum("...ij,...j->...i", A, v)


def cross(a, b):
    """a × b: (…, 3) in 3D, the e3 component (…, 1) in 2D."""
    if a.shape[-1] == 2:
        return (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])[..., None]
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def rotation(theta):
    """expm([θ]×) for rotation vectors θ (…, r): 2D angle (r = 1), 3D Rodrigues with analytic sin(t)/t and
    (1 - cos t)/t² of t² = θ·θ (series below |t²| = 1e-4, so t = 0 and complex steps are exact)."""
    theta = np.asarray(theta)
    if theta.shape[-1] == 1:
        c, s = np.cos(theta[..., 0]), np.sin(theta[..., 0])
        return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    t2 = dot(theta, theta)
    small = np.abs(t2) < 1e-4
    t = np.sqrt(np.where(small, 1.0, t2))
    a = np.where(small, 1 - t2 / 6 + t2**2 / 120 - t2**3 / 5040, np.sin(t) / t)
    b = np.where(small, 0.5 - t2 / 24 + t2**2 / 720 - t2**3 / 40320, (1 - np.cos(t)) / np.where(small, 1.0, t2))
    z = np.zeros_like(theta[..., 0])
    K = np.stack([np.stack([z, -theta[..., 2], theta[..., 1]], -1),
                  np.stack([theta[..., 2], z, -theta[..., 0]], -1),
                  np.stack([-theta[..., 1], theta[..., 0], z], -1)], -2)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def tangent_frame(n, pick):
    """Analytic orthonormal tangent basis (…, d, d-1) of the bilinear-unit n; `pick` (…,) is the index of the
    axis used to seed it in 3D (fixed from the real reference normal)."""
    if n.shape[-1] == 2:
        return np.stack([-n[..., 1], n[..., 0]], -1)[..., None]
    e = np.zeros(n.shape)
    np.put_along_axis(e, pick[..., None], 1.0, axis=-1)
    t1 = e - dot(e, n)[..., None] * n
    t1 = t1 / np.sqrt(dot(t1, t1))[..., None]
    return np.stack([t1, cross(n, t1)], -1)


# --------------------------------------------------------------------------------------------- the model

@dataclass
class Cluster:
    """Reference configuration: bodies (x0 (N, d), R0 (N, d, d), semi-axes (N, d)) and contacts (p, q (M,),
    k, alpha, k_r (M,), anchors a_p0, a_q0 (M, d), reference normals n0 (M, d))."""

    x0: np.ndarray
    R0: np.ndarray
    axes: np.ndarray
    p: np.ndarray
    q: np.ndarray
    k: np.ndarray
    alpha: np.ndarray
    k_r: np.ndarray
    a_p0: np.ndarray
    a_q0: np.ndarray
    n0: np.ndarray
    blockiness: np.ndarray | None = None   # (N,) superquadrics with n1 = n2 = ν (3D); None: ellipses/ellipsoids

    @property
    def dim(self) -> int:
        return self.x0.shape[1]

    @property
    def rdim(self) -> int:
        return 1 if self.dim == 2 else 3


def ellipsoid_support(S):
    """n ↦ (h, ∇h, ∇²h) of the support function h(n) = sqrt(nᵀSn)."""
    def support(n):
        Sn = mv(S, n)
        h = np.sqrt(dot(n, Sn))
        return h, Sn / h[..., None], S / h[..., None, None] - Sn[..., :, None] * Sn[..., None, :] / h[..., None, None] ** 3
    return support


def superquadric_support(R, axes, nu):
    """n ↦ (h, ∇h, ∇²h) of a superquadric with n1 = n2 = ν, rotation R (body → world): with m = Rᵀn, w_i = (a_i m_i)²
    and q = ν/(ν − 1), h = (Σ w_i^(q/2))^(1/q) (the dual norm; complex-analytic for m_i ≠ 0)."""
    q = (nu / (nu - 1.0))[..., None]
    a2 = axes**2

    def support(n):
        m = mv(np.swapaxes(R, -1, -2), n)
        w = a2 * m * m
        H = np.sum(w ** (q / 2), axis=-1)
        e = 1.0 / q[..., 0]
        g = w ** (q / 2 - 1) * a2 * m
        grad_b = (H ** (e - 1))[..., None] * g
        hess_b = ((H ** (e - 1))[..., None, None] * (q[..., None] - 1) * _diag(a2 * w ** (q / 2 - 1))
                  + ((1 - q[..., 0]) * H ** (e - 2))[..., None, None] * g[..., :, None] * g[..., None, :])
        return H ** e, mv(R, grad_b), R @ hess_b @ np.swapaxes(R, -1, -2)
    return support


def _diag(v):
    return v[..., :, None] * np.eye(v.shape[-1])


def common_normal(d, sup_p, sup_q, n, pick, iters=NEWTON_ITERS):
    """Newton on the sphere for ∇g ∥ n, g(n) = d·n − h_p(n) − h_q(n) (centrally symmetric bodies, so h_q(−n) = h_q(n)),
    i.e. Tᵀ(d − ∇h_p − ∇h_q) = 0, with the exact Riemannian Hessian Tᵀ(∇²g)T − g I at each iterate (re-centred
    tangent chart), in complex arithmetic. sup_p, sup_q: n ↦ (h, ∇h, ∇²h)."""
    for _ in range(iters):
        hp, Gp, Hp = sup_p(n)
        hq, Gq, Hq = sup_q(n)
        g = dot(d, n) - hp - hq
        grad = d - Gp - Gq
        hess = -(Hp + Hq)
        T = tangent_frame(n, pick)
        Tt = np.swapaxes(T, -1, -2)
        J = Tt @ hess @ T - g[..., None, None] * np.eye(T.shape[-1])
        a = -np.linalg.solve(J, mv(Tt, grad)[..., None])[..., 0]
        n = (n + mv(T, a)) / np.sqrt(1 + dot(a, a))[..., None]
    return n


def contact_state(cl: Cluster, x, R):
    """Exact contact geometry for body positions x (…, N, d) and rotations R (…, N, d, d):
    normal n, overlap δ, contact point c (…, M, …)."""
    if cl.blockiness is None:
        A2 = cl.axes**2
        S = (R * A2[..., None, :]) @ np.swapaxes(R, -1, -2)
        sup_p, sup_q = ellipsoid_support(S[..., cl.p, :, :]), ellipsoid_support(S[..., cl.q, :, :])
    else:
        sup_p, sup_q = (superquadric_support(R[..., i, :, :], cl.axes[i], cl.blockiness[i]) for i in (cl.p, cl.q))
    xp, xq = x[..., cl.p, :], x[..., cl.q, :]
    pick = np.broadcast_to(np.argmin(np.abs(cl.n0), axis=-1), xp.shape[:-1])
    n = common_normal(xq - xp, sup_p, sup_q, np.broadcast_to(cl.n0, xp.shape).astype(x.dtype), pick)
    P = xp + sup_p(n)[1]
    Q = xq - sup_q(n)[1]
    return n, dot(P - Q, n), 0.5 * (P + Q)


def loads(cl: Cluster, u, theta):
    """[b, w] per particle (…, N, d + r) for translations u (…, N, d) and rotation vectors θ (…, N, r)."""
    E = rotation(theta)
    x = cl.x0 + u
    R = E @ cl.R0
    n, delta, c = contact_state(cl, x, R)
    Ep, Eq = E[..., cl.p, :, :], E[..., cl.q, :, :]
    a_p = x[..., cl.p, :] + mv(Ep, cl.a_p0 - cl.x0[cl.p])
    a_q = x[..., cl.q, :] + mv(Eq, cl.a_q0 - cl.x0[cl.q])
    s = a_q - a_p
    f = (-cl.k * delta)[..., None] * n + (cl.alpha * cl.k)[..., None] * (s - dot(s, n)[..., None] * n)
    m = cl.k_r[..., None] * (theta[..., cl.q, :] - theta[..., cl.p, :])
    N = cl.x0.shape[0]
    Ip = np.eye(N)[:, cl.p]            # (N, M) incidence of the p side
    Iq = np.eye(N)[:, cl.q]
    tau_p = cross(c - x[..., cl.p, :], f) + m
    tau_q = cross(c - x[..., cl.q, :], -f) - m
    b = np.einsum("nm,...md->...nd", Iq - Ip, f)
    w = -np.einsum("nm,...md->...nd", Ip, tau_p) - np.einsum("nm,...md->...nd", Iq, tau_q)
    return np.concatenate([b, w], axis=-1)


def _perturbations(cl: Cluster, steps):
    """Per dof j (particle i, local l) and step value: u (J, N, d) and θ (J, N, r) with y_j = step."""
    N, d, r = cl.x0.shape[0], cl.dim, cl.rdim
    J = N * (d + r)
    steps = np.asarray(steps)
    u = np.zeros((J, N, d), steps.dtype)
    th = np.zeros((J, N, r), steps.dtype)
    for j in range(J):
        i, comp = divmod(j, d + r)
        if comp < d:
            u[j, i, comp] = steps
        else:
            th[j, i, comp - d] = steps
    return u, th


def stiffness_exact(cl: Cluster) -> np.ndarray:
    """H_exact = ∂[b, w]/∂[u, θ] by the complex step (rows and columns: particles in order, (u, θ) each)."""
    u, th = _perturbations(cl, np.complex128(1j * CSTEP))
    L = loads(cl, u, th)                                   # (J, N, d + r)
    return (L.imag / CSTEP).reshape(L.shape[0], -1).T


def central_difference(cl: Cluster, h=1e-3) -> np.ndarray:
    """The same matrix by central differences with two Richardson steps (h, h/2, h/4): truncation O(h⁶)."""
    def cd(step):
        up, tp = _perturbations(cl, step)
        L = loads(cl, up, tp) - loads(cl, -up, -tp)
        return (L / (2 * step)).reshape(L.shape[0], -1).T
    D1, D2, D4 = cd(h), cd(h / 2), cd(h / 4)
    R1, R2 = (4 * D2 - D1) / 3, (4 * D4 - D2) / 3
    return (16 * R2 - R1) / 15


def reference_loads(cl: Cluster) -> np.ndarray:
    """[b, w] (N, d + r) in the reference configuration."""
    N = cl.x0.shape[0]
    return loads(cl, np.zeros((N, cl.dim)), np.zeros((N, cl.rdim)))


# ------------------------------------------------------------------------------------------ construction

def cluster_from_scene(scene, particles, k_r=0.0) -> Cluster:
    """The exact model of a shape scene: bodies from `particles` (name, shape, (x, orientation)), contacts and
    tangential forces from `scene` (f_t = f - (f·n)n fixes the anchors a_p0, a_q0 = c ∓ f_t/(2αk)); the normal
    is re-solved here (the scene's normal is only the start)."""
    dim = scene.dim
    x0 = np.array([np.asarray(pose[0], float) for _, _, pose in particles])
    R0 = np.array([gshapes.rotation_matrix(dim, pose[1]) for _, _, pose in particles])
    axes = np.array([shape.semi_axes for _, shape, _ in particles], float)
    base = Cluster(x0=x0, R0=R0, axes=axes, p=scene.p, q=scene.q, k=scene.k, alpha=scene.alpha,
                   k_r=np.full(scene.n_contacts, float(k_r)), a_p0=scene.point, a_q0=scene.point,
                   n0=scene.normal)
    n, _, c = contact_state(base, x0, R0)
    s = (scene.force - np.sum(scene.force * n, axis=1)[:, None] * n) / (scene.alpha * scene.k)[:, None]
    base.n0, base.a_p0, base.a_q0 = n, c - s / 2, c + s / 2
    return base


def press(particles, pairs, delta, iters=40):
    """Move bodies 1.. (body 0 fixed) so that every listed pair (i, j) overlaps by exactly `delta`: Gauss-Newton
    with minimum-norm steps on δ_c(x) - delta, using ∂δ/∂x^q = -n, ∂δ/∂x^p = n. Returns new particles."""
    names = [nm for nm, _, _ in particles]
    shapes_ = [sh for _, sh, _ in particles]
    orient = [pose[1] for _, _, pose in particles]
    x = np.array([np.asarray(pose[0], float) for _, _, pose in particles])
    dim = x.shape[1]
    S = np.array([gshapes.shape_tensor(sh, o) for sh, o in zip(shapes_, orient)])
    p, q = np.array(pairs).T
    for _ in range(iters):
        d = x[q] - x[p]
        n = gshapes.common_normals(d, S[p], S[q], np.zeros(len(p), bool))
        hp = np.sqrt(np.einsum("mi,mij,mj->m", n, S[p], n))
        hq = np.sqrt(np.einsum("mi,mij,mj->m", n, S[q], n))
        res = hp + hq - np.sum(d * n, axis=1) - delta
        if np.abs(res).max() <= 1e-15 * max(delta, 1.0):
            break
        Jac = np.zeros((len(p), x.size))
        for c in range(len(p)):
            Jac[c, p[c] * dim:(p[c] + 1) * dim] += n[c]
            Jac[c, q[c] * dim:(q[c] + 1) * dim] -= n[c]
        step = np.linalg.lstsq(Jac[:, dim:], -res, rcond=None)[0]
        x[1:] += step.reshape(-1, dim)
    return [(nm, sh, (xi, o)) for nm, sh, xi, o in zip(names, shapes_, x, orient)]
