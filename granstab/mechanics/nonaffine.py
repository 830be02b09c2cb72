"""A rigorous bound of the part of the stiffness's change over the data's band that is NOT affine in the forces
(issue 42): positions (branch vectors, normals, contact frames, curvature radii, the rigid-motion projection) and, in
3D, the turn of a sliding contact's direction h with its tangential force.

The model of the position band of length ℓ (`Band.position`): every particle centre and contact point moves by at
most ℓ, so each radial vector r^pq = c − x^p by at most 2ℓ; the normal follows the centre line b^pq (round
particles), so it turns by at most θ = arcsin(2ℓ/|b^pq|) (inf where 2ℓ >= |b^pq|), and the contact frame, the
curvature tensors and a rolling stiffness turn with it (by a rotation of angle θ, ‖R − I‖ <= θ); each principal
radius of curvature moves by at most 2ℓ (as the arm of a disk does): ‖ΔK‖ <= ρ‖K‖, ρ = 2ℓκ/(1 − 2ℓκ). Forces stay
within their own band (|f'| <= |f| + δ) and are not turned. The metric's L is the data's (a choice of the analysis).

Ball arithmetic, per contact and vectorised over contacts: each factor A of the blocks carries a bound a >= ‖A‖₂
and a bound α >= ‖A' − A‖₂ over the band; ‖Δ(AB)‖ <= aβ + αb + αβ, ‖Δ(A + B)‖ <= α + β and a block matrix
[A; B] (or [A B]) has ‖·‖ <= (‖A‖² + ‖B‖²)^½ for both its size and its change. The factors are those of
stiffness.contact_blocks in the scaled dofs [du, L dθ] (U = D Ũ): B̃u = [−I, −X(r^pq)/L, I, X(r^qp)/L] (eq:dudef),
the rolling and contact-frame maps (eq:rolling, eq:Drpq, eq:Dnpq), the force rotation C_f = (f·n)I − n⊗f (eq:Dfpq,
eq:A3), statics rows [−δf; −(r × δf + δm)/L] (eq:Matrix2), so that Hg1 (eq:Hg1), Hg2 (eq:equilibrium4), Hg3
(eq:Hg3) and the elastic Hm (eq:Hm, eq:ContactF: F = k[αI + (1 − α)n⊗n]) each get a change bound. The
pseudo-inverse Γ = (K^p + K^q)^+ on the tangent plane (eq:rolling) keeps its rank d − 1 (n' spans the kernel) while
‖Γ‖ε < 1: ‖ΔΓ‖ <= √2 ‖Γ'‖² ε (Wedin, equal ranks), ‖Γ'‖ <= ‖Γ‖/(1 − ‖Γ‖ε), ε the change of the projected sum; inf
where a cut-off eigenvalue may cross pinv_rtol's threshold or a contact with force has a dropped rolling. A contact
that may slide adds a ⊗ s (eq:flow, eq:Hdirection): h = f_t/|f_t| moves by at most 2(δ + θ(|f| + δ))/|f_t| (3D;
2D with its sign fixed: by θ, since h = ±t), a = [h; r^pq × h/L; −h; −r^qp × h/L], s = B̃uᵀ g, g = k(αh + μn).

Every function of ℓ (and of δ = t δ₁) above is convex and increasing and zero at 0 (arcsin, 1/(1 − x), products
and sums of such, norms of vectors of them), so a bound e(t) at a band factor t is convex with e(0) = 0:
e(s) <= (s/t) e(t) for s <= t, which is how `granstab.uncertainty` turns a few evaluations into margins.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.law import sliding_direction, tangential_ratio
from ..model.vec import rot_dim
from .rigid import rotation_columns
from .stiffness import kinematics, tangent_curvatures

SLACK = 1.0 + 1e-9      # the bound is formed in floating point from O(100) operations: rounded up by this factor


@dataclass(frozen=True, eq=False)
class Ball:
    """Per contact (M,): `size` >= ‖A‖₂ and `moved` >= ‖A' − A‖₂ over the band."""

    size: np.ndarray
    moved: np.ndarray

    def __add__(self, other: Ball) -> Ball:
        return Ball(self.size + other.size, self.moved + other.moved)

    def __matmul__(self, other: Ball) -> Ball:
        return Ball(self.size * other.size,
                    self.size * other.moved + self.moved * other.size + self.moved * other.moved)

    def __mul__(self, c) -> Ball:
        return Ball(self.size * c, self.moved * c)


def stack(*parts: Ball) -> Ball:
    """[A; B; …] (or side by side): sizes and changes add in squares."""
    return Ball(np.sqrt(sum(p.size ** 2 for p in parts)), np.sqrt(sum(p.moved ** 2 for p in parts)))


def _fixed(size) -> Ball:
    size = np.asarray(size, dtype=float)
    return Ball(size, np.zeros_like(size))


def normal_turn(scene, length: float) -> np.ndarray:
    """θ (M,): the normal's largest turn when both centres move by `length` (arcsin(2ℓ/|b|), inf where 2ℓ >= |b|)."""
    ratio = 2.0 * length / np.linalg.norm(scene.branch, axis=1)
    with np.errstate(invalid="ignore"):
        return np.where(ratio < 1.0, np.arcsin(np.minimum(ratio, 1.0)), np.inf) * SLACK


def _norm2(K: np.ndarray) -> np.ndarray:
    return np.abs(np.linalg.eigvalsh(0.5 * (K + np.swapaxes(K, -1, -2)))).max(axis=-1)


def _curvatures(scene, ell: float, turn: Ball, theta: np.ndarray):
    """Balls of K^p, K^q restricted to the tangent plane (P_t K P_t) and of Γ = (K^p + K^q)^+ there."""
    def radius_change(kappa):
        x = 2.0 * ell * kappa
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(x < 1.0, x / (1.0 - x), np.inf)
    spin = (1.0 + theta) ** 2 - 1.0
    kp, kq, ks = (_norm2(getattr(scene, k)) for k in ("curvature_p", "curvature_q", "curvature_sum"))
    rp, rq = radius_change(kp), radius_change(kq)
    Kp = Ball(kp, kp * ((1 + rp) * (1 + theta) ** 2 - 1))
    Kq = Ball(kq, kq * ((1 + rq) * (1 + theta) ** 2 - 1))
    Ks = turn @ Ball(ks, ks * spin + rp * kp + rq * kq) @ turn
    _, _, G, cut, _ = tangent_curvatures(scene)
    g = _norm2(G)
    eps = Ks.moved
    cutoff = scene.tol.pinv_rtol * (np.maximum(kp, kq) + np.maximum(Kp.moved, Kq.moved))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ok = (g * eps < 1.0) & (1.0 / np.where(g > 0, g, np.inf) - eps > cutoff)
        moved = np.where(ok, np.sqrt(2.0) * eps * (g / (1.0 - g * eps)) ** 2, np.inf)
    moved = np.where(cut, np.inf, moved)
    return turn @ Kp @ turn, turn @ Kq @ turn, Ball(g, moved)


def contact_changes(scene, ell: float, L: float, delta: np.ndarray, delta_m: np.ndarray, v=None) -> dict:
    """`_changes` with every floating-point exception ignored (an unbounded factor is inf, inf·0 is read as inf)."""
    with np.errstate(all="ignore"):
        return _changes(scene, ell, L, delta, delta_m, v)


def _changes(scene, ell: float, L: float, delta: np.ndarray, delta_m: np.ndarray, v=None) -> dict:
    """Per contact (M,) bounds over the band (module docstring), inf where none holds: `block`, ‖Δ X̃_c‖ with X̃_c =
    D(Hg1 + Hg2 + Hg3 + Hm_el)D; `slide`, ‖Δ D(a ⊗ s)D‖ (a contact that may slide); `s`, ‖Δ D s‖ (S = s·U moves by at
    most that × ‖Ũ_c‖); `rigid`, a bound of ‖(Hg3 + ½(Hg1 + Hg2))'‖ over the band (the only parts a rigid rotation
    of consistent geometry feels: δu_def = δθ_def = 0 there, and A1ᵀ, aᵀ, sᵀ vanish on it). With `v` (M, n), a
    motion's scaled dofs at each contact, `block` and `slide` bound the change of its work v_cᵀX̃_c v_c instead: the
    right factors enter as B̃u v, B̃t v, |θ̃| of the data (exact sizes), the geometric parts by |v|‖Δ(X̃_g v)‖ and
    the elastic and sliding parts as quadratic forms in y = B̃u v (`_quadratic`; a ⊗ s: (h·y)(g·y)), so a mode no
    contact deforms (rolling: y = 0) has no first-order change of its elastic work. ell: the position band (0: forces only, the 3D
    sliding turn), L the metric's rotation length, delta, delta_m (M,) the force and moment radii."""
    d, r = scene.dim, rot_dim(scene.dim)
    theta = normal_turn(scene, ell) if ell > 0 else np.zeros(scene.n_contacts)
    turn = Ball(np.ones_like(theta), theta)                       # n, n⊗n, P_t, X(n): size 1, change <= θ
    arm = 2.0 * ell / L
    Rp = Ball(np.linalg.norm(scene.r_pq, axis=1) / L, np.full_like(theta, arm))
    Rq = Ball(np.linalg.norm(scene.r_qp, axis=1) / L, np.full_like(theta, arm))
    one = _fixed(np.ones_like(theta))
    Bu_matrix = stack(one, Rp, one, Rq)
    if v is None:
        Bu, Bt, th_p, th_q = Bu_matrix, _fixed(np.full_like(theta, np.sqrt(2.0) / L)), one, one
    else:
        Bu_phys, Bt_phys = kinematics(scene)
        scale = np.tile(np.r_[np.ones(d), np.full(r, 1.0 / L)], 2)           # U = D Ũ over [du^p, dθ^p, du^q, dθ^q]
        th_p, th_q = (_fixed(np.linalg.norm(v[:, k:k + r], axis=1)) for k in (d, 2 * d + r))
        du_def = np.einsum("mdn,mn->md", Bu_phys, scale * v)
        Bu = Ball(np.linalg.norm(du_def, axis=1), arm * (th_p.size + th_q.size))
        Bt = _fixed(np.linalg.norm(np.einsum("mdn,mn->md", Bt_phys, scale * v), axis=1))
    Kp, Kq, G = _curvatures(scene, ell, turn, theta)
    fmag = np.linalg.norm(scene.force, axis=1) + delta
    mmag = np.linalg.norm(scene.moment, axis=1) + delta_m
    G = Ball(G.size, np.where(fmag + mmag > 0, G.moved, 0.0))     # Γ enters only through f and m
    twist, du_t = turn @ Bt, turn @ Bu
    st_p, st_q = G @ (twist + Kq @ du_t), G @ (twist + Kp @ du_t)
    dr_p, dr_q = turn @ Bu * 0.5 + st_p, turn @ Bu * 0.5 + st_q

    def rotation_of(mag):                                         # C = (v·n)I − n⊗v and the twirl ½(v × n)(n·B̃t)
        C = Ball(2 * mag, 2 * mag * theta)
        twirl = Ball(0.5 * mag, 0.5 * mag * theta) @ (turn @ Bt) if d == 3 else _fixed(np.zeros_like(mag))
        return lambda dn: C @ dn + twirl

    df, dm = rotation_of(fmag), rotation_of(mmag)
    has_m = scene.has_moments and d == 3

    def statics(R, f_rows, m_rows):
        return stack(f_rows, R @ f_rows + (m_rows * (1.0 / L) if m_rows is not None else _fixed(0 * theta)))

    Hg2 = stack(statics(Rp, df(Kp @ st_p), dm(Kp @ st_p) if has_m else None),
                statics(Rq, df(Kq @ st_q), dm(Kq @ st_q) if has_m else None))
    Xf = _fixed(fmag / L)
    Hg1 = stack(Xf @ dr_p, Xf @ dr_q)
    a = tangential_ratio(scene.alpha, scene.mu)
    F = Ball(scene.k * (np.abs(a) + np.abs(1 - a)), scene.k * np.abs(1 - a) * theta)
    roll = None
    if scene.has_rolling:
        kr = _norm2(scene.rolling)
        roll = Ball(kr, kr * ((1 + theta) ** 2 - 1))
    Hm = stack(statics(Rp, F @ Bu, roll @ Bt if roll else None),
               statics(Rq, F @ Bu, roll @ Bt if roll else None)) if v is None else None
    blocks = [Xf @ th_p, Xf @ th_q]
    if d == 3:
        blocks += [Ball((Rp.size * fmag + mmag / L) / L, arm * fmag / L) @ th_p,
                   Ball((Rq.size * fmag + mmag / L) / L, arm * fmag / L) @ th_q]
    Hg3 = stack(*blocks)
    slide, s = _sliding(scene, theta, delta, fmag, Rp, Rq, Bu_matrix, v, Bu)
    rigid = Hg3 + (Hg1 + Hg2) * 0.5
    if v is None:
        block = (Hg1 + Hg2 + Hg3 + Hm).moved
    else:          # the work: |v|‖Δ(geometric v)‖, and Hm = B̃uᵀF B̃u + B̃tᵀ M B̃t (eq:Hm) as quadratic forms in B̃u v, B̃t v
        block = np.linalg.norm(v, axis=1) * (Hg1 + Hg2 + Hg3).moved + _quadratic(F, Bu)
        block = block + (_quadratic(roll, Bt) if roll else 0.0)
    return {k: np.nan_to_num(x * SLACK, nan=np.inf) for k, x in
            (("block", block), ("slide", slide.moved), ("s", s.moved), ("rigid", rigid.size + rigid.moved))}


def _quadratic(A: Ball, y: Ball) -> np.ndarray:
    """|Δ(yᵀAy)| <= ‖A‖(2|y|η + η²) + ‖ΔA‖(|y| + η)², η the change of y."""
    return A.size * (2 * y.size * y.moved + y.moved ** 2) + A.moved * (y.size + y.moved) ** 2


def _sliding(scene, theta, delta, fmag, Rp, Rq, Bu, v=None, y=None):
    """Balls of a ⊗ s (with v: of the work (a·v)(s·v) = −(h·y)(g·y), y = B̃u v the Ball of δu_def) and of s (eq:flow): h within 2(δ + θ|f'|)/|f_t| (3D), θ (2D, the sign of
    f_t fixed: h = ±t)."""
    ft = np.linalg.norm(scene.force - np.sum(scene.force * scene.normal, axis=1, keepdims=True) * scene.normal,
                        axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        h_moved = theta if scene.dim == 2 else np.where(ft > 0, 2 * (delta + theta * fmag) / ft, np.inf)
    h_moved = np.where(np.isnan(h_moved), np.inf, h_moved)
    h = Ball(np.linalg.norm(sliding_direction(scene.force, scene.normal), axis=1), h_moved)
    a_ = stack(h, Rp @ h, h, Rq @ h)
    g = Ball(scene.k * (scene.alpha + scene.mu), scene.k * (scene.alpha * h_moved + scene.mu * theta))
    s = Bu @ g
    if v is None:
        return a_ @ s, s
    return (h @ y) @ (g @ y), s


def projection_change(scene, ell: float, L: float, rotations: int) -> float:
    """‖P̃' − P̃‖₂ for the orthogonal projector onto the rigid motions in scaled dofs (eq:Prr, eq:Pnrr): the
    translations do not move; the rotations C̃ about the centroid (eq:dtrigid) move by ‖ΔC̃‖ <= ℓ√N (the centred
    positions move by the centring projection of the moves: Σ_p |Δx̂_p|² <= N ℓ²), and for subspaces of equal dimension
    ‖P' − P‖ = ‖(I − P')P‖ <= ‖ΔC̃‖ ‖C̃⁺‖, ‖C̃⁺‖ = λ_min(C̃ᵀC̃)^-½ with C̃ᵀC̃ >= N L² I. 0 without rotations."""
    if rotations == 0 or ell <= 0:
        return 0.0
    if not np.isfinite(ell):
        return np.inf
    C = rotation_columns(scene.x, L)
    n = scene.n_particles
    low = max(n * L * L, float(np.linalg.eigvalsh(C.T @ C).min()) * (1 - 1e-9))
    return ell * np.sqrt(n) / np.sqrt(low) * SLACK


def symmetric_norm(blocks, Dp: np.ndarray, may_slide: np.ndarray, n_dof: int) -> float:
    """A bound of ‖sym(D H^i D)‖₂ over every branch (H^i: the elastic and geometric blocks plus a ⊗ s of any subset
    of the `may_slide` contacts): the largest absolute row sum of the blocks' entries, assembled (symmetric)."""
    from .stiffness import geometric
    X = (geometric(blocks.blocks) + blocks.blocks["Hm"]) * Dp[:, :, None] * Dp[:, None, :]
    rows = np.abs(0.5 * (X + np.swapaxes(X, 1, 2))).sum(axis=2)
    a, s = np.abs(blocks.slide_left) * Dp, np.abs(blocks.slide_right) * Dp      # ã = D a, s̃ = D s
    rows = rows + may_slide[:, None] * 0.5 * (a * s.sum(axis=1, keepdims=True) + s * a.sum(axis=1, keepdims=True))
    total = np.zeros(n_dof)
    np.add.at(total, blocks.index, rows)
    return float(total.max(initial=0.0)) * SLACK
