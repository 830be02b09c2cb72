"""The sparse path's problem (sparse.py), assembled in chunks of contacts so that memory stays linear in M: the
parts Hm, Hg1, Hg2, Hg3 and H as CSR, the scaled stiffness with its projection (`SparseProblem`), a norm estimate,
and the identity checks computed from the parts without dense matrices."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..mechanics import checks
from ..mechanics.assembly import Assembly, sliding_factors, stack_blocks
from ..mechanics.checks import modified_leakage
from ..mechanics.metric import Metric, default_length, length_metric
from ..mechanics.rigid import Projection, free_spins, rigid_basis, rotations, translations
from ..mechanics.stiffness import ContactBlocks, assembled_error, contact_blocks, geometric
from ..model.scene import CONTACT_FIELDS, Scene

CHUNK = 16384   # contacts per chunk of contact_blocks: temporaries stay ~10 MB, so the cost stays linear in M


def contact_chunks(scene: Scene, chunk: int = CHUNK):
    """(slice, ContactBlocks of those contacts) over the scene's contacts in chunks (global dof indices)."""
    import dataclasses

    M = scene.n_contacts
    if M <= chunk:
        yield slice(0, M), contact_blocks(scene)
        return
    for start in range(0, M, chunk):
        sl = slice(start, min(start + chunk, M))
        sub = dataclasses.replace(scene, **{f: getattr(scene, f)[sl] for f in CONTACT_FIELDS},
                                  state=scene.state[sl])
        yield sl, contact_blocks(sub)


@dataclass(frozen=True, eq=False)
class SparseProblem:
    """A scene set up for the sparse path, in scaled dofs Ũ = D⁻¹U (rigid.py). n = n_dof.

    H: CSR scaled elastic H̃ (non-symmetric); Hs: CSR sym(H̃); Hm: CSR scaled elastic mechanical part (for the
    preconditioner); A, S: (n, Ms) sliding factors (scaled, like branches.Problem); C: (n, r) scaled rotations;
    R: (n, d + r) orthonormal basis of all rigid motions (translations first, rigid.rigid_basis) and Q = R[:, d:]
    (n, r) that of the rotations; norm: upper bound of ‖Hs‖₂ (max absolute row sum, plus the sliding terms);
    local: stiffness.ContactBlocks without its (M, n_loc, n_loc) blocks.
    """

    scene: Scene
    length: float | None
    scale: np.ndarray | None
    metric: Metric
    H: sp.csr_matrix
    Hs: sp.csr_matrix
    Hm: sp.csr_matrix
    A: np.ndarray
    S: np.ndarray
    sliding: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    norm: float
    local: ContactBlocks
    timings: dict = field(default_factory=dict)
    free_spins: int = 0       # rotation dofs no contact feels (rigid.untouched_dofs): Hs has 2·norm there, far above

    @property
    def n(self) -> int:
        return self.H.shape[0]

    @property
    def n_rigid(self) -> int:
        return self.R.shape[1]

    @property
    def projection(self) -> Projection:
        return Projection.from_rotations(self.C)


@dataclass(frozen=True, eq=False)
class SparseParts:
    """The metric-independent part of the sparse path (physical dofs): CSR H and Hm, sliding factors A, S (n, Ms),
    the contacts' local data (ContactBlocks without blocks) and the timings of building them."""

    H: sp.csr_matrix
    Hm: sp.csr_matrix
    A: np.ndarray
    S: np.ndarray
    sliding: np.ndarray
    local: ContactBlocks
    timings: dict
    curvature_error: sp.csr_matrix | None = None   # stiffness.assembled_error: H's error from rounding K^p + K^q
    rigid_applied: dict | None = None   # Hg1, Hg2, Hm times the rigid basis (_apply_rigid), for identity_errors


def _rigid_columns(scene: Scene) -> np.ndarray:
    """The translations and unit rotations (physical dofs) that checks.identity_errors applies the parts to."""
    return np.concatenate([translations(scene), rotations(scene, 1.0)], axis=1)


def _apply_rigid(applied: dict, cb: ContactBlocks, rigid: np.ndarray, n_dof: int) -> None:
    """Add the chunk's Hg1, Hg2, Hm blocks times the rigid basis, contact by contact, scattered to `applied`."""
    local = rigid[cb.index]                                          # (m, n_loc, d + r)
    owner = np.zeros(len(cb.index), dtype=np.intp)
    for name, acc in applied.items():
        contrib = cb.blocks[name] @ local
        for j in range(rigid.shape[1]):
            acc[:, j] += stack_blocks(contrib[:, :, j], owner, cb.index, 1, n_dof)[0]


def sparse_parts(scene: Scene, chunk: int = CHUNK) -> SparseParts:
    """H and its mechanical part as CSR from the contact blocks, computed in chunks of contacts and scattered once
    (assembly.Assembly, one pattern for all three), and the sliding factors. Memory O(contacts); no per-part block arrays are kept."""
    t0 = time.perf_counter()
    per = scene.dof_per_particle
    M, n_loc = scene.n_contacts, 2 * per
    total = np.empty((M, n_loc, n_loc))
    mech = np.empty((M, n_loc, n_loc))
    a = np.empty((M, n_loc))
    s = np.empty((M, n_loc))
    index = np.empty((M, n_loc), dtype=np.intp)
    undetermined = np.zeros(M, bool)
    error = np.empty((M, n_loc, n_loc))
    rigid = _rigid_columns(scene)
    applied = {name: np.zeros(rigid.shape) for name in ("Hg1", "Hg2", "Hm")}
    for sl, cb in contact_chunks(scene, chunk):
        b = cb.blocks
        _apply_rigid(applied, cb, rigid, scene.n_dof)
        total[sl] = b["Hm"] + geometric(b)
        mech[sl] = b["Hm"]
        a[sl], s[sl], index[sl] = cb.slide_left, cb.slide_right, cb.index
        undetermined[sl] = cb.rolling_undetermined
        error[sl] = cb.curvature_error
    t1 = time.perf_counter()
    assembly = Assembly(scene.p, scene.q, per, scene.n_dof)          # one pattern for H, Hm and H's error bound
    curvature_error = assembled_error(scene, error, assembly)
    del error
    H = assembly(total)
    del total
    Hm = assembly(mech)
    del mech
    sliding = np.flatnonzero(scene.at_yield())
    local = ContactBlocks(blocks={}, slide_left=a, slide_right=s, index=index, n_dof=scene.n_dof,
                          rolling_undetermined=undetermined)
    A, S = sliding_factors(local, sliding)
    return SparseParts(H=H, Hm=Hm, A=A, S=S, sliding=sliding, local=local, curvature_error=curvature_error,
                       rigid_applied=applied, timings={"blocks": t1 - t0, "assembly": time.perf_counter() - t1})


def sparse_problem(scene: Scene, length: float | None = None, chunk: int = CHUNK, *,
                   metric: Metric | None = None, parts: SparseParts | None = None) -> SparseProblem:
    """The sparse problem in a metric's dofs (metric.py; default the L metric with `length`, itself defaulting to
    the mean contact radius): H̃ = D H D and its mechanical part (sparse congruences, O(nnz)), sym(H̃), the scaled
    sliding factors and the rigid bases. `parts` (sparse_parts) are shared by every metric of a family."""
    if metric is None:
        metric = length_metric(scene, length or default_length(scene), name="L")
    parts = parts or sparse_parts(scene, chunk)
    t1 = time.perf_counter()
    H = metric.sparse_congruence(parts.H)
    Hm = metric.sparse_congruence(parts.Hm)
    Hs = ((H + H.T) * 0.5).tocsr()
    D = metric.matrix()
    A, S = np.asarray(D @ parts.A), np.asarray(D @ parts.S)
    Ms = A.shape[1]
    C = metric.rotations(scene)
    R, _ = rigid_basis(np.concatenate([metric.translations(scene), C], axis=1))
    Q = R[:, scene.dim:]                                                # spans C, which is orthogonal to T
    norm = float(abs(Hs).sum(axis=1).max()) if Hs.nnz else 1.0
    if Ms:
        norm += float(np.sum(np.linalg.norm(A, axis=0) * np.linalg.norm(S, axis=0)))
    spins = free_spins(scene, H, A, S, scale=norm) if scene.fixed is None else np.zeros(0, dtype=np.intp)
    if spins.size:              # free spins (frictionless round particles): exactly decoupled, moved to the top
        Hs = (Hs + sp.csr_matrix((np.full(spins.size, 2.0 * norm), (spins, spins)), shape=Hs.shape)).tocsr()
        norm *= 2.0
    return SparseProblem(scene=scene, length=metric.rotation_length, scale=metric.diagonal, metric=metric, H=H,
                         Hs=Hs, Hm=Hm, A=A, S=S, sliding=parts.sliding, C=C, Q=Q, R=R, norm=max(norm, 1e-300),
                         local=parts.local, timings={**parts.timings, "projection": time.perf_counter() - t1},
                         free_spins=int(spins.size))


def norm_estimate(A, iters: int = 30, seed: int = 0) -> float:
    """‖A‖₂ of a sparse matrix (or operator) by power iteration on AᵀA (a lower bound, within a few %)."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(A.shape[1])
    x /= np.linalg.norm(x)
    s = 0.0
    for _ in range(iters):
        y = A.T @ (A @ x)
        s = np.sqrt(np.linalg.norm(y))
        if s == 0:
            return 0.0
        x = y / np.linalg.norm(y)
    return float(s)


class _Applied:
    """A part of H known only through its product with the rigid basis (what checks.identity_errors needs)."""

    def __init__(self, value: np.ndarray):
        self.value = value

    def __matmul__(self, other):
        return self.value


def identity_errors(sp_: SparseProblem, chunk: int = CHUNK, parts: SparseParts | None = None) -> dict:
    """The identities of the dense path (granstab.mechanics.checks; Frobenius norms) without assembling the parts: H in
    physical dofs from the scaled H̃, and Hg1, Hg2, Hm applied to the rigid basis contact by contact (taken from
    `parts`, where sparse_parts made them with the blocks, else chunked again); plus the rigid leakage of ℍ = H̃ P on
    all rigid motions and the projection's own checks."""
    scene = sp_.scene
    H = sp_.metric.sparse_congruence(sp_.H, inverse=True)
    applied = getattr(parts, "rigid_applied", None)
    if applied is None:
        rigid = _rigid_columns(scene)
        applied = {name: np.zeros(rigid.shape) for name in ("Hg1", "Hg2", "Hm")}
        for _, cb in contact_chunks(scene, chunk):
            _apply_rigid(applied, cb, rigid, scene.n_dof)
    errs = checks.identity_errors(scene, {"H": H, **{k: _Applied(v) for k, v in applied.items()}})
    proj = sp_.projection
    errs["rigid_leakage_modified"] = modified_leakage(sp_.H, sp_.R, proj)
    errs.update(proj.errors())
    return errs
