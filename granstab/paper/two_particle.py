"""Two-particle cluster of Sec. 4.1 and Appendix C: closed forms, the batched λ⁽⁶⁾ field, checks against the core.

Set-up (Table 1). Particles p, q on the e1 axis, contact point at r^p from x^p, normal n^pq = e1, compressive
normal force f^pq = [-f, 0] (f > 0 compression, f < 0 cohesion), convex radii of curvature ρ^p, ρ^q, elastic
contact (k, αk), no contact moment stiffness. Dofs in the paper's order [u1^p, u2^p, θ3^p, u1^q, u2^q, θ3^q].

Stiffness (eq:exampleH2, with erratum 2, docs/errata.md for B): H = Hm + Hg, and the rigid rotation about the centre
C = [0, -(r^p+r^q)/2, 1, 0, (r^p+r^q)/2, 1]ᵀ (eq:exampleC); P = I - C Cᵀ/(CᵀC) (eq:Pnrr), ℍ = H P and
𝓗 = P H P (eq:newstiffnesses). H is symmetric here (elastic contact, normal force), so 𝓗 = sym(𝓗) and the
spectra of ℍ and 𝓗 coincide (eq:proof1-3).

Closed forms, symmetric case r^p = r^q = r, ρ^p = ρ^q = ρ (derived with sympy from the matrices above; the
characteristic polynomial of ℍ factors as λ³ (λ - 2k) (λ - λ⁽⁵⁾) (λ - λ⁽⁶⁾)):

    λ⁽¹⁾ = λ⁽²⁾ = λ⁽³⁾ = 0                     rigid translations and rotation
    λ⁽⁴⁾ = 2k                                   ν⁽⁴⁾ = [1, 0, 0, -1, 0, 0]/√2 (normal indentation)
    λ⁽⁵⁾ = 2αk(1 + r²) - f [(1 + r²)² - rρ(2 + r²)] / (ρ (1 + r²))      (tangential shearing)
    λ⁽⁶⁾ = f (ρ - r)                            ν⁽⁶⁾ = [0, 0, 1, 0, 0, -1]/√2 (rolling)

λ⁽⁶⁾ is exact for every k and α: on the rolling mode Hm vanishes and Hg1 + Hg2 + Hg3 reduce to f(ρ - r) (Hg2's
force rows cancel Hg3's). Dimensionless: λ⁽⁶⁾/(k r²) = (f/(kr)) (ρ/r - 1), which changes sign exactly on ρ/r = 1
and on f = 0 (docs/errata.md). λ⁽⁵⁾ mixes translations and rotations, so it depends on the unit of length (the 1 in
1 + r² is 1 length²): the formula is in the paper's literal metric, dofs [du, dθ] with lengths in file units.
The field of Fig. 5 uses r = 1, where the metric is unambiguous (and equals granstab's scaled metric, L = r).
"""
from __future__ import annotations

import numpy as np

import granstab
from granstab.mechanics.branches import branch_matrices

DOFS = ("p.u1", "p.u2", "p.th3", "q.u1", "q.u2", "q.th3")
NU4 = np.array([1.0, 0, 0, -1, 0, 0]) / np.sqrt(2)      # normal indentation
NU6 = np.array([0, 0, 1.0, 0, 0, -1]) / np.sqrt(2)      # rolling
#: default grid of the λ⁽⁶⁾ figure: ρ/r and f/(kr) ∈ [-0.005, 0.02] (Sec. 4.1), α = 1
RHO_GRID = np.linspace(0.2, 3.0, 141)
FORCE_GRID = np.linspace(-0.005, 0.02, 126)
#: sample points (ρ/r, f/(kr)) of the six-eigenvalue table: sharp, disk, flat at compression, cohesion, zero force
SAMPLES = ((0.5, 0.01), (1.0, 0.01), (2.0, 0.01), (0.5, 0.02), (2.0, 0.02), (0.5, -0.005), (2.0, -0.005),
           (1.0, -0.005), (0.5, 0.0), (2.0, 0.0))


# --------------------------------------------------------------------------------------- paper's matrices

def paper_parts(k, alpha, rp, rq, rhop, rhoq, f):
    """Hm and Hg = Hg1 + Hg2 + Hg3 of eq:exampleH2, broadcast over array arguments: two (..., 6, 6) arrays."""
    k, a, rp, rq, pp, pq, f = np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                                    for v in (k, alpha, rp, rq, rhop, rhoq, f)))
    z = np.zeros_like(k)
    Hm = k[..., None, None] * np.stack([
        np.stack([1 + z, z, z, -1 + z, z, z], -1),
        np.stack([z, a, a * rp, z, -a, a * rq], -1),
        np.stack([z, a * rp, a * rp ** 2, z, -a * rp, a * rp * rq], -1),
        np.stack([-1 + z, z, z, 1 + z, z, z], -1),
        np.stack([z, -a, -a * rp, z, a, -a * rq], -1),
        np.stack([z, a * rq, a * rp * rq, z, -a * rq, a * rq ** 2], -1)], -2)
    Hg = (f / (pp + pq))[..., None, None] * np.stack([
        np.stack([z, z, z, z, z, z], -1),
        np.stack([z, -1 + z, pp - rp, z, 1 + z, pq - rq], -1),
        np.stack([z, pp - rp, (pp - rp) * (pq + rp), z, rp - pp, (pq - rq) * (rp - pp)], -1),
        np.stack([z, z, z, z, z, z], -1),
        np.stack([z, 1 + z, rp - pp, z, -1 + z, rq - pq], -1),
        np.stack([z, pq - rq, (pq - rq) * (rp - pp), z, rq - pq, (pq - rq) * (pp + rq)], -1)], -2)
    return Hm, Hg


def paper_stiffness(k, alpha, rp, rq, rhop, rhoq, f) -> np.ndarray:
    """H = Hm + Hg of eq:exampleH2, (..., 6, 6)."""
    Hm, Hg = paper_parts(k, alpha, rp, rq, rhop, rhoq, f)
    return Hm + Hg


def rotation_vector(rp, rq) -> np.ndarray:
    """C of eq:exampleC, (..., 6): rigid rotation about the centre of the pair."""
    h = 0.5 * (np.asarray(rp, float) + np.asarray(rq, float))
    z = np.zeros_like(h)
    return np.stack([z, -h, 1 + z, z, h, 1 + z], -1)


def rigid_basis(rp, rq) -> np.ndarray:
    """Orthonormal basis (..., 6, 3) of the rigid motions: translations e1, e2 and the rotation C."""
    C = rotation_vector(rp, rq)
    C = C / np.linalg.norm(C, axis=-1, keepdims=True)
    e1 = np.broadcast_to(np.array([1.0, 0, 0, 1, 0, 0]) / np.sqrt(2), C.shape)
    e2 = np.broadcast_to(np.array([0, 1.0, 0, 0, 1, 0]) / np.sqrt(2), C.shape)
    return np.stack([e1, e2, C], -1)       # C ⟂ e1 always; C ⟂ e2 because the origin is the centre


def projected(H: np.ndarray, C: np.ndarray):
    """ℍ = H P and 𝓗 = P H P for P = I - C Cᵀ/(CᵀC) (eq:Pnrr, eq:newstiffnesses); stacked (..., 6, 6)."""
    c = C / np.linalg.norm(C, axis=-1, keepdims=True)
    P = np.eye(6) - c[..., :, None] * c[..., None, :]
    HH = H @ P
    return HH, P @ HH


# ------------------------------------------------------------------------------------------ closed forms

def lambda5(k, alpha, r, rho, f):
    """λ⁽⁵⁾ (tangential shearing), symmetric case, paper's literal metric (see module docstring)."""
    k, alpha, r, rho, f = (np.asarray(v, dtype=float) for v in (k, alpha, r, rho, f))
    s = 1.0 + r ** 2
    return 2.0 * alpha * k * s - f * (s ** 2 - r * rho * (2.0 + r ** 2)) / (rho * s)


def lambda6(r, rho, f):
    """λ⁽⁶⁾ = f (ρ - r) (rolling), symmetric case, any k and α."""
    return np.asarray(f, float) * (np.asarray(rho, float) - np.asarray(r, float))


def closed_form_eigenvalues(k, alpha, r, rho, f) -> np.ndarray:
    """[λ⁽¹⁾ … λ⁽⁶⁾] = [0, 0, 0, 2k, λ⁽⁵⁾, λ⁽⁶⁾] (mode order, not sorted), (..., 6)."""
    k, alpha, r, rho, f = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (k, alpha, r, rho, f)))
    z = np.zeros_like(k)
    return np.stack([z, z, z, 2.0 * k, lambda5(k, alpha, r, rho, f), lambda6(r, rho, f)], -1)


# ------------------------------------------------------------------------------- numerical eigenproblems

def identify_modes(calH: np.ndarray, rigid: np.ndarray) -> dict:
    """λ⁽⁴⁾, λ⁽⁵⁾, λ⁽⁶⁾ and ν⁽⁵⁾ from a stacked symmetric 𝓗 (..., 6, 6) whose null space holds `rigid` (..., 6, 3).

    𝓗 is reduced to the 3-dimensional complement of the rigid motions (where its eigenvalues are λ⁽⁴⁻⁶⁾ exactly),
    solved there, and the modes are named by their overlap with ν⁽⁴⁾ and ν⁽⁶⁾; the third one is the shearing mode.
    Returns lam4, lam5, lam6 (...), nu5 (..., 6) and the overlaps |ν·ν⁽⁴⁾|, |ν·ν⁽⁶⁾| of the named modes.
    """
    comp_proj = np.eye(6) - rigid @ np.swapaxes(rigid, -1, -2)
    _, vecs = np.linalg.eigh(comp_proj)
    Q = vecs[..., 3:]                                                # eigenvalue-1 eigenvectors: the complement
    A = np.swapaxes(Q, -1, -2) @ calH @ Q
    w, U = np.linalg.eigh(0.5 * (A + np.swapaxes(A, -1, -2)))
    V = Q @ U                                                        # (..., 6, 3)
    o4 = np.abs(np.einsum("...ij,i->...j", V, NU4))
    o6 = np.abs(np.einsum("...ij,i->...j", V, NU6))
    j4 = np.argmax(o4, axis=-1)
    o6_masked = np.where(np.arange(3) == j4[..., None], -1.0, o6)
    j6 = np.argmax(o6_masked, axis=-1)
    j5 = 3 - j4 - j6
    take = lambda arr, j: np.take_along_axis(arr, j[..., None], -1)[..., 0]  # noqa: E731
    nu5 = np.take_along_axis(V, j5[..., None, None], -1)[..., 0]
    return {"lam4": take(w, j4), "lam5": take(w, j5), "lam6": take(w, j6), "nu5": nu5,
            "overlap4": take(o4, j4), "overlap6": take(o6, j6)}


def paper_modes(k, alpha, r, rho, f) -> dict:
    """Stacked numerical λ⁽⁴⁻⁶⁾ of ℍ for the symmetric case from the paper's own matrices (eq:exampleH2, eq:exampleC),
    plus the sorted six eigenvalues of ℍ, the symmetry defect of H and the rigid-leakage of 𝓗 (all (...))."""
    H = paper_stiffness(k, alpha, r, r, rho, rho, f)
    C = rotation_vector(r, r)
    HH, calH = projected(H, C)
    rigid = rigid_basis(r, r)
    modes = identify_modes(calH, rigid)
    norm = np.linalg.norm(calH, ord=2, axis=(-2, -1))
    modes["all"] = np.sort(np.linalg.eigvals(HH).real, axis=-1)
    modes["norm"] = norm
    modes["asymmetry"] = np.abs(H - np.swapaxes(H, -1, -2)).max(axis=(-2, -1)) / norm
    modes["rigid_leakage"] = np.abs(calH @ rigid).max(axis=(-2, -1)) / norm
    return modes


def lambda6_field(rho_over_r=RHO_GRID, f_over_kr=FORCE_GRID, alpha: float = 1.0, verify: bool = False) -> dict:
    """λ⁽⁶⁾ (and λ⁽⁴⁾, λ⁽⁵⁾) over the grid ρ/r × f/(kr), r = k = 1: arrays (len(f_over_kr), len(rho_over_r)) in units
    of k (λ⁽⁶⁾: k r²).

    The field is the closed forms (exact, batched over the grid). verify=True also solves the paper's matrices as
    stacked 6×6 eigenproblems and reports `error_*` = max |numerical - closed| / ‖𝓗‖₂ over the grid (round-off
    ≈ 1e-16 expected), the symmetry defect, the rigid leakage and the overlap of the rolling mode with ν⁽⁶⁾.
    """
    rho = np.asarray(rho_over_r, float)
    f = np.asarray(f_over_kr, float)
    F, R = np.meshgrid(f, rho, indexing="ij")
    closed = closed_form_eigenvalues(1.0, alpha, 1.0, R, F)
    out = {"rho_over_r": rho, "f_over_kr": f, "alpha": alpha,
           "lam4": closed[..., 3], "lam5": closed[..., 4], "lam6": closed[..., 5]}
    if not verify:
        return out
    num = paper_modes(1.0, alpha, 1.0, R, F)
    for name in ("lam4", "lam5", "lam6"):
        out[f"{name}_stacked"] = num[name]
        out[f"error_{name}"] = float(np.max(np.abs(num[name] - out[name]) / num["norm"]))
    out["max_asymmetry"] = float(num["asymmetry"].max())
    out["max_rigid_leakage"] = float(num["rigid_leakage"].max())
    out["min_overlap6"] = float(num["overlap6"][np.abs(out["lam6"]) > 1e-12 * num["norm"]].min())
    return out


# --------------------------------------------------------------------------------------------- the core

def scene(r: float = 1.0, rho: float = 0.5, f: float = 0.01, k: float = 1.0, alpha: float = 1.0,
          mu: float = 0.5, rq: float | None = None, rhoq: float | None = None,
          state: str = "elastic", title: str | None = None) -> granstab.Scene:
    """The Table-1 scene in the core's format: x^p = 0, x^q = (r^p + r^q) e1, n = e1, f^pq = [-f, 0].

    rq, rhoq default to r, rho (symmetric case); a concave q (hand-in-glove) has rhoq < 0. The contact is declared
    elastic by default, so that cohesive forces (f < 0) are accepted as in the paper's figure.
    """
    rq = r if rq is None else rq
    rhoq = rho if rhoq is None else rhoq
    t = np.array([0.0, 1.0])
    arrays = {
        "p": np.array([0]), "q": np.array([1]), "point": np.array([[r, 0.0]]), "normal": np.array([[1.0, 0.0]]),
        "curvature_p": (-1.0 / rho * np.outer(t, t))[None], "curvature_q": (-1.0 / rhoq * np.outer(t, t))[None],
        "force": np.array([[-f, 0.0]]), "moment": np.zeros((1, 1)), "k": np.array([k]),
        "alpha": np.array([alpha]), "mu": np.array([mu]), "rolling": np.zeros((1, 1, 1)), "state": (state,),
    }
    title = title or f"two particles, r = {r:g}, rho = {rho:g}, f/(kr) = {f / (k * r):g}"
    return granstab.build_scene(2, ["p", "q"], np.array([[0.0, 0.0], [r + rq, 0.0]]), arrays, title=title,
                                source="<two_particle>")


def core_modes(r: float, rho: float, f: float, k: float = 1.0, alpha: float = 1.0) -> dict:
    """λ⁽⁴⁻⁶⁾ of the symmetric case computed by granstab.analyze (paper's metric, rotation_length = 1)."""
    result = granstab.analyze(scene(r, rho, f, k, alpha), metric="L", rotation_length=1.0)
    branch = result.branches[0]
    _, _, calH = branch_matrices(result.problem, branch.mask[None])   # the core's sym(𝓗) (= 𝓗, H symmetric)
    modes = identify_modes(calH[0], rigid_basis(r, r))
    lam = branch.stability_eigenvalues
    modes.update(stability=lam, uniqueness=np.sort(branch.uniqueness_eigenvalues.real),
                 uniqueness_imag=float(np.abs(branch.uniqueness_eigenvalues.imag).max()),
                 verdict=result.summary["verdict"], n_zero=branch.n_zero, errors=result.errors)
    return modes


def core_blocks_field(rho_over_r=RHO_GRID, f_over_kr=FORCE_GRID, alpha: float = 1.0) -> dict:
    """λ⁽⁴⁻⁶⁾ over the whole grid from the core's own stiffness: ONE scene holding every grid point as a separate
    pair (pair i on the line x2 = 10 i), whose per-contact 6×6 blocks Hg1 + Hg2 + Hg3 + Hm
    (granstab.mechanics.stiffness.contact_blocks) are each pair's H; then eq:exampleC's projection and stacked eigenproblems.
    Arrays (len(f_over_kr), len(rho_over_r)); errors relative to ‖𝓗‖₂ as in `lambda6_field`."""
    from granstab.mechanics.stiffness import contact_blocks

    rho = np.asarray(rho_over_r, float)
    f = np.asarray(f_over_kr, float)
    F, R = np.meshgrid(f, rho, indexing="ij")
    M = F.size
    t = np.array([0.0, 1.0])
    K = -(1.0 / R.reshape(-1))[:, None, None] * np.outer(t, t)
    offset = 10.0 * np.arange(M)
    x = np.stack([np.stack([np.zeros(M), offset], 1), np.stack([np.full(M, 2.0), offset], 1)], 1).reshape(-1, 2)
    arrays = {
        "p": 2 * np.arange(M), "q": 2 * np.arange(M) + 1, "point": np.stack([np.ones(M), offset], 1),
        "normal": np.tile([1.0, 0.0], (M, 1)), "curvature_p": K, "curvature_q": K.copy(),
        "force": np.stack([-F.reshape(-1), np.zeros(M)], 1), "moment": np.zeros((M, 1)), "k": np.ones(M),
        "alpha": np.full(M, alpha), "mu": np.full(M, 0.5), "rolling": np.zeros((M, 1, 1)),
        "state": ("elastic",) * M,
    }
    names = [f"{side}{i}" for i in range(M) for side in ("p", "q")]
    sc = granstab.build_scene(2, names, x, arrays, title="two-particle grid", source="<two_particle grid>")
    blocks = contact_blocks(sc).blocks
    H = sum(blocks[name] for name in ("Hg1", "Hg2", "Hg3", "Hm")).reshape(F.shape + (6, 6))
    _, calH = projected(H, rotation_vector(1.0, 1.0))
    modes = identify_modes(0.5 * (calH + np.swapaxes(calH, -1, -2)), rigid_basis(1.0, 1.0))
    norm = np.linalg.norm(calH, ord=2, axis=(-2, -1))
    closed = closed_form_eigenvalues(1.0, alpha, 1.0, R, F)
    out = {"rho_over_r": rho, "f_over_kr": f, "lam4": modes["lam4"], "lam5": modes["lam5"], "lam6": modes["lam6"],
           "asymmetry": float((np.abs(H - np.swapaxes(H, -1, -2)).max(axis=(-2, -1)) / norm).max())}
    for j, name in ((3, "lam4"), (4, "lam5"), (5, "lam6")):
        out[f"error_{name}"] = float(np.max(np.abs(out[name] - closed[..., j]) / norm))
    return out


def core_field(rho_over_r, f_over_kr, alpha: float = 1.0, progress=None) -> dict:
    """λ⁽⁴⁻⁶⁾ from granstab.analyze at every point of a (coarser) grid, r = k = 1, and their closed forms."""
    rho = np.asarray(rho_over_r, float)
    f = np.asarray(f_over_kr, float)
    shape = (len(f), len(rho))
    out = {name: np.zeros(shape) for name in ("lam4", "lam5", "lam6", "norm")}
    verdicts = np.empty(shape, dtype=object)
    for i, fi in enumerate(f):
        for j, rj in enumerate(rho):
            m = core_modes(1.0, rj, fi, 1.0, alpha)
            for name in ("lam4", "lam5", "lam6"):
                out[name][i, j] = m[name]
            out["norm"][i, j] = np.abs(m["stability"]).max()
            verdicts[i, j] = m["verdict"]
            if progress is not None:
                progress()
    F, R = np.meshgrid(f, rho, indexing="ij")
    closed = closed_form_eigenvalues(1.0, alpha, 1.0, R, F)
    out.update(rho_over_r=rho, f_over_kr=f, verdict=verdicts, lam4_closed=closed[..., 3],
               lam5_closed=closed[..., 4], lam6_closed=closed[..., 5])
    for name in ("lam4", "lam5", "lam6"):
        out[f"error_{name}"] = float(np.max(np.abs(out[name] - out[name + "_closed"]) / out["norm"]))
    return out


def sample_table(samples=SAMPLES, alpha: float = 1.0) -> list[dict]:
    """All six eigenvalues of ℍ at sample points (r = k = 1): from the core, the paper's matrix and closed forms."""
    rows = []
    for rho, f in samples:
        core = core_modes(1.0, rho, f, 1.0, alpha)
        paper = paper_modes(1.0, alpha, 1.0, rho, f)
        closed = closed_form_eigenvalues(1.0, alpha, 1.0, rho, f)
        rows.append({
            "rho_over_r": rho, "f_over_kr": f,
            "core_sorted": [float(v) for v in core["uniqueness"]],
            "paper_sorted": [float(v) for v in paper["all"]],
            "closed": [float(v) for v in closed],
            "core_modes": [float(core[n]) for n in ("lam4", "lam5", "lam6")],
            "verdict": core["verdict"], "n_zero": core["n_zero"],
        })
    return rows


def general_case_check(seed: int = 0, n: int = 20) -> float:
    """Largest relative difference between the core's H and eq:exampleH2 for random unequal r, ρ, k, α, f."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(n):
        rp, rq, pp, pq = rng.uniform(0.3, 3.0, 4)
        k, a = rng.uniform(0.5, 2.0), rng.uniform(0.2, 1.0)
        f = k * rp * rng.uniform(-0.005, 0.02)
        K = granstab.stiffness(scene(rp, pp, f, k, a, rq=rq, rhoq=pq))
        H = paper_stiffness(k, a, rp, rq, pp, pq, f)
        worst = max(worst, float(np.abs(K.H - H).max() / np.abs(H).max()))
    return worst
