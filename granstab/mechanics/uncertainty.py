"""How far the stiffness can move when the measured contact forces move within their stated uncertainty (issue 42).

H = Hg1 + Hg2 + Hg3 + Hm (eq:final1). On a fixed loading branch and with every contact's yield state fixed, H is
affine in the contact forces and moments: Hg1 (eq:Hg1), Hg2 (eq:equilibrium4) and Hg3 (eq:Hg3) are linear in
(f, m) contact by contact, the elastic Hm (eq:Hm, eq:ContactF) does not depend on them, and in 2D the sliding
term a ⊗ s of a contact at yield depends only on the sign of its tangential force (h = ±t, eq:Hdirection). So a
change δf_c of contact c's force changes H by exactly Σ_j δf_cj G_cj, G_cj the geometric block of contact c for a
unit force along e_j, and in the metric's dofs (U = D Ũ)

    ‖Δ sym(𝓗)‖₂ <= Σ_c ‖δf_c‖ β_c,   β_c = (Σ_j ‖sym(D_c G_cj D_c)‖₂²)^½        (Cauchy–Schwarz; P orthogonal)

and Weyl's inequality |λ_i(A + E) − λ_i(A)| <= ‖E‖₂ moves no eigenvalue further. For a fixed vector v (a consistent
negative eigenvector, eq:instab) the change of its second-order work is exactly linear: vᵀΔ𝓗v = Σ_c δf_c·w_c with
w_cj = U_cᵀ G_cj U_c (U = D P v over the contact's dofs), whose worst case over the band is Σ_c δ_c ‖w_c‖ (first
order and exact: no remainder, H being affine). Both are added to the floating-point bounds of accuracy.py.

Contacts whose mobilisation is itself uncertain (state "auto" and within the band of the cone |f_t| = μ f_n) count
in both states: the caller adds their sliding branches. Where f_t can vanish within the band no bound is given
(`unbounded`); where h turns (3D) or positions move, the sliding term and the geometry are not affine in the band:
nonaffine.py bounds that part.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..model.errors import SceneError
from ..model.tolerances import EPS
from ..model.vec import rot_dim
from .stiffness import contact_blocks, geometric

SAFETY = 1.0 + 1e-10      # the norms below are computed in floating point: rounded up by this relative amount


@dataclass(frozen=True)
class Band:
    """The stated uncertainty of the data: each contact force within rel·|f| + abs (and moment within rel·|m|) of
    its measured value (`per_contact` (M,), from a file's columns, replaces rel·|f| + abs where given); positions
    (particle centres and contact points) within `position` (nonaffine.py: the model and its rigorous bound)."""

    rel: float = 0.0
    abs: float = 0.0
    position: float = 0.0
    per_contact: np.ndarray | None = None

    def force_radius(self, force: np.ndarray) -> np.ndarray:
        """δ_c (M,): the radius of contact c's force ball."""
        if self.per_contact is not None:
            return np.asarray(self.per_contact, dtype=float)
        return self.rel * np.linalg.norm(force, axis=1) + self.abs

    def moment_radius(self, moment: np.ndarray) -> np.ndarray:
        return self.rel * np.linalg.norm(moment, axis=1)

    def describe(self) -> str:
        parts = [f"forces ±({self.rel:g}·|f| + {self.abs:g})" if self.per_contact is None
                 else "forces ± the file's per-contact uncertainty"]
        if self.position:
            parts.append(f"positions ±{self.position:g}")
        return ", ".join(parts)


def band_from(options: dict, scene) -> Band:
    """The Band of a scan's `uncertainty` option for `scene` (a packing, chunk or cluster): rel, abs, position and,
    with "per_contact" (`--force-uncertainty file`), the scene's own contacts' `force_err` (the file's columns)."""
    per = None
    if options.get("per_contact"):
        if scene.force_err is None:
            raise SceneError(f"{scene.source}: --force-uncertainty file: the input has no per-contact uncertainty "
                             "columns (f_err, or fn_err and ft_err; a scene file's force_err: docs/formats.md)")
        per = scene.force_err
    return Band(rel=options.get("rel", 0.0), abs=options.get("abs", 0.0), position=options.get("position", 0.0),
                per_contact=per)


def parse_force_uncertainty(text: str) -> tuple[float, float]:
    """`REL[,ABS]` → (rel, abs), each finite and >= 0 (ValueError naming the field otherwise)."""
    fields = text.split(",")
    if not 1 <= len(fields) <= 2:
        raise ValueError(f"--force-uncertainty: REL[,ABS], got {text!r}")
    try:
        values = [float(v) for v in fields]
    except ValueError:
        raise ValueError(f"--force-uncertainty: REL[,ABS] are numbers, got {text!r}") from None
    if not all(np.isfinite(v) and v >= 0 for v in values):
        raise ValueError(f"--force-uncertainty: REL and ABS must be finite and >= 0, got {text!r}")
    return values[0], (values[1] if len(values) == 2 else 0.0)


def unit_blocks(scene) -> np.ndarray:
    """G (M, J, n, n): the geometric blocks Hg1 + Hg2 + Hg3 of each contact for a unit force along each axis (J = d)
    and, where the scene has contact moments, a unit moment about each axis (J = d + r); linear in (f, m)."""
    d, r = scene.dim, rot_dim(scene.dim)
    axes = [np.eye(d)[j] for j in range(d)]
    out = []
    for j in range(d + (r if scene.has_moments else 0)):
        f = np.zeros_like(scene.force)
        m = np.zeros_like(scene.moment)
        if j < d:
            f[:] = axes[j]
        else:
            m[:, j - d] = 1.0
        probe = replace(scene, force=f, moment=m, state=("elastic",) * scene.n_contacts)
        out.append(geometric(contact_blocks(probe).blocks))
    return np.stack(out, axis=1)


def contact_norms(G: np.ndarray, Dp: np.ndarray) -> np.ndarray:
    """β (P,) for the unit blocks G (P, J, n, n) of P (cluster, contact) entries in metric scales Dp (P, n) (0 on held
    dofs): (Σ_j ‖sym(D G_j D)‖₂²)^½, rounded up."""
    X = G * Dp[:, None, :, None] * Dp[:, None, None, :]
    X = 0.5 * (X + np.swapaxes(X, -1, -2))
    norms = np.abs(np.linalg.eigvalsh(X)).max(axis=-1) + 8 * EPS * np.abs(X).sum(axis=-1).max(axis=-1)
    return np.sqrt(np.sum(norms ** 2, axis=1)) * SAFETY


def radius(scene, band: Band) -> np.ndarray:
    """‖(δf_c, δm_c)‖ at most (M,): the force radius and the moment radius together."""
    return np.hypot(band.force_radius(scene.force), band.moment_radius(scene.moment))


def mobilisation(scene, band: Band) -> dict:
    """Which contacts' yield state the band leaves open (eq:yield, Q = |f_t| + μ f·n): `uncertain` (M,) bool, state
    "auto" not at yield whose Q can reach the cone (|ΔQ| <= (1 + μ)(δ + θ(|f| + δ)), θ the normal's turn under a
    position band (nonaffine.normal_turn), plus the yield test's own tolerance); `unbounded` (M,) bool, contacts that
    may be at yield and whose tangential force can vanish within the band (|f_t| <= δ + θ(|f| + δ): the sign of f_t
    open in 2D, h undefined in 3D); `turning` (M,) bool, contacts that may slide and whose sliding term is not affine
    in the band (3D with δ > 0: h turns with f_t; any with a position band), bounded by nonaffine.py."""
    from .nonaffine import normal_turn
    delta = band.force_radius(scene.force)
    at_yield = scene.at_yield()
    Q = scene.yield_function()
    scale = np.linalg.norm(scene.force, axis=1) + delta
    theta = normal_turn(scene, band.position) if band.position > 0 else np.zeros(scene.n_contacts)
    move = delta + theta * scale
    reach = (1.0 + scene.mu) * move + scene.tol.yield_rtol * scale
    uncertain = (np.asarray(scene.state) == "auto") & ~at_yield & (Q >= -reach) & (move > 0)
    may_slide = at_yield | uncertain
    ft = np.linalg.norm(scene.tangential_force(), axis=1)
    unbounded = may_slide & (ft <= move * SAFETY) & (move > 0)
    turning = may_slide & ((delta > 0) & (scene.dim == 3) | (theta > 0))
    return {"uncertain": uncertain, "unbounded": unbounded, "turning": turning}


def margins(lam, bounds, codes, e, owner, groups: int, rigid: int, consistent) -> dict:
    """Per group (a cluster's branches) the band factors its verdict survives (flat per-eigenvalue arrays, `owner`
    the group of each): `stable` = min over non-rigid eigenvalues of (λ − δ)/e (Weyl: > 1 keeps every one positive
    for every force in the band) and `unstable` = max over consistent ones of (−λ − δ)/e (the fixed eigenvector's
    work stays negative and its S values do not move); e (groups,) the band's ‖Δ sym(𝓗)‖ bound, 0: inf/−inf."""
    e_flat = np.asarray(e, dtype=float)[owner]
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(e_flat > 0, (lam - bounds) / e_flat, np.where(lam - bounds > 0, np.inf, -np.inf))
        down = np.where(e_flat > 0, (-lam - bounds) / e_flat, np.where(-lam - bounds > 0, np.inf, -np.inf))
    stable = np.full(groups, np.inf)
    np.minimum.at(stable, owner, np.where(codes != rigid, up, np.inf))
    unstable = np.full(groups, -np.inf)
    np.maximum.at(unstable, owner, np.where(np.isin(codes, consistent), down, -np.inf))
    return {"stable": stable, "unstable": unstable}


def work_gradient(G: np.ndarray, U: np.ndarray) -> np.ndarray:
    """w (M, J): the change of a fixed motion's second-order work Uᵀ H U per unit force (and moment) component,
    U (M, n) the motion over each contact's dofs (physical, U = D P v): w_cj = U_cᵀ G_cj U_c."""
    return np.einsum("mi,mjik,mk->mj", U, G, U)


def focused_factors(lam, bounds, share, e, need: float) -> np.ndarray:
    """Per eigenvalue (rows of one branch each, (L, n), sorted) the band factor t up to which it cannot become a
    counted non-positive mode of a focused verdict (analysis.focus: a mode with λ <= its bound counts only with at
    least `need` of its squared norm inside, `share`): it stays positive, (λ − δ)/e (Weyl), or it stays outside:
    the perturbed eigenvector is within sin θ <= te/(g − te) of the computed one (Davis–Kahan, g its gap to the
    other eigenvalues less both bounds), so its share is at most (√share + sin θ)² < need while
    t < c g / (e (1 + c)), c = √need − √share − √2 δ/g > 0 (the last: the computed vector's angle to the exact
    one). e (L,): the band's bound of each row."""
    e = np.asarray(e, dtype=float)[:, None]
    gaps = np.full(lam.shape, np.inf)
    if lam.shape[1] > 1:
        step = np.diff(lam, axis=1) - bounds[:, 1:] - bounds[:, :-1]
        gaps[:, 1:] = step
        gaps[:, :-1] = np.minimum(gaps[:, :-1], step)
    with np.errstate(divide="ignore", invalid="ignore"):
        computed = np.where(gaps > 0, np.minimum(1.0, np.sqrt(2) * bounds / gaps), 1.0)   # the computed vector's own
        c = np.sqrt(need) - np.sqrt(np.clip(share, 0.0, 1.0)) - computed                    # angle to the exact one
        positive = np.where(e > 0, (lam - bounds) / e, np.where(lam - bounds > 0, np.inf, -np.inf))
        outside = np.where((c > 0) & (gaps > 0), c * gaps / (e * (1 + c)), -np.inf)
    return np.maximum(positive, outside)
