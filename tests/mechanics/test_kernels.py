"""The kernels with a leading batch axis: a stack of G clusters gives, bit for bit, what G calls of one cluster give
(the scan's batch and `analyze` call the same functions), and each kernel computes what it says."""
import numpy as np
import pytest
import scipy.sparse as sp
from helpers import random_cluster, scene

from granstab.analysis import build_problem
from granstab.mechanics.accuracy import abs_norm_inf, gamma
from granstab.mechanics.assembly import assemble, dof_index, scatter_columns, sliding_factors, stack_blocks
from granstab.mechanics.branches import (
    BOTH,
    INCONSISTENT,
    MINUS,
    PLUS,
    RIGID,
    Problem,
    enumerate_masks,
    search_eigenspaces,
    sign_patterns,
)
from granstab.mechanics.branches import test_codes as codes_of
from granstab.mechanics.rigid import (
    Projection,
    dof_scale,
    on_complement,
    rigid_basis,
    rotation_columns,
    rotation_length,
    translation_columns,
)
from granstab.mechanics.stiffness import contact_blocks
from granstab.model.tolerances import DEFAULT
from granstab.model.vec import rot_dim
from granstab.scan import batch
from granstab.solve import lowrank

EPS = np.finfo(float).eps


def _clusters(d: int, G: int = 5, n: int = 7, seed: int = 0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-3, 3, (G, n, d)), rng.uniform(0.2, 2.0, G)


@pytest.mark.parametrize("d", [2, 3])
def test_rigid_complement_of_a_stack_is_each_clusters_own(d):
    x, L = _clusters(d)
    G, n, _ = x.shape
    C = rotation_columns(x, L)
    T = translation_columns(n, d, (G,))
    R, N = rigid_basis(np.concatenate([T, C], axis=2), complement=True)
    P = Projection.from_rotations(C)
    rng = np.random.default_rng(1)
    H = rng.standard_normal((G, N.shape[1], N.shape[1]))
    A = rng.standard_normal((G, H.shape[1], 3))
    M0, a = on_complement(N, H, A)
    for g in range(G):
        Cg = rotation_columns(x[g], L[g])
        Rg, Ng = rigid_basis(np.concatenate([translation_columns(n, d), Cg], axis=1), complement=True)
        np.testing.assert_array_equal(C[g], Cg)
        np.testing.assert_array_equal(R[g], Rg)
        np.testing.assert_array_equal(N[g], Ng)
        np.testing.assert_array_equal(P.apply(R)[g], Projection.from_rotations(Cg).apply(Rg))
        M0g, ag = on_complement(Ng, H[g], A[g])
        np.testing.assert_array_equal(M0[g], M0g)
        np.testing.assert_array_equal(a[g], ag)


@pytest.mark.parametrize("d", [2, 3])
def test_rigid_complement_spans_what_it_says(d):
    """[R, N] is orthogonal, R spans the translations and the rotations about the centroid (the L-scaled rotation
    dofs: dθ̄ × x and L dθ̄), and P = I - C C⁺ removes the rotations: to a few ε of the scale of C."""
    x, L = _clusters(d, G=1)
    C = rotation_columns(x[0], L[0])
    n, r = x.shape[1], rot_dim(d)
    T = translation_columns(n, d)
    R, N = rigid_basis(np.concatenate([T, C], axis=1), complement=True)
    B = np.concatenate([R, N], axis=1)
    tol = 100 * n * EPS
    assert np.abs(B.T @ B - np.eye(n * (d + r))).max() <= tol
    for M in (T, C):
        assert np.abs(M - R @ (R.T @ M)).max() <= tol * np.abs(M).max()
    assert np.abs(Projection.from_rotations(C).apply(C)).max() <= tol * np.abs(C).max()
    rot = C.reshape(n, d + r, r)                      # per particle: dθ̄ × (x - x̄) and L dθ̄
    np.testing.assert_allclose(rot[:, d:, :], np.broadcast_to(L[0] * np.eye(r), (n, r, r)))
    assert np.abs(rot[:, :d, :].sum(axis=0)).max() <= tol * np.abs(x).max()   # about the centroid
    np.testing.assert_array_equal(dof_scale(n, d, L)[0], dof_scale(n, d, L[0]))
    np.testing.assert_array_equal(dof_scale(n, d, L[0]).reshape(n, d + r),
                                  np.broadcast_to(np.r_[np.ones(d), np.full(r, 1 / L[0])], (n, d + r)))


def test_masks_of_a_stack_are_each_clusters_own():
    n_sliding = np.array([0, 3, 1, 3, 2, 0])
    width = 4
    owner, signs = sign_patterns(n_sliding, width)
    np.testing.assert_array_equal(np.bincount(owner, minlength=len(n_sliding)), 2 ** n_sliding)
    for c, k in enumerate(n_sliding):
        own, mine = sign_patterns([k], k)
        np.testing.assert_array_equal(own, 0)
        np.testing.assert_array_equal(signs[owner == c, :k], mine)
        np.testing.assert_array_equal(signs[owner == c, k:], 0)
        assert len({tuple(row) for row in mine}) == 2 ** k and np.all(np.abs(mine) == 1)
        if k:
            np.testing.assert_array_equal(mine[0], 1)                  # branch 0: all loading
    masks = enumerate_masks(np.array([4, 1, 6]), 8)                    # one scene: the same signs, on its contacts
    np.testing.assert_array_equal(masks[:, [4, 1, 6]], sign_patterns([3], 3)[1])
    np.testing.assert_array_equal(masks[:, [0, 2, 3, 5, 7]], 0)


def test_abs_norm_of_a_stack_is_each_matrix_own():
    rng = np.random.default_rng(2)
    H = rng.standard_normal((6, 9, 9)) * rng.uniform(1e-3, 1e3, (6, 1, 1))
    norms = abs_norm_inf(H)
    assert norms.shape == (6,)
    for g in range(6):
        assert norms[g] == abs_norm_inf(H[g])
        assert norms[g] == pytest.approx(max(sum(abs(v) for v in row) for row in H[g].tolist()), rel=10 * EPS)
        assert abs_norm_inf(sp.csr_matrix(H[g])) == pytest.approx(norms[g], rel=10 * EPS)
    np.testing.assert_array_equal(abs_norm_inf(np.zeros((3, 0, 0))), np.zeros(3))
    assert abs_norm_inf(np.zeros((0, 0))) == 0.0


def _entries(G: int, n: int, per: int, seed: int):
    """Random (cluster, contact) entries sorted by cluster over two different particles, one of them at most held
    (-1)."""
    rng = np.random.default_rng(seed)
    P = 40
    owner = np.sort(rng.integers(0, G, P))
    particles = n // per
    p = rng.integers(0, particles, P)
    q = (p + rng.integers(1, particles, P)) % particles
    held = rng.integers(0, 4, P)
    return owner, np.where(held == 1, -1, p), np.where(held == 2, -1, q), rng


@pytest.mark.parametrize("per", [3, 6])
def test_block_scatter_of_a_stack_is_each_clusters_own(per):
    G, n = 4, 5 * per
    owner, p, q, rng = _entries(G, n, per, seed=per)
    index = dof_index(p, q, per, held=n)
    blocks = rng.standard_normal((len(owner), 2 * per, 2 * per))
    rows = rng.standard_normal((len(owner), 2 * per))
    H, v = stack_blocks(blocks, owner, index, G, n), stack_blocks(rows, owner, index, G, n)
    for g in range(G):
        mine = owner == g
        zero = np.zeros(mine.sum(), dtype=int)
        np.testing.assert_array_equal(H[g], stack_blocks(blocks[mine], zero, index[mine], 1, n)[0])
        np.testing.assert_array_equal(v[g], stack_blocks(rows[mine], zero, index[mine], 1, n)[0])
        reference = np.zeros((n + 1, n + 1))                            # entry by entry, the held dof n cut off
        for b, i in zip(blocks[mine], index[mine]):
            reference[np.ix_(i, i)] += b
        np.testing.assert_array_equal(H[g], reference[:n, :n])
    held = (p < 0)[:, None] & (np.arange(2 * per) < per) | (q < 0)[:, None] & (np.arange(2 * per) >= per)
    np.testing.assert_array_equal(index[held], n)


@pytest.mark.parametrize("per", [3, 6])
def test_one_scene_and_a_stack_come_from_the_same_blocks(per):
    """The two outputs of one intermediate: the CSR of one scene and its (1, n, n) stack, equal up to the order in
    which each sums an entry's terms (γ_m of the sum of their magnitudes, m terms at most: 4 per contact of a
    particle, bounded by 2M)."""
    rng = np.random.default_rng(7)
    N, M = 6, 15
    p = rng.integers(0, N, M)
    q = (p + rng.integers(1, N, M)) % N
    blocks = rng.standard_normal((M, 2 * per, 2 * per))
    owner, index = np.zeros(M, dtype=int), dof_index(p, q, per)
    dense = stack_blocks(blocks, owner, index, 1, N * per)[0]
    magnitude = stack_blocks(np.abs(blocks), owner, index, 1, N * per)[0]
    difference = np.abs(assemble(blocks, p, q, per, N * per).toarray() - dense)
    assert np.all(difference <= gamma(2 * M) * magnitude)
    assert np.count_nonzero(magnitude) > 0.3 * magnitude.size


def test_sliding_factors_of_a_stack_are_each_clusters_own():
    G, per, width = 3, 3, 4
    n = 4 * per
    owner, p, q, rng = _entries(G, n, per, seed=3)
    column = batch._rank_within(owner)
    keep = column < width
    owner, p, q, column = owner[keep], p[keep], q[keep], column[keep]
    index = dof_index(p, q, per, held=n)
    values = rng.standard_normal((len(owner), 2 * per))
    A = scatter_columns(values, owner, index, column, G, n, width)
    for g in range(G):
        mine = owner == g
        zero = np.zeros(mine.sum(), dtype=int)
        np.testing.assert_array_equal(A[g], scatter_columns(values[mine], zero, index[mine], column[mine], 1, n,
                                                            width)[0])
        for v, i, c in zip(values[mine], index[mine], column[mine]):
            live = i < n
            np.testing.assert_array_equal(A[g][i[live], c], v[live])


def test_sliding_factors_of_a_scene():
    """A, S of one scene: a and s of contact sliding[j] at its dofs in column j (eq:ContactF), zero elsewhere."""
    sc = scene(random_cluster(3, n_particles=4, seed=5))
    blocks = contact_blocks(sc)
    sliding = np.array([1, 4, 5])
    A, S = sliding_factors(blocks, sliding)
    assert A.shape == S.shape == (sc.n_dof, 3)
    for j, c in enumerate(sliding):
        for F, f in ((A, blocks.slide_left), (S, blocks.slide_right)):
            column = np.zeros(sc.n_dof)
            column[blocks.index[c]] = f[c]
            np.testing.assert_array_equal(F[:, j], column)


@pytest.mark.parametrize("d", [2, 3])
def test_lowrank_reduces_with_the_batch_kernels(d):
    """lowrank.reduce (one cluster, G = 1) is rigid.on_complement on rigid.rigid_basis's complement, as the batch."""
    sc = scene(random_cluster(d, n_particles=5, seed=d))
    problem, _ = build_problem(sc, contact_blocks(sc), rotation_length(sc))
    red = lowrank.reduce(problem)
    _, N = rigid_basis(problem.rigid, complement=True)
    M0, a, s = on_complement(N, problem.H_el, problem.A, problem.S)
    for got, want in ((red.N, N), (red.M0, M0), (red.a, a), (red.s, s)):
        np.testing.assert_array_equal(got, want)


def _search_problem():
    """Three dofs, two sliding contacts (mask +1, +1): S of e0 is (1, -1) (inconsistent either way), of e1 (0, 0)
    (a rigid-like motion: consistent both ways), of e2 (1, 1) (consistent as +v)."""
    S = np.array([[1.0, -1.0], [0.0, 0.0], [1.0, 1.0]])
    problem = Problem(H_el=np.zeros((3, 3)), A=np.zeros((3, 2)), S=S, projection=None, rigid=np.zeros((3, 0)),
                      sliding=np.array([0, 1]), n_contacts=2, tol=DEFAULT)
    return problem, np.array([1, 1], dtype=np.int8)


def test_appendix_d_search_skips_a_run_that_holds_a_zero():
    """A run of eigenvalues that touches a zero is not one eigenspace to search (the zero's vector may be rigid):
    the negative eigenvalue keeps its own, inconsistent, code rather than a rigid vector's 'both'."""
    problem, mask = _search_problem()
    V = np.eye(3)
    codes, hinges = (a[0].copy() for a in codes_of(problem, mask[None], V[None]))
    codes[1] = RIGID
    search_eigenspaces(problem, mask, np.array([-0.15, 0.0, 1.0]), np.full(3, 0.1), V, codes, hinges)
    np.testing.assert_array_equal(codes, [INCONSISTENT, RIGID, PLUS])
    np.testing.assert_array_equal(V, np.eye(3))


def test_appendix_d_search_of_a_repeated_eigenvalue_and_of_the_null_space():
    """A repeated eigenvalue (e0, e2 within their bounds) is searched as one eigenspace: its first slot gets a
    consistent vector (+v: every m_j S_j >= 0), the other is INCONSISTENT; the null space likewise."""
    problem, mask = _search_problem()
    V = np.eye(3)[:, [0, 2, 1]]
    codes, hinges = (a[0].copy() for a in codes_of(problem, mask[None], V[None]))
    search_eigenspaces(problem, mask, np.array([0.5, 0.55, 2.0]), np.full(3, 0.1), V, codes, hinges)
    assert codes[0] in (PLUS, MINUS, BOTH) and codes[1] == INCONSISTENT
    s = problem.S.T @ V[:, 0] * (1 if codes[0] != MINUS else -1)
    assert np.all(s >= -problem.s_tol) and abs(np.linalg.norm(V[:, 0]) - 1) <= 10 * EPS
    W = np.eye(3)[:, [0, 1]]                                            # a two-dimensional non-rigid null space
    V, codes = np.eye(3), np.array([INCONSISTENT, INCONSISTENT, PLUS], dtype=np.int8)
    search_eigenspaces(problem, mask, np.array([0.0, 0.0, 2.0]), np.full(3, 0.1), V, codes, hinges,
                       np.array([0, 1]), W)
    assert codes[0] == BOTH and codes[1] == INCONSISTENT
    np.testing.assert_allclose(np.abs(V[:, 0]), [0, 1, 0], atol=1e-12)   # the combination with every S = 0
