"""The field's baselines of the prediction test (issue 39) on hand-made cases with known answers: the frictionless
dynamical matrix against finite differences of the harmonic energy, soft-spot participation on a chain whose
lowest mode is known in closed form, D²min of an affine motion (0) and of a known non-affine one, the previous
window's D²min by name, and the softness classifier never scoring the frames it was trained on."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import scene as scene_from

from granstab.track import baselines, motion, softspots


def harmonic_disks(seed: int = 0):
    """Five disks (radius 0.5) in contact along their centre lines, k = 2, force k·overlap (compressive):
    the scene and the energy's gradient E = Σ ½ k (1 − ℓ)² over the contacts."""
    rng = np.random.default_rng(seed)
    x = np.array([[0, 0], [0.95, 0.1], [0.45, 0.85], [-0.5, 0.8], [1.3, 0.95]]) + 0.01 * rng.standard_normal((5, 2))
    pairs = [(0, 1), (0, 2), (1, 2), (2, 3), (0, 3), (1, 4), (2, 4)]
    k = 2.0
    contacts = []
    for p, q in pairs:
        b = x[q] - x[p]
        ell = np.linalg.norm(b)
        n = b / ell
        contacts.append({"p": f"d{p}", "q": f"d{q}", "point": (x[p] + 0.5 * b).tolist(), "normal": n.tolist(),
                         "force": (-k * (1.0 - ell) * n).tolist(), "curvature_p": -2.0, "curvature_q": -2.0,
                         "k": k, "mu": 0.5})
    data = {"dim": 2, "defaults": {"k": k, "alpha": 0.5, "mu": 0.5},
            "particles": [{"name": f"d{i}", "x": x[i].tolist()} for i in range(5)], "contacts": contacts}

    def gradient(flat):
        y = flat.reshape(5, 2)
        g = np.zeros_like(y)
        for p, q in pairs:
            b = y[q] - y[p]
            ell = np.linalg.norm(b)
            g[q] += k * (ell - 1.0) * b / ell
            g[p] -= k * (ell - 1.0) * b / ell
        return g.ravel()

    return scene_from(data), x, gradient


def test_frictionless_matrix_is_the_hessian_of_the_harmonic_energy():
    """Central differences of the exact gradient (step 1e-6: error O(h²) ≈ 1e-12 · k) equal D to 1e-8 · k."""
    scene, x, gradient = harmonic_disks()
    D = softspots.frictionless_matrix(scene).toarray()
    h, n = 1e-6, x.size
    fd = np.stack([(gradient(x.ravel() + h * e) - gradient(x.ravel() - h * e)) / (2 * h) for e in np.eye(n)], 1)
    assert np.abs(D - fd).max() < 1e-8 * 2.0
    assert np.abs(D - D.T).max() == 0


def test_participation_on_a_chain_is_its_lowest_mode():
    """A free chain of N unit springs (1D, d = 1): D is the path Laplacian, its lowest non-trivial mode
    u_i ∝ cos(π(i + ½)/N) with eigenvalue 2(1 − cos(π/N)) (the uniform translation lifted); the participation in
    that one mode is u_i² / Σ u²; both eigensolvers agree."""
    N = 30
    L = sp.diags([np.r_[1, 2 * np.ones(N - 2), 1], -np.ones(N - 1), -np.ones(N - 1)], [0, 1, -1]).tocsr()
    u = np.cos(np.pi * (np.arange(N) + 0.5) / N)
    for dense_below in (10 ** 6, 0):
        softspots.DENSE_BELOW, old = dense_below, softspots.DENSE_BELOW
        try:
            lam, V, info = softspots.lowest_modes(L, 1, 1)
        finally:
            softspots.DENSE_BELOW = old
        assert info["method"] == ("dense" if dense_below else "shift-invert, count checked")
        assert info["residual"] < 1e-12 * 4                     # ‖Lv − λv‖ against ‖L‖ ≤ 4
        assert lam[0] == pytest.approx(2 * (1 - np.cos(np.pi / N)), rel=1e-9)
        share = softspots.participation(V.T.reshape(1, N, 1))
        assert share == pytest.approx(u ** 2 / np.sum(u ** 2), abs=1e-9)
    assert softspots.lowest_count(6000) == 60 and softspots.lowest_count(50) == 1


def test_frictionless_soft_spots_of_a_scene_sum_to_one():
    scene, _, _ = harmonic_disks()
    row, share = softspots.frictionless(scene)
    assert row["soft_spots_count"] == 1 and share.sum() == pytest.approx(1.0, abs=1e-12)


def test_d2min_of_affine_motion_is_zero_and_of_a_known_displacement_its_closed_form():
    """Affine x → F x: D²min 0 for every particle. The centre of a square lattice moved by δ: its 8 neighbours within
    1.5 are symmetric about it (Σ r = 0), so the best X is I and each vector keeps the residual −δ: D²min = 8|δ|²."""
    g = np.stack(np.meshgrid(np.arange(7.0), np.arange(7.0)), -1).reshape(-1, 2)
    present = np.ones(len(g), bool)
    F = np.array([[1.02, 0.05], [-0.01, 0.97]])
    assert np.nanmax(np.abs(motion.d2min(g, g @ F.T, present, 1.5))) < 1e-24
    centre = 24                                       # (3, 3): 8 neighbours within 1.5, symmetric about it
    delta = np.array([0.03, -0.02])
    moved = g.copy()
    moved[centre] += delta
    got = motion.d2min(g, moved, present, 1.5)
    assert got[centre] == pytest.approx(8 * delta @ delta, rel=1e-12)


def test_previous_d2min_is_the_same_particle_one_window_back():
    code = np.array([0, 1, 2, 0, 1, 2, 1, 0])
    pos = np.array([0, 0, 0, 1, 1, 1, 2, 2])                          # particle 2 is gone at frame 2
    d2 = np.array([1.0, 2, 3, 4, 5, 6, 7, 8])
    got = baselines.previous_d2min(code, pos, d2, 1)
    assert np.isnan(got[:3]).all() and got[3:].tolist() == [1, 2, 3, 5, 4]
    assert np.isnan(baselines.previous_d2min(code, pos, d2, 2)[:6]).all()
    assert baselines.previous_d2min(code, pos, d2, 2)[6:].tolist() == [2, 1]


def test_radial_features_count_neighbours_at_their_shell():
    """Two particles at distance 1.0 (d̄ = 1): each has G = exp(−(1 − μ)²/(2 · 0.1²)) at every shell μ."""
    got = baselines.radial_features(np.array([[0.0, 0.0], [1.0, 0.0]]), None, 1.0)
    want = np.exp(-((1.0 - baselines.MU) ** 2) / (2 * baselines.WIDTH ** 2))
    assert got == pytest.approx(np.stack([want, want]), abs=1e-15)


def test_softness_scores_only_the_second_half_and_learns_a_planted_structure():
    pytest.importorskip("sklearn", reason="scikit-learn: the optional baselines extra")
    rng = np.random.default_rng(0)
    pos = np.repeat(np.arange(10), 200)
    label = rng.random(len(pos)) < 0.2
    features = rng.standard_normal((len(pos), 4))
    features[:, 2] += 1.5 * label                          # one shell carries the label
    out = baselines.softness(features, label, pos, np.ones(len(pos), bool))
    assert np.isnan(out[pos < 5]).all() and np.isfinite(out[pos >= 5]).all()
    from granstab.track.scores import metrics
    assert metrics(out[pos >= 5], label[pos >= 5])["auc"] > 0.8


def test_frictionless_modes_by_shift_invert_equal_the_dense_ones_with_their_count_checked():
    """A jammed packing of 128 disks: the large-packing path (shift-invert below the spectrum, the count below
    the k-th checked by inertia) gives the dense eigh's lowest 1 % (3 modes) to 1e-9·‖D‖, residuals within
    1e-10·‖D‖, and the same participation to 1e-8 (a mode's share is sign-free)."""
    from helpers import DATA

    import granstab
    from granstab_bench import jamming_packings as jp
    m = jp.load(DATA / "jammed_disks_n128_p1e-3.json")[0]
    scene = granstab.scene_from_dict(jp.scene_dict(m["x"], m["radius"], m["cell"]))
    D = softspots.frictionless_matrix(scene)
    norm = float(abs(D).sum(axis=1).max())
    dense = softspots.frictionless(scene)
    softspots.DENSE_BELOW, old = 0, softspots.DENSE_BELOW
    try:
        large = softspots.frictionless(scene)
    finally:
        softspots.DENSE_BELOW = old
    assert dense[0]["soft_spots_frictionless_method"] == "dense"
    assert large[0]["soft_spots_frictionless_method"] == "shift-invert, count checked"
    assert large[0]["soft_spots_count"] == 3
    assert abs(large[0]["soft_spots_frictionless_lambda_max"] - dense[0]["soft_spots_frictionless_lambda_max"]) \
        < 1e-9 * norm
    assert large[0]["soft_spots_frictionless_residual"] < 1e-10 * norm
    assert large[1] == pytest.approx(dense[1], abs=1e-8)
