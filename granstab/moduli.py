"""`moduli(scene)`: the elastic moduli of a periodic packing per loading branch, the stress, and the cell's
stability at fixed cell and at fixed stress (docs/periodic.md).

Branch i (a mask of the potentially sliding contacts, eq:ContactF) has the extended stiffness
[[H^i, Ξ^i], [Ξ'^i, B^i]] (mechanics/cell.py); with no load on the particles the fluctuations follow a strain ε
as Ũ = -H^i⁺ Ξ^i ε, and C^i = (B^i - Ξ'^i H^i⁺ Ξ^i) / V in the Mandel basis. H^i⁺ acts on the complement of the d
translations (a bordered system) and of the dofs no contact touches (free spins, rattlers): one solve of the
elastic H serves every right-hand side and, through Woodbury, every branch. The parts are assembled in chunks of
contacts (solve/cellparts.py: one block kernel at every size, memory linear in M). Up to DENSE_MAX kept dofs H is
factorised by SuperLU; above, by GMRES on H preconditioned by the multifrontal Cholesky factor of sym(H)
(solve/multifrontal.py, solve/gmres.py), which also gives the fixed-cell check (its inertia), so that 10⁶ disks fit
(one factor of the symmetric part instead of an LU of both triangles).

Each modulus carries a bound (`CellBranch.bound`, docs/periodic.md "How C is solved"): with R = Ξ^i - H^i X̂ the
residual, ‖(H^i)⁻¹‖₂ ≤ h^i, and the formation errors ΔH, ΔΞ, ΔΞ', ΔB of cellparts.py (first order in ε),

    V |ΔC_ab| ≤ |ΔB_ab| + |ΔΞ'_a|·|X̂_b| + ‖Ξ'_a‖ h^i (‖R_b‖ + ‖ΔΞ_b‖ + ‖ΔH‖‖X̂_b‖) + γ_n |Ξ'_a|·|X̂_b|,

where ‖H⁻¹‖₂ ≤ 1/τ because xᵀHx = xᵀ sym(H) x ≥ τ‖x‖² once sym(H) - τI is proven positive definite (its
inertia, a second elimination; dense: its eigenvalues), and a branch's h^i follows from Woodbury,
h^i ≤ h (1 + ‖H⁻¹A_on‖ ‖(I + S_onᵀH⁻¹A_on)⁻¹‖ ‖S_on‖). Where sym(H) is not positive definite there is no such
τ and the bound is not available (None).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .mechanics.accuracy import curvature_error, gamma
from .mechanics.branches import enumerate_masks, s_limits, sample_masks
from .mechanics.cell import mandel_basis, stress, stress_work, to_tensor
from .mechanics.rigid import untouched_dofs
from .model.scene import Scene, SceneError
from .model.tolerances import EPS
from .model.vec import rot_dim
from .solve.cellparts import cell_system
from .solve.threads import blas_threads

__all__ = ["CellBranch", "Moduli", "moduli"]

PIVOT_RTOL = 1e-11   # an LU pivot below this times ‖H‖∞: a floppy mode beyond translations and untouched dofs


@dataclass(frozen=True, eq=False)
class CellBranch:
    """The cell's response on one branch: `mask` (M,) (+1 loading/sliding, -1 unloading, 0 not at yield),
    `mandel` C^i (m, m) and `C` (d, d, d, d); `fixed_stress` C^i - Q (m, m) (cell.stress_work); the eigenvalues
    of their symmetric parts; `residual` of the non-affine solve ‖H^i X - Ξ^i‖ / (‖H^i‖∞‖X‖ + ‖Ξ^i‖);
    `symmetry_defect` ‖C - Cᵀ‖ / ‖C‖ (Mandel, Frobenius; 0 for a conservative law up to round-off); `bound` (m, m)
    |C^i - Ĉ^i| ≤ bound entrywise (Mandel; module docstring), None where not available."""

    name: str
    mask: np.ndarray
    mandel: np.ndarray
    fixed_stress: np.ndarray
    residual: float
    response: np.ndarray = field(repr=False)      # X = H^i⁺ Ξ^i (n, m): Ũ = -X ε
    s_values: np.ndarray = field(repr=False)      # (Ms, m): S of each potentially sliding contact per unit strain
    bound: np.ndarray | None = None

    @property
    def C(self) -> np.ndarray:
        return to_tensor(self.mandel)

    @property
    def symmetry_defect(self) -> float:
        return float(np.linalg.norm(self.mandel - self.mandel.T) / max(np.linalg.norm(self.mandel), 1e-300))

    @property
    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvalsh(0.5 * (self.mandel + self.mandel.T))

    @property
    def fixed_stress_eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvalsh(0.5 * (self.fixed_stress + self.fixed_stress.T))

    def to_dict(self) -> dict:
        return {"name": self.name, "mask": [int(v) for v in self.mask], "C": self.C.tolist(),
                "mandel": self.mandel.tolist(), "eigenvalues": self.eigenvalues.tolist(),
                "fixed_stress_eigenvalues": self.fixed_stress_eigenvalues.tolist(),
                "residual": self.residual, "symmetry_defect": self.symmetry_defect,
                "bound": None if self.bound is None else self.bound.tolist()}


@dataclass(frozen=True, eq=False)
class Moduli:
    """Result of `moduli`: C (d, d, d, d) of the elastic (all-unloading) branch, `stress` σ (d, d) (tension
    positive), `volume`, `branches` (CellBranch: elastic and all-loading, or the one branch without sliding
    contacts), `direction` (the tangent response to a strain direction, when asked), `zero_modes`, `verdicts`
    (fixed cell, fixed stress), `errors` and `seconds`."""

    dim: int
    volume: float
    stress: np.ndarray
    branches: tuple
    zero_modes: dict
    verdicts: dict
    errors: dict
    seconds: float
    direction: dict | None = None
    notes: tuple = ()
    solve: dict = field(default_factory=dict)

    @property
    def C(self) -> np.ndarray:
        return self.branches[0].C

    @property
    def mandel(self) -> np.ndarray:
        return self.branches[0].mandel

    @property
    def pressure(self) -> float:
        return float(-np.trace(self.stress) / self.dim)

    @property
    def bulk(self) -> float:
        """(1/d²) Σ C_iijj: the response to an isotropic strain (jax-md's `extract_isotropic_moduli` B)."""
        return float(np.einsum("iijj->", self.C) / self.dim ** 2)

    @property
    def shear(self) -> float:
        """The orientation-averaged shear modulus C::P_dev / (2(m - 1)) (jax-md's G)."""
        d = self.dim
        eye = np.eye(d)
        dev = 0.5 * (np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye)) \
            - np.einsum("ij,kl->ijkl", eye, eye) / d
        return float(np.einsum("ijkl,ijkl->", self.C, dev) / (d * (d + 1) - 2))

    def to_dict(self) -> dict:
        """The `granstab moduli --json` object."""
        return {"dim": self.dim, "volume": self.volume, "stress": self.stress.tolist(), "pressure": self.pressure,
                "C": self.C.tolist(), "bulk": self.bulk, "shear": self.shear,
                "strain_basis": "Mandel (orthonormal): " + ("xx, yy, xy" if self.dim == 2 else
                                                            "xx, yy, zz, yz, xz, xy"),
                "branches": [b.to_dict() for b in self.branches], "direction": self.direction,
                "zero_modes": self.zero_modes, "verdicts": self.verdicts, "errors": self.errors,
                "seconds": self.seconds, "notes": list(self.notes), "solve": self.solve}


DENSE_MAX = 3000     # kept dofs up to which a singular H is handled by a dense pseudo-inverse (mechanisms)
ITERATIVE_MIN = DENSE_MAX   # kept dofs above which H is solved by GMRES with sym(H)'s factor (below: SuperLU)
PINV_RTOL = 1e-10    # singular values of H below this times the largest: its mechanisms (dense fallback only)


@dataclass(eq=False)
class _Solver:
    """X^i = H^i⁺ Ξ^i on the kept dofs: those some contact touches, less the d translations of one particle that
    ground the translations (X is then the solution with that particle still; C does not see a translation, since
    every block annihilates one). `solve` B ↦ H⁻¹B (SuperLU, or GMRES with sym(H)'s factor: solve/cellsolve.py),
    every branch by Woodbury; `solve` None: H has mechanisms beyond the translations (gear-like rolling, floppy
    rattlers), so each branch uses the dense pseudo-inverse and `mechanisms` counts its zeros. `inverse_bound()`
    bounds ‖H⁻¹‖₂ (None: not available), `H_error` ‖ΔH‖₂ (formation), `held` the fixed-cell check, `info` how it solved."""

    keep: np.ndarray
    H: sp.csr_matrix
    A: np.ndarray
    S: np.ndarray
    solve: object
    d: int
    held: dict
    inverse: object = None          # a float, None, or a cellsolve.Floor still being proven (`inverse_bound`)
    H_error: float = 0.0
    info: dict = field(default_factory=dict)
    Y: np.ndarray | None = None
    mechanisms: int = 0

    def response(self, parts, on: np.ndarray) -> np.ndarray:
        """X = H^i⁺ Ξ^i for the branch whose loading contacts are `on` (bool (Ms,))."""
        m = parts.B.shape[0]
        Ao, So = self.A[:, on], self.S[:, on]
        if not len(self.keep):                                        # nothing but the cell moves
            return np.zeros((0, m))
        if self.solve is None:
            H = self.H.toarray() + Ao @ So.T
            return np.linalg.pinv(H, rcond=PINV_RTOL) @ (parts.Xi[self.keep] + Ao @ parts.S_cell[:, on].T)
        if self.Y is None:                                            # H⁻¹[Ξ, A]: one solve, every branch
            self.Y = self.solve(np.hstack([parts.Xi[self.keep], self.A]))
        X = self.Y[:, :m] + self.Y[:, m:][:, on] @ parts.S_cell[:, on].T
        if on.any():
            HA = self.Y[:, m:][:, on]
            X = X - HA @ np.linalg.solve(np.eye(int(on.sum())) + So.T @ HA, So.T @ X)
        return X

    def inverse_bound(self) -> float | None:
        """The bound of ‖H⁻¹‖₂: `inverse`, or 1/τ once its proof (cellsolve.Floor, perhaps still running) is in."""
        if hasattr(self.inverse, "tau"):
            tau = self.inverse.tau()
            self.info["floor"] = tau
            self.inverse = None if tau is None else 1.0 / tau
        return self.inverse

    def branch_inverse(self, on: np.ndarray) -> float | None:
        """A bound of ‖(H + A_on S_onᵀ)⁻¹‖₂ by Woodbury from `inverse` (module docstring; first order)."""
        if self.inverse_bound() is None or not on.any():
            return self.inverse
        HA, So = self.Y[:, self.Y.shape[1] - self.A.shape[1]:][:, on], self.S[:, on]     # H⁻¹A_on
        K = np.eye(int(on.sum())) + So.T @ HA
        return self.inverse * (1.0 + np.linalg.norm(HA) * np.linalg.norm(np.linalg.inv(K), 2) * np.linalg.norm(So))


def _inf_norm(H) -> float:
    """‖H‖∞ of a sparse matrix (0 for an empty one)."""
    return float(abs(H).sum(axis=1).max()) if H.shape[0] else 0.0


def _grounded(scene: Scene, untouched: np.ndarray) -> np.ndarray:
    """The kept dofs: not untouched, and not the translations of the first particle whose translations are kept."""
    per = scene.dof_per_particle
    moving = ~untouched.reshape(scene.n_particles, per)[:, :scene.dim].any(axis=1)
    keep = ~untouched
    if moving.any():
        first_moving = int(np.flatnonzero(moving)[0])
        keep[first_moving * per:first_moving * per + scene.dim] = False
    return np.flatnonzero(keep)


def _factor(scene: Scene, H, untouched: np.ndarray, A, S, H_error=None) -> _Solver:
    """The solver on the kept dofs (`_grounded`): above DENSE_MAX GMRES with sym(H)'s multifrontal factor where
    sym(H) is positive definite (solve/cellsolve.py); else sparse LU (minimum-degree order of Hᵀ + H), or the dense
    pseudo-inverse where H is singular there (mechanisms)."""
    keep = _grounded(scene, untouched)
    Hk = H[keep][:, keep].tocsr()
    A, S = A[keep], S[keep]
    e_H = 0.0 if H_error is None or not len(keep) else curvature_error(H_error[keep][:, keep].tocsr())
    base = {"keep": keep, "H": Hk, "A": A, "S": S, "d": scene.dim, "H_error": e_H}
    if not len(keep):
        return _Solver(**base, solve=None, held=_held_dense(Hk)[0])
    if len(keep) > max(DENSE_MAX, ITERATIVE_MIN):
        from .solve import cellsolve
        sym = cellsolve.symmetric_factor(scene, Hk, keep)
        held = cellsolve.held(sym.mf)
        if sym.mf.definite:
            info = {"method": "GMRES preconditioned by the multifrontal Cholesky factor of sym(H)",
                    "factor_entries": sym.mf.nnz}
            floor = cellsolve.Floor(scene, Hk, keep, sym)
            info.update(estimate=floor.theta)
            return _Solver(**base, solve=cellsolve.iterative(Hk, sym, info), held=held, inverse=floor, info=info)
        del sym
    elif len(keep) <= DENSE_MAX:
        held, inverse = _held_dense(Hk)
    else:                                                            # SuperLU above DENSE_MAX: no bound of ‖H⁻¹‖
        from .solve import cellsolve
        held, inverse = cellsolve.held(cellsolve.symmetric_factor(scene, Hk, keep, factors=False).mf), None
    scale = max(_inf_norm(Hk), 1e-300)
    try:
        lu = spla.splu(Hk.tocsc(), permc_spec="MMD_AT_PLUS_A")
        singular = float(np.abs(lu.U.diagonal()).min()) < PIVOT_RTOL * scale
    except RuntimeError:                                             # exactly singular
        lu, singular = None, True
    info = {"method": "SuperLU (minimum degree of Hᵀ + H)"}
    if not singular:
        return _Solver(**base, solve=lu.solve, held=held, inverse=inverse, info=info)
    if len(keep) > DENSE_MAX:
        raise SceneError(f"{scene.source}: moduli: the stiffness has zero modes beyond the {scene.dim} translations "
                         f"and the untouched dofs (mechanisms or floppy rattlers) and {len(keep)} dofs are too many "
                         f"for the dense pseudo-inverse (at most {DENSE_MAX}): remove rattlers")
    sv = np.linalg.svd(Hk.toarray(), compute_uv=False)
    return _Solver(**base, solve=None, held=held, info={"method": "dense pseudo-inverse"},
                   mechanisms=int(np.sum(sv <= PINV_RTOL * sv.max())))


def _branch(name, mask, on, solver, system, volume, Q) -> CellBranch:
    """C^i = (B^i - Ξ'^i X^i)/V of the branch with the loading contacts `on` (bool (Ms,)), X^i = H^i⁺ Ξ^i, and
    its bound (`_bound`)."""
    parts = system.parts
    Ao, So = solver.A[:, on], solver.S[:, on]
    Xi = parts.Xi[solver.keep] + Ao @ parts.S_cell[:, on].T
    X = solver.response(parts, on)
    R = Xi - (solver.H @ X + Ao @ (So.T @ X))
    norm = _inf_norm(solver.H) + float(np.abs(Ao).sum(axis=1).max(initial=0.0)
                                                          * np.abs(So).sum(axis=0).max(initial=0.0))
    residual = float(np.abs(R).max(initial=0.0) / max(norm * np.abs(X).max(initial=0.0)
                                                       + np.abs(Xi).max(initial=0.0), 1e-300))
    left = parts.Xi_left[:, solver.keep] + parts.A_cell[:, on] @ So.T
    B = parts.B + parts.A_cell[:, on] @ parts.S_cell[:, on].T
    C = (B - left @ X) / volume
    s_values = parts.S_cell.T - solver.S.T @ X                        # S per unit strain, Ũ = -X ε
    return CellBranch(name=name, mask=mask, mandel=C, fixed_stress=C - Q, residual=residual, response=X,
                      s_values=s_values, bound=_bound(solver, system, on, X, R, Xi, left, volume))


def _bound(solver, system, on, X, R, Xi, left, volume):
    """|C^i - Ĉ^i| ≤ this (m, m), entrywise (module docstring), None where ‖(H^i)⁻¹‖ has no bound. The sliding
    terms' formation: 8ε of |a||s| (accuracy.part_scales); the residual's own rounding γ_k(|H||X| + |Ξ|)."""
    h = solver.branch_inverse(on) if len(solver.keep) else 0.0
    if h is None:
        return None
    keep, parts = solver.keep, system.parts
    Ao, So = np.abs(solver.A[:, on]), np.abs(solver.S[:, on])
    Ac, Sc = np.abs(parts.A_cell[:, on]), np.abs(parts.S_cell[:, on])
    slide = 8 * EPS
    Xa = np.abs(X)
    rows = int(np.diff(solver.H.indptr).max(initial=0)) + int(on.sum()) + 2
    rnd = gamma(rows) * np.linalg.norm(abs(solver.H) @ Xa + Ao @ (So.T @ Xa) + np.abs(Xi), axis=0)
    Xi_err = np.linalg.norm(system.Xi_error[keep] + slide * Ao @ Sc.T, axis=0)
    e_H = solver.H_error + slide * float(system.sliding_scale[on].sum())
    inner = np.linalg.norm(R, axis=0) + rnd + Xi_err + e_H * np.linalg.norm(X, axis=0)
    left_err = system.left_error[:, keep] + slide * Ac @ So.T
    E = (system.B_error + slide * Ac @ Sc.T + left_err @ Xa + np.outer(np.linalg.norm(left, axis=1), h * inner)
         + gamma(len(keep) + 2) * np.abs(left) @ Xa)
    return E / volume


def _stage(progress, name: str, total: int | None = None) -> None:
    """Report a stage to a reporter with stages (io.progress.Heartbeat), if any."""
    if progress is not None:
        progress.stage(name, total)


def moduli(scene: Scene, *, strain=None, max_sliding: int = 12, sample_branches: int = 64, seed: int = 0,
           progress=None) -> Moduli:
    """Elastic moduli, stress and cell stability of a periodic `scene` (docs/periodic.md).

    Parameters
    ----------
    scene : Scene
        A periodic scene (`scene.cell`), N particles, M contacts.
    strain : array_like (d, d), optional
        A strain direction (symmetric): the tangent moduli of the branch consistent with it (Appendix D applied
        to the cell's response), by enumerating the 2^Ms branches up to `max_sliding` potentially sliding
        contacts; above, the range over the all-loading, all-unloading and `sample_branches` seeded random
        branches (a sample, not a bound).
    progress : a reporter with stages (granstab.io.progress.Heartbeat: a line a minute), optional
        Told the stage (assembly, factorisation, branches i of n, fixed-cell check) as the work goes.

    Returns
    -------
    Moduli
        ``C`` (d, d, d, d) of the elastic branch (Mandel matrix ``mandel``), ``stress`` (d, d), ``volume``,
        ``bulk``, ``shear``, ``branches``, ``direction``, ``zero_modes``, ``verdicts``, ``errors``, ``seconds``.
    """
    start = time.perf_counter()
    if not scene.periodic:
        raise SceneError(f"{scene.source}: moduli need a periodic scene (a `cell`); this one has none")
    _stage(progress, "assembly")
    system = cell_system(scene)
    H, A, S, sliding, parts = system.H, system.A, system.S, system.sliding, system.parts
    scale = max(_inf_norm(H), 1e-300)
    untouched = np.zeros(scene.n_dof, bool)
    untouched[untouched_dofs(H, parts.Xi, parts.Xi_left.T, A, S, scale=scale)] = True
    _stage(progress, "factorisation")
    seconds = {"assembly": time.perf_counter() - start}
    solver = _factor(scene, H, untouched, A, S, system.H_error)
    seconds["factorisation"] = time.perf_counter() - start - seconds["assembly"]
    volume, sigma = scene.volume, stress(scene)
    Q = stress_work(sigma)
    Ms = len(sliding)
    partial = Ms > max_sliding
    masks = (sample_masks(sliding, scene.n_contacts, sample_branches, seed) if partial
             else enumerate_masks(sliding, scene.n_contacts))
    _stage(progress, "branches", len(masks))
    every = []
    with blas_threads(1):            # small dense Woodbury solves per branch: one BLAS thread (solve/threads.py)
        for mk in masks:
            every.append(_branch("tangent", mk, mk[sliding] == 1, solver, system, volume, Q))
            if progress is not None:
                progress.update()
    signs = masks[:, sliding]
    named = [("elastic", int(np.flatnonzero(np.all(signs == -1, axis=1))[0]))]
    if Ms:
        named.append(("all loading", int(np.flatnonzero(np.all(signs == 1, axis=1))[0])))
    branches = tuple(replace(every[i], name=name) for name, i in named)
    s_tol = s_limits(np.vstack([solver.S, parts.S_cell]), scene.tol)[0]
    direction = None if strain is None else _direction(scene, strain, sliding, every, s_tol, partial)
    zero = {**_zero_modes(scene, untouched), "mechanisms": solver.mechanisms}
    _stage(progress, "fixed-cell check")
    seconds["branches"] = time.perf_counter() - start - sum(seconds.values())
    return Moduli(dim=scene.dim, volume=volume, stress=sigma, branches=branches, zero_modes=zero,
                  verdicts=_verdicts(every, sliding, s_tol, partial, _asymmetry(solver, parts), solver.held),
                  errors=_errors(scene, sigma, every),
                  seconds=time.perf_counter() - start, direction=direction, notes=_notes(scene, Ms, zero),
                  solve={**solver.info, "inverse_bound": solver.inverse_bound(), "dofs": len(solver.keep),
                         "seconds": seconds})


def _consistent(branch, sliding, e: np.ndarray, s_tol: float) -> bool:
    """Whether strain direction e (Mandel) is consistent with the branch (Appendix D): mask·sign(S) >= 0 on every
    potentially sliding contact, S = (S_cellᵀ - Sᵀ X^i) e, |S| <= s_tol counted as 0."""
    Sv = branch.s_values @ e
    sign = np.where(np.abs(Sv) <= s_tol, 0, np.sign(Sv))
    return bool(np.all(branch.mask[sliding] * sign >= 0))


def _direction(scene, strain, sliding, every, s_tol, partial):
    """The branches consistent with a strain direction ε (Appendix D): mask·sign(S(ε)) >= 0 on every potentially
    sliding contact, S(ε) = (S_cellᵀ - Sᵀ X^i) ε; their directional moduli ε̂·C^i·ε̂ (ε̂ = ε/|ε|)."""
    d = scene.dim
    eps = np.asarray(strain, float).reshape(d, d)
    if np.abs(eps - eps.T).max() > 1e-12 * np.abs(eps).max() or not np.abs(eps).max() > 0:
        raise SceneError(f"{scene.source}: moduli: strain must be a non-zero symmetric {d}x{d} tensor")
    e = np.einsum("aij,ij->a", mandel_basis(d), eps)
    eps, e = eps / np.linalg.norm(e), e / np.linalg.norm(e)            # |ε| (Frobenius) = |e| (Mandel)
    Ms = len(sliding)
    values = [float(e @ b.mandel @ e) for b in every]
    found = [{"mask": [int(v) for v in b.mask], "modulus": value, "fixed_stress_modulus": float(e @ b.fixed_stress @ e),
              "C": b.C.tolist()} for b, value in zip(every, values) if _consistent(b, sliding, e, s_tol)]
    out = {"strain": eps.tolist(), "consistent": found,
           "n_branches": len(every), "enumerated": not partial, "unique": len(found) == 1 and not partial}
    if not found:
        out["note"] = ("no branch is consistent with this strain direction: the cell cannot follow it "
                       "quasi-statically on any branch examined")
    elif len(found) > 1:
        out["note"] = (f"{len(found)} branches are consistent with this strain direction: Type-1 non-uniqueness of "
                       "the cell's response (Appendix D)")
    if partial:
        out["range"] = [min(values), max(values)]
        out["note"] = (f"{Ms} potentially sliding contacts: {len(every)} of 2^{Ms} branches examined (all loading, "
                       "all unloading and seeded random ones); `range` is over them, a sample, not a bound")
    return out


def _zero_modes(scene: Scene, untouched: np.ndarray) -> dict:
    """The zero modes the solve set aside: the d translations, free spins (rotation dofs no contact touches, of
    particles that have stiff translations) and rattlers (particles none of whose dofs any contact touches)."""
    d, r = scene.dim, rot_dim(scene.dim)
    per = untouched.reshape(scene.n_particles, d + r)
    rattler = per.all(axis=1) & ~per.all()          # all untouched: a one-particle lattice, its translations rigid
    spins = int(per[~rattler, d:].sum())
    return {"translations": d, "free_spins": spins, "rattlers": int(rattler.sum()),
            "rattler_dofs": int(per[rattler].size),
            "note": "trivial: free spins and rattlers change no contact; translations are the rigid motions"}


def _errors(scene: Scene, sigma: np.ndarray, branches) -> dict:
    fmag = np.linalg.norm(scene.force, axis=1)
    bmag = np.linalg.norm(scene.branch, axis=1)
    load = float(np.linalg.norm(scene.load, axis=1).max(initial=0.0) / max(fmag.max(initial=0.0), 1e-300))
    bounds = [b.bound for b in branches]
    scale = max(max(float(np.abs(b.mandel).max()) for b in branches), 1e-300)
    return {"residual": max(b.residual for b in branches),
            "moduli_bound": None if any(e is None for e in bounds) else max(float(e.max()) for e in bounds) / scale,
            "symmetry_defect": max(b.symmetry_defect for b in branches),
            "stress_asymmetry": float(np.abs(sigma - sigma.T).max() * scene.volume / max(fmag @ bmag, 1e-300)),
            "load_residual": load}


def _asymmetry(solver, parts) -> float:
    """max(|H - Hᵀ|, |Ξ - Ξ'ᵀ|, |B - Bᵀ|) / max|[[H, Ξ], [Ξ', B]]| of the elastic branch (0 for a conservative law)."""
    H = solver.H.toarray() if len(solver.keep) <= DENSE_MAX else solver.H
    Xi, left = parts.Xi[solver.keep], parts.Xi_left[:, solver.keep]
    biggest = abs(H).max() if H.size else 0.0
    skew = abs(H - H.T).max() if H.size else 0.0
    scale = max(float(biggest), float(np.abs(Xi).max(initial=0.0)), float(np.abs(parts.B).max()), 1e-300)
    return max(float(skew), float(np.abs(Xi - left.T).max(initial=0.0)),
               float(np.abs(parts.B - parts.B.T).max())) / scale


SYMMETRIC_RTOL = 1e-12   # an extended matrix this close to symmetric is a conservative one (its Schur complement
#                          is the minimum of the second-order work over the particles' motions)


def _held_dense(H) -> tuple:
    """The particles at fixed cell, elastic branch, conservative view: the eigenvalues of sym(H) on the kept dofs
    (the translations grounded: positive there iff positive off the translations), up to DENSE_MAX dofs (beyond:
    its inertia, solve/cellsolve.held); and the bound 1/(λ_min - tolerance) of ‖H⁻¹‖₂ where that is positive
    (module docstring), else None. `granstab analyze` gives the full answer (every branch, consistency, error
    bounds)."""
    rest = np.linalg.eigvalsh(0.5 * (H + H.T).toarray())               # translations grounded (`_grounded`)
    tol = 1e3 * EPS * max(float(np.abs(rest).max(initial=0.0)), 1e-300) * max(len(rest), 1)
    if not rest.size:
        return {"verdict": "stable", "min_eigenvalue": None, "tolerance": tol,
                "note": "nothing but the translations moves at fixed cell"}, 0.0
    low = float(rest.min())
    held = {"verdict": "stable" if low > tol else "unstable" if low < -tol else "neutral", "min_eigenvalue": low,
            "tolerance": tol, "note": "sym(H) of the elastic branch without the translations (granstab analyze: "
                                      "every branch, consistency and error bounds)"}
    return held, (1.0 / (low - tol) if low > tol else None)


def _verdicts(every, sliding, s_tol: float, partial: bool, asymmetry: float, held: dict) -> dict:
    """Fixed cell: `granstab analyze` of the scene answers it (the particles move, the cell is held). Fixed stress
    (eq:stab, eq:instab for the cell): V ε·(C^i - Q)·ε is the second-order work of the motion [-X^i ε, ε] that
    keeps the particles in equilibrium. A negative one whose strain is consistent with its branch (`_consistent`)
    proves instability, a zero one so consistent neutrality. sym(C^i - Q) positive definite on every branch proves
    stability only for a symmetric extended matrix (no sliding, conservative geometry: the Schur complement is then
    the minimum over the particles' motions) and with the particles stable at fixed cell; otherwise it is reported
    as not proven."""
    scale = max(max(np.abs(b.mandel).max() for b in every), 1e-300)
    tol = (1e3 * EPS + max(b.residual for b in every)) * scale
    lam_min, unstable, neutral = np.inf, False, False
    for b in every:
        lam, V = np.linalg.eigh(0.5 * (b.fixed_stress + b.fixed_stress.T))
        lam_min = min(lam_min, float(lam[0]))
        for j in np.flatnonzero(lam <= tol):
            ok = _consistent(b, sliding, V[:, j], s_tol) or _consistent(b, sliding, -V[:, j], s_tol)
            unstable |= ok and lam[j] < -tol
            neutral |= ok and lam[j] >= -tol
    if unstable:
        verdict, proof = "unstable", True
    elif lam_min > tol:
        verdict, proof = "stable", (not partial and len(sliding) == 0 and asymmetry <= SYMMETRIC_RTOL
                                    and held["verdict"] == "stable")
    elif neutral:
        verdict, proof = "neutral", True
    else:
        verdict, proof = "not determined", False
    return {"fixed_cell": held,
            "fixed_stress": {"verdict": verdict, "sufficient": proof, "min_eigenvalue": lam_min, "tolerance": tol,
                             "n_branches": len(every), "all_branches": not partial, "asymmetry": asymmetry,
                             "note": "the cell under constant Cauchy stress: sym(C^i - Q) on every branch examined; "
                                     "a proof of stability needs a symmetric extended matrix and the particles "
                                     "stable at fixed cell (granstab analyze)"}}


def _notes(scene: Scene, Ms: int, zero: dict) -> tuple:
    out = []
    if Ms:
        out.append(f"{Ms} potentially sliding contact(s): C depends on the branch; `C` is the elastic (all "
                   "unloading) branch, C^i = (B^i - Ξ'^i H^i⁺ Ξ^i)/V the tangent of the nominal stress rate on "
                   "branch i (not an energy's second derivative)")
    if zero["mechanisms"]:
        out.append(f"{zero['mechanisms']} mechanism(s) beyond the translations (e.g. gear-like rolling): the "
                   "non-affine response is the pseudo-inverse's, orthogonal to them; the residual says whether the "
                   "strain drives one")
    if zero["free_spins"] or zero["rattlers"]:
        out.append(f"{zero['free_spins']} free spin(s) and {zero['rattlers']} rattler(s) set aside: they change no "
                   "contact, so they are zero modes that are neither rigid motions nor instabilities")
    return tuple(out)
