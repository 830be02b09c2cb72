"""Property-based tests (hypothesis) over random valid scenes: the exact identities of H hold to round-off, the
sparse path agrees with the dense one, rigid motions of the whole scene change nothing, and no exception escapes.

Scenes come from two independent generators: granstab.model.packings (lattice / random contact networks with forces at
any level, sliding contacts, contact moments, rolling stiffness) and tests/helpers.random_cluster (fully connected
clusters with off-centre normals). Bound for the identities: 1e-12 relative (they hold exactly; measured
≤ 1e-15; 1e-10 for the residual of the non-symmetric ℍ eigenproblem); for eigenvalues: zero_tol = 64·n·eps·‖A‖
(tolerances.py).
"""
import json

import numpy as np
from helpers import random_cluster
from helpers import scene as make_scene
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import granstab
from granstab.mechanics.branches import RIGID, eigen_groups
from granstab.model import packings
from granstab.model.tolerances import DEFAULT
from granstab.solve import sparse

IDENTITIES = ("force_balance", "moment_balance", "rigid_leakage_parts", "rigid_leakage_H_translations",
              "rigid_leakage_modified", "projection_idempotence", "projection_symmetry", "equilibrium_residual",
              "eigen_residual_stability", "eigen_residual_uniqueness")
# derandomized: CI runs the same examples every time (a random draw found the grouping above once; a failing CI on
# a fresh draw would say nothing about the change under test)
SETTINGS = settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


@st.composite
def packing_scenes(draw):
    dim = draw(st.sampled_from([2, 3]))
    kind = draw(st.sampled_from(["lattice", "random"]))
    common = dict(
        f_over_k=draw(st.floats(1e-8, 0.2)),
        curvature_ratio=draw(st.floats(0.3, 3.0)),
        mu=draw(st.floats(0.05, 1.5)),
        alpha=draw(st.floats(1e-4, 2.0)),
        mobilised=draw(st.floats(0.0, 0.99)),
        n_sliding=draw(st.integers(0, 2)),
        moments=draw(st.sampled_from([0.0, 0.3])),
        rolling=draw(st.sampled_from([0.0, 0.02])),
        radius=draw(st.sampled_from([1e-3, 1.0, 50.0])),
        seed=draw(st.integers(0, 2**16)),
    )
    if kind == "lattice":
        size = draw(st.integers(2, 4)) if dim == 2 else 2
        return packings.lattice(dim, size, kind=draw(st.sampled_from(packings.KINDS[dim])), **common)
    n = draw(st.integers(4, 30)) if dim == 2 else draw(st.integers(4, 20))
    return packings.random_packing(dim, n, polydispersity=draw(st.floats(0.0, 0.4)),
                                   jitter=draw(st.floats(0.0, 0.3)), **common)


@st.composite
def cluster_scenes(draw):
    dim = draw(st.sampled_from([2, 3]))
    data = random_cluster(dim, draw(st.integers(2, 5)), seed=draw(st.integers(0, 2**16)),
                          moments=draw(st.booleans()), rolling=draw(st.sampled_from([0.0, 0.05])),
                          scale=draw(st.sampled_from([1e-4, 1.0, 1e4])), f_over_k=draw(st.floats(1e-10, 0.1)))
    return make_scene(data)


def check_identities(res):
    for key in IDENTITIES:
        bound = 1e-12
        if key == "eigen_residual_stability":
            # a vector chosen inside a group of eigenvalues whose accuracy intervals touch (the Appendix-D subspace
            # search, grouped as solve.dense._branch groups them: gaps <= δ_i + δ_i+1, up to 2·zero_tol) has a residual
            # up to the group's width
            width = 0.0
            for b in res.branches:
                lam = b.stability_eigenvalues
                for g in eigen_groups(lam, b.accuracy):
                    width = max(width, (lam[g[-1]] - lam[g[0]]) / max(np.abs(lam).max(), 1e-300))
            bound = 1e-12 + width
        if key == "eigen_residual_uniqueness":
            # ℍ is not normal: LAPACK's geev (with balancing) is backward stable for the balanced matrix, and its
            # residual relative to ‖ℍ‖ reaches ~1e-11 on nearly defective spectra (found by this test)
            bound = 1e-10
        assert res.errors[key] <= bound, (key, res.errors[key])
    json.dumps(res.to_dict())                                        # the --json object serialises


@SETTINGS
@given(packing_scenes())
def test_identities_hold_on_random_packings(s):
    res = granstab.analyze(s, method="dense")
    check_identities(res)
    assert res.summary["verdict"] in ("stable", "neutral", "unstable")
    assert len(res.branches) == 2 ** int(np.sum(s.at_yield()))
    for b in res.branches:
        assert np.sum(b.codes == RIGID) == (3 if s.dim == 2 else 6)


@SETTINGS
@given(cluster_scenes())
def test_identities_hold_on_random_clusters(s):
    check_identities(granstab.analyze(s, method="dense"))


@SETTINGS
@given(packing_scenes(), st.integers(1, 6))
def test_sparse_path_agrees_with_dense(s, k):
    dense = granstab.analyze(s, method="dense")
    spr = granstab.analyze(s, method="sparse", k=k)
    n_rigid = 3 if s.dim == 2 else 6
    for bd, bs in zip(dense.branches, spr.branches):
        assert len(bs.stability_eigenvalues) == min(n_rigid + k, s.n_dof)
        lam_d = np.sort(bd.stability_eigenvalues[bd.codes != RIGID])
        lam_s = bs.stability_eigenvalues[bs.codes != RIGID]
        bound = DEFAULT.zero_tol(np.abs(bd.stability_eigenvalues).max(), s.n_dof)
        assert np.abs(lam_d[:len(lam_s)] - lam_s).max(initial=0.0) <= 4 * bound
    for key in ("force_balance", "moment_balance", "rigid_leakage_parts", "rigid_leakage_modified"):
        assert spr.errors[key] <= 1e-12
    if dense.summary["verdict"] == "unstable" or spr.summary["verdict"] == "unstable":
        # the lowest eigenpair decides instability on the elastic branch of both paths alike
        assert dense.summary["verdict"] == spr.summary["verdict"] or len(dense.branches) > 1


@SETTINGS
@given(packing_scenes(), st.floats(-np.pi, np.pi), st.floats(-100, 100))
def test_a_rigid_motion_of_the_whole_scene_changes_no_eigenvalue(s, angle, shift):
    """Rotate and translate every position, point, normal, force and curvature: the spectra are the same."""
    d = s.dim
    if d == 2:
        Q = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    else:
        axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14)
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        Q = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    arrays = {name: getattr(s, name) for name in ("p", "q", "k", "alpha", "mu", "rolling", "state")}
    arrays.update(point=s.point @ Q.T + shift, normal=s.normal @ Q.T, force=s.force @ Q.T,
                  curvature_p=Q @ s.curvature_p @ Q.T, curvature_q=Q @ s.curvature_q @ Q.T,
                  moment=s.moment @ Q.T if d == 3 else s.moment)
    s2 = granstab.build_scene(d, s.names, s.x @ Q.T + shift, arrays)
    a, b = granstab.analyze(s), granstab.analyze(s2)
    # a translation t rounds every coordinate to eps·|t|: relative to the smallest contact radius r that is an
    # input perturbation of eps·|t|/r, which the eigenvalues inherit (H is linear in the radii)
    r_min = np.linalg.norm(s.r_pq, axis=1).min()
    input_rel = 64 * np.finfo(float).eps * (1 + abs(shift) / r_min)
    assert a.summary["verdict"] == b.summary["verdict"] or a.summary["zero_margin"] < 1e3
    for ba, bb in zip(a.branches, b.branches):
        norm = np.abs(ba.stability_eigenvalues).max()
        bound = 4 * DEFAULT.zero_tol(norm, s.n_dof) + input_rel * norm
        assert np.abs(ba.stability_eigenvalues - bb.stability_eigenvalues).max() <= bound


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_no_exception_escapes_from_the_sparse_solver(data):
    """Any valid small scene (including a single contact, sharp or flat contacts, huge or tiny forces): the sparse
    solver returns finite eigenpairs with small residuals or raises nothing."""
    s = data.draw(packing_scenes())
    k = data.draw(st.integers(1, 8))
    method = data.draw(st.sampled_from(["auto", "shift-invert", "lobpcg"]))
    modes = sparse.lowest_modes(s, k=k, method=method)
    assert np.all(np.isfinite(modes.eigenvalues))
    # residuals ‖Bv - λv‖/‖Hs‖: shift-invert converges the Ritz values of (B - σ)⁻¹ to machine precision, the
    # residual in B then carries the LU's backward error times |λ - σ|/‖Hs‖ (≤ 1): bounded by 1e-10 with margin
    # (seen up to 4e-12); LOBPCG stops at its residual tolerance 1e-8 ‖Hs‖.
    assert modes.residuals.max(initial=0.0) <= (1e-10 if modes.method != "lobpcg" else 1e-7)
