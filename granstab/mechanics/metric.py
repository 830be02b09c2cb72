"""The metric of the no-rigid-rotation projection (Sec. 2.4): which motions count as "rigid rotation removed".

C⁺ of eq:Moore1 is a least-squares fit, so it needs a metric on [du, dθ]; because Hg3·C ≠ 0 the spectra of ℍ and
𝓗 depend on it (issue 11). Every metric here is a block-diagonal D per particle with U = D Ũ: the analysis works in
Ũ, where the metric is Euclidean, so P^nrr = I - C̃ C̃⁺ is the orthogonal projector (C̃ = D⁻¹ C) and
sym(𝓗) = P D sym(H) D P.

* `L` metrics, D = diag(1, 1/L): Ũ = [du, L dθ]; every eigenvalue in force/length. L = the mean contact radius
  ("L") is invariant when all lengths are scaled; L = 1 is the paper's literal metric; the family adds L/10, 10L.
* the inertia metric, D = M^-1/2 with M = diag(m, m, I) per particle in 2D (m, m, m and the 3×3 inertia tensor
  in the global frame in 3D): the kinetic energy. Rigid rotations about the centre of mass are M-orthogonal to the
  translations, so removing them orthogonally in Ũ removes rigid motions M-orthogonally (zero linear and angular
  momentum); sym(𝓗) is then the dynamical matrix M^-1/2 sym(H) M^-1/2 on that complement, the eigenvalues of the
  pencil (Qᵀ sym(H) Q, Qᵀ M Q) are λ = ω² and the eigenvectors D Ũ are the normal modes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..model.scene import Scene, SceneError
from ..model.vec import rot_dim
from .rigid import dof_scale, rotation_columns, translation_columns
from .rigid import rotation_length as default_length

# the family evaluated by default: the name and the factor on the default L (None: the inertia metric)
FAMILY = (("L/10", 0.1), ("L", 1.0), ("10L", 10.0), ("inertia", None))
CHOICES = ("family", "L", "L/10", "10L", "inertia")


@dataclass(frozen=True, eq=False)
class Metric:
    """A projection metric: `name` ("L", "L/10", "10L", "L=<value>" or "inertia"), `rotation_length` (L, None for
    inertia) and D per particle, `blocks` (N, per, per) symmetric positive definite, and the `weights` (N,) of the
    rotations' centre (rigid.centred; None: the centroid; masses: the centre of mass)."""

    name: str
    rotation_length: float | None
    blocks: np.ndarray
    weights: np.ndarray | None = None

    @property
    def diagonal(self) -> np.ndarray | None:
        """diag(D) (n,) when every block is diagonal, else None."""
        b = self.blocks
        off = b - np.einsum("nii->ni", b)[:, :, None] * np.eye(b.shape[1])
        return np.einsum("nii->ni", b).reshape(-1) if not np.any(off) else None

    @property
    def units(self) -> str:
        return "1/time²" if self.rotation_length is None else "force/length"

    def matrix(self) -> sp.csr_matrix:
        """D as a sparse block-diagonal matrix."""
        N, per, _ = self.blocks.shape
        return sp.bsr_matrix((self.blocks, np.arange(N), np.arange(N + 1)), shape=(N * per, N * per)).tocsr()

    def inverse_matrix(self) -> sp.csr_matrix:
        """D⁻¹ as a sparse block-diagonal matrix."""
        N, per, _ = self.blocks.shape
        inv = np.linalg.inv(self.blocks)
        return sp.bsr_matrix((inv, np.arange(N), np.arange(N + 1)), shape=(N * per, N * per)).tocsr()

    def physical(self, V: np.ndarray) -> np.ndarray:
        """U = D Ũ for Ũ (n,) or (n, k)."""
        N, per, _ = self.blocks.shape
        shape = V.shape
        return np.einsum("nij,nj...->ni...", self.blocks, V.reshape(N, per, *shape[1:])).reshape(shape)

    def scaled(self, U: np.ndarray) -> np.ndarray:
        """Ũ = D⁻¹ U for U (n,) or (n, k)."""
        N, per, _ = self.blocks.shape
        shape = U.shape
        inv = np.linalg.inv(self.blocks)
        return np.einsum("nij,nj...->ni...", inv, U.reshape(N, per, *shape[1:])).reshape(shape)

    def congruence(self, H) -> np.ndarray:
        """D H D (D symmetric) for a dense or sparse H; dense output."""
        d = self.diagonal
        if d is not None:
            Hd = H.toarray() if sp.issparse(H) else H
            return d[:, None] * Hd * d[None, :]
        D = self.matrix()
        out = D @ (D @ H).T                                                # (D H D)ᵀ = D Hᵀ D, then transpose
        out = out.T
        return out.toarray() if sp.issparse(out) else np.asarray(out)

    def sparse_congruence(self, H, inverse: bool = False, absolute: bool = False) -> sp.csr_matrix:
        """D H D for a sparse H as CSR (D⁻¹ H D⁻¹ with `inverse`, |D| H |D| with `absolute`): where every block is
        diagonal an entrywise scaling of H's entries in H's pattern, (d_i h_ij) d_j as the sparse products round it,
        O(nnz) instead of two sparse products; else those products."""
        d = self.diagonal
        if d is None:
            D = self.inverse_matrix() if inverse else self.matrix()
            D = abs(D) if absolute else D
            return (D @ H @ D).tocsr()
        d = np.abs(1.0 / d if inverse else d) if absolute else (1.0 / d if inverse else d)
        H = sp.csr_matrix(H)
        rows = np.repeat(np.arange(H.shape[0]), np.diff(H.indptr))
        return sp.csr_matrix((d[rows] * H.data * d[H.indices], H.indices.copy(), H.indptr.copy()), shape=H.shape)

    def local(self, index: np.ndarray, per: int) -> np.ndarray:
        """Per contact the block diag(D_p, D_q) (M, 2per, 2per) over its local dofs `index` (M, 2per)."""
        M = len(index)
        out = np.zeros((M, 2 * per, 2 * per))
        out[:, :per, :per] = self.blocks[index[:, 0] // per]
        out[:, per:, per:] = self.blocks[index[:, per] // per]
        return out

    def rotations(self, scene: Scene) -> np.ndarray:
        """C̃ = D⁻¹ C (n, r): rigid rotations about the `weights` centre (eq:dtrigid) in the metric's dofs; (n, 0) for a periodic
        scene, whose only rigid motions are the d translations (a rotation does not carry the images along)."""
        if scene.periodic:
            return np.zeros((scene.n_dof, 0))
        return self.scaled(rotation_columns(scene.x, 1.0, self.weights))

    def translations(self, scene: Scene) -> np.ndarray:
        """T̃ = D⁻¹ T (n, d): rigid translations in the metric's dofs."""
        return self.scaled(translation_columns(scene.n_particles, scene.dim))


def length_metric(scene: Scene, length: float, name: str | None = None) -> Metric:
    """D = diag(1, 1/L) on every particle; rotations about the centroid."""
    d, r, N = scene.dim, rot_dim(scene.dim), scene.n_particles
    per = np.diag(dof_scale(1, d, length))
    return Metric(name=name or f"L={length:.6g}", rotation_length=float(length),
                  blocks=np.broadcast_to(per, (N, d + r, d + r)).copy())


def inertia_metric(scene: Scene) -> Metric:
    """D = M^-1/2 per particle from scene.mass and scene.inertia; rotations about the centre of mass."""
    if getattr(scene, "mass", None) is None or getattr(scene, "inertia", None) is None:
        raise SceneError(f"{scene.source}: metric inertia: the scene has no masses (give particles `mass` and "
                         "`inertia`, or shapes with a density)")
    d, r, N = scene.dim, rot_dim(scene.dim), scene.n_particles
    m = np.asarray(scene.mass, float)
    J = np.asarray(scene.inertia, float).reshape(N, r, r)
    w, Q = np.linalg.eigh(0.5 * (J + np.swapaxes(J, 1, 2)))
    blocks = np.zeros((N, d + r, d + r))
    blocks[:, :d, :d] = np.eye(d) / np.sqrt(m)[:, None, None]
    blocks[:, d:, d:] = (Q / np.sqrt(w)[:, None, :]) @ np.swapaxes(Q, 1, 2)
    return Metric(name="inertia", rotation_length=None, blocks=blocks, weights=m)


def has_masses(scene: Scene) -> bool:
    return getattr(scene, "mass", None) is not None and getattr(scene, "inertia", None) is not None


def resolve(scene: Scene, metric: str = "L", rotation_length: float | None = None) -> Metric:
    """One metric by name: "L", "L/10", "10L" (L = rotation_length, default the mean contact radius), "inertia"."""
    if metric == "inertia":
        return inertia_metric(scene)
    factors = {name: f for name, f in FAMILY if f is not None}
    if metric not in factors:
        raise ValueError(f"metric must be one of {', '.join(CHOICES)}, got {metric!r}")
    base = default_length(scene) if rotation_length is None else float(rotation_length)
    return length_metric(scene, factors[metric] * base, name=metric)


def family(scene: Scene, rotation_length: float | None = None) -> list[Metric]:
    """The family evaluated by default: L/10, L, 10L around L (rotation_length or the default) and the inertia
    metric where the scene has masses. The primary metric (the one whose spectra the result shows) is "L"."""
    base = rotation_length or default_length(scene)
    out = [length_metric(scene, f * base, name=name) for name, f in FAMILY if f is not None]
    if has_masses(scene):
        out.append(inertia_metric(scene))
    return out
