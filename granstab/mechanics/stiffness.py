"""Incremental stiffness H = Hg1 + Hg2 + Hg3 + Hm (eq:final1): the contact blocks, and H of a branch assembled
(assembly.py).

Each contact contributes a block over its local dofs U = [du^p, dθ^p, du^q, dθ^q] (n = 2(d + r): 6 in 2D,
12 in 3D) with rows [db^p, dw^p, db^q, dw^q] (eq:piece). The blocks of all M contacts are built at once as
(M, n, n) arrays from per-contact linear maps (…, rows, n):

  kinematics (eq:dudef, eq:dtdef)   Bu: δu_def = du^q - du^p + dθ^q × r^qp - dθ^p × r^pq,  Bt: δθ_def
  rolling    (eq:rolling)           δs^t t^pq = -(K^p+K^q)^+ [δθ_def × n - K^q·δu_def,t]  (qp: +K^p, same n)
  contact point and normal          δr^pq = ½(δu_def·n)n + δs^t t (eq:dsn, eq:Drpq),  δn^pq = -K^p·δs^t t (eq:Dnpq)
  force rotation (eq:Dfpq, eq:A3)   f × (δn × n) - ½(δθ_def·n) f × n  — with erratum 1, docs/errata.md: the qp rows use
                                    (δθ^qp_def·n^qp) = (δθ_def·n), so both sides carry the same twirl term
  statics A1 (eq:Matrix2)           force rows -δf, moment rows -(r × δf + δm)

Hm = -A1 [F/M] B (eq:Hm), Hg2 = -A1 A2 (eq:equilibrium4), Hg1 from -δr × f (eq:Hg1), Hg3 from the corotation
of the loads, dθ^p × b^p and dθ^p × w^p written per contact (eq:Hg3). A sliding contact changes Hm by a
rank-one block a ⊗ s with s·U = S = g·δu_def (eq:flow), which the branch enumeration uses directly.
Terms a scene does not need are not built: no twirl or moment-rotation blocks in 2D, no moment blocks without
contact moments, no rolling-stiffness blocks without rolling stiffness.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..model.law import elastic_stiffness, sliding_direction, yield_normal
from ..model.scene import Scene
from ..model.tolerances import EPS
from ..model.vec import (
    cross,
    cross_matrix,
    rot_dim,
    rotate_matrix,
    spin_matrix,
    tangent_basis,
)
from .assembly import Assembly, dof_index
from .checks import identity_errors


@dataclass(frozen=True, eq=False)
class ContactBlocks:
    """Per-contact 12×12 (3D) or 6×6 (2D) blocks of every part, and where they go.

    blocks[name]: (M, n, n) for name in Hg1, Hg2, Hg3, Hm (Hm elastic);
    slide_left a, slide_right s: (M, n) — a sliding contact adds a ⊗ s to Hm, and S = s·U (eq:flow);
    index: (M, n) global dof numbers; rolling_undetermined: (M,) bool, contacts whose K^p+K^q is singular on the
    tangent plane (flat-on-flat or exact hand-in-glove) while carrying force: their rolling is not determined;
    curvature_error: (M, n, n) entrywise bound of the error of the blocks from rounding K^p + K^q (inf where
    unresolved; docs/bounds.md), None where not computed.
    """

    blocks: dict
    slide_left: np.ndarray
    slide_right: np.ndarray
    index: np.ndarray
    n_dof: int
    rolling_undetermined: np.ndarray
    curvature_error: np.ndarray | None = None


def geometric(parts: dict):
    """Hg = Hg1 + Hg2 + Hg3 (eq:final1) of a dict of parts: per-contact blocks or assembled matrices."""
    return parts["Hg1"] + parts["Hg2"] + parts["Hg3"]


def assemble_parts(scene: Scene, blocks: ContactBlocks, hm: np.ndarray | None = None) -> dict:
    """Hg1, Hg2, Hg3, Hm and H = their sum (eq:final1) as CSR over the scene's dofs (assembly.Assembly: one pattern
    for all parts); `hm`: the Hm blocks of a branch (default the elastic ones)."""
    assembly = Assembly(scene.p, scene.q, scene.dof_per_particle, blocks.n_dof)
    parts = {name: assembly(hm if name == "Hm" and hm is not None else b) for name, b in blocks.blocks.items()}
    parts["H"] = (geometric(parts) + parts["Hm"]).tocsr()
    return parts


def assembled_error(scene: Scene, error: np.ndarray | None, assembly=None):
    """The contacts' entrywise error bounds (M, n, n) summed into CSR over the scene's dofs (with `assembly`, the
    scene's assembly.Assembly where the caller has one); None where a contact's is infinite (its pseudo-inverse
    unresolved: stiffness._inverse_error)."""
    if error is None or not np.all(np.isfinite(error)):
        return None
    return (assembly or Assembly(scene.p, scene.q, scene.dof_per_particle, scene.n_dof))(error)


@dataclass(frozen=True, eq=False)
class Stiffness:
    """H = Hg1 + Hg2 + Hg3 + Hm (eq:final1) of one branch, with dof labels, error estimates and wall time.

    Attributes
    ----------
    H, Hm, Hg1, Hg2, Hg3 : ndarray or scipy.sparse.csr_matrix, (n_dof, n_dof)
        The stiffness (not symmetric in general) and its mechanical (eq:Hm) and geometric (eq:Hg1,
        eq:equilibrium4, eq:Hg3) parts; rows and columns in `dofs` order.
    dofs : list of str, (n_dof,)
        Particle by particle, translations then rotations: "p.u1", "p.u2", "p.th3" (2D); "p.u1" … "p.th3" (3D).
    errors : dict
        Relative residuals of H's exact identities (granstab.mechanics.checks).
    seconds : float
        Wall time.
    """

    H: object
    Hm: object
    Hg1: object
    Hg2: object
    Hg3: object
    dofs: list
    errors: dict
    seconds: float


def kinematics(scene: Scene):
    """Bu (M, d, n) and Bt (M, r, n): contact deformations δu_def, δθ_def from local dofs (eq:dudef, eq:dtdef)."""
    return relative_motion(scene.r_pq, scene.r_qp)


def relative_motion(r_pq: np.ndarray, r_qp: np.ndarray):
    """Bu (M, d, n), Bt (M, r, n): δu_def = du^q - du^p + dθ^q × r^qp - dθ^p × r^pq and δθ_def = dθ^q - dθ^p over
    the local dofs [du^p, dθ^p, du^q, dθ^q] (eq:dudef, eq:dtdef), from the radial vectors alone (the rigidity
    analysis's compatibility rows use the same map)."""
    M, d = r_pq.shape
    r = rot_dim(d)
    n = 2 * (d + r)
    Bu = np.zeros((M, d, n))
    Bt = np.zeros((M, r, n))
    Bu[:, :, :d] = -np.eye(d)
    Bu[:, :, d:d + r] = -rotate_matrix(r_pq)
    Bu[:, :, d + r:2 * d + r] = np.eye(d)
    Bu[:, :, 2 * d + r:] = rotate_matrix(r_qp)
    Bt[:, :, d:d + r] = -np.eye(r)
    Bt[:, :, 2 * d + r:] = np.eye(r)
    return Bu, Bt


def tangent_plane(scene: Scene):
    """The contacts' tangent bases T (M, d, d-1), the curvature sum K^p + K^q projected on the tangent plane and
    symmetrised (M, d-1, d-1), and the scale max(|K^p|, |K^q|) (M,), the largest |eigenvalue| of either on the
    tangent plane.

    The sum is the scene's `curvature_sum`, formed from the input before anything else (the readers add the 2D
    scalars; otherwise the tensors are added in the input frame): near a conforming contact (K^p + K^q ≈ 0) it is
    exact or rounded relative to the sum itself (Sterbenz), whereas projecting first rounds each term to ε|K| and
    leaves an absolute error ε|K| on a sum of size η: a relative error ε|K|/η in (K^p + K^q)^+ (docs/bounds.md)."""
    T = tangent_basis(scene.normal)
    Tt = np.swapaxes(T, 1, 2)
    ks = Tt @ scene.curvature_sum @ T
    ks = 0.5 * (ks + np.swapaxes(ks, 1, 2))
    kp = Tt @ scene.curvature_p @ T
    kq = Tt @ scene.curvature_q @ T
    scale = np.maximum(np.abs(np.linalg.eigvalsh(0.5 * (kp + np.swapaxes(kp, 1, 2)))).max(axis=1),
                       np.abs(np.linalg.eigvalsh(0.5 * (kq + np.swapaxes(kq, 1, 2)))).max(axis=1))
    return T, ks, scale


def curvature_sum_error(scene: Scene) -> np.ndarray:
    """A bound (M,) of ‖(T^T (K^p + K^q) T) as computed − exact‖₂ on the tangent plane (docs/bounds.md), the exact
    sum being that of the input data: `curvature_sum` is rounded entrywise relative to the sum (u |K^p + K^q|:
    the tensors added in the input frame, or the 2D scalars added and times t⊗t), and the projection with the
    computed basis T (orthonormal and normal to n within a few ε) adds at most 30ε‖K^p + K^q‖_F."""
    return 32 * EPS * np.linalg.norm(scene.curvature_sum, axis=(1, 2))


def tangent_curvatures(scene: Scene):
    """Tangent-plane curvatures K^p, K^q (M, d, d) and the pseudo-inverse G = (K^p+K^q)^+ on the tangent plane.

    The cut-off is scale-aware: eigenvalues of K^p+K^q below pinv_rtol·max(|K^p|, |K^q|) are dropped (Table 1,
    erratum 4, docs/errata.md). Returns (Kp, Kq, G, cut, error) with cut (M,) True where an eigenvalue was dropped
    and error (M,) a bound of ‖G − G_exact‖₂ (inf where the cut-off decision itself is not resolved; bounds.md).
    """
    T, ks, scale = tangent_plane(scene)
    lam, V = np.linalg.eigh(ks)                                       # (M, d-1)
    cutoff = scene.tol.pinv_rtol * scale[:, None]
    keep = np.abs(lam) > cutoff
    inv = np.divide(1.0, lam, out=np.zeros_like(lam), where=keep)
    TV = T @ V
    G = (TV * inv[:, None, :]) @ np.swapaxes(TV, 1, 2)
    return (_tangent(scene.curvature_p, T), _tangent(scene.curvature_q, T), G, ~keep.all(axis=1),
            _inverse_error(scene, lam, keep, cutoff))


def _tangent(K: np.ndarray, T: np.ndarray) -> np.ndarray:
    """T sym(Tᵀ K T) Tᵀ: K restricted to the tangent plane, symmetrised, in the global frame (M, d, d)."""
    Tt = np.swapaxes(T, 1, 2)
    k = Tt @ K @ T
    return T @ (0.5 * (k + np.swapaxes(k, 1, 2))) @ Tt


def _inverse_error(scene: Scene, lam: np.ndarray, keep: np.ndarray, cutoff: np.ndarray) -> np.ndarray:
    """‖Γ − Γ̂‖₂ (M,) for Γ̂ = (K^p + K^q)^+ on the tangent plane from the computed eigenvalues `lam` (M, d-1):
    with δ the error of the projected sum (`curvature_sum_error`) plus the 2×2 eigensolver's 8ε‖Ŝ‖, perturbation of
    an inverse gives ‖Γ̂‖²δ / (1 − ‖Γ̂‖δ), plus 4ε‖Γ̂‖ for forming Γ̂; inf where δ reaches half a kept eigenvalue
    or an eigenvalue is within δ of the cut-off (the exact data might be cut where the computed are not)."""
    mag = np.abs(lam)
    delta = curvature_sum_error(scene) + 8 * EPS * mag.max(axis=1, initial=0.0)
    g = np.divide(1.0, mag, out=np.zeros_like(mag), where=keep).max(axis=1, initial=0.0)
    gd = g * delta
    err = g * gd / np.maximum(1.0 - gd, 1e-300) + 4 * EPS * g
    unresolved = (gd >= 0.5) | np.any(np.abs(mag - cutoff) <= delta[:, None], axis=1) & (delta > 0)
    return np.where(unresolved, np.inf, err)


def conforming_ratio(scene: Scene) -> np.ndarray:
    """Per contact: smallest |eigenvalue| of K^p + K^q on the tangent plane over max(|K^p|, |K^q|) (0 when both are
    zero: flat-on-flat)."""
    _, ks, scale = tangent_plane(scene)
    lam = np.abs(np.linalg.eigvalsh(ks)).min(axis=1)
    return np.divide(lam, scale, out=np.zeros_like(lam), where=scale > 0)


CONFORMING_RATIO = 1e-6   # |K^p + K^q| below this times max(|K^p|, |K^q|): a nearly conforming contact (warned)


def curvature_warnings(scene: Scene, blocks: ContactBlocks) -> list[str]:
    """Warnings for contacts where the pseudo-inverse (K^p + K^q)^+ of eq:rolling decides the answer: exactly
    singular (flat-on-flat, exact hand-in-glove; the cut-off drops the rolling) or nearly so (the rolling term
    grows like 1/ratio and the answer is as sensitive to the curvature data)."""
    out = []
    bad = np.flatnonzero(blocks.rolling_undetermined)
    if bad.size:
        out.append(f"{bad.size} contact(s) (first: contacts[{bad[0]}]) have K^p + K^q singular on the "
                   "tangent plane (flat-on-flat or exact hand-in-glove): rolling is undetermined there "
                   "and the pseudo-inverse drops it; the identities below measure the consequence")
    ratio = conforming_ratio(scene)
    near = np.flatnonzero((ratio <= CONFORMING_RATIO) & ~blocks.rolling_undetermined
                          & (np.linalg.norm(scene.force, axis=1) > 0))
    if near.size:
        c = near[np.argmin(ratio[near])]
        out.append(f"{near.size} nearly conforming contact(s) (smallest |K^p + K^q| / max(|K^p|, |K^q|) = "
                   f"{ratio[c]:.1e} at contacts[{c}], cut-off pinv_rtol = {scene.tol.pinv_rtol:.0e}): the rolling "
                   "term scales like the inverse of that ratio, so the result is only as accurate as the "
                   "curvature data relative to it")
    return out


def _statics(r_side: np.ndarray, df: np.ndarray, dm) -> np.ndarray:
    """Rows of one particle for contact forces δf (M, d, n) and moments δm (M, r, n): [-δf; -(r × δf + δm)]."""
    moment = cross_matrix(r_side) @ df
    if dm is not None:
        moment = moment + dm
    return -np.concatenate([df, moment], axis=1)


def _rolling_geometric(scene: Scene, G: np.ndarray, kin: dict, affine: bool = True):
    """Hg1 and Hg2 blocks (M, n, n) for the pseudo-inverse G (M, d, d) of eq:rolling: linear in G, plus (affine) the
    terms without it (½(δu_def·n)n in δr, the twirl of eq:A3). `kin`: the per-contact maps of `contact_blocks`."""
    d, r, M = scene.dim, rot_dim(scene.dim), scene.n_contacts
    n_loc = 2 * (d + r)
    Bu, nn, twist, du_t, Kp, Kq, Cf = (kin[k] for k in ("Bu", "nn", "twist", "du_t", "Kp", "Kq", "Cf"))
    st_pq = -G @ (twist - Kq @ du_t)
    st_qp = -G @ (twist + Kp @ du_t)
    dr_pq = 0.5 * (nn @ Bu) + st_pq if affine else st_pq
    dr_qp = -0.5 * (nn @ Bu) + st_qp if affine else st_qp
    dn_pq = -Kp @ st_pq
    dn_qp = -Kq @ st_qp
    df_pq, df_qp = Cf @ dn_pq, Cf @ dn_qp
    dm_pq = dm_qp = None
    if d == 3:
        if affine:
            twirl = scene.normal[:, None, :] @ kin["Bt"]                 # (M, 1, n): δθ_def·n
            df_twirl = -0.5 * cross(scene.force, scene.normal)[:, :, None] * twirl
            df_pq, df_qp = df_pq + df_twirl, df_qp + df_twirl
        if scene.has_moments:
            m, nrm = scene.moment, scene.normal
            Cm = np.sum(m * nrm, axis=1)[:, None, None] * np.eye(3) - nrm[:, :, None] * m[:, None, :]
            dm_pq, dm_qp = Cm @ dn_pq, Cm @ dn_qp
            if affine:
                dm_twirl = -0.5 * cross(m, nrm)[:, :, None] * (nrm[:, None, :] @ kin["Bt"])
                dm_pq, dm_qp = dm_pq + dm_twirl, dm_qp + dm_twirl
    Hg2 = np.concatenate([_statics(scene.r_pq, df_pq, dm_pq), _statics(scene.r_qp, df_qp, dm_qp)], axis=1)
    Xf = cross_matrix(scene.force)
    Hg1 = np.zeros((M, n_loc, n_loc))
    Hg1[:, d:d + r] = Xf @ dr_pq
    Hg1[:, 2 * d + r:] = -Xf @ dr_qp
    return Hg1, Hg2


def _rolling_error(scene: Scene, T: np.ndarray, kin: dict, error: np.ndarray) -> np.ndarray:
    """Entrywise bound (M, n, n) of |ΔHg1 + ΔHg2| from the error ‖ΔΓ‖₂ <= error (M,) of (K^p + K^q)^+ on the
    tangent plane: ΔΓ = Σ_b c_b E_b over the symmetric basis E_b with |c_b| <= ‖ΔΓ‖₂, and Hg1 + Hg2 is affine in G,
    so |ΔH| <= ‖ΔΓ‖₂ Σ_b |Lin(T E_b Tᵀ)| (docs/bounds.md)."""
    k = T.shape[2]
    Tt = np.swapaxes(T, 1, 2)
    total = 0.0
    for i in range(k):
        for j in range(i, k):
            E = np.zeros((k, k))
            E[i, j] = E[j, i] = 1.0
            h1, h2 = _rolling_geometric(scene, T @ E @ Tt, kin, affine=False)
            total = total + np.abs(h1 + h2)
    finite = np.isfinite(error)[:, None, None]
    return np.where(finite, np.where(finite, error[:, None, None], 0.0) * total, np.where(total > 0, np.inf, 0.0))


def contact_blocks(scene: Scene) -> ContactBlocks:
    """The (M, n, n) blocks of Hg1, Hg2, Hg3 and elastic Hm for all contacts, and the sliding rank-one factors."""
    d, r, M = scene.dim, rot_dim(scene.dim), scene.n_contacts
    n_loc = 2 * (d + r)
    nrm, f = scene.normal, scene.force
    Bu, Bt = kinematics(scene)
    Kp, Kq, G, cut, g_error = tangent_curvatures(scene)
    nn = nrm[:, :, None] * nrm[:, None, :]
    Pt = np.eye(d) - nn

    # rolling (eq:rolling), contact-point and normal increments (eq:Drpq, eq:dsn, eq:Dnpq), force rotation with the
    # contact frame (eq:Dfpq, eq:Dmpq, eq:A3 with erratum 1): f × (δn × n) = Cf·δn; Hg1 from -δr × f (eq:Hg1)
    kin = {"Bu": Bu, "Bt": Bt, "nn": nn, "twist": rotate_matrix(nrm) @ Bt, "du_t": Pt @ Bu, "Kp": Kp, "Kq": Kq,
           "Cf": np.sum(f * nrm, axis=1)[:, None, None] * np.eye(d) - nrm[:, :, None] * f[:, None, :]}
    Hg1, Hg2 = _rolling_geometric(scene, G, kin)
    rolling_error = _rolling_error(scene, tangent_basis(nrm), kin, g_error)

    # mechanical stiffness, elastic branch (eq:Hm, eq:ContactF)
    F = elastic_stiffness(nrm, scene.k, scene.alpha, scene.mu)
    dfm = F @ Bu
    dmm = scene.rolling @ Bt if scene.has_rolling else None
    Hm = np.concatenate([_statics(scene.r_pq, dfm, dmm),
                         _statics(scene.r_qp, -dfm, None if dmm is None else -dmm)], axis=1)

    # third geometric stiffness: dθ^p × b^p, dθ^p × w^p per contact (eq:Hg3)
    Hg3 = np.zeros((M, n_loc, n_loc))
    tau_p = cross(scene.r_pq, f) + scene.moment
    tau_q = -(cross(scene.r_qp, f) + scene.moment)
    Hg3[:, :d, d:d + r] = -rotate_matrix(f)
    Hg3[:, d:d + r, d:d + r] = -spin_matrix(tau_p, d)
    Hg3[:, d + r:2 * d + r, 2 * d + r:] = rotate_matrix(f)
    Hg3[:, 2 * d + r:, 2 * d + r:] = -spin_matrix(tau_q, d)

    # sliding: F = F_el - h⊗g adds a ⊗ s with s = Bu^T g and a = A1 rows of [h; -h] (eq:ContactF)
    h = sliding_direction(f, nrm)
    g = yield_normal(h, nrm, scene.k, scene.alpha, scene.mu)
    s = np.einsum("mdn,md->mn", Bu, g)
    Xh_p = np.einsum("mrd,md->mr", cross_matrix(scene.r_pq), h)
    Xh_q = np.einsum("mrd,md->mr", cross_matrix(scene.r_qp), h)
    a = np.concatenate([h, Xh_p, -h, -Xh_q], axis=1)

    index = dof_index(scene.p, scene.q, d + r)
    undetermined = cut & (np.linalg.norm(f, axis=1) > 0)
    return ContactBlocks(blocks={"Hg1": Hg1, "Hg2": Hg2, "Hg3": Hg3, "Hm": Hm}, slide_left=a, slide_right=s,
                         index=index, n_dof=scene.n_dof, rolling_undetermined=undetermined,
                         curvature_error=rolling_error)


class MaskError(ValueError):
    """A branch mask that does not fit the scene."""


def sliding_mask(scene: Scene, mask) -> np.ndarray:
    """Validate a branch mask (one entry per contact: +1 sliding, -1 or 0 elastic) and return the bool (M,)."""
    mask = np.asarray(mask if mask is not None else np.zeros(scene.n_contacts), dtype=float)
    if mask.shape != (scene.n_contacts,) or not np.all(np.isin(mask, (-1, 0, 1))):
        raise MaskError(f"mask must have {scene.n_contacts} entries, each +1, -1 or 0")
    sliding = mask == 1
    bad = np.flatnonzero(sliding & ~scene.at_yield())
    if bad.size:
        raise MaskError(f"mask entry {bad[0]} is +1 but contact {bad[0]} is not at yield (Q < 0)")
    return sliding


def stiffness(scene: Scene, mask=None, sparse: bool = False, blocks: ContactBlocks | None = None) -> Stiffness:
    """H = Hg1 + Hg2 + Hg3 + Hm (eq:final1) of `scene` on one loading branch.

    Parameters
    ----------
    scene : Scene
        N particles, M contacts; n_dof = N·(d + r) (d = dim; r = 1 rotation in 2D, 3 in 3D).
    mask : array_like of int, (M,), optional
        +1 where the contact slides (only contacts at yield, eq:yield), -1 or 0 where it sticks (eq:ContactF);
        default: every contact elastic.
    sparse : bool
        CSR matrices instead of dense arrays; both come from the same assembly (assembly.py).
    blocks : ContactBlocks, optional
        The scene's contact blocks, if already computed (`contact_blocks`).

    Returns
    -------
    Stiffness
        ``H``, ``Hm``, ``Hg1``, ``Hg2``, ``Hg3`` (n_dof, n_dof), ``dofs``, ``errors``, ``seconds``.

    Raises
    ------
    MaskError
        A mask of the wrong length, or +1 on a contact that is not at yield.
    """
    start = time.perf_counter()
    sliding = sliding_mask(scene, mask)
    cb = blocks if blocks is not None else contact_blocks(scene)
    hm_blocks = cb.blocks["Hm"]
    if np.any(sliding):
        hm_blocks = hm_blocks + sliding[:, None, None] * (cb.slide_left[:, :, None] * cb.slide_right[:, None, :])
    parts = assemble_parts(scene, cb, hm_blocks)
    errors = identity_errors(scene, parts)
    if not sparse:
        parts = {name: m.toarray() for name, m in parts.items()}
    return Stiffness(dofs=scene.dofs(), errors=errors, seconds=time.perf_counter() - start, **parts)
