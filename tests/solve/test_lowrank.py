"""The low-rank branch paths (granstab/solve/lowrank.py, ritz.py) checked against the full solves they replace.

Dense: every branch's reduced (rigid-free) eigenproblem against the full stacked path of branches.py — same codes,
same summary, eigenvalues within the sum of both paths' reported per-eigenvalue bounds. Sparse: the Ritz
branches of one elastic solve against shift-invert ARPACK per branch and against the dense spectra.
"""
import dataclasses

import numpy as np
import pytest

import granstab
from granstab.analysis import build_problem
from granstab.mechanics import branches
from granstab.mechanics.branches import RIGID, enumerate_masks
from granstab.mechanics.rigid import rotation_length
from granstab.mechanics.stiffness import contact_blocks
from granstab.model import packings
from granstab.solve import sparse
from granstab.solve.dense import solve_branches
from granstab.solve.lowrank import LazyVectors, solve_branches_lowrank
from granstab.solve.ritz import SparseRitz


def problem_of(scene):
    return build_problem(scene, contact_blocks(scene), rotation_length(scene))[0]


def both_paths(scene):
    problem = problem_of(scene)
    masks = enumerate_masks(problem.sliding, scene.n_contacts)
    low, info = solve_branches_lowrank(problem, masks)
    return problem, solve_branches(problem, masks), low, info


CASES = {
    "2D, Ms = 5": dict(dim=2, n_particles=16, n_sliding=5, mobilised=0.3, seed=1),
    "3D, Ms = 4, contact moments": dict(dim=3, n_particles=10, n_sliding=4, moments=0.2, seed=3),
    "2D, f/k = 1e-9": dict(dim=2, n_particles=16, n_sliding=4, f_over_k=1e-9, seed=2),
    "2D, f/k = 0.2, sharp tips": dict(dim=2, n_particles=16, n_sliding=4, f_over_k=0.2, curvature_ratio=0.3,
                                       seed=4),
    "3D, 1e-6 length scale": dict(dim=3, n_particles=10, n_sliding=3, radius=1e-6, seed=5),
}


@pytest.mark.parametrize("name", CASES)
def test_lowrank_branches_agree_with_the_full_path_within_their_bounds(name):
    scene = packings.random_packing(**CASES[name])
    problem, full, low, info = both_paths(scene)
    assert len(full) == len(low) == 2 ** len(problem.sliding)
    for f, lo in zip(full, low):
        assert np.array_equal(f.mask, lo.mask)
        gap = np.abs(f.stability_eigenvalues - lo.stability_eigenvalues)
        # each path's eigenvalue lies within its bound of a true one (Bauer-Fike + Weyl for the leakage)
        assert np.all(gap <= f.accuracy + lo.accuracy)
        assert np.array_equal(f.codes, lo.codes)                        # canonical signs: no flip ambiguity
        assert np.array_equal(f.hinges, lo.hinges)
        assert (f.n_zero, f.uniqueness_n_zero) == (lo.n_zero, lo.uniqueness_n_zero)
    # the bounds are round-off small: backward error and leakage relative to ‖M_i‖
    assert info["backward_error"] <= 1e-13 and info["leakage"] <= 1e-13
    summary = granstab.mechanics.verdicts.summarize(full)
    other = granstab.mechanics.verdicts.summarize(low)
    assert dataclasses.replace(summary, zero_margin=None) == dataclasses.replace(other, zero_margin=None)


def test_vectors_on_demand_are_the_eigenvectors_their_codes_describe():
    scene = packings.random_packing(2, 16, n_sliding=4, mobilised=0.3, seed=1)
    problem, full, low, _ = both_paths(scene)
    plain = [b for b in low if isinstance(b.stability_vectors, LazyVectors)]
    assert len(plain) == len(low)
    from granstab.mechanics.branches import branch_matrices
    for b, f in zip(low, full):
        V = np.asarray(b.stability_vectors)
        _, _, Hsym = branch_matrices(problem, b.mask[None])
        res = np.linalg.norm(Hsym[0] @ V - V * b.stability_eigenvalues, axis=0)
        assert np.all(res <= b.accuracy + 1e-14 * np.abs(b.stability_eigenvalues).max())
        assert np.abs(V.T @ V - np.eye(len(V))).max() <= 1e-13
        codes, _ = branches.test_codes(problem, b.mask[None], V[None])
        keep = b.codes != RIGID
        assert np.array_equal(codes[0][keep], b.codes[keep])
        # the same eigenvectors as the full path, column by column (distinct eigenvalues: unique up to sign, and
        # the sign is canonical)
        assert np.abs(V[:, keep] - f.stability_vectors[:, keep]).max() <= 1e-8
        assert np.allclose(b.stability_vectors[:, 3], V[:, 3])          # indexing like an array
        cols = [5, 0, len(V) - 1, 3]                # columns alone (subset eigh): the same vectors, signs included
        assert np.abs(b.stability_vectors[:, cols] - V[:, cols]).max() <= 1e-8
        assert np.abs(b.stability_vectors[:, keep] - V[:, keep]).max() <= 1e-8              # a boolean mask too


def test_kept_memory_per_branch_is_linear_in_the_dofs():
    scene = packings.random_packing(2, 16, n_sliding=6, mobilised=0.3, seed=1)
    _, full, low, _ = both_paths(scene)
    n = scene.n_dof

    def kept(b):
        arrays = [b.stability_eigenvalues, b.codes, b.hinges, b.accuracy, b.uniqueness_eigenvalues]
        vec = b.stability_vectors
        arrays += [vec] if isinstance(vec, np.ndarray) else [vec.finger, vec.sign, vec.order]
        return sum(a.nbytes for a in arrays)

    assert max(kept(b) for b in low) <= 64 * n                           # O(n) numbers per branch
    assert min(kept(b) for b in full) >= 8 * n * n                       # the full path keeps n × n vectors


@pytest.mark.parametrize("preset", ["four_disk", "gear_packing", "spheres_tetrahedron", "two_particle"])
def test_presets_give_the_same_summary_on_both_paths(preset):
    scene = granstab.load_scene(f"presets/{preset}.toml")
    a = granstab.analyze(scene, lowrank=False)
    b = granstab.analyze(scene, lowrank=True)
    assert {k: v for k, v in a.summary.items() if k != "zero_margin"} == \
           {k: v for k, v in b.summary.items() if k != "zero_margin"}
    assert any("low-rank branch path" in w for w in b.warnings)


def test_branches_with_free_spins_take_the_full_path_for_type2():
    """Every contact at yield on 4 disks (5 contacts): half the branches have non-rigid null vectors of ℍ^i
    (Type-2 searches); exactly those must go to the full path, and the Type-2 findings must be the same."""
    scene = packings.random_packing(2, 4, n_sliding=5, mobilised=0.3, seed=1)
    problem, full, low, info = both_paths(scene)
    n_rigid = problem.rigid.shape[1]
    assert info["full_path"] == sum(b.uniqueness_n_zero > n_rigid for b in full) == 16
    assert [bool(b.type2) for b in full] == [bool(b.type2) for b in low]
    assert [b.uniqueness_n_zero for b in full] == [b.uniqueness_n_zero for b in low]


# ---------------------------------------------------------------------------------------------- sparse path

@pytest.mark.slow
def test_sparse_ritz_branches_agree_with_shift_invert_and_dense():
    scene = packings.random_packing(2, 60, n_sliding=3, mobilised=0.3, f_over_k=0.1, curvature_ratio=0.2, seed=2)
    spb = sparse.sparse_problem(scene)
    masks = enumerate_masks(spb.sliding, scene.n_contacts)
    k = 6
    ritz = SparseRitz(spb, k)
    modes = list(ritz.modes(masks, k))
    assert ritz.stats["ritz"] >= 4 and ritz.stats["ritz"] + ritz.stats["arpack"] == len(masks)
    dense = solve_branches(problem_of(scene), masks)
    for mask, m, d in zip(masks, modes, dense):
        ref = sparse.lowest_modes(spb, k, mask)
        assert m.verified
        bound = (m.residuals + ref.residuals) * spb.norm
        assert np.all(np.abs(m.eigenvalues - ref.eigenvalues) <= bound)
        lam_d = d.stability_eigenvalues[d.codes != RIGID][:k]
        assert np.all(np.abs(m.eigenvalues - lam_d) <= m.residuals * spb.norm + d.accuracy.max())
        # the inertia count: exactly the dense number of eigenvalues below σ (some branches have one)
        assert m.n_below == int(np.sum(lam_d < m.sigma))
    assert max(m.n_below for m in modes) >= 1


@pytest.mark.slow
def test_sparse_analyze_uses_ritz_and_keeps_the_verdict():
    scene = packings.random_packing(2, 60, n_sliding=3, mobilised=0.3, f_over_k=0.1, curvature_ratio=0.2, seed=2)
    d = granstab.analyze(scene, method="dense")
    s = granstab.analyze(scene, method="sparse", k=6)
    assert s.summary["verdict"] == d.summary["verdict"]
    assert s.summary["consistent_negative"] == d.summary["consistent_negative"]
    assert not any("could not prove" in w for w in s.warnings)


def test_branches_whose_ritz_problem_would_not_fit_go_to_shift_invert(monkeypatch):
    """Many sliding contacts (a whole periodic packing: hundreds) make the Ritz basis and its Ms width² updates too
    large (RigidLibrary's frame: 19 GiB): past RITZ_BYTES every branch is solved by shift-invert, with the Ritz
    path's eigenvalues within both paths' residual bounds and the same verdict."""
    from granstab.solve import budget
    scene = packings.random_packing(2, 30, n_sliding=2, mobilised=0.3, f_over_k=0.1, curvature_ratio=0.2, seed=2)
    ritz = granstab.analyze(scene, method="sparse", k=4)
    monkeypatch.setattr(budget, "RITZ_BYTES", 0)
    direct = granstab.analyze(scene, method="sparse", k=4)
    assert any("Ritz updates" in w for w in ritz.warnings) and not any("Ritz updates" in w for w in direct.warnings)
    assert direct.summary["verdict"] == ritz.summary["verdict"] and len(direct.branches) == 4
    for a, b in zip(ritz.branches, direct.branches):
        bound = 1e-10 * np.abs(a.stability_eigenvalues).max()      # both verified to 1e-12 ‖Hs‖
        assert np.allclose(a.stability_eigenvalues, b.stability_eigenvalues, rtol=0, atol=bound)


def test_analyze_takes_the_low_rank_path_from_min_branches_on():
    from granstab.solve.lowrank import MIN_BRANCHES
    scene = packings.random_packing(2, 16, n_sliding=10, mobilised=0.3, seed=1)
    assert 2 ** 10 >= MIN_BRANCHES
    fast = granstab.analyze(scene, device="auto")
    full = granstab.analyze(scene, lowrank=False)
    assert any("low-rank branch path" in w for w in fast.warnings)
    assert not any("low-rank branch path" in w for w in full.warnings)
    assert {k: v for k, v in fast.summary.items() if k != "zero_margin"} == \
           {k: v for k, v in full.summary.items() if k != "zero_margin"}
    for bf, bl in zip(fast.to_dict()["branches"], full.to_dict()["branches"]):
        assert [c["vector_sign"] for c in bf["consistent"]] == [c["vector_sign"] for c in bl["consistent"]]
        assert bf["uniqueness_eigenvalues"] == [] and len(bl["uniqueness_eigenvalues"]) == scene.n_dof


def test_chunks_on_every_core_give_the_one_chunk_numbers():
    """The CPU runs the chunks of branches in a thread pool (one BLAS thread each): any chunking gives exactly the
    numbers of one chunk, in mask order, with the special branches of every chunk on the full path."""
    scene = packings.random_packing(2, 16, n_sliding=7, mobilised=0.3, seed=1)
    problem = problem_of(scene)
    masks = enumerate_masks(problem.sliding, scene.n_contacts)
    whole, info_whole = solve_branches_lowrank(problem, masks, chunk=len(masks))
    parts, info_parts = solve_branches_lowrank(problem, masks, chunk=9)               # 15 chunks, the last short
    assert info_parts["full_path"] == info_whole["full_path"]
    for a, b in zip(whole, parts):
        assert np.array_equal(a.mask, b.mask) and np.array_equal(a.codes, b.codes)
        assert np.array_equal(a.stability_eigenvalues, b.stability_eigenvalues)
        assert np.array_equal(a.accuracy, b.accuracy)


def test_keeping_only_what_the_verdict_rests_on_changes_no_number():
    """keep="verdict" (memory independent of 2^Ms) against keep="all" on a cluster with 4,096 branches, unstable on
    some: the same summary (verdict, proof, every count over all branches, zero margin) and error estimates; the kept
    branches are exactly the all-branch results that have a consistent eigenpair of sign <= 0, plus the lowest."""
    scene = packings.random_packing(2, 16, n_sliding=12, mobilised=0.3, seed=1)
    every = granstab.analyze(scene, metric="L", keep="all")
    few = granstab.analyze(scene, metric="L", keep="verdict")
    assert every.summary["verdict"] == "unstable" and every.summary["n_branches"] == 4096
    for key in ("verdict", "sufficient", "insufficient_because", "consistent_negative", "consistent_zero",
                "consistent_positive", "n_branches", "zero_margin", "hinges_on_tolerance", "type2_nonuniqueness"):
        assert few.summary[key] == every.summary[key], key
    assert few.errors["eigen_residual_stability"] == every.errors["eigen_residual_stability"]
    by_mask = {b.mask.tobytes(): b for b in every.branches}
    wanted = {key for key, b in by_mask.items()
              if any(c["eigenvalue"] <= b.accuracy[c["index"]] for c in b.consistent())}
    lowest = min(by_mask, key=lambda key: by_mask[key].stability_eigenvalues[by_mask[key].codes != RIGID].min())
    kept = {b.mask.tobytes() for b in few.branches}
    assert kept == wanted | {lowest} and 0 < len(kept) < 4096
    assert few.summary["branches_kept"] == len(kept) and any("branches kept" in w for w in few.warnings)
    for b in few.branches:
        assert np.array_equal(b.stability_eigenvalues, by_mask[b.mask.tobytes()].stability_eigenvalues)


@pytest.mark.parametrize("lowrank", [False, True])
def test_without_uniqueness_the_stability_is_the_same_and_no_eig_runs(lowrank, monkeypatch):
    """uniqueness=False (track --whole): every branch's sym(𝓗^i) eigenvalues, codes and bounds as with ℍ^i, on the
    full and the low-rank path, and ℍ^i is not touched (np.linalg.eig, its only user, raises)."""
    scene = packings.random_packing(2, 16, n_sliding=4, mobilised=0.3, seed=1)
    with_u = granstab.analyze(scene, metric="L", lowrank=lowrank)
    monkeypatch.setattr(np.linalg, "eig", lambda *a: pytest.fail("ℍ^i's eig ran with uniqueness=False"))
    without = granstab.analyze(scene, metric="L", lowrank=lowrank, uniqueness=False)
    assert len(without.branches) == len(with_u.branches) == 2 ** 4
    for a, b in zip(with_u.branches, without.branches):
        # the same eigh of the same matrix on the same path: equal to round-off (1e-12 of the largest |λ|; the
        # low-rank path's special branches are solved on the full path in both)
        assert np.abs(a.stability_eigenvalues - b.stability_eigenvalues).max() <= \
            1e-12 * np.abs(a.stability_eigenvalues).max()
        assert np.array_equal(a.codes, b.codes) and np.array_equal(a.hinges, b.hinges)
        assert np.allclose(a.accuracy, b.accuracy, rtol=1e-9, atol=0)
        assert b.uniqueness_n_zero == -1 and b.uniqueness_eigenvalues.size == 0 and b.type2 == []
        assert a.uniqueness_n_zero >= 3                                 # with ℍ^i: at least the rigid motions
    assert without.verdict.verdict == with_u.verdict.verdict
    assert "eigen_residual_uniqueness" in with_u.errors and "eigen_residual_uniqueness" not in without.errors
    assert any("uniqueness=False" in w for w in without.warnings)


def test_the_svd_floor_tells_a_singular_h_from_one_the_gram_floor_cannot():
    """lowrank.svd_floor on X = H^i N with singular values 1 … 1e-7 (σ_min/σ_max = 1e-7: the Gram matrix's floor,
    4nε‖X‖_F² ~ 1e-11, cannot tell it from 0) proves σ_min above the zero tolerance; with σ_min = 0 (a non-rigid
    null vector, Type-2) it does not."""
    from types import SimpleNamespace

    from granstab.model.tolerances import DEFAULT
    from granstab.solve.lowrank import svd_floor
    rng = np.random.default_rng(3)
    n, k = 60, 57
    U = np.linalg.qr(rng.standard_normal((n, k)))[0]
    W = np.linalg.qr(rng.standard_normal((k, k)))[0]
    floors = []
    for smallest in (1e-7, 0.0):
        X = (U * np.r_[np.logspace(0, -6, k - 1), smallest]) @ W.T
        red = SimpleNamespace(HN=X, s=np.zeros((k, 1)), n=n)
        problem = SimpleNamespace(A=np.zeros((n, 1)), tol=DEFAULT)
        floors.append(svd_floor(problem, red, np.ones((1, 1)))[0])
        assert np.linalg.eigvalsh(X.T @ X)[0] - 4 * n * np.finfo(float).eps * np.sum(X * X) <= 0   # Gram: no
    assert floors[0] > 0 and floors[1] <= 0


def test_an_unstable_branch_the_gram_floor_cannot_tell_stays_on_the_low_rank_path(monkeypatch):
    """Before, an unstable branch whose Gram floor could not tell (L/10 and 10L of the 300-disk packing) went to the
    full path (eig + SVD + search, seconds a branch at 900 dofs); the SVD floor now decides it. Forced here on the
    Ms = 5 packing's unstable branches: the same results as the full path, none on it."""
    from granstab.solve import lowrank
    calls = []
    monkeypatch.setattr(lowrank, "gram_floor", lambda be, A, red, on: calls.append(len(on)) or
                        (np.full(len(on), -1.0), np.ones(len(on))))
    scene = packings.random_packing(**CASES["2D, f/k = 0.2, sharp tips"])
    problem, full, low, info = both_paths(scene)
    assert sum(calls) > 0 and info["full_path"] == 0
    for f, lo in zip(full, low):
        assert np.all(np.abs(f.stability_eigenvalues - lo.stability_eigenvalues) <= f.accuracy + lo.accuracy)
        assert np.array_equal(f.codes, lo.codes) and f.uniqueness_n_zero == lo.uniqueness_n_zero
