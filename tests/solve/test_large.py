"""The sparse path (granstab.solve.sparse) against dense eigh, and large scenes (granstab.model.packings).

Tolerance (why): both the sparse and the dense eigenvalues carry round-off of a few eps·‖Hs‖ per dof of
accumulation; the documented bound is the core's zero tolerance, zero_factor·n·eps·‖Hs‖ (tolerances.py), which
every comparison below uses (measured agreement is 1e-16…1e-15 relative to ‖Hs‖, far inside it).
"""
import numpy as np
import pytest
import scipy.sparse as sp

import granstab
from granstab.mechanics.assembly import Assembly, assemble
from granstab.mechanics.branches import BOTH, MINUS, PLUS, RIGID
from granstab.mechanics.stiffness import contact_blocks
from granstab.model import packings
from granstab.model.tolerances import DEFAULT
from granstab.solve import budget, krylov, sparse


def bound(spb) -> float:
    return DEFAULT.zero_tol(spb.norm, spb.n)


def dense_deflated(spb, mask=None):
    """Eigen-decomposition of the deflated operator B as a dense matrix (small scenes only)."""
    B = sparse.operator(spb, mask).matmat(np.eye(spb.n))
    lam, V = np.linalg.eigh(0.5 * (B + B.T))
    return sparse._drop_rigid(spb, lam, V)


def dense_branch_nonrigid(result, mask):
    """Non-rigid eigenvalues of sym(𝓗^mask) from the dense analyze(), ascending."""
    for b in result.branches:
        if np.array_equal(b.mask, mask):
            return np.sort(b.stability_eigenvalues[b.codes != RIGID])
    raise KeyError(mask)


SCENES = {
    "random2d": lambda: packings.random_packing(2, 150, seed=3),
    "lattice3d": lambda: packings.lattice(3, 2),
    "random3d_moments_rolling": lambda: packings.random_packing(3, 60, moments=0.3, rolling=0.05, seed=4),
    "sharp2d": lambda: packings.lattice(2, 6, curvature_ratio=0.3, f_over_k=0.05),
}


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("method", ["shift-invert", "lobpcg"])
def test_lowest_modes_agree_with_dense(name, method):
    s = SCENES[name]()
    spb = sparse.sparse_problem(s)
    modes = sparse.lowest_modes(spb, k=6, method=method)
    lam_d, V_d = dense_deflated(spb)
    tol = bound(spb)
    assert np.abs(modes.eigenvalues - lam_d[:6]).max() <= tol
    if method == "shift-invert":                                     # exact inverse: residuals at round-off
        assert modes.verified
        assert modes.residuals.max() * spb.norm <= tol
    else:                                                            # LOBPCG stops at residual 1e-8 ‖Hs‖
        assert modes.residuals.max() <= 1e-8
    # the same eigenspaces: distance between projectors onto each (well separated) eigenvalue cluster
    groups = np.split(np.arange(6), np.flatnonzero(np.diff(lam_d[:7]) > 1e-8 * spb.norm)[:5] + 1)
    for g in groups:
        if g[-1] == 5 and abs(lam_d[6] - lam_d[5]) <= 1e-8 * spb.norm:
            continue                                               # cluster cut by k: not comparable
        Ps, Pd = modes.vectors[:, g] @ modes.vectors[:, g].T, V_d[:, g] @ V_d[:, g].T
        assert np.abs(Ps - Pd).max() <= 1e-6
    # and with the core's dense analysis
    res = granstab.analyze(s, method="dense")
    lam_core = dense_branch_nonrigid(res, res.branches[0].mask)
    assert np.abs(modes.eigenvalues - lam_core[:6]).max() <= tol


def test_sliding_branches_share_one_factorisation_and_agree():
    s = packings.random_packing(2, 60, n_sliding=3, seed=2)
    spb = sparse.sparse_problem(s)
    res = granstab.analyze(s, method="dense")
    fac = None
    for b in res.branches:
        modes = sparse.lowest_modes(spb, k=5, mask=b.mask, factorization=fac, method="shift-invert")
        fac = modes.info["factorization"]
        lam = dense_branch_nonrigid(res, b.mask)
        assert np.abs(modes.eigenvalues - lam[:5]).max() <= bound(spb)
        assert modes.verified


def test_negative_eigenvalues_are_found_and_verified_by_inertia():
    """A shift inside the spectrum: the inertia counts the eigenvalues below it, and the result is still the
    lowest k (the ν > 0 path); the two-particle rolling instability (one negative eigenvalue)."""
    s = packings.random_packing(2, 80, seed=5)
    spb = sparse.sparse_problem(s)
    lam_d, _ = dense_deflated(spb)
    sigma = 0.5 * (lam_d[2] + lam_d[3])                             # three eigenvalues below σ
    modes = sparse.lowest_modes(spb, k=6, sigma=sigma, method="shift-invert")
    assert modes.n_below == 3 and modes.verified
    assert np.abs(modes.eigenvalues - lam_d[:6]).max() <= bound(spb)
    pair = granstab.load_scene("presets/two_particle.toml")
    m = sparse.lowest_modes(pair, k=3)
    assert m.eigenvalues[0] == pytest.approx(0.01 * (0.5 - 1.0), abs=bound(sparse.sparse_problem(pair)))


def test_inertia_counts_match_dense():
    s = packings.lattice(2, 5, curvature_ratio=0.2, f_over_k=0.2)
    spb = sparse.sparse_problem(s)
    lam_d, _ = dense_deflated(spb)
    for sigma in (-1e-3, lam_d[0] + 1e-9, 0.5 * (lam_d[4] + lam_d[5])):
        fac = sparse.factor(spb, sigma)
        U, K = sparse._lowrank(spb, np.zeros(0, bool), spb.norm)
        shifted = sparse.Shifted(fac, U, K, sigma, fac.n_neg)
        assert shifted.n_below == int(np.sum(lam_d < sigma))


@pytest.mark.parametrize("dim", [2, 3])
def test_analyze_sparse_matches_dense_verdicts_and_codes(dim):
    s = packings.random_packing(dim, 40 if dim == 2 else 32, n_sliding=2, moments=0.1 * (dim == 3), seed=7)
    d = granstab.analyze(s, method="dense")
    k = 8
    sres = granstab.analyze(s, method="sparse", k=k)
    assert sres.summary["verdict"] == d.summary["verdict"]
    assert sres.summary["n_branches"] == d.summary["n_branches"] == 4
    assert any("sparse path" in w for w in sres.warnings)
    n_rigid = 3 if dim == 2 else 6
    for bd, bs in zip(d.branches, sres.branches):
        assert np.array_equal(bd.mask, bs.mask)
        m = n_rigid + k
        assert np.abs(bs.stability_eigenvalues - bd.stability_eigenvalues[:m]).max() <= 64 * s.n_dof * 2.3e-16 * 4
        # codes agree up to the arbitrary sign of an eigenvector (PLUS <-> MINUS)
        flip = {PLUS: MINUS, MINUS: PLUS, BOTH: BOTH}
        for cd, cs in zip(bd.codes[:m], bs.codes):
            assert cs == cd or cs == flip.get(int(cd), cd)
        assert bs.uniqueness_n_zero == -1
    for key in ("force_balance", "moment_balance", "rigid_leakage_parts", "rigid_leakage_modified"):
        assert sres.errors[key] <= 1e-13


def test_auto_method_switches_to_sparse_above_the_dense_limit():
    s = packings.random_packing(2, 800, seed=1)                        # 2352 dofs > DENSE_MAX_DOF
    assert s.n_dof > sparse.DENSE_MAX_DOF
    res = granstab.analyze(s, k=4)
    assert any("sparse path" in w for w in res.warnings)
    assert len(res.branches[0].stability_eigenvalues) == 3 + 4
    with pytest.raises(ValueError):
        granstab.analyze(s, method="magic")


@pytest.mark.parametrize("dim", [2, 3])
def test_block_assembly_equals_scalar_assembly(dim):
    s = packings.random_packing(dim, 50, moments=0.2, seed=dim)
    cb = contact_blocks(s)
    total = sum(cb.blocks.values())
    M, n, _ = total.shape                                   # reference: scalar COO triplets, summed by scipy
    rows = np.broadcast_to(cb.index[:, :, None], (M, n, n)).reshape(-1)
    cols = np.broadcast_to(cb.index[:, None, :], (M, n, n)).reshape(-1)
    A = sp.coo_matrix((total.reshape(-1), (rows, cols)), shape=(cb.n_dof, cb.n_dof)).tocsr()
    B = assemble(total, s.p, s.q, s.dof_per_particle, s.n_dof)
    assert sp.issparse(B) and B.format == "csr"
    assert abs(A - B).max() <= 1e-15 * abs(A).max()
    # one Assembly (one pattern) scatters every part: each equals its own scalar reference, and the pattern is not
    # shared by reference (a later in-place change of one matrix must not reach the others)
    assembly = Assembly(s.p, s.q, s.dof_per_particle, s.n_dof)
    for part in cb.blocks.values():
        ref = sp.coo_matrix((part.reshape(-1), (rows, cols)), shape=(cb.n_dof, cb.n_dof)).tocsr()
        got = assembly(part)
        assert abs(ref - got).max() <= 1e-15 * max(abs(ref).max(), 1e-300)
    assert assembly(total).indices is not assembly(total).indices


@pytest.mark.parametrize("diagonal", [True, False])
def test_sparse_congruence_equals_the_products(diagonal):
    """D H D, D⁻¹ H D⁻¹ and |D| H |D| of a sparse H (Metric.sparse_congruence) against the sparse products with the
    block-diagonal D: where every block is diagonal (the L metric) the entrywise scaling rounds as the products do
    (bit-equal); with full blocks (as the inertia metric of ellipsoids has) it is the products, to round-off."""
    from granstab.mechanics.metric import Metric, length_metric
    s = packings.random_packing(3, 30, seed=5)
    if diagonal:
        metric = length_metric(s, 0.7)
    else:
        G = np.random.default_rng(2).standard_normal((s.n_particles, 6, 6))
        metric = Metric(name="full", rotation_length=None, blocks=G @ np.swapaxes(G, 1, 2) + 6 * np.eye(6))
    H = sp.random(s.n_dof, s.n_dof, density=0.05, random_state=1, format="csr")
    for inverse, absolute in ((False, False), (True, False), (False, True)):
        D = metric.inverse_matrix() if inverse else metric.matrix()
        D = abs(D) if absolute else D
        ref = (D @ H @ D).toarray()
        got = metric.sparse_congruence(H, inverse=inverse, absolute=absolute).toarray()
        assert (metric.diagonal is not None) == diagonal
        if diagonal:
            assert np.array_equal(got, ref)
        else:     # sums of ≤ 36 products per entry: a few eps of the largest entry
            assert np.abs(got - ref).max() <= 1e-14 * np.abs(ref).max()


def test_untouched_dofs_of_a_sparse_matrix_equal_the_dense_ones():
    """rigid.untouched_dofs on CSR (one pass over the entries) and on the same matrix dense (row and column maxima):
    the same dofs, with rows or columns that are zero, below the threshold (64 eps·scale), felt only through the
    other triangle (a non-symmetric H), or NaN (felt: never reported as a free motion)."""
    from granstab.mechanics.rigid import untouched_dofs
    rng = np.random.default_rng(6)
    H = sp.random(40, 40, density=0.1, random_state=6, format="lil")
    H[3, :], H[:, 3] = 0.0, 0.0                                     # untouched
    H[7, :], H[:, 7] = 0.0, 0.0
    H[7, 8] = 1e-17                                                 # below 64 eps: still untouched
    H[11, :], H[:, 11] = 0.0, 0.0
    H[2, 11] = 0.5                                                  # felt through its column only
    H[13, :], H[:, 13] = 0.0, 0.0
    H[13, 13] = np.nan
    A = rng.standard_normal((40, 2))
    A[[3, 7, 11, 13]] = 0.0
    H = H.tocsr()
    got = untouched_dofs(H, A, scale=1.0)
    assert np.array_equal(got, untouched_dofs(H.toarray(), A, scale=1.0))
    assert set(got) >= {3, 7} and not {11, 13} & set(got)


def test_dissection_order_is_a_permutation():
    s = packings.random_packing(3, 500, seed=0)
    order = sparse.dissection_order(s.x, s.p, s.q)
    assert np.array_equal(np.sort(order), np.arange(s.n_particles))


@pytest.mark.parametrize("dim,kind", [(2, "triangular"), (2, "square"), (3, "fcc"), (3, "cubic")])
def test_packings_are_valid_scenes_in_equilibrium(dim, kind):
    s = packings.lattice(dim, 4 if dim == 2 else 2, kind=kind, mobilised=0.5, n_sliding=2, moments=0.1,
                         rolling=0.01, seed=1)
    assert s.n_contacts > s.n_particles
    assert np.allclose(np.linalg.norm(s.normal, axis=1), 1.0, atol=1e-14)
    assert np.sum(s.at_yield()) == 2
    assert np.all(s.yield_function() <= 1e-9 * np.linalg.norm(s.force, axis=1))
    res = granstab.analyze(s)
    assert res.errors["equilibrium_residual"] == 0.0
    assert res.errors["force_balance"] <= 1e-14 and res.errors["moment_balance"] <= 1e-14


def test_ten_thousand_particles_sparse_without_dense_matrices():
    """10⁴ particles (30 000 dofs): a dense n×n matrix would need 7.2 GB; the whole analysis stays far below
    that (numpy allocations traced), the identities hold to round-off, and the two eigensolvers agree."""
    import tracemalloc

    s = packings.random_packing(2, 10_000, seed=11)
    tracemalloc.start()
    res = granstab.analyze(s, k=4)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1.5e9
    assert res.summary["verdict"] == "stable" and res.summary["sufficient"]
    for key in ("force_balance", "moment_balance", "rigid_leakage_parts", "rigid_leakage_H_translations",
                "rigid_leakage_modified", "eigen_residual_stability"):
        assert res.errors[key] <= 1e-13, key
    spb = sparse.sparse_problem(s)
    lob = sparse.lowest_modes(spb, k=4, method="lobpcg")
    lam = res.branches[0].stability_eigenvalues[3:]
    assert np.abs(lob.eigenvalues - lam).max() <= bound(spb)


@pytest.mark.parametrize("method", ["dense", "sparse"])
def test_branches_stream_as_they_come_with_a_progress_bar(method, capsys):
    s = packings.random_packing(2, 30, n_sliding=3, seed=4)
    seen = []
    res = granstab.analyze(s, method=method, k=4, progress=True, on_branch=seen.append)
    assert len(seen) == 8 and all(a is b for a, b in zip(seen, res.branches))
    err = capsys.readouterr().err
    assert "branch" in err and "8/8" in err                           # tqdm bar with counts (and time left)


def _dissected(spb, sigma):
    """Hs - σI in the nested-dissection order and its node bounds (as sparse.Factor builds them)."""
    s, per = spb.scene, spb.scene.dof_per_particle
    order, sizes = sparse.dissection_order(s.x, s.p, s.q, nodes=True)
    perm = (order[:, None] * per + np.arange(per)).reshape(-1)
    M = (spb.Hs - sigma * sp.identity(spb.n, format="csr"))[perm][:, perm]
    return M, np.r_[0, np.cumsum(sizes) * per]


def test_multifrontal_inertia_and_solves_against_dense():
    """The multifrontal congruence (multifrontal.py) counts the eigenvalues below σ exactly as a dense eigvalsh does,
    on a 3D packing (several fronts, indefinite ones for σ inside the spectrum), and solves the definite case to
    round-off (residual ≤ 1e-12 relative: a Cholesky's backward error with fronts of a few hundred dofs)."""
    from granstab.solve.multifrontal import Multifrontal
    spb = sparse.sparse_problem(packings.random_packing(3, 120, seed=2))
    lam = np.linalg.eigvalsh(spb.Hs.toarray())
    for j in (0, 8, 101, 300):
        sigma = -1e-3 * spb.norm if j == 0 else 0.5 * (lam[j - 1] + lam[j])
        f = Multifrontal(*_dissected(spb, sigma))
        assert len(f.bounds) > 3 and f.negative == j
        assert f.definite == (j == 0)
    M, bounds = _dissected(spb, -1e-3 * spb.norm)
    x = Multifrontal(M, bounds).solve(b := np.random.default_rng(0).standard_normal((spb.n, 3)))
    assert np.abs(M @ x - b).max() <= 1e-12 * abs(M).sum(axis=1).max() * np.abs(x).max()


def test_multifrontal_solve_against_dense_for_any_right_hand_side_shape():
    """Multifrontal.solve (per front: x_s ← G x_s, x_struct −= W x_s, then back) against scipy's dense solve of the
    same matrix, for one vector, one column and a block, in float64 and float32. Tolerance: a backward-stable solve
    has a relative forward error ≲ c·n·eps·cond(M); here 10·n·eps·cond (~1e-9 with cond ~1e3), float32 the same
    with its eps (the float32 solve is only a preconditioner: its error must be small, not round-off)."""
    from granstab.solve.multifrontal import Multifrontal
    spb = sparse.sparse_problem(packings.random_packing(3, 120, seed=2))
    M, bounds = _dissected(spb, -1e-3 * spb.norm)
    lam = np.linalg.eigvalsh(M.toarray())
    cond = lam[-1] / lam[0]
    f = Multifrontal(M, bounds)
    assert f.definite and len(f.bounds) > 3
    rng = np.random.default_rng(3)
    for b in (rng.standard_normal(spb.n), rng.standard_normal((spb.n, 1)), rng.standard_normal((spb.n, 7))):
        ref = np.linalg.solve(M.toarray(), b)
        for single, eps in ((False, np.finfo(float).eps), (True, np.finfo(np.float32).eps)):
            x = f.solve(b, single)
            assert x.shape == b.shape and x.dtype == float
            assert np.abs(x - ref).max() <= 10 * spb.n * eps * cond * np.abs(ref).max()


def test_extend_orthonormal_in_one_pass_or_two():
    """sparse.extend: the columns it returns are orthonormal and orthogonal to X to round-off (≤ 15·√m·eps, its
    docstring's bound for a single pass) and span what B has outside span(X), both for a block well outside X
    (one pass) and for one almost inside X, as shift-invert makes it (two passes); a dependent column is dropped."""
    rng = np.random.default_rng(4)
    n, m = 4000, 30
    X, _ = np.linalg.qr(rng.standard_normal((n, m)))
    outside = rng.standard_normal((n, 6))
    for B in (outside, X @ rng.standard_normal((m, 6)) + 1e-6 * outside,
              np.concatenate([outside, outside[:, :1] + X[:, :1]], axis=1)):
        Q = krylov.extend(X, B)
        tol = 15 * np.sqrt(m + Q.shape[1]) * np.finfo(float).eps
        assert Q.shape[1] == 6
        assert np.abs(X.T @ Q).max() <= tol
        assert np.abs(Q.T @ Q - np.eye(Q.shape[1])).max() <= tol
        rest = B - X @ (X.T @ B)                                        # what B has outside span(X) …
        assert np.linalg.norm(rest - Q @ (Q.T @ rest)) <= 1e-8 * np.linalg.norm(rest)   # … lies in span(Q)


def test_sparse_ritz_reuses_the_krylov_products_and_solves(monkeypatch):
    """SparseRitz takes Wᵀ Hs W's Krylov block from the block iteration's own Xᵀ B X (less the low-rank deflation)
    and (Hs − σI)⁻¹[A, S] from the elastic Woodbury solve: both must equal the direct products
    and a fresh solve (entries of Wᵀ Hs W: unit vectors through Hs, ~m·eps·‖Hs‖ of accumulated rounding; 1e-12
    relative leaves room for the restarts' rotations and is far below the Ritz residual test, 1e-12·‖Hs‖)."""
    from granstab.solve.ritz import SparseRitz
    from granstab_bench.periodic_child import periodic_packing
    spb = sparse.sparse_problem(periodic_packing(300, 2))
    found, block_near = [], sparse._block_near
    monkeypatch.setattr(sparse, "_block_near", lambda *a: found.append(block_near(*a)) or found[-1])
    ritz = SparseRitz(spb, 7)
    assert len(found) == 1 and isinstance(found[0][2], sparse.Krylov)      # the Krylov path, not its fallback
    W = ritz.W
    assert np.abs(ritz.M0 - W.T @ (spb.Hs @ W)).max() <= 1e-12 * spb.norm
    fac = ritz.factorization
    for name, F in (("A", spb.A), ("S", spb.S), ("T", spb.R[:, :2])):
        x = fac.solve(F)
        assert np.abs(ritz.solved[name] - x).max() <= 1e-12 * np.abs(x).max()


def test_float32_preconditioned_branches_match_dense_within_their_bounds(monkeypatch):
    """The whole-packing path (issue 24) on a small periodic packing with two sliding contacts (four branches): one
    float64 factorisation for the counts, its float32 copy for the Krylov solves (Multifrontal.solve(single=True),
    only as a preconditioner: the residuals and Rayleigh quotients are float64) and the branches as Ritz updates of
    the shared elastic solve. Every reported eigenvalue must lie within its reported bound of the dense path's (whose
    own bound is added: both are proven), and the count below σ must equal the dense count of negative eigenvalues.
    The float32 solves must really have run, and a float32 solve alone must be inaccurate (relative residual above
    1e-10: were it not, the test would not exercise an approximate preconditioner)."""
    from granstab.solve.multifrontal import Multifrontal
    from granstab_bench.periodic_child import periodic_packing
    scene = periodic_packing(300, 2)
    calls = []
    solve = Multifrontal.solve

    def spy(self, b, single=False):
        calls.append(single)
        return solve(self, b, single)

    monkeypatch.setattr(Multifrontal, "solve", spy)
    sres = granstab.analyze(scene, method="sparse", k=6, metric="L")
    assert any(calls), "the float32 solves did not run"
    assert any("Ritz updates" in w for w in sres.warnings)
    dres = granstab.analyze(scene, method="dense", metric="L")
    assert len(sres.branches) == len(dres.branches) == 4
    for bs in sres.branches:
        bd = next(b for b in dres.branches if np.array_equal(b.mask, bs.mask))
        keep_s, keep_d = bs.codes != RIGID, bd.codes != RIGID
        lam_s, bound_s = bs.stability_eigenvalues[keep_s], bs.bounds[keep_s]
        lam_d, bound_d = bd.stability_eigenvalues[keep_d][:len(lam_s)], bd.bounds[keep_d][:len(lam_s)]
        assert len(lam_s) == 6
        assert np.all(np.abs(lam_s - lam_d) <= bound_s + bound_d)
        # the bounds are tight, not vacuous: every eigenvalue to 9 digits (measured ~1e-10 of λ_min: the formation
        # floor ~7e-12 and a Ritz residual ≤ 1e-12·‖Hs‖; a LOBPCG-tolerance residual, 1e-8·‖Hs‖, would fail)
        assert np.all(bound_s <= 1e-9 * lam_d.min())
        assert bs.negative_count["total"]
        assert bs.negative_count["count"] == int(np.sum(bd.stability_eigenvalues[keep_d] < -bd.bounds[keep_d]))
    # a float32 solve by itself has a backward error ~1e-7 (float32 round-off times a modest growth), a float64 one
    # ~1e-16: the agreement above comes from the float64 iteration around the float32 solves
    spb = sparse.sparse_problem(scene)
    fac = sparse.factor(spb, -sparse.SIGMA_REL * spb.norm)
    b = np.random.default_rng(1).standard_normal((spb.n, 2))
    M = spb.Hs - fac.sigma * sp.identity(spb.n, format="csr")

    def backward(x):
        return np.abs(M @ x - b).max() / (abs(M).sum(axis=1).max() * np.abs(x).max())

    assert 1e-10 < backward(fac.solve(b, single=True)) < 1e-5
    assert backward(fac.solve(b)) <= 1e-14


def test_branches_are_made_on_one_blas_thread(monkeypatch):
    """sparse.sparse_branch (signs, codes, eigenspace search on the n × k vectors) runs under the one-BLAS-thread
    bound of the sparse path, as the solves do: outside it, 10⁵ disks gave vectors differing by ~1e-18 between one
    core and two (OpenBLAS splits large products by thread). threadpoolctl is a test dependency, so the bound is
    always seen here: None would mean that the branches ran with the library's threads."""
    from granstab.solve import threads
    from granstab_bench.periodic_child import periodic_packing
    seen = []
    branch = sparse.sparse_branch

    def spy(*args):
        seen.append(threads.bound())
        return branch(*args)

    monkeypatch.setattr(sparse, "sparse_branch", spy)
    r = granstab.analyze(periodic_packing(800, 1), k=4, metric="L", method="sparse")
    assert r.backend == "sparse" and len(seen) == len(r.branches) == 2
    assert seen == [1, 1]


@pytest.mark.parametrize("n_sliding, ritz", [(10, False), (2, True)])
def test_two_branches_go_to_shift_invert_unless_the_ritz_basis_is_narrow(n_sliding, ritz, monkeypatch):
    """track's whole stage asks for two branches (all-unloading, all-loading; max_sliding 0, sample_branches 0),
    as does issue 41's periodic packing with one contact at yield. With many sliding contacts (8.5 Taylor columns
    each above the elastic Krylov space's kk + 48) each branch is solved by shift-invert (cheaper: issue 39); with a
    narrow basis both are Ritz updates of one elastic solve (one factor instead of one a branch: issue 41's 2·10⁵
    disks 50 s and 3.8 GB against 74 s and 5.9 GB). Each eigenvalue equals the dense one within the branch's
    reported accuracy (a bound) and the same round-off allowance as above."""
    s = packings.random_packing(2, 40, n_sliding=n_sliding, seed=7)
    options = dict(metric="L", max_sliding=0, sample_branches=0, uniqueness=False)
    d = granstab.analyze(s, method="dense", **options)
    k = 8
    from granstab.solve import ritz as ritz_module
    built = []
    original = ritz_module.SparseRitz.__init__
    monkeypatch.setattr(ritz_module.SparseRitz, "__init__", lambda self, *a, **kw: (built.append(1),
                                                                                   original(self, *a, **kw))[1])
    sres = granstab.analyze(s, method="sparse", k=k, **options)
    assert sres.summary["n_branches"] == d.summary["n_branches"] == 2
    assert budget.use_ritz(2, s.n_dof, int(s.at_yield().sum()), k + 1) is ritz
    assert len(built) == int(ritz)                          # the path taken: one Ritz basis, or none
    assert budget.use_ritz(2, 3 * 10 ** 6, 1, 7) and not budget.use_ritz(2, 5937, 60, 61)    # issue 41's; issue 39's
    assert budget.use_ritz(3, 10 ** 4, 10, k + 1)
    for bd, bs in zip(d.branches, sres.branches):
        assert np.array_equal(bd.mask, bs.mask)
        m = len(bs.stability_eigenvalues)
        error = np.abs(bs.stability_eigenvalues - bd.stability_eigenvalues[:m])
        assert np.all(error <= np.asarray(bs.accuracy) + 64 * s.n_dof * 2.3e-16 * 4)


def test_a_branch_with_many_sliding_contacts_factors_its_own_matrix_within_its_bounds():
    """Issue 39's cost: a branch with more than OWN_FACTOR_COLUMNS / 2 sliding contacts factors its own sparse
    matrix Hs + ½ Σ (a sᵀ + s aᵀ) (sparse.branch_problem) instead of a Woodbury correction of 2 columns a contact,
    and more than BLOCK_MAX_WANTED eigenpairs go to ARPACK instead of the block Krylov solve. Both are the same
    operator B: every eigenvalue equals the dense one of the deflated B (with the low-rank sliding terms, as
    before) within the round-off bound of this file, the count below σ equals the dense count, for the default
    shift and for one inside the spectrum (an indefinite factor: SuperLU); the elastic branch (no sliding contact)
    keeps the block solve up to BLOCK_MAX_WANTED and goes to ARPACK above it."""
    s = packings.random_packing(2, 150, n_sliding=40, seed=7)
    spb = sparse.sparse_problem(s)
    mask = s.at_yield().astype(np.int8)                                  # every sliding contact loading
    assert 2 * mask.sum() > sparse.OWN_FACTOR_COLUMNS
    lam_d, _ = dense_deflated(spb, mask)
    inside = 0.5 * (lam_d[4] + lam_d[5])                                  # five eigenvalues below it
    for k, sigma in ((6, None), (40, inside)):
        modes = sparse.lowest_modes(spb, k, mask, sigma=sigma, method="shift-invert")
        assert modes.info.get("own_factor") and modes.verified and np.array_equal(modes.mask, mask)
        assert modes.n_below == int(np.sum(lam_d < modes.sigma))
        assert np.abs(modes.eigenvalues - lam_d[:k]).max() <= bound(spb)
        assert modes.residuals.max() * spb.norm <= bound(spb)
    lam_e, _ = dense_deflated(spb)
    for k, block in ((6, True), (sparse.BLOCK_MAX_WANTED + 8, False)):
        modes = sparse.lowest_modes(spb, k, method="shift-invert")
        assert "own_factor" not in modes.info and modes.verified
        assert ("krylov" in modes.info) is block
        assert np.abs(modes.eigenvalues - lam_e[:k]).max() <= bound(spb)
