"""The four-disk cluster of Sec. 4.2 (Fig. 7): 16 branches, consistent eigenmodes, robustness, the sliding path.

Geometry. Four equal disks of radius R (= ρ = r at every contact, docs/errata.md) at the corners of a rhombus: "top" at
(0, 2R sin β), "left" at (-2R cos β, 0), "bottom" at (0, -2R sin β), "right" at (2R cos β, 0); β is the angle of
the branch vectors left→top and right→top with the horizontal (at β = 45° the rhombus is a square, so the
convention does not matter there). Contacts, in this order: top-left, top-right, bottom-left, bottom-right, with
p the top/bottom disk and n^pq pointing from p to the side disk.

Forces. The cluster is compressed vertically and expands horizontally, all four contacts sliding: the top disk
moves down relative to the side disks, so friction on it points up along the tangent. With f the normal force and
μf the friction, for the top-left contact n = -(cos β, sin β) and
    f^pq = f (cos β - μ sin β, sin β + μ cos β)         (f^pq·n = -f, |f_t| = μ f: Q = 0, eq:yield)
and the other three by mirror symmetry. Equilibrium (eq:equil1) needs no load moments and loads
    b^top = -b^v e2, b^bottom = b^v e2, b^left = b^h e1, b^right = -b^h e1,
    b^v = 2f (sin β + μ cos β),  b^h = 2f (cos β - μ sin β),  b^v/b^h = tan(β + φ),  tan φ = μ.

Sliding path (Fig. 7c). Continued sliding without rotation keeps f and μf constant (the sliding branch of
eq:ContactF gives no mechanical increment for a tangential δu_def along h) while β decreases: b^v/b^h = tan(β + φ)
falls (softening). Per unit dβ the motion is du^top = (0, 2R cos β), du^left = (2R sin β, 0), … and the
second-order work is dUᵀ𝓗dU = -4R (b^h cos β + b^v sin β) = -8 f R, all of it geometric (Hm·dU = 0).
"""
from __future__ import annotations

import dataclasses
import types

import numpy as np

import granstab
from granstab.mechanics.assembly import assemble
from granstab.mechanics.branches import (
    BOTH,
    INCONSISTENT,
    MINUS,
    PLUS,
    RIGID,
    branch_matrices,
    canonical,
    search_subspace,
    test_codes,
)
from granstab.mechanics.stiffness import contact_blocks
from granstab.model.tolerances import DEFAULT as DEFAULT_TOL
from granstab.model.tolerances import Tolerances
from granstab.solve.dense import solve_branches

NAMES = ("top", "left", "bottom", "right")
PAIRS = ((0, 1), (0, 3), (2, 1), (2, 3))          # top-left, top-right, bottom-left, bottom-right
CONTACT_LABELS = ("top-left", "top-right", "bottom-left", "bottom-right")
#: Sec. 4.2: α = 1, f/k = 1/1000, μ = 0.5, β = 45°, R = 1
PAPER = {"beta_deg": 45.0, "mu": 0.5, "alpha": 1.0, "f_over_k": 1e-3, "R": 1.0, "k": 1.0}
#: the paper's totals over the 16 branches of sym(𝓗^i)
PAPER_TOTALS = {"zeros_per_branch": 4, "consistent_nonzero": 30, "positive": 21, "negative": 9}
CODE_NAME = {PLUS: "+v", MINUS: "-v", BOTH: "±v", INCONSISTENT: "none", RIGID: "rigid"}


# ------------------------------------------------------------------------------------------------ scene

def geometry(beta: float, R: float = 1.0):
    """Centres x (4, 2), unit normals n^pq (4, 2) and contact points (4, 2) for the rhombus at angle β (radians)."""
    c, s = np.cos(beta), np.sin(beta)
    x = np.array([[0.0, 2 * R * s], [-2 * R * c, 0.0], [0.0, -2 * R * s], [2 * R * c, 0.0]])
    n = np.array([(x[q] - x[p]) / (2 * R) for p, q in PAIRS])
    return x, n, x[[p for p, _ in PAIRS]] + R * n


def contact_forces(beta: float, f: float, mu: float) -> np.ndarray:
    """f^pq (4, 2) of the four contacts at yield (module docstring): normal f, friction μf against the sliding."""
    a = f * (np.cos(beta) - mu * np.sin(beta))
    b = f * (np.sin(beta) + mu * np.cos(beta))
    return np.array([[a, b], [-a, b], [a, -b], [-a, -b]])


def loads(beta: float, f: float, mu: float):
    """(b^v, b^h) = 2f (sin β + μ cos β), 2f (cos β - μ sin β)."""
    return 2 * f * (np.sin(beta) + mu * np.cos(beta)), 2 * f * (np.cos(beta) - mu * np.sin(beta))


def scene(beta_deg: float = 45.0, mu: float = 0.5, alpha: float = 1.0, f_over_k: float = 1e-3, R: float = 1.0,
          k: float = 1.0, rho: float | None = None, state: str = "sliding",
          tol: Tolerances = DEFAULT_TOL) -> granstab.Scene:
    """The four-disk scene; `rho` (default R) is the curvature radius at every contact (r ≠ ρ tests)."""
    beta = np.radians(beta_deg)
    rho = R if rho is None else rho
    x, n, point = geometry(beta, R)
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    K = -1.0 / rho * t[:, :, None] * t[:, None, :]
    arrays = {
        "p": np.array([p for p, _ in PAIRS]), "q": np.array([q for _, q in PAIRS]), "point": point, "normal": n,
        "curvature_p": K, "curvature_q": K.copy(), "force": contact_forces(beta, f_over_k * k, mu),
        "moment": np.zeros((4, 1)), "k": np.full(4, k), "alpha": np.full(4, alpha), "mu": np.full(4, mu),
        "rolling": np.zeros((4, 1, 1)), "state": (state,) * 4,
    }
    title = f"four disks, beta = {beta_deg:g} deg, mu = {mu:g}, alpha = {alpha:g}, f/k = {f_over_k:g}"
    return granstab.build_scene(2, NAMES, x, arrays, title=title, source="<four_disk>", tol=tol)


# ------------------------------------------------------------------------------------ branch tables

def _s_scale(problem) -> float:
    return float(np.linalg.norm(problem.S, axis=0).max())


def s_threshold(problem, mask, v) -> float:
    """The smallest |S_c(v)|/scale over the potentially sliding contacts: the s_rtol above which the test vector of
    v, and so possibly its consistency, changes (scale as in Problem.s_tol)."""
    return float(np.abs(problem.S.T @ v).min() / _s_scale(problem))


def stability_table(result) -> list[dict]:
    """Per branch: mask, zero count of sym(𝓗^i), its non-rigid eigenpairs with consistency, S-thresholds and gaps."""
    problem = result.problem
    rows = []
    for b in result.branches:
        lam = b.stability_eigenvalues
        norm = np.abs(lam).max()
        pairs = []
        for j, (value, code) in enumerate(zip(lam, b.codes)):
            if code == RIGID:
                continue
            others = np.delete(lam, j)
            pairs.append({"eigenvalue": float(value), "code": int(code), "sign": CODE_NAME[int(code)],
                          "zero": bool(abs(value) <= b.zero_tol), "hinges": bool(b.hinges[j]),
                          "s_threshold": s_threshold(problem, b.mask, b.stability_vectors[:, j]),
                          "gap": float(np.abs(others - value).min() / norm)})
        consistent = [p for p in pairs if p["code"] in (PLUS, MINUS, BOTH)]
        rows.append({
            "mask": [int(v) for v in b.mask], "n_zero": b.n_zero, "zero_tol": b.zero_tol, "pairs": pairs,
            "consistent_nonzero": [p for p in consistent if not p["zero"]],
            "consistent_zero": [p for p in consistent if p["zero"]],
            "positive": sum(1 for p in consistent if not p["zero"] and p["eigenvalue"] > 0),
            "negative": sum(1 for p in consistent if not p["zero"] and p["eigenvalue"] < 0),
        })
    return rows


def totals(rows) -> dict:
    """Totals over branches: zero counts, consistent non-zero eigenvalues, positive, negative."""
    return {"zeros": [r["n_zero"] for r in rows], "zeros_min": min(r["n_zero"] for r in rows),
            "zeros_max": max(r["n_zero"] for r in rows),
            "consistent_nonzero": sum(len(r["consistent_nonzero"]) for r in rows),
            "positive": sum(r["positive"] for r in rows), "negative": sum(r["negative"] for r in rows),
            "consistent_zero": sum(len(r["consistent_zero"]) for r in rows)}


def uniqueness_table(result) -> list[dict]:
    """The same for ℍ^i = H^i P (eq:problem): eigenvalues (complex in general), nullity, and the consistency of the
    real eigenvectors (Appendix D). A repeated real eigenvalue is searched over its whole eigenspace (null space of
    ℍ^i - λI); the non-rigid null space is the Type-2 test of the core. Complex pairs are not real motions."""
    problem = result.problem
    masks = np.array([b.mask for b in result.branches])
    _, HH, _ = branch_matrices(problem, masks)
    rows = []
    for b, A in zip(result.branches, HH):
        mu, W = np.linalg.eig(A)
        norm = np.linalg.svd(A, compute_uv=False).max()
        tol = problem.tol.zero_tol(norm, len(mu))
        order = np.argsort(mu.real, kind="stable")
        mu, W = mu[order], W[:, order]
        entries, done = [], np.zeros(len(mu), bool)
        zero = np.zeros(len(mu), bool)                       # the nullity is the core's (SVD): drop that many
        zero[np.argsort(np.abs(mu))[:b.uniqueness_n_zero]] = True
        for j in range(len(mu)):
            if done[j] or zero[j]:
                continue
            if abs(mu[j].imag) > tol:
                entries.append({"eigenvalue": [float(mu[j].real), float(mu[j].imag)], "code": INCONSISTENT,
                                "sign": "complex", "multiplicity": 1})
                done[j] = True
                continue
            group = np.flatnonzero(~done & ~zero & (np.abs(mu - mu[j]) <= 1e3 * tol))
            done[group] = True
            _, sv, Vt = np.linalg.svd(A - mu[j].real * np.eye(len(mu)))
            space = Vt[sv <= max(1e3 * tol, sv.max() * 1e-12)].T
            if space.shape[1] == 0:
                space = np.real(W[:, [j]])
            if space.shape[1] == 1:
                v = canonical(space[:, 0] / np.linalg.norm(space[:, 0]))      # the SVD's sign is arbitrary
                codes, _ = test_codes(problem, b.mask[None], v[None, :, None])
                code = int(codes[0, 0])
            else:
                found = search_subspace(problem, b.mask, space)
                code = INCONSISTENT if found is None else found[1]
            entries.append({"eigenvalue": [float(mu[j].real), 0.0], "code": code, "sign": CODE_NAME[code],
                            "multiplicity": len(group)})
        consistent = [e for e in entries if e["code"] in (PLUS, MINUS, BOTH)]
        rows.append({
            "mask": [int(v) for v in b.mask], "n_zero": b.uniqueness_n_zero, "entries": entries,
            "consistent": consistent, "n_complex": sum(e["sign"] == "complex" for e in entries),
            "positive": sum(e["eigenvalue"][0] > 0 for e in consistent),
            "negative": sum(e["eigenvalue"][0] < 0 for e in consistent),
            "type2": [{"sign": CODE_NAME[t["vector_sign"]], "dimension": t["dimension"]} for t in b.type2],
        })
    return rows


def uniqueness_totals(rows) -> dict:
    return {"zeros": [r["n_zero"] for r in rows], "consistent": sum(len(r["consistent"]) for r in rows),
            "positive": sum(r["positive"] for r in rows), "negative": sum(r["negative"] for r in rows),
            "complex": sum(r["n_complex"] for r in rows), "type2_branches": sum(bool(r["type2"]) for r in rows)}


def count(**params) -> dict:
    """Totals of sym(𝓗^i) for one parameter set (keywords of `scene`)."""
    tol = params.pop("tol", DEFAULT_TOL)
    result = granstab.analyze(scene(**params, tol=tol), metric="L")
    t = totals(stability_table(result))
    t["verdict"] = result.summary["verdict"]
    return t


# -------------------------------------------------------------------------------------------- robustness

S_RTOLS = (1e-14, 1e-12, 1e-10, 1e-8, 1e-6, 1e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
ZERO_FACTORS = (1.0, 64.0, 1e4, 1e8, 1e10, 1e11, 1e12)
PARAMETERS = {
    "mu": (0.1, 0.3, 0.4, 0.45, 0.5, 0.55, 0.6, 0.7, 0.9),
    "alpha": (0.5, 0.8, 0.9, 0.95, 1.0, 1.05, 1.25, 2.0),
    "beta_deg": (30.0, 40.0, 44.0, 45.0, 46.0, 50.0, 60.0),
    "f_over_k": (1e-5, 1e-4, 5e-4, 1e-3, 2e-3, 1e-2, 3e-2),
    "rho_over_r": (0.99, 0.999, 1.0, 1.001, 1.01),
}


def tolerance_sweep(s_rtols=S_RTOLS, zero_factors=ZERO_FACTORS, progress=None) -> dict:
    """Totals at the paper's parameters for a range of S tolerances (s_rtol) and zero-eigenvalue tolerances."""
    out = {"s_rtol": [], "zero_factor": []}
    for s in s_rtols:
        out["s_rtol"].append({"value": s, **count(**PAPER, tol=Tolerances(s_rtol=s))})
        if progress:
            progress()
    for z in zero_factors:
        out["zero_factor"].append({"value": z, **count(**PAPER, tol=Tolerances(zero_factor=z))})
        if progress:
            progress()
    return out


def parameter_sweep(parameters=PARAMETERS, progress=None) -> dict:
    """Totals when one parameter moves away from the paper's value (the others fixed)."""
    out = {}
    for name, values in parameters.items():
        out[name] = []
        for value in values:
            params = dict(PAPER)
            if name == "rho_over_r":
                params["rho"] = value * PAPER["R"]
            else:
                params[name] = value
            out[name].append({"value": value, **count(**params)})
            if progress:
                progress()
    return out


def robustness(rows, s_rtol: float = DEFAULT_TOL.s_rtol, f_over_k: float = PAPER["f_over_k"]) -> dict:
    """Which consistency verdicts are robust: an eigenpair's verdict is S-robust if its s_threshold exceeds 100
    s_rtol (it would survive a 100× larger S tolerance) and it is 'split by geometry' when its gap to the nearest
    eigenvalue is below 10 f/k of ‖sym(𝓗)‖ (the cluster would merge without the geometric stiffness, and its
    eigenvectors turn with O(1) angles under O(f/k) changes)."""
    out = {"pairs": 0, "s_fragile": [], "geometric_split": []}
    for i, row in enumerate(rows):
        for p in row["pairs"]:
            if p["zero"]:
                continue
            out["pairs"] += 1
            tag = {"branch": i, "mask": row["mask"], "eigenvalue": p["eigenvalue"], "sign": p["sign"],
                   "s_threshold": p["s_threshold"], "gap": p["gap"]}
            if p["s_threshold"] <= 100 * s_rtol:
                out["s_fragile"].append(tag)
            if p["gap"] <= 10 * f_over_k:
                out["geometric_split"].append(tag)
    return out


def mechanical_only(**params) -> dict:
    """Totals with the geometric stiffness switched off (H = Hm on every branch), same consistency test: which
    consistent eigenvalues owe their sign or their consistency to Hg."""
    sc = scene(**{**PAPER, **params})
    result = granstab.analyze(sc, metric="L")
    cb = contact_blocks(sc)
    Hm = assemble(cb.blocks["Hm"], sc.p, sc.q, sc.dof_per_particle, cb.n_dof).toarray()
    problem = dataclasses.replace(result.problem, H_el=result.scale[:, None] * Hm * result.scale[None, :])
    masks = np.array([b.mask for b in result.branches])
    branches = solve_branches(problem, masks)
    return totals(stability_table(types.SimpleNamespace(problem=problem, branches=branches)))


CLUSTER_GAPS = (0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)


def cluster_sweep(gaps=CLUSTER_GAPS, **params) -> list[dict]:
    """Totals when eigenvalues closer than gap·‖sym(𝓗^i)‖ are treated as one eigenspace (searched for a consistent
    vector as a whole, as the core does for exactly repeated eigenvalues) instead of as separate eigenvectors.
    gap = 0 is the core's rule. Clusters split only by the O(f/k) geometric terms merge once gap exceeds their split."""
    sc = scene(**{**PAPER, **params})
    result = granstab.analyze(sc, metric="L")
    problem = result.problem
    masks = np.array([b.mask for b in result.branches])
    _, _, Hsym = branch_matrices(problem, masks)
    lam_all, V_all = np.linalg.eigh(Hsym)
    out = []
    for gap in gaps:
        pos = neg = 0
        for b, lam, V in zip(result.branches, lam_all, V_all):
            norm = np.abs(lam).max()
            zero = np.abs(lam) <= b.zero_tol
            keep = np.flatnonzero(~zero)
            breaks = np.flatnonzero(np.diff(lam[keep]) > max(gap * norm, b.zero_tol)) + 1
            for group in np.split(keep, breaks):
                if len(group) == 1:
                    codes, _ = test_codes(problem, b.mask[None], V[None][:, :, group])
                    ok = int(codes[0, 0]) in (PLUS, MINUS, BOTH)
                else:
                    ok = search_subspace(problem, b.mask, V[:, group]) is not None
                if ok:
                    pos += int(lam[group].mean() > 0)
                    neg += int(lam[group].mean() < 0)
        out.append({"gap": gap, "consistent_nonzero": pos + neg, "positive": pos, "negative": neg})
    return out


# ------------------------------------------------------------------------------------- the sliding path

def path_motion(beta: float, R: float = 1.0) -> np.ndarray:
    """dU/dβ along the path of continued sliding without rotation (12,): du^top = (0, 2R cos β),
    du^left = (2R sin β, 0), … Vertical compression is dβ < 0, i.e. the motion -dU/dβ (`compression_motion`)."""
    c, s = np.cos(beta), np.sin(beta)
    du = np.array([[0, 2 * R * c], [2 * R * s, 0], [0, -2 * R * c], [-2 * R * s, 0]])
    return np.concatenate([du, np.zeros((4, 1))], axis=1).reshape(-1)


def compression_motion(beta: float, R: float = 1.0) -> np.ndarray:
    """The motion per unit decrease of β (vertical compression, horizontal expansion): -dU/dβ (12,)."""
    return -path_motion(beta, R)


def load_vector(beta: float, f: float, mu: float) -> np.ndarray:
    """Equilibrium loads [b^p, w^p] of the four disks (12,) at angle β."""
    bv, bh = loads(beta, f, mu)
    b = np.array([[0, -bv], [bh, 0], [0, bv], [-bh, 0]])
    return np.concatenate([b, np.zeros((4, 1))], axis=1).reshape(-1)


def sliding_path(betas_deg=None, mu: float = PAPER["mu"], alpha: float = PAPER["alpha"],
                 f_over_k: float = PAPER["f_over_k"], R: float = PAPER["R"], k: float = PAPER["k"],
                 progress=None) -> dict:
    """b^v/b^h against β for continued sliding without rotation (Fig. 7c): closed form, and integrated from the
    core's stiffness, db/dβ = H^(all sliding)(β)·dU/dβ, starting from the exact loads at the first β.

    Also at every β: the residual |H dU/dβ - db/dβ|/|db/dβ| against the closed-form derivative, the S values of
    the compression motion relative to their largest (all > 0: the all-sliding branch is the consistent one) and
    the second-order work dUᵀ𝓗dU per dβ² of the compression motion, split into Hg1, Hg2, Hg3 and Hm (ours) and
    into geometric and mechanical parts by granstab.second_order_work (the core), against -8 f R.
    """
    from scipy.integrate import cumulative_simpson

    betas_deg = np.linspace(45.0, 15.0, 61) if betas_deg is None else np.asarray(betas_deg, float)
    f = f_over_k * k
    betas = np.radians(betas_deg)
    names = ("Hg1", "Hg2", "Hg3", "Hm", "total", "core_total", "core_geometric", "core_mechanical")
    rates, residuals, s_min, masks, work = [], [], [], [], {name: [] for name in names}
    for beta, bdeg in zip(betas, betas_deg):
        sc = scene(bdeg, mu, alpha, f_over_k, R, k)
        K = granstab.stiffness(sc, mask=[1, 1, 1, 1])
        rate = K.H @ path_motion(beta, R)
        bv, bh = loads(beta, f, mu)
        exact = np.concatenate([np.array([[0, -bh], [-bv, 0], [0, bh], [bv, 0]]), np.zeros((4, 1))], axis=1)
        exact = exact.reshape(-1)                                    # d(loads)/dβ, closed form
        rates.append(rate)
        residuals.append(float(np.linalg.norm(rate - exact) / np.linalg.norm(exact)))
        w = compression_motion(beta, R)
        cb = contact_blocks(sc)
        S = np.einsum("mn,mn->m", cb.slide_right, w[cb.index])      # S = g·δu_def per contact (eq:flow)
        s_min.append(float(S.min() / np.abs(S).max()))
        for name in ("Hg1", "Hg2", "Hg3", "Hm"):
            work[name].append(float(w @ getattr(K, name) @ w))
        work["total"].append(float(w @ K.H @ w))
        sow = granstab.second_order_work(granstab.analyze(sc, metric="L"), w)
        masks.append(sow["mask"])
        work["core_total"].append(sow["work"])
        work["core_geometric"].append(sow["geometric"])
        work["core_mechanical"].append(sow["mechanical"])
        if progress:
            progress()
    rates = np.array(rates)
    b0 = load_vector(betas[0], f, mu)
    sign = 1.0 if betas[-1] > betas[0] else -1.0                     # Simpson needs an increasing abscissa
    integrated = b0 + cumulative_simpson(sign * rates, x=sign * betas, axis=0, initial=0.0)
    bv_num = -integrated[:, 1]                                       # top: b = (0, -b^v)
    bh_num = integrated[:, 3]                                        # left: b = (b^h, 0)
    bv, bh = loads(betas, f, mu)
    return {
        "beta_deg": betas_deg, "ratio_closed": bv / bh, "ratio_core": bv_num / bh_num,
        "bv_closed": bv, "bh_closed": bh, "bv_core": bv_num, "bh_core": bh_num,
        "rate_residual": np.array(residuals), "s_min_relative": np.array(s_min), "core_masks": masks,
        "work": {name: np.array(vals) for name, vals in work.items()}, "work_closed": -8.0 * f * R,
        "params": {"mu": mu, "alpha": alpha, "f_over_k": f_over_k, "R": R, "k": k},
    }


# ------------------------------------------------------------------------------------------------ study

PATH_BETAS = np.linspace(45.0, 15.0, 61)


def n_steps() -> int:
    """Progress ticks of `study`."""
    return 2 + len(S_RTOLS) + len(ZERO_FACTORS) + sum(len(v) for v in PARAMETERS.values()) + len(PATH_BETAS)


def study(progress=None) -> dict:
    """Everything `granstab reproduce four-disk` reports."""
    tick = progress or (lambda: None)
    result = granstab.analyze(scene(**PAPER), metric="L")
    rows = stability_table(result)
    urows = uniqueness_table(result)
    tick()
    out = {
        "params": dict(PAPER), "scene": result.scene, "summary": result.summary, "errors": result.errors,
        "stability": rows, "totals": totals(rows), "uniqueness": urows, "uniqueness_totals": uniqueness_totals(urows),
        "robustness": robustness(rows), "loads": loads(np.radians(PAPER["beta_deg"]), PAPER["f_over_k"], PAPER["mu"]),
        "mechanical_only": mechanical_only(),
    }
    tick()
    out["tolerance_sweep"] = tolerance_sweep(progress=tick)
    out["parameter_sweep"] = parameter_sweep(progress=tick)
    out["path"] = sliding_path(PATH_BETAS, progress=tick)
    return out
