"""eq:exampleH2 (Appendix C, with erratum 2, docs/errata.md) for random r^p, r^q, ρ^p, ρ^q, k, α, f; λ⁽⁴⁾ = 2k."""
import numpy as np
import pytest

import granstab


def closed_form(rp, rq, pp, pq, k, a, f):
    """Hm and Hg = Hg1 + Hg2 + Hg3 of eq:exampleH2, rows [db1, db2, dw3] of p then q."""
    Hm = k * np.array([
        [1, 0, 0, -1, 0, 0], [0, a, a * rp, 0, -a, a * rq], [0, a * rp, a * rp ** 2, 0, -a * rp, a * rp * rq],
        [-1, 0, 0, 1, 0, 0], [0, -a, -a * rp, 0, a, -a * rq], [0, a * rq, a * rp * rq, 0, -a * rq, a * rq ** 2]])
    Hg = f / (pp + pq) * np.array([
        [0, 0, 0, 0, 0, 0],
        [0, -1, pp - rp, 0, 1, pq - rq],
        [0, pp - rp, (pp - rp) * (pq + rp), 0, rp - pp, (pq - rq) * (rp - pp)],
        [0, 0, 0, 0, 0, 0],
        [0, 1, rp - pp, 0, -1, rq - pq],
        [0, pq - rq, (pq - rq) * (rp - pp), 0, rq - pq, (pq - rq) * (pp + rq)]])
    return Hm, Hg


def two_particle(rp, rq, pp, pq, k, a, f):
    return granstab.scene_from_dict({
        "dim": 2, "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [rp + rq, 0.0]}],
        "contacts": [{"p": "p", "q": "q", "point": [rp, 0.0], "normal": [1.0, 0.0], "curvature_p": -1 / pp,
                      "curvature_q": -1 / pq, "force": [-f, 0.0], "k": k, "alpha": a, "state": "elastic"}]})


@pytest.mark.parametrize("seed", range(20))
def test_matches_eq_exampleH2(seed):
    rng = np.random.default_rng(seed)
    rp, rq, pp, pq = rng.uniform(0.2, 5.0, 4)
    k, a = rng.uniform(0.1, 10.0), rng.uniform(0.05, 1.0)
    f = k * rp * rng.uniform(-0.01, 0.03)          # tension allowed: the contact is declared elastic
    K = granstab.stiffness(two_particle(rp, rq, pp, pq, k, a, f))
    Hm, Hg = closed_form(rp, rq, pp, pq, k, a, f)
    scale_m = k * max(rp, rq, 1) ** 2                # entries of Hm are k, k r, k r²
    scale_g = abs(f) * max(rp, rq, pp, pq) ** 2 / (pp + pq)
    assert np.abs(K.Hm - Hm).max() <= 1e-13 * scale_m
    assert np.abs((K.Hg1 + K.Hg2 + K.Hg3) - Hg).max() <= 1e-12 * scale_g
    assert np.abs(K.H - (Hm + Hg)).max() <= 1e-12 * (scale_m + scale_g)


@pytest.mark.parametrize("seed", range(5))
def test_lambda4_is_2k(seed):
    rng = np.random.default_rng(seed)
    r, rho = rng.uniform(0.5, 2.0, 2)
    k = rng.uniform(0.5, 5.0)
    result = granstab.analyze(two_particle(r, r, rho, rho, k, 1.0, 0.01 * k * r))
    lam = result.branches[0].stability_eigenvalues
    assert np.min(np.abs(lam - 2 * k)) <= 1e-12 * k
    nu4 = np.array([1, 0, 0, -1, 0, 0]) / np.sqrt(2)
    j = np.argmin(np.abs(lam - 2 * k))
    assert abs(abs(result.motion(result.branches[0].stability_vectors[:, j]) @ nu4) - 1) <= 1e-12


def test_sharp_flat_and_disk_verdicts():
    """Sec. 4.1: sharp (ρ/r < 1) unstable, flat (ρ/r > 1) stable, disks (ρ = r) neutral, for f > 0."""
    verdicts = {rho: granstab.analyze(two_particle(1, 1, rho, rho, 1, 1, 0.01)).summary["verdict"]
                for rho in (0.5, 1.0, 2.0)}
    assert verdicts == {0.5: "unstable", 1.0: "neutral", 2.0: "stable"}
