"""Stiff and extreme cases: every test asserts the error achieved against an independent value, with the bound
stated, and that an ill-posed case says so (warnings, summary["sufficient"], ["hinges_on_tolerance"],
["zero_margin"]) instead of answering confidently.

Error bound used throughout (tolerances.py): an eigenvalue of an n×n symmetric matrix A computed in double
precision is within zero_tol = zero_factor·n·eps·‖A‖₂ of the exact one; each eigenvalue's own accuracy bound
(accuracy.py, Branch.accuracy) is much tighter and is the level below which granstab
calls an eigenvalue zero. Where the INPUT is ill-conditioned (nearly conforming curvatures) the bound is
multiplied by the condition number of that input, stated at the test.
"""
import math

import numpy as np
import pytest

import granstab
from granstab.mechanics.branches import MINUS, PLUS, RIGID
from granstab.model import packings
from granstab.model.scene import SceneError
from granstab.model.tolerances import DEFAULT, EPS
from granstab.paper import sliding_contact
from granstab.paper import two_particle as tp
from granstab.solve import sparse


def pair_result(rho=0.5, f=0.01, alpha=1.0, k=1.0, rhoq=None, r=1.0):
    """analyze() of the Table-1 pair in the paper's metric (L = 1), where the closed forms hold."""
    return granstab.analyze(tp.scene(r, rho, f, k, alpha, rhoq=rhoq), rotation_length=1.0)


def closed_sorted(rho, f, alpha=1.0, k=1.0, r=1.0):
    return np.sort(tp.closed_form_eigenvalues(k, alpha, r, rho, f))


def check_against_closed_form(res, rho, f, alpha=1.0, k=1.0):
    (b,) = res.branches
    lam = np.sort(b.stability_eigenvalues)
    exact = closed_sorted(rho, f, alpha, k)
    bound = DEFAULT.zero_tol(np.abs(lam).max(), 6)
    assert np.abs(lam - exact).max() <= bound
    return b, exact, bound


# ----------------------------------------------------------------------------------------- f/k and α

@pytest.mark.parametrize("f", [1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2, 1e0, 1e1])
@pytest.mark.parametrize("rho", [0.5, 2.0])
def test_force_over_stiffness_from_1e_12_to_10(f, rho):
    """All six eigenvalues against the closed forms (λ⁽⁶⁾ = f(ρ - r)), each within its own accuracy bound
    (accuracy.py); the verdict follows the sign of λ⁽⁶⁾ (and of λ⁽⁵⁾, negative at f/k = 10) whenever the bound
    resolves it, and zero_margin = min |λ|/δ over the non-rigid eigenvalues says by how much."""
    res = pair_result(rho, f)
    b, exact, bound = check_against_closed_form(res, rho, f)
    lam, acc = b.stability_eigenvalues, b.accuracy
    order = np.argsort(lam)
    assert np.all(np.abs(lam[order] - exact) <= acc[order])                 # the bound holds for every eigenvalue
    nonrigid = b.codes != RIGID
    assert res.summary["zero_margin"] == pytest.approx(np.min(np.abs(lam[nonrigid]) / acc[nonrigid]))
    if np.all(np.abs(lam[nonrigid]) > acc[nonrigid]):
        expected = "unstable" if lam[nonrigid].min() < 0 else "stable"
        assert res.summary["verdict"] == expected and res.summary["zero_margin"] > 1.0
    for key in ("force_balance", "moment_balance", "rigid_leakage_modified", "eigen_residual_stability"):
        assert res.errors[key] <= 1e-14


@pytest.mark.parametrize("f", [1e-12, 1e-13])
def test_tiny_force_negative_eigenvalue_is_resolved(f):
    """Issue 15: the sharp pair (ρ/r = 0.5, k = 1) at f/k = 1e-12 and 1e-13 has λ⁽⁶⁾ = -f/2 = -5e-13, -5e-14; the
    old blanket threshold 64·n·ε·‖A‖ ≈ 1.7e-13 called the second zero and the pair 'neutral, sufficient'. The
    accuracy bound (≈ 2.5e-14 here) resolves both: unstable, proven, margin |λ⁽⁶⁾|/δ > 1."""
    res = pair_result(0.5, f)
    b = res.branches[0]
    j = int(np.argmin(b.stability_eigenvalues))
    assert abs(b.stability_eigenvalues[j] + f / 2) <= b.accuracy[j] < f / 2
    assert res.summary["verdict"] == "unstable" and res.summary["sufficient"] is True
    assert res.summary["zero_margin"] > 1.0


def test_unresolved_sign_is_never_a_proof():
    """At f/k = 1e-14 λ⁽⁶⁾ = -5e-15 lies inside its accuracy bound: the pair reads 'neutral' (zero within accuracy)
    but NOT sufficient, with the reason, and zero_margin < 1 covers that eigenvalue."""
    res = pair_result(0.5, 1e-14)
    assert res.summary["verdict"] == "neutral"
    assert res.summary["sufficient"] is False and "unresolved_sign" in res.summary["insufficient_because"]
    assert "NOT DETERMINED" in res.summary["reason"]
    assert res.summary["zero_margin"] < 1.0
    assert res.branches[0].n_zero == 4


@pytest.mark.parametrize("alpha", [1e-8, 1e-6, 1e-4, 1e-2, 1.0])
@pytest.mark.parametrize("rho", [0.5, 2.0])
def test_alpha_from_1e_8_to_1(alpha, rho):
    """λ⁽⁵⁾ = 2αk(1 + r²) - f[...] against its closed form for tiny tangential stiffness."""
    f = 0.01
    res = pair_result(rho, f, alpha=alpha)
    _, exact, bound = check_against_closed_form(res, rho, f, alpha)
    expected = "unstable" if exact.min() < -bound else "stable"
    assert res.summary["verdict"] == expected


@pytest.mark.parametrize("alpha", [1e-8, 1e-4, 1.0])
@pytest.mark.parametrize("dim", [2, 3])
def test_sliding_law_eigenvalues_at_small_alpha(alpha, dim):
    """sym(F^sliding) of an assembled pair against k(1 ± √(1+μ²))/2 (+ αk in 3D), bound 4 eps·k."""
    for mu in (0.05, 0.5, 1.5):
        lam = sliding_contact.scene_eigenvalues(mu, alpha, dim=dim)
        assert np.abs(lam - sliding_contact.closed_form(mu, alpha, dim=dim)).max() <= 8 * EPS * (1 + mu)


# ------------------------------------------------------------------------- flat and hand-in-glove contacts

@pytest.mark.parametrize("rhoq", [math.inf, -1.0, -(1.0 - 1e-12)], ids=["flat-on-flat", "hand-in-glove",
                                                                       "below-cut-off"])
def test_singular_curvature_sum_is_reported_undetermined(rhoq):
    """K^p + K^q = 0 on the tangent plane (or below the pseudo-inverse cut-off pinv_rtol = 1e-10 of |K|): the
    rolling is undetermined, and the analysis must not give a confident verdict."""
    rho = math.inf if rhoq == math.inf else 1.0
    res = pair_result(rho, 0.01, rhoq=rhoq)
    assert any("undetermined" in w for w in res.warnings)
    assert res.summary["sufficient"] is False
    assert res.summary["hinges_on_tolerance"] is True
    assert "NOT DETERMINED" in res.summary["reason"]


@pytest.mark.parametrize("eps", [1e-2, 1e-4, 1e-6, 1e-8])
def test_nearly_conforming_contact_against_the_paper_matrix(eps):
    """ρ^q = -(1 - ε) ρ^p (a convex particle in a slightly wider socket): the rolling term grows like 1/ε. The
    core's eigenvalues match those of eq:exampleH2 (independent, written with f/(ρ^p + ρ^q)) to the input's
    conditioning: K^p + K^q = 1/ρ^p + 1/ρ^q cancels to relative size ε, so its rounding error is eps/ε and the
    bound is 8·eps/ε relative to ‖𝓗‖ (plus the usual zero_tol). Below ε = 1e-6 the result carries a warning."""
    rp, rq, rhop, rhoq, f = 1.0, 1.0, 1.0, -(1.0 - eps), 0.01
    res = pair_result(rhop, f, rhoq=rhoq)
    lam = np.sort(res.branches[0].stability_eigenvalues)
    H = tp.paper_stiffness(1.0, 1.0, rp, rq, rhop, rhoq, f)
    _, calH = tp.projected(H, tp.rotation_vector(rp, rq))
    exact = np.sort(np.linalg.eigvalsh(0.5 * (calH + calH.T)))
    norm = np.abs(exact).max()
    assert np.abs(lam - exact).max() <= (8 * EPS / eps) * norm + DEFAULT.zero_tol(norm, 6)
    assert res.summary["sufficient"] is True
    assert any("nearly conforming" in w for w in res.warnings) == (eps < 1e-6)


# ------------------------------------------------------------------------------------- at the yield surface

def yield_pair(ft_over_mufn, mu=0.5, f=0.01, state="auto"):
    force = [-f, mu * f * ft_over_mufn]
    return granstab.scene_from_dict({
        "dim": 2, "defaults": {"mu": mu, "alpha": 0.7},
        "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [2.0, 0.0]}],
        "contacts": [{"p": "p", "q": "q", "point": [1.0, 0.0], "normal": [1.0, 0.0], "curvature_p": -1.5,
                      "curvature_q": -1.5, "force": force, "state": state}]}, source="<yield>")


def test_exactly_at_yield_and_a_hair_inside():
    """|f_t| = μ f_n exactly, and 1e-12 inside (within yield_rtol = 1e-9 of |f|): both are potentially sliding
    (two branches) and their sliding-branch spectra agree to O(1e-12 ‖𝓗‖); 1e-6 inside is elastic (one branch);
    1e-12 outside is accepted as at yield, 1e-6 outside is refused."""
    exact = granstab.analyze(yield_pair(1.0))
    hair = granstab.analyze(yield_pair(1.0 - 1e-12))
    assert [list(b.mask) for b in exact.branches] == [[1], [-1]] == [list(b.mask) for b in hair.branches]
    for be, bh in zip(exact.branches, hair.branches):
        norm = np.abs(be.stability_eigenvalues).max()
        assert np.abs(be.stability_eigenvalues - bh.stability_eigenvalues).max() <= 1e-11 * norm
    assert exact.summary["verdict"] == hair.summary["verdict"]
    inside = granstab.analyze(yield_pair(1.0 - 1e-6))
    assert len(inside.branches) == 1
    assert len(granstab.analyze(yield_pair(1.0 + 1e-12)).branches) == 2
    with pytest.raises(SceneError, match="outside the friction cone"):
        yield_pair(1.0 + 1e-6)
    # the sliding branch's contact law, from the assembled Hm of the exact-yield pair
    K = granstab.stiffness(yield_pair(1.0), mask=[1])
    lam = np.linalg.eigvalsh(0.5 * (K.Hm[:2, :2] + K.Hm[:2, :2].T))
    assert np.abs(lam - sliding_contact.closed_form(0.5, 0.7)).max() <= 8 * EPS


# --------------------------------------------------------------------------------- repeated eigenvalues

@pytest.mark.parametrize("delta", [0.0, 1e-13, 1e-9, -1e-9, 1e-6])
def test_rolling_mode_meets_the_rigid_zeros(delta):
    """ρ = r(1 + δ): λ⁽⁶⁾ = f r δ joins the three rigid zeros at δ = 0 (a repeated zero: neutral). Near it the
    verdict follows the sign of λ⁽⁶⁾ when |λ⁽⁶⁾| exceeds the zero tolerance, and zero_margin = |λ⁽⁶⁾| / zero_tol
    says by how much; below, the pair is neutral (zero in double precision) with four zero eigenvalues."""
    f = 0.01
    res = pair_result(1.0 + delta, f)
    b, _, _ = check_against_closed_form(res, 1.0 + delta, f)
    lam6 = f * delta
    j = int(np.argmin(np.abs(b.stability_eigenvalues - lam6)))
    delta6 = b.accuracy[j]
    if abs(lam6) > 2 * delta6:
        assert res.summary["verdict"] == ("stable" if lam6 > 0 else "unstable")
        assert abs(res.summary["zero_margin"] - abs(lam6) / delta6) <= 1.0   # ± one bound of round-off
    elif abs(lam6) < delta6 / 2:
        assert res.summary["verdict"] == "neutral"
        assert b.n_zero == 4
        assert np.sum(b.codes == RIGID) == 3


def test_repeated_and_nearly_repeated_eigenvalues_of_a_symmetric_lattice():
    """A cubic-symmetric fcc block has exactly repeated eigenvalues. Their eigenspaces are found by the dense and
    the sparse path alike (projectors agree to 1e-8 — eigenvectors of a cluster are only defined up to rotation
    inside it), and a perturbation of 1e-10 that splits them moves the eigenvalues by no more than itself."""
    s = packings.lattice(3, 2)
    spb = sparse.sparse_problem(s)
    modes = sparse.lowest_modes(spb, k=12)
    res = granstab.analyze(s, method="dense")
    lam_d = np.sort(res.branches[0].stability_eigenvalues[res.branches[0].codes != RIGID])
    bound = DEFAULT.zero_tol(spb.norm, spb.n)
    assert np.abs(modes.eigenvalues - lam_d[:12]).max() <= bound
    gaps = np.diff(lam_d[:13])
    assert np.sum(gaps <= bound) >= 3                                   # clusters exist
    # a cluster fully inside the computed range: compare projectors
    starts = np.flatnonzero(np.r_[True, gaps[:-1] > bound])
    ends = np.r_[starts[1:], 12]
    b = res.branches[0]
    V_d = b.stability_vectors[:, b.codes != RIGID][:, np.argsort(b.stability_eigenvalues[b.codes != RIGID])]
    for a, e in zip(starts, ends):
        if e - a > 1 and e < 12:
            Ps = modes.vectors[:, a:e] @ modes.vectors[:, a:e].T
            Pd = V_d[:, a:e] @ V_d[:, a:e].T
            assert np.abs(Ps - Pd).max() <= 1e-8
    # split the degeneracy by perturbing one contact's stiffness by 1e-10
    k = s.k.copy()
    k[0] *= 1 + 1e-10
    arrays = {name: getattr(s, name) for name in ("p", "q", "point", "normal", "curvature_p", "curvature_q",
                                                   "force", "moment", "alpha", "mu", "rolling", "state")}
    s2 = granstab.build_scene(3, s.names, s.x, {**arrays, "k": k})
    lam2 = sparse.lowest_modes(s2, k=12).eigenvalues
    assert np.abs(lam2 - lam_d[:12]).max() <= 1e-10 * s.k[0] * 4 + bound


# ------------------------------------------------------------------------------------------- length scale

@pytest.mark.parametrize("dim", [2, 3])
def test_lengths_scaled_from_1e_6_to_1e6_give_identical_dimensionless_results(dim):
    """Lengths × s with f/(kr) fixed: rigid.py's scaled dofs make every eigenvalue invariant (units force/length
    with k fixed), so the spectra agree to zero_tol and the verdicts and consistency codes are identical."""
    base = packings.random_packing(dim, 12 if dim == 2 else 10, radius=1.0, n_sliding=1, moments=0.2 * (dim == 3),
                                   rolling=0.01, seed=3)
    ref = granstab.analyze(base)
    for s in (1e-6, 1e-3, 1e3, 1e6):
        sc = packings.random_packing(dim, 12 if dim == 2 else 10, radius=s, n_sliding=1,
                                     moments=0.2 * (dim == 3), rolling=0.01, seed=3)
        res = granstab.analyze(sc)
        assert res.summary["verdict"] == ref.summary["verdict"]
        for b0, b1 in zip(ref.branches, res.branches):
            bound = b0.accuracy + b1.accuracy
            assert np.all(np.abs(b0.stability_eigenvalues - b1.stability_eigenvalues) <= bound)
            # an eigenvector's sign is LAPACK's choice: PLUS on v is MINUS on -v
            assert np.array_equal(np.where(b0.codes == MINUS, PLUS, b0.codes), np.where(b1.codes == MINUS, PLUS, b1.codes))
        for key in ("force_balance", "moment_balance", "rigid_leakage_modified"):
            assert res.errors[key] <= 1e-13


# ------------------------------------------------------------------------------------------ large clusters

def test_3d_cluster_with_thousands_of_particles_two_solvers_agree():
    """A 3D random packing (about 2000 spheres, 12 000 dofs): shift-invert (inertia-verified) and LOBPCG
    (TwoLevel-preconditioned) give the same lowest eigenvalues to the round-off bound."""
    s = packings.random_packing(3, 2000, seed=5)
    spb = sparse.sparse_problem(s)
    a = sparse.lowest_modes(spb, k=4, method="shift-invert")
    b = sparse.lowest_modes(spb, k=4, method="lobpcg")
    assert a.verified
    assert np.abs(a.eigenvalues - b.eigenvalues).max() <= DEFAULT.zero_tol(spb.norm, spb.n)
