"""Verdicts of Sec. 3: stability (eq:stab, eq:neutral, eq:instab), Type-1 and Type-2 non-uniqueness (Sec. 3.1),
and the second-order work of a given motion (eq:newinner, softening).

The conditions are the paper's sufficient ones: a consistent negative eigenvalue of some sym(𝓗^i) proves
instability, a consistent non-rigid zero proves neutral stability, and all branches positive definite off the
rigid modes proves stability. A negative eigenvalue whose eigenvector is not consistent proves nothing (Sec. 3.2);
the summary then says that stability is not proven instead of claiming it.
"""
from __future__ import annotations

import numpy as np

from .branches import BOTH, MINUS, PLUS, RIGID, branch_matrices, test_codes
from .rigid import dof_scale
from .stiffness import stiffness

CONSISTENT = (PLUS, MINUS, BOTH)


def summarize(scene, branches, problem) -> dict:
    """Counts of consistent eigenvalues over all branches and the verdict with its reason."""
    pos = neg = zero = 0
    hinge = False
    inconsistent_negative = extra_zero = False
    margin = np.inf
    for b in branches:
        lam, tol = b.stability_eigenvalues, b.zero_tol
        nonzero = np.abs(lam) > tol
        if nonzero.any():
            margin = min(margin, float(np.abs(lam[nonzero]).min() / max(tol, 1e-300)))
        ok = np.isin(b.codes, CONSISTENT)
        pos += int(np.sum(ok & (lam > tol)))
        neg += int(np.sum(ok & (lam < -tol)))
        zero += int(np.sum(ok & nonzero.__invert__()))
        hinge |= bool(np.any(b.hinges & ok & ((lam < -tol) | ~nonzero)))
        inconsistent_negative |= bool(np.any(~ok & (lam < -tol)))
        extra_zero |= bool(np.any((b.codes != RIGID) & ~nonzero))
    if neg:
        verdict, sufficient = "unstable", True
        reason = f"{neg} consistent negative eigenvalue(s) of sym(𝓗^i): negative second-order work (eq:instab)"
    elif zero:
        verdict, sufficient = "neutral", True
        reason = f"{zero} consistent non-rigid zero eigenvalue(s): zero second-order work (eq:neutral)"
    else:
        verdict = "stable"
        sufficient = not (inconsistent_negative or extra_zero)
        reason = ("every branch positive definite off the rigid modes (eq:stab)" if sufficient else
                  "no consistent negative or zero eigenmode, but some eigenvalues are negative or zero with "
                  "inconsistent eigenvectors: the sufficient condition of eq:stab is not met (Sec. 3.2)")
    type2 = any(b.type2 for b in branches)
    return {
        "verdict": verdict,
        "sufficient": sufficient,
        "reason": reason,
        "consistent_positive": pos,
        "consistent_negative": neg,
        "consistent_zero": zero,
        "type2_nonuniqueness": type2,
        "hinges_on_tolerance": hinge,
        "n_branches": len(branches),
        "zero_margin": None if not np.isfinite(margin) else margin,
    }


def load_response(analysis, load_increment, rtol: float = 1e-8) -> dict:
    """Solve ℍ^i dU = d𝕓 on every branch (eq:problem) and keep the consistent solutions (Sec. 3.1).

    load_increment: (n_dof,) objective increments [d𝕓, d𝕨] per particle. Type-1 non-uniqueness: two consistent
    solutions on different branches that differ by more than a rigid motion. Solutions are physical motions with
    the rigid part removed.
    """
    problem, scene = analysis.problem, analysis.scene
    D = dof_scale(scene, analysis.length)
    rhs = D * np.asarray(load_increment, dtype=float)
    masks = np.array([b.mask for b in analysis.branches])
    _, HH, _ = branch_matrices(problem, masks)
    solutions = []
    for mask, A in zip(masks, HH):
        x, *_ = np.linalg.lstsq(A, rhs, rcond=None)
        residual = float(np.linalg.norm(A @ x - rhs) / max(np.linalg.norm(rhs), 1e-300))
        x = x - problem.rigid @ (problem.rigid.T @ x)
        code, hinge = (int(c[0, 0]) for c in test_codes(problem, mask[None], x[None, :, None]))
        ok = residual <= rtol and code in (PLUS, BOTH)
        solutions.append({"mask": mask.tolist(), "residual": residual, "consistent": ok, "hinges": bool(hinge),
                          "motion": D * x, "scaled": x})
    good = [s for s in solutions if s["consistent"]]
    distinct = any(np.linalg.norm(a["scaled"] - b["scaled"]) > 1e-6 * max(np.linalg.norm(a["scaled"]), 1e-300)
                   for i, a in enumerate(good) for b in good[i + 1:])
    return {"solutions": solutions, "n_consistent": len(good), "type1_nonuniqueness": bool(distinct)}


def second_order_work(analysis, motion) -> dict:
    """dUᵀ 𝓗^i dU for a motion dU on the branch its own S signs select (eq:newinner), split into geometric
    (Hg1 + Hg2 + Hg3) and mechanical (Hm) parts; negative work means softening along dU (Sec. 3.2)."""
    problem, scene = analysis.problem, analysis.scene
    D = dof_scale(scene, analysis.length)
    u = np.asarray(motion, dtype=float) / D
    S = problem.S.T @ u
    mask = np.zeros(scene.n_contacts, dtype=int)
    mask[problem.sliding] = np.where(S > problem.s_tol, 1, -1)
    K = stiffness(scene, mask)
    v = D * problem.projection.apply(u)                              # physical motion, rigid rotation removed
    geometric = float(v @ (K.Hg1 + K.Hg2 + K.Hg3) @ v)
    mechanical = float(v @ K.Hm @ v)
    return {"mask": mask.tolist(), "work": geometric + mechanical, "geometric": geometric, "mechanical": mechanical}
