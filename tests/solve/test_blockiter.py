"""The whole packing's block iteration on the backend's device (issue 41, solve/blockiter.py): preconditioned LOBPCG
with the sparse products where the arrays live. On the CPU backend (numpy/scipy) it is checked against the
inertia-verified shift-invert path (sparse.lowest_modes) on both branches of a periodic packing with a contact at
yield: the same 6 lowest eigenvalues to 1e-10 relative, residuals recomputed in float64 with the exact operator. On a
GPU (CuPy) the same against the CPU; without one those tests skip, saying why."""
import numpy as np
import pytest

import granstab
from granstab.mechanics.accuracy import vector_bounds
from granstab.model.packings import random_packing
from granstab.solve import device
from granstab.solve.assembled import sparse_problem
from granstab.solve.blockiter import device_lowest, jacobi_blocks
from granstab.solve.sparse import lowest_modes

GPU = pytest.mark.skipif(not device.gpu_available(), reason="no GPU: CuPy is not installed or sees no CUDA device "
                                                            "(run where one is lent: BENCHMARKS-gpu.md `million`)")
REL = 1e-10     # eigenvalues of LOBPCG (tol 1e-9 ‖Hs‖ on residuals: eigenvalue errors ~ residual²/gap) vs shift-invert


@pytest.fixture(scope="module")
def packing():
    scene = random_packing(2, 300, seed=7, n_sliding=1)
    spb = sparse_problem(scene)
    assert len(spb.sliding) == 1
    mask = np.zeros(scene.n_contacts, np.int8)
    mask[spb.sliding] = 1
    return spb, (None, mask)


def test_cpu_backend_matches_shift_invert_on_both_branches(packing):
    spb, masks = packing
    for mask in masks:
        ref = lowest_modes(spb, 6, mask)
        got = device_lowest(spb, 6, mask, device="cpu")
        assert ref.verified and got.method == "lobpcg-cpu" and not got.verified and got.n_below is None
        assert np.allclose(got.eigenvalues, ref.eigenvalues, rtol=REL, atol=0)
        assert got.info["converged"] and got.residuals.max() < 1e-8
        # within the bounds the sparse path reports for them (accuracy.vector_bounds: residual and its rounding)
        bound = vector_bounds(got.eigenvalues, got.residuals * spb.norm, spb.norm, 0.0, spb.n)
        assert np.all(np.abs(got.eigenvalues - ref.eigenvalues) <= bound)
        overlap = np.abs(np.sum(got.vectors[:, :1] * ref.vectors[:, :1]))        # an isolated lowest mode
        assert overlap > 1 - 1e-8


def test_jacobi_blocks_invert_the_particle_blocks(packing):
    """Each preconditioner block times its particle block of sym(Hm) + τI is the identity (SPD blocks here)."""
    spb, _ = packing
    from granstab.solve.krylov import particle_blocks
    Dinv = jacobi_blocks(spb, tau_rel=1e-6)
    Hm = 0.5 * (spb.Hm + spb.Hm.T)
    blocks = particle_blocks(Hm.tocsr(), spb.scene.dof_per_particle) + 1e-6 * spb.norm * np.eye(3)
    assert np.abs(Dinv @ blocks - np.eye(3)).max() < 1e-8


def test_analyze_on_gpu_without_one_is_one_line(packing):
    if device.gpu_available():
        pytest.skip("a GPU is present: the one-line refusal is for machines without one")
    with pytest.raises(device.DeviceError, match="needs CuPy and a CUDA GPU"):
        granstab.analyze(packing[0].scene, metric="L", device="gpu")


@GPU
def test_gpu_matches_cpu(packing):
    spb, masks = packing
    for mask in masks:
        cpu = device_lowest(spb, 6, mask, device="cpu")
        gpu = device_lowest(spb, 6, mask, device="gpu")
        assert gpu.method == "lobpcg-gpu" and gpu.info["converged"]
        assert np.allclose(gpu.eigenvalues, cpu.eigenvalues, rtol=REL, atol=0)


@GPU
def test_analyze_whole_packing_on_gpu_gives_the_cpu_verdict(packing):
    scene = packing[0].scene
    cpu = granstab.analyze(scene, metric="L", method="sparse")
    gpu = granstab.analyze(scene, metric="L", method="sparse", device="gpu")
    # LOBPCG has no inertia count: a stable CPU verdict is "not determined" on the GPU, saying why (an unstable one,
    # a consistent negative eigenpair found, stays a proof)
    if cpu.summary["verdict"] == "unstable":
        assert gpu.summary["verdict"] == "unstable"
    else:
        assert gpu.summary["verdict"] == "not determined" and "no inertia count" in gpu.summary["reason"]
    for a, b in zip(cpu.branches, gpu.branches):
        assert np.all(np.abs(a.stability_eigenvalues - b.stability_eigenvalues) <= a.bounds + b.bounds)
