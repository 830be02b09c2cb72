"""The memory cuts that let a 10⁶-disk whole packing fit (issue 41): no float32 copy of a factor above
multifrontal.SINGLE_MAX entries (its preconditioning solves then read the float64 factors), and the block Krylov
solve's thick restart rotated in place (krylov.rotate: no n × keep temporaries)."""
import numpy as np

from granstab.solve import krylov, multifrontal, sparse
from granstab_bench.periodic_child import periodic_packing


def _factor():
    spb = sparse.sparse_problem(periodic_packing(300, 0))
    return spb, sparse.factor(spb, -sparse.SIGMA_REL * spb.norm)


def test_no_float32_copy_above_the_limit(monkeypatch):
    """Below SINGLE_MAX a `single` solve makes the float32 copy (error ~1e-7 relative); above it none is made and the
    `single` solve is the float64 one, to round-off (1e-12 relative: cond ~1e3 times eps). The old code made the copy
    whatever the factor's size."""
    spb, fac = _factor()
    b = np.random.default_rng(0).standard_normal((spb.n, 3))
    exact = fac.solve(b)
    x32 = fac.solve(b, single=True)
    assert np.float32 in fac.mf.plans
    assert 1e-12 < np.abs(x32 - exact).max() / np.abs(exact).max() < 1e-4
    monkeypatch.setattr(multifrontal, "SINGLE_MAX", fac.mf.nnz - 1)
    _, big = _factor()
    x = big.solve(b, single=True)
    assert set(big.mf.plans) == {np.float64}
    assert x.dtype == float and np.abs(x - exact).max() <= 1e-12 * np.abs(exact).max()


def test_rotate_in_place_equals_the_product(monkeypatch):
    """krylov.rotate(A, Y) leaves A[:, :c] = A₀ Y (c = Y's columns) and the rest of A as it was, across several row
    passes (ROTATE_ROWS made small); to round-off of the product (1e-13 relative)."""
    monkeypatch.setattr(krylov, "ROTATE_ROWS", 7)
    rng = np.random.default_rng(1)
    A = np.asfortranarray(rng.standard_normal((50, 9)))
    Y = rng.standard_normal((6, 4))
    before = A.copy()
    krylov.rotate(A[:, 1:7], Y)
    assert np.abs(A[:, 1:5] - before[:, 1:7] @ Y).max() <= 1e-13 * np.abs(before).max() * 6
    assert np.array_equal(A[:, 5:], before[:, 5:]) and np.array_equal(A[:, :1], before[:, :1])


def test_the_physical_parts_go_after_the_last_metric(monkeypatch):
    """SparseMethod.release: after the last metric's problem the physical H and Hm are dropped (1.5 GB on 10⁶ disks),
    so the errors step sees them gone; a family analysis (four metrics' problems from the same parts) still builds
    every metric and gives the same L spectrum as the single metric (to 1e-12 relative: the same solve)."""
    import granstab
    from granstab.solve.methods import SparseMethod
    seen = []
    errors = SparseMethod.errors
    monkeypatch.setattr(SparseMethod, "errors", lambda self, state, *a: seen.append(state.parts.H) or
                        errors(self, state, *a))
    scene = periodic_packing(800, 1)
    one = granstab.analyze(scene, method="sparse", metric="L")
    fam = granstab.analyze(scene, method="sparse")
    assert seen == [None, None]
    assert len(fam.summary["metrics"]) >= 3
    a, b = one.branches[0].stability_eigenvalues, fam.branches[0].stability_eigenvalues
    assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max()
