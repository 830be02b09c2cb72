"""Exact identities of H for every motion, objectivity, and scale invariance (Sec. 2; erratum 1, docs/errata.md)."""
import numpy as np
import pytest
from helpers import dof_rotation, random_cluster, rotate_scene_dict, rotation, scene

import granstab
from granstab.mechanics.rigid import rotations, translations
from granstab.model.vec import cross_matrix

CASES = [(2, 4, 0), (2, 6, 1), (3, 4, 2), (3, 5, 3)]


@pytest.mark.parametrize("dim,n,seed", CASES)
def test_force_and_moment_balance_of_increments(dim, n, seed):
    """Σ_p db^p = 0 and Σ_p (x^p × db^p + dw^p + du^p × b^p) = 0 for every motion (rows of H), relative to ‖H‖."""
    s = scene(random_cluster(dim, n, seed))
    H = granstab.stiffness(s).H
    norm = np.linalg.norm(H, 2)
    T, C = translations(s), rotations(s, 1.0)
    assert np.abs(T.T @ H).max() <= 1e-14 * norm
    d = dim
    per = s.dof_per_particle
    L = np.zeros((C.shape[1], s.n_dof))
    for i in range(s.n_particles):
        L[:, i * per:i * per + d] = -cross_matrix(s.load[i])
    size = np.abs(s.x - s.x.mean(axis=0)).max()
    assert np.abs(C.T @ H + L).max() <= 1e-14 * norm * size


@pytest.mark.parametrize("dim,n,seed", CASES)
def test_parts_vanish_on_rigid_motions(dim, n, seed):
    s = scene(random_cluster(dim, n, seed))
    K = granstab.stiffness(s)
    rigid = np.concatenate([translations(s), rotations(s, 1.0)], axis=1)
    norm = np.linalg.norm(K.H, 2)
    for part in (K.Hg1, K.Hg2, K.Hm):
        assert np.abs(part @ rigid).max() <= 1e-14 * norm
    assert np.abs(K.H @ translations(s)).max() <= 1e-14 * norm
    # Hg3 does not vanish on rotations: the anomaly the projection resolves (Sec. 2.4)
    assert np.abs(K.Hg3 @ rotations(s, 1.0)).max() > 1e-6 * np.abs(s.force).max()


@pytest.mark.parametrize("dim,n,seed", CASES)
def test_modified_stiffness_has_exactly_rigid_zeros(dim, n, seed):
    result = granstab.analyze(scene(random_cluster(dim, n, seed)))
    (branch,) = result.branches
    n_rigid = 3 if dim == 2 else 6
    assert branch.uniqueness_n_zero == n_rigid
    assert np.sum(np.abs(branch.uniqueness_eigenvalues) <= branch.zero_tol) == n_rigid
    assert branch.n_zero == n_rigid
    assert result.errors["rigid_leakage_modified"] <= 1e-13


@pytest.mark.parametrize("dim,n,seed", CASES)
def test_objectivity(dim, n, seed):
    """Rotating the whole scene by Q rotates H: H(Q·scene) = R H Rᵀ."""
    data = random_cluster(dim, n, seed)
    Q = rotation(dim, seed + 7)
    H = granstab.stiffness(scene(data)).H
    H_rot = granstab.stiffness(scene(rotate_scene_dict(data, Q))).H
    R = dof_rotation(dim, n, Q)
    assert np.abs(H_rot - R @ H @ R.T).max() <= 1e-13 * np.linalg.norm(H, 2)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("scale", [1e-6, 1e-3, 1e3, 1e6])
def test_dimensionless_results_invariant_under_length_scaling(dim, scale):
    """Lengths × s with f/(kr) fixed (k = 1): eigenvalues of sym(𝓗) and ℍ (units of k) are unchanged."""
    base = granstab.analyze(scene(random_cluster(dim, 4, 11)))
    scaled = granstab.analyze(scene(random_cluster(dim, 4, 11, scale=scale)))
    for b0, b1 in zip(base.branches, scaled.branches):
        lam0, lam1 = b0.stability_eigenvalues, b1.stability_eigenvalues
        assert np.abs(lam1 - lam0).max() <= 1e-9 * np.abs(lam0).max()
        mu0, mu1 = b0.uniqueness_eigenvalues, b1.uniqueness_eigenvalues
        assert np.abs(np.sort_complex(mu1) - np.sort_complex(mu0)).max() <= 1e-9 * np.abs(mu0).max()
    assert scaled.summary["verdict"] == base.summary["verdict"]


def test_dense_and_sparse_are_the_same_numbers():
    s = scene(random_cluster(3, 6, 5))
    dense, sparse = granstab.stiffness(s), granstab.stiffness(s, sparse=True)
    for name in ("H", "Hm", "Hg1", "Hg2", "Hg3"):
        assert np.array_equal(getattr(dense, name), getattr(sparse, name).toarray())


def test_two_dimensional_scene_carries_three_dof_per_particle():
    s = scene(random_cluster(2, 5, 0))
    assert granstab.stiffness(s).H.shape == (15, 15)
    assert s.dofs()[:3] == ["b0.u1", "b0.u2", "b0.th3"]
