"""Rigid motions and the no-rigid-rotation projection (Sec. 2.4), applied as low-rank updates.

C (eq:dtrigid) maps a cluster rotation dθ̄ to particle motions du^p = dθ̄ × x^p, dθ^p = dθ̄ with x measured
from the centroid; C⁺ = (CᵀC)⁻¹Cᵀ (eq:Moore1), P^rr = C C⁺ (eq:Prr), P^nrr = I - P^rr (eq:Pnrr), and
ℍ = H P^nrr, 𝓗 = P^nrrᵀ H P^nrr (eq:newstiffnesses). P is never formed: P v = v - C (C⁺ v).

Dof scaling. The paper's C⁺ is the least-squares fit of |du - dθ̄ × x|² + |dθ - dθ̄|², which adds a length² to
an angle²; and because Hg3·C ≠ 0 the spectra of ℍ and 𝓗 depend on that weighting. granstab works in scaled
dofs Ũ = [du, L dθ] (U = D Ũ, D = diag(1, 1/L)), H̃ = D H D, C̃ = D⁻¹ C, with L the mean contact radius |r^pq|:
every eigenvalue then has units of force/length and is invariant when all lengths are scaled. With L = 1 this
is the paper's literal metric (all of the paper's examples have r = 1, so they are reproduced unchanged).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.scene import Scene, mean_contact_radius
from ..model.tolerances import EPS
from ..model.vec import rot_dim, rotate_matrix

rotation_length = mean_contact_radius   # the default L of the scaled dofs [du, L dθ]


def dof_scale(n: int, d: int, length) -> np.ndarray:
    """Diagonal of D = diag(1 for translations, 1/L for rotations) of n particles in d dimensions, U = D Ũ:
    (n_dof,) for one length, (..., n_dof) for a stack of them (...)."""
    rotation = np.tile(np.r_[np.zeros(d), np.ones(rot_dim(d))].astype(bool), n)
    return np.where(rotation, 1.0 / np.asarray(length, float)[..., None], 1.0)


def translation_columns(n: int, d: int, lead: tuple = ()) -> np.ndarray:
    """T (*lead, n_dof, d): rigid translations of n particles (the same in scaled and unscaled dofs)."""
    r = rot_dim(d)
    T = np.zeros((*lead, n, d + r, d))
    T[..., :d, :] = np.eye(d)
    return T.reshape(*lead, n * (d + r), d)


def centred(x: np.ndarray, weights=None, defect: bool = False):
    """x (..., n, d) about its centroid (weighted by `weights` (..., n), e.g. masses), to ε·(spread of x), not ε·|x|.

    One pass, x - mean(x), is rounded to ε|x| through the mean: far from the origin (accepted up to 1e9 L) the
    rotations about it are then not orthogonal to the translations, and a rigid motion leaks into the spectrum by
    ε(|x|/L)‖Hg3‖ (issue 26). The second pass subtracts the mean of the (now small) differences, whose rounding is
    relative to the spread. defect=True also returns a bound (...,) of max_p |centred_p - (x_p - c)| for the exact
    centroid c (docs/bounds.md): the common offset, |Σ w_p centred_p| / Σ w summed exactly (math.fsum), plus each
    position's own rounding, u(2 max|centred| + |second mean|) twice."""
    def mean(y):
        if weights is None:
            return y.mean(axis=-2, keepdims=True)
        w = np.asarray(weights, float)
        return np.sum(w[..., :, None] * y, axis=-2, keepdims=True) / np.sum(w, axis=-1)[..., None, None]

    rel = x - mean(x)
    second = mean(rel)
    out = rel - second
    if not defect:
        return out
    u = EPS / 2
    own = u * (2 * np.abs(out).max(axis=(-2, -1)) + np.abs(second).max(axis=(-2, -1)))
    w = np.ones(x.shape[:-1]) if weights is None else np.broadcast_to(np.asarray(weights, float), x.shape[:-1])
    flat_w, flat = w.reshape(-1, x.shape[-2]), out.reshape(-1, *x.shape[-2:])
    offset = np.array([max(abs(math.fsum(wi * yi[:, k])) for k in range(x.shape[-1])) / wi.sum() * (1 + 4 * EPS)
                       + u * np.abs(yi).max(initial=0.0) for wi, yi in zip(flat_w, flat)]).reshape(x.shape[:-2])
    return out, offset + 2 * own


def rotation_columns(x: np.ndarray, length=1.0, weights=None) -> np.ndarray:
    """C̃ (..., n_dof, r): rigid rotations of the particles at x (..., n, d) about their centroid (weighted by
    `weights` (..., n): the centre of mass; eq:dtrigid, `centred`), dθ̄ × x^p and dθ̄, in scaled dofs [du, L dθ] with
    L = `length` (...) (1: physical dofs)."""
    *lead, n, d = x.shape
    r = rot_dim(d)
    C = np.zeros((*lead, n, d + r, r))
    C[..., :d, :] = rotate_matrix(centred(x, weights).reshape(-1, d)).reshape(*lead, n, d, r)
    C[..., d:, :] = np.asarray(length, float)[..., None, None, None] * np.eye(r)
    return C.reshape(*lead, n * (d + r), r)


def rotations(scene: Scene, length: float = 1.0) -> np.ndarray:
    """C̃ (n_dof, r) of a scene: rigid rotations about the centroid (eq:dtrigid) in scaled dofs [du, L dθ]; none,
    (n_dof, 0), in a periodic scene: a rotation is not compatible with the images, only the d translations are rigid."""
    if scene.periodic:
        return np.zeros((scene.n_dof, 0))
    return rotation_columns(scene.x, length)


def translations(scene: Scene) -> np.ndarray:
    """T (n_dof, d) of a scene: rigid translations."""
    return translation_columns(scene.n_particles, scene.dim)


def untouched_dofs(H, *factors: np.ndarray, scale: float, dofs: np.ndarray | None = None) -> np.ndarray:
    """The dofs (indices) whose row and column of H (dense or sparse) and whose rows of every factor (A, S, Ξ, …)
    are zero within 64 eps·`scale`: motions no contact feels — the free spins of frictionless disks and spheres
    (F = k n⊗n, a round surface turning in place), particles without contacts. `dofs` (bool mask) limits the
    search (e.g. to rotation dofs)."""
    tiny = 64 * np.finfo(float).eps * scale
    if hasattr(H, "tocsr"):                     # one pass over the entries (a column max of CSR converts it to CSC)
        A = H.tocsr()
        loud = ~(np.abs(A.data) <= tiny)                                 # NaN counts as felt
        felt = np.zeros(A.shape[0], bool)
        felt[np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))[loud]] = True
        felt[A.indices[loud]] = True
        rows = np.where(felt, np.inf, 0.0)
    else:
        rows = np.maximum(np.abs(H).max(axis=1, initial=0.0), np.abs(H).max(axis=0, initial=0.0))
    for F in factors:
        rows = np.maximum(rows, np.abs(F).max(axis=1, initial=0.0))
    quiet = rows <= tiny
    return np.flatnonzero(quiet if dofs is None else quiet & dofs)


def free_spins(scene, H, *factors: np.ndarray, scale: float) -> np.ndarray:
    """The free spins of a periodic scene (`untouched_dofs` among the rotation dofs of particles that have contacts:
    frictionless round particles turning in place), set aside with the rigid motions; none in a free cluster.
    In a periodic scene the rigid motions are the d translations, to which the spins are orthogonal, so the spins are
    exact zero modes of sym(𝓗) and setting them aside moves no other eigenvalue. In a free cluster the rigid
    rotations have spin parts and Hg3 (the loads) does not vanish on them: holding the spins too would also hold the
    orbital rotation and move the other eigenvalues (tests/mechanics/test_metric.py, the pair potential's dynamical matrix),
    so there they stay in the spectrum as zeros. A particle without contacts is a rattler: all its dofs stay."""
    if not scene.periodic:
        return np.zeros(0, dtype=np.intp)
    touching = np.zeros(scene.n_particles, bool)
    touching[np.r_[scene.p, scene.q]] = True
    dofs = rotation_dofs(scene.n_particles, scene.dim) & np.repeat(touching, scene.dof_per_particle)
    return untouched_dofs(H, *factors, scale=scale, dofs=dofs)


def rotation_dofs(n_particles: int, dim: int) -> np.ndarray:
    """(n_dof,) bool: True on the rotation dofs."""
    return np.tile(np.r_[np.zeros(dim), np.ones(rot_dim(dim))].astype(bool), n_particles)


def unit_columns(n: int, index: np.ndarray) -> np.ndarray:
    """(n, len(index)) columns e_j."""
    out = np.zeros((n, len(index)))
    out[index, np.arange(len(index))] = 1.0
    return out


def rigid_basis(motions: np.ndarray, complement: bool = False):
    """(R, N): an orthonormal basis R (..., n, m) of the rigid motions (..., n, m), [T, C] with the translations
    first, from one Householder QR (R[..., :d] spans T, R[..., d:] the rotations C, which every metric of metric.py
    makes orthogonal to T: rotations about the centroid, or the centre of mass in the inertia metric); with
    complement=True N (..., n, n - m), an orthonormal basis of their complement (complete QR), else N is empty.
    A stack of clusters gives the bits of each cluster alone."""
    Q, _ = np.linalg.qr(motions, mode="complete" if complement else "reduced")
    m = motions.shape[-1]
    return Q[..., :m], Q[..., m:]


def on_complement(N: np.ndarray, H: np.ndarray, *factors: np.ndarray) -> tuple:
    """sym(Nᵀ H N) and Nᵀ F of each factor F (sliding factors A, S): a problem on the orthonormal basis N (..., n, k)
    of the complement of the rigid motions, where every branch's sym(Nᵀ 𝓗^i N) = sym(Nᵀ H^i N) (Nᵀ P = Nᵀ for
    P = I - C C̃⁺ and N ⟂ C, eq:Moore1, eq:newstiffnesses): the d + r rigid zeros taken out exactly."""
    Nt = np.swapaxes(N, -1, -2)
    HN = Nt @ (H @ N)
    return (0.5 * (HN + np.swapaxes(HN, -1, -2)), *(Nt @ F for F in factors))


@dataclass(frozen=True, eq=False)
class Projection:
    """P^nrr = I - C C⁺ as a low-rank operator (eq:Pnrr, eq:Prr); C (n, r) the rotations, each column scaled by a
    power of two (`from_rotations`), C⁺ (r, n)."""

    C: np.ndarray
    Cplus: np.ndarray

    @classmethod
    def from_rotations(cls, C: np.ndarray) -> Projection:
        """P^nrr of the rotations C (..., n, r) (a stack of clusters too); r = 0 (a cluster held by fixed particles):
        the identity. Each column is first scaled by a power of two to a largest entry in [1, 2): exact, P = C C⁺ is
        unchanged, and CᵀC can neither underflow nor overflow (a cluster at 1e-78 L in the inertia metric has
        entries ~1e-156: CᵀC was subnormal and C⁺ infinite)."""
        if C.shape[-1]:
            top = np.abs(C).max(axis=-2, keepdims=True)
            C = C * np.ldexp(1.0, -np.frexp(np.where(top > 0, top, 1.0))[1] + 1)
        Ct = np.swapaxes(C, -1, -2)
        return cls(C=C, Cplus=np.linalg.solve(Ct @ C, Ct) if C.shape[-1] else Ct.copy())

    def apply(self, v: np.ndarray) -> np.ndarray:
        """P^nrr v for v (..., n) or (..., n, k)."""
        return v - self.C @ (self.Cplus @ v)

    def right(self, H) -> np.ndarray:
        """ℍ = H P^nrr = H - (H C) C⁺ (eq:newstiffnesses); H dense (…, n, n) or sparse."""
        return H - (H @ self.C) @ self.Cplus

    def both(self, HP: np.ndarray) -> np.ndarray:
        """𝓗 = P^nrrᵀ ℍ = ℍ - C⁺ᵀ (Cᵀ ℍ) from ℍ; P is symmetric, so P^T = P (eq:newstiffnesses)."""
        return HP - np.swapaxes(self.Cplus, -1, -2) @ (np.swapaxes(self.C, -1, -2) @ HP)

    def errors(self, rng: np.random.Generator | None = None) -> dict:
        """Idempotence ‖C⁺C - I‖ and symmetry |uᵀPv - vᵀPu| / (|u||v|) on random probes."""
        rng = rng or np.random.default_rng(0)
        r = self.C.shape[1]
        u, v = rng.standard_normal((2, self.C.shape[0]))
        sym = abs(u @ self.apply(v) - v @ self.apply(u)) / (np.linalg.norm(u) * np.linalg.norm(v))
        return {"projection_idempotence": float(np.abs(self.Cplus @ self.C - np.eye(r)).max(initial=0.0)),
                "projection_symmetry": float(sym)}
