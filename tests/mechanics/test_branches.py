"""Branches of sliding contacts and Appendix-D consistency, checked against an independent S = g·δu_def."""
import numpy as np
import pytest
from helpers import random_cluster, scene

import granstab
from granstab.mechanics.branches import (
    BOTH,
    INCONSISTENT,
    MINUS,
    PLUS,
    RIGID,
    Problem,
    search_subspace,
)
from granstab.model.law import contact_stiffness
from granstab.model.tolerances import DEFAULT


def sliding_pair(dim=2, mu=0.5, f=0.01, rho=0.7):
    """Two particles whose contact is at yield: f^pq = -f n + μ f t."""
    if dim == 2:
        K = -1 / rho
        t = [0.0, 1.0]
        x1, point, n = [2.0, 0.0], [1.0, 0.0], [1.0, 0.0]
    else:
        K = np.diag([0, -1 / rho, -1 / rho]).tolist()
        t = [0.0, 0.6, 0.8]
        x1, point, n = [2.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]
    force = (-f * np.array(n) + mu * f * np.array(t)).tolist()
    return scene({"dim": dim, "defaults": {"mu": mu, "alpha": 0.8},
                  "particles": [{"name": "p", "x": [0.0] * dim}, {"name": "q", "x": x1}],
                  "contacts": [{"p": "p", "q": "q", "point": point, "normal": n, "curvature_p": K,
                                "curvature_q": K, "force": force}]})


def independent_S(s, motion):
    """S = g·δu_def per contact from a physical motion, written out from eq:dudef and eq:G (no B matrices)."""
    d, per = s.dim, s.dof_per_particle
    U = motion.reshape(s.n_particles, per)
    du, th = U[:, :d], U[:, d:]
    out = []
    for c in range(s.n_contacts):
        p, q = s.p[c], s.q[c]
        rp, rq = s.r_pq[c], s.r_qp[c]
        if d == 2:
            def spin(w, r):
                return w[0] * np.array([-r[1], r[0]])
        else:
            def spin(w, r):
                return np.cross(w, r)
        dudef = du[q] - du[p] + spin(th[q], rq) - spin(th[p], rp)
        n, f = s.normal[c], s.force[c]
        ft = f - (f @ n) * n
        h = ft / np.linalg.norm(ft)
        g = s.k[c] * (s.alpha[c] * h + s.mu[c] * n)
        out.append(g @ dudef)
    return np.array(out)


def appendix_d(mask, S, tol):
    test = np.where(np.abs(S) <= tol, 0, np.sign(S))
    prod = mask * test
    if np.all(prod == 0):
        return BOTH
    if np.all(prod >= 0):
        return PLUS
    if np.all(prod <= 0):
        return MINUS
    return INCONSISTENT


@pytest.mark.parametrize("dim", [2, 3])
def test_one_sliding_contact_has_two_branches_with_independent_consistency(dim):
    s = sliding_pair(dim)
    result = granstab.analyze(s)
    assert result.to_dict()["n_sliding"] == 1
    assert [list(b.mask) for b in result.branches] == [[1], [-1]]
    checked = 0
    for b in result.branches:
        tol = result.problem.s_tol
        for j, code in enumerate(b.codes):
            if code == RIGID:
                continue
            motion = result.scale * b.stability_vectors[:, j]
            assert code == appendix_d(b.mask, independent_S(s, motion), tol)
            checked += 1
    assert checked == 2 * (s.n_dof - (3 if dim == 2 else 6))


def test_sliding_branch_stiffness_is_the_rank_one_update():
    """Hm on the sliding branch equals -A1 [F_sliding] B assembled from eq:ContactF directly."""
    s = sliding_pair(2)
    Hs = granstab.stiffness(s, mask=[1]).Hm
    He = granstab.stiffness(s, mask=[-1]).Hm
    F_el = contact_stiffness(s.normal, s.k, s.alpha, s.mu, s.force, np.array([False]))[0]
    F_sl = contact_stiffness(s.normal, s.k, s.alpha, s.mu, s.force, np.array([True]))[0]
    # for this pair δu_def = B U with B rows of eq:dudef; Hm = -A1 [F; -F] B with A1 of Appendix C
    r = 1.0
    B = np.array([[-1, 0, 0, 1, 0, 0], [0, -1, -r, 0, 1, -r]], float)
    A1 = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, r, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, -r]], float)
    for F, H in ((F_el, He), (F_sl, Hs)):
        expected = -A1 @ np.vstack([F, -F]) @ B
        assert np.abs(H - expected).max() <= 1e-15 * s.k[0]


def test_sliding_contact_symmetric_part_eigenvalues():
    """erratum 3, docs/errata.md: sym(F_sliding) has eigenvalues k(1 ± √(1+μ²))/2 in 2D for every α (3D adds αk)."""
    for mu, alpha, k in [(0.5, 1.0, 1.0), (0.3, 0.2, 7.0), (1.2, 1e-3, 0.1)]:
        n = np.array([[1.0, 0.0]])
        f = np.array([[-1.0, mu]])
        F = contact_stiffness(n, np.array([k]), np.array([alpha]), np.array([mu]), f, np.array([True]))[0]
        lam = np.linalg.eigvalsh(0.5 * (F + F.T))
        expected = k * (1 + np.array([-1, 1]) * np.sqrt(1 + mu ** 2)) / 2
        assert np.allclose(lam, expected, rtol=0, atol=1e-14 * k)


def test_eigenspace_search_finds_a_consistent_vector_lapack_basis_misses():
    """A repeated eigenvalue: neither basis vector is consistent with mask (+1, +1), their sum is."""
    S = np.array([[1.0, -0.5], [-0.5, 1.0]])           # columns: s of contacts 0 and 1
    problem = Problem(H_el=None, A=None, S=S, projection=None, rigid=np.zeros((2, 0)),
                      sliding=np.array([0, 1]), n_contacts=2, tol=DEFAULT)
    mask = np.array([1, 1])
    for e in np.eye(2):
        assert appendix_d(mask, S.T @ e, problem.s_tol) == INCONSISTENT
    v, code, hinges = search_subspace(problem, mask, np.eye(2))
    assert code == PLUS and not hinges
    assert np.all(S.T @ v > 0.1)
    # and none exists when the constraints are contradictory
    S_bad = np.array([[1.0, -1.0], [-1.0, 1.0]])
    bad = Problem(None, None, S_bad, None, np.zeros((2, 0)), np.array([0, 1]), 2, DEFAULT)
    found = search_subspace(bad, mask, np.eye(2))
    assert found is not None and found[1] == BOTH     # only S = 0 on both: the direction (1, 1)
    assert np.abs(S_bad.T @ found[0]).max() <= 1e-12


def test_second_order_work_of_the_rolling_mode():
    """Symmetric pair: the rolling motion ν = (0,0,1,0,0,-1) has work 2f(ρ - r), all geometric (Sec. 4.1)."""
    f, rho, r = 0.01, 0.5, 1.0
    s = scene({"dim": 2, "particles": [{"name": "p", "x": [0, 0]}, {"name": "q", "x": [2 * r, 0]}],
               "contacts": [{"p": "p", "q": "q", "point": [r, 0], "normal": [1, 0], "curvature_p": -1 / rho,
                             "curvature_q": -1 / rho, "force": [-f, 0]}]})
    work = granstab.second_order_work(granstab.analyze(s), np.array([0, 0, 1.0, 0, 0, -1.0]))
    assert abs(work["work"] - 2 * f * (rho - r)) <= 1e-15
    assert abs(work["mechanical"]) <= 1e-15 and abs(work["geometric"] - work["work"]) <= 1e-15


def test_load_response_recovers_a_consistent_motion():
    """d𝕓 = ℍ^i u0 for a motion u0 on its own branch: Type-1 search finds u0 (up to rigid motions) there."""
    s = sliding_pair(2)
    result = granstab.analyze(s)
    D, proj, R = result.scale, result.problem.projection, result.problem.rigid
    rng = np.random.default_rng(3)
    for _ in range(4):
        u0 = rng.standard_normal(s.n_dof)
        mask = np.where(independent_S(s, u0) > 0, 1, -1)
        K = granstab.stiffness(s, mask=mask)
        load = K.H @ (D * proj.apply(u0 / D))                       # physical d𝕓 = H P u0
        out = granstab.load_response(result, load)
        (mine,) = [sol for sol in out["solutions"] if sol["mask"] == mask.tolist()]
        assert mine["consistent"] and mine["residual"] <= 1e-12
        target = u0 / D - R @ (R.T @ (u0 / D))                      # u0 without its rigid part (scaled dofs)
        assert np.linalg.norm(mine["scaled"] - target) <= 1e-10 * np.linalg.norm(target)
        for sol in out["solutions"]:
            if sol["consistent"]:
                assert np.all(np.array(sol["mask"]) * independent_S(s, sol["motion"]) >= -1e-12)


def test_random_cluster_with_several_sliding_contacts_streams_every_branch():
    data = random_cluster(2, 4, 9)
    for c in data["contacts"][:3]:                      # put three contacts exactly at yield
        n = np.array(c["normal"])
        t = np.array([-n[1], n[0]])
        c["force"] = (-0.01 * n + 0.5 * 0.01 * t).tolist()
    s = scene(data)
    seen = []
    result = granstab.analyze(s, on_branch=seen.append)
    assert len(seen) == 8 == result.summary["n_branches"]
    assert {tuple(b.mask[:3]) for b in seen} == {(a, b, c) for a in (1, -1) for b in (1, -1) for c in (1, -1)}
    for b in result.branches:
        for j, code in enumerate(b.codes):
            if code != RIGID and code != INCONSISTENT:
                S = independent_S(s, result.scale * b.stability_vectors[:, j])
                assert appendix_d(b.mask, S, result.problem.s_tol) == code
