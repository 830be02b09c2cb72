"""The gear-like bifurcation mode of a regular packing (Sec. 4.1, Fig. 6) and its removal by rolling stiffness.

A square packing of equal disks (radius R, centres 2R apart, so r = ρ = R at every contact) carrying normal contact
forces has, with zero rolling stiffness (M^pq = 0, eq:constitutiveM), a zero-work mode besides the rigid motions:
neighbours counter-rotate by equal angles (the checkerboard sign pattern (-1)^(i+j)), no contact deforms
(δu_def = 0) and each contact rolls like the two disks of Sec. 4.1 with λ⁽⁶⁾ = f(ρ - r) = 0. A rolling stiffness
k_r penalises δθ_def = ±2θ and lifts the mode to about 4 k_r M_c / (N L²) (the Rayleigh quotient of the unit
gear vector in granstab's scaled dofs [du, L dθ]; M_c contacts, N disks).

The square lattice is bipartite, so the pattern exists for every nx × ny. When nx·ny is odd the two colours are
unequal, the gear vector has a rigid-rotation component, and the projection P^nrr mixes the loads' corotation
(Hg3) into it: the mode is then not an exact zero (see `parity`).
"""
from __future__ import annotations

import numpy as np

import granstab
from granstab.mechanics.branches import branch_matrices

#: the presets gear_packing.toml / gear_packing_rolling.toml: 4 × 4 disks, R = 1, f_h = 0.01, f_v = 0.02 (k = 1)
DEFAULT = {"nx": 4, "ny": 4, "R": 1.0, "f_h": 0.01, "f_v": 0.02, "k": 1.0, "alpha": 1.0, "mu": 0.5}
PRESET_ROLLING = 0.01          # k_r of gear_packing_rolling.toml, in units of k R²


def packing(nx: int = 4, ny: int = 4, R: float = 1.0, f_h: float = 0.01, f_v: float = 0.02, k: float = 1.0,
            alpha: float = 1.0, mu: float = 0.5, rolling: float = 0.0, rho: float | None = None,
            title: str | None = None) -> granstab.Scene:
    """nx × ny square packing; disk (i, j) is named d{i}{j} at (2Ri, 2Rj); horizontal contacts carry the normal
    compression f_h, vertical ones f_v; loads follow from equilibrium. `rho` (default R) sets the curvature radius
    at every contact, to test r ≠ ρ."""
    rho = R if rho is None else rho
    names, x, contacts = [], [], []
    for j in range(ny):
        for i in range(nx):
            names.append(f"d{i}{j}")
            x.append([2.0 * R * i, 2.0 * R * j])
    index = lambda i, j: j * nx + i  # noqa: E731
    for j in range(ny):
        for i in range(nx):
            if i + 1 < nx:
                contacts.append((index(i, j), index(i + 1, j), np.array([1.0, 0.0]), f_h))
            if j + 1 < ny:
                contacts.append((index(i, j), index(i, j + 1), np.array([0.0, 1.0]), f_v))
    x = np.array(x)
    M = len(contacts)
    n = np.array([c[2] for c in contacts])
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    K = -1.0 / rho * t[:, :, None] * t[:, None, :]
    arrays = {
        "p": np.array([c[0] for c in contacts]), "q": np.array([c[1] for c in contacts]),
        "point": x[[c[0] for c in contacts]] + R * n, "normal": n, "curvature_p": K, "curvature_q": K.copy(),
        "force": -np.array([c[3] for c in contacts])[:, None] * n, "moment": np.zeros((M, 1)),
        "k": np.full(M, k), "alpha": np.full(M, alpha), "mu": np.full(M, mu),
        "rolling": np.full((M, 1, 1), rolling), "state": ("auto",) * M,
    }
    title = title or f"{nx}x{ny} square packing, rolling stiffness {rolling:g}"
    return granstab.build_scene(2, names, x, arrays, title=title, source="<gear>")


def gear_vector(scene: granstab.Scene, nx: int) -> np.ndarray:
    """Unit checkerboard counter-rotation (-1)^(i+j) on the rotation dofs, zero translations, (n_dof,)."""
    g = np.zeros(scene.n_dof)
    for p in range(scene.n_particles):
        g[3 * p + 2] = (-1.0) ** (p % nx + p // nx)
    return g / np.linalg.norm(g)


def _sym_calH(result) -> np.ndarray:
    _, _, Hs = branch_matrices(result.problem, result.branches[0].mask[None])
    return Hs[0]


def analyse(scene: granstab.Scene, nx: int) -> dict:
    """The single (elastic) branch of a packing: zero count, the non-rigid null space and the gear vector in it,
    or (with rolling stiffness) the lowest non-rigid mode and how close it is to the gear vector."""
    result = granstab.analyze(scene, metric="L")
    b = result.branches[0]
    Hs = _sym_calH(result)
    lam, V = np.linalg.eigh(Hs)
    norm = np.abs(lam).max()
    rigid = result.problem.rigid
    g = gear_vector(scene, nx)                                      # rotation dofs: scaled by L, pattern unchanged
    V_off = V - rigid @ (rigid.T @ V)                               # part outside the rigid motions
    nonrigid = np.linalg.norm(V_off, axis=0) > 0.5
    j = np.flatnonzero(nonrigid)[np.argmin(lam[nonrigid])]          # lowest non-rigid eigenpair
    v = V_off[:, j] / np.linalg.norm(V_off[:, j])
    jg = int(np.argmax(np.abs(V_off.T @ g) * nonrigid))               # the eigenpair most like the gear vector
    rot = v[2::3]
    pattern = np.array([(-1.0) ** (p % nx + p // nx) for p in range(scene.n_particles)])
    return {
        "n_particles": scene.n_particles, "n_contacts": scene.n_contacts, "n_dof": scene.n_dof,
        "rolling": float(scene.rolling[0, 0, 0]) if scene.n_contacts else 0.0,
        "length": result.length, "n_zero": b.n_zero, "zero_tol": b.zero_tol, "verdict": result.summary["verdict"],
        "eigenvalues": lam, "lowest_nonrigid": float(lam[j]), "lowest_nonrigid_relative": float(lam[j] / norm),
        "overlap": float(abs(v @ g)),                               # |cos| between that mode and the gear vector
        "translation_share": float(np.linalg.norm(np.delete(v, np.s_[2::3])) / np.linalg.norm(v)),
        "rotation_pattern_spread": float(np.ptp(rot * pattern * np.sign(rot @ pattern))
                                         / np.abs(rot).mean()),
        "gear_like_eigenvalue": float(lam[jg]),
        "gear_like_overlap": float(abs(V_off[:, jg] @ g) / np.linalg.norm(V_off[:, jg])),
        "rayleigh": float(g @ Hs @ g), "residual": float(np.linalg.norm(Hs @ g - (g @ Hs @ g) * g) / norm),
        "rigid_part_of_gear": float(np.linalg.norm(rigid.T @ g)),
        "estimate": 4.0 * float(scene.rolling[0, 0, 0]) * scene.n_contacts / (scene.n_particles * result.length ** 2),
        "norm": float(norm),
    }


def study(nx: int = DEFAULT["nx"], ny: int = DEFAULT["ny"], rolling_values=(0.0, 1e-4, 1e-3, 1e-2, 1e-1),
          rho_ratios=(0.99, 0.999, 1.0, 1.001, 1.01), progress=None) -> dict:
    """Zero-rolling packing (the gear mode), a sweep of the rolling stiffness, r ≠ ρ and the parity of nx·ny."""
    base = {key: DEFAULT[key] for key in ("R", "f_h", "f_v", "k", "alpha", "mu")}
    out = {"params": {"nx": nx, "ny": ny, **base}, "rolling": [], "rho": [], "parity": []}
    tick = progress or (lambda: None)
    out["gear"] = analyse(packing(nx, ny, rolling=0.0, **base), nx)
    tick()
    out["with_rolling"] = analyse(packing(nx, ny, rolling=PRESET_ROLLING, **base), nx)
    tick()
    for kr in rolling_values:
        out["rolling"].append(analyse(packing(nx, ny, rolling=kr, **base), nx))
        tick()
    for ratio in rho_ratios:
        res = analyse(packing(nx, ny, rho=ratio * base["R"], **base), nx)
        res["rho_over_r"] = ratio
        out["rho"].append(res)
        tick()
    for n in (2, 3, 4, 5):
        res = analyse(packing(n, n, **base), n)
        res["nx"] = res["ny"] = n
        out["parity"].append(res)
        tick()
    return out
