"""The array backend (granstab/solve/device.py) and the BLAS thread policy (granstab/solve/threads.py).

The numpy path runs everywhere; the GPU tests need CuPy and a CUDA device and are skipped with that reason
elsewhere (the only skip in the suite)."""
import subprocess
import sys

import numpy as np
import pytest

import granstab
from granstab.analysis import build_problem
from granstab.mechanics.accuracy import vector_bounds
from granstab.mechanics.branches import enumerate_masks
from granstab.mechanics.rigid import rotation_length
from granstab.mechanics.stiffness import contact_blocks
from granstab.model import packings
from granstab.solve import device as backend
from granstab.solve import threads
from granstab.solve.lowrank import solve_branches_lowrank

GPU = pytest.mark.skipif(not backend.gpu_available(),
                         reason="no CuPy with a CUDA GPU here: the GPU backend is tested where one is present "
                                "(pip install 'granstab[gpu]')")


def known_stack(L=40, n=12, seed=0, spread=1e-8):
    """Symmetric matrices Q diag(λ) Qᵀ with known eigenvalues, some pairs split by only `spread`."""
    rng = np.random.default_rng(seed)
    lam = np.sort(rng.uniform(-1, 1, (L, n)), axis=1)
    lam[:, 1] = lam[:, 0] + spread
    Q, _ = np.linalg.qr(rng.standard_normal((L, n, n)))
    return (Q * lam[:, None, :]) @ np.swapaxes(Q, 1, 2), lam


def test_cpu_eigh_stack_meets_its_own_error_bounds():
    A, lam = known_stack()
    got = backend.eigh_stack(A, "cpu")
    assert got["device"] == "cpu" and got["eps"] == np.finfo(float).eps
    err = np.abs(got["lam"] - lam)
    assert np.all(err <= honest_bounds(A, got))                        # the bound holds per eigenvalue
    assert got["residual"].max() <= 1e-13                              # and it is round-off small (‖A‖ ≤ 1)


def test_chunking_gives_the_same_numbers(monkeypatch):
    A, _ = known_stack(L=50)
    whole = backend.eigh_stack(A, "cpu")
    monkeypatch.setattr(backend, "CHUNK_BYTES", 8 * 12 * 12 * 4 * 7)   # 7 matrices per chunk: 8 chunks
    assert backend.backend("cpu").chunk(8.0 * 12 * 12 * 4, 50) == 7
    parts = backend.eigh_stack(A, "cpu", keep=lambda xp, A, lam, V, start: {"lam": lam, "first": lam[:, :1] * 0 + start})
    assert np.array_equal(parts["lam"], whole["lam"])
    assert sorted(set(parts["first"][:, 0])) == list(range(0, 50, 7))  # keep() saw every chunk's offset


def test_unknown_device_is_an_error():
    with pytest.raises(backend.DeviceError):
        backend.backend("tpu")


def test_auto_picks_the_gpu_exactly_when_cupy_sees_one():
    assert backend.backend("auto").name == ("gpu" if backend.gpu_available() else "cpu")
    assert backend.backend("cpu").xp is np


def test_cli_device_gpu_without_cupy_is_one_line_exit_2():
    cmd = [sys.executable, "-m", "granstab", "analyze", "presets/four_disk.toml", "--device", "gpu", "--json"]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if backend.gpu_available():                                          # then it must simply work
        assert run.returncode == 0
        return
    assert run.returncode == 2
    assert run.stdout == ""
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "CuPy" in lines[0] and "--device" in lines[0]


@pytest.fixture(autouse=True)
def _no_process_cap(monkeypatch):
    """An explorer test earlier in the run may have capped the process's BLAS threads (threads.cap_process): the
    policy tests here start uncapped (they failed only in the full suite, after the app folder)."""
    monkeypatch.setattr(threads, "_process_cap", None)


def test_thread_policy_by_size(monkeypatch):
    monkeypatch.setattr(threads, "runnable", lambda fresh=False: 0.0)               # at rest (busy: tests/solve/test_plan.py)
    assert threads.for_size(48) == 1
    assert threads.for_size(threads.SMALL + 1) == threads.cores() >= 1
    pytest.importorskip("threadpoolctl", reason="threadpoolctl (test extra) applies the policy")
    from threadpoolctl import threadpool_info
    np.linalg.eigh(np.eye(3))                                            # BLAS is loaded
    with threads.sized(10):
        assert all(p["num_threads"] == 1 for p in threadpool_info() if p["user_api"] == "blas")


def test_an_outer_limit_bounds_the_inner_policy(monkeypatch):
    """`with blas_threads(1)` around an analysis keeps its dense solves on one thread (issue 26: the explorer's limit
    was lifted by the core's own `sized(n)` above SMALL dofs, and a busy machine made it 18× slower)."""
    monkeypatch.setattr(threads, "runnable", lambda fresh=False: 0.0)               # at rest
    pytest.importorskip("threadpoolctl", reason="threadpoolctl (test extra) applies the policy")
    from threadpoolctl import threadpool_info
    np.linalg.eigh(np.eye(3))
    big = threads.SMALL + 1
    assert threads.for_size(big) == threads.cores()
    with threads.blas_threads(1):
        assert threads.for_size(big) == 1
        with threads.sized(big):
            assert all(p["num_threads"] == 1 for p in threadpool_info() if p["user_api"] == "blas")
    assert threads.for_size(big) == threads.cores()                     # the bound ends with its block
    try:
        threads.cap_process(1)
        assert threads.for_size(big) == 1
        with threads.blas_threads(4):                                    # a cap bounds explicit limits too
            assert all(p["num_threads"] == 1 for p in threadpool_info() if p["user_api"] == "blas")
    finally:
        threads.cap_process(None)
    assert threads.for_size(big) == threads.cores()


def test_results_do_not_depend_on_blas_threads_above_small(monkeypatch):
    """The rule (docs/design.md, solve/threads.py): above SMALL dofs the full path takes every core, and nothing a
    result reports depends on it. A 150-dof packing with two contacts at the limit (four branches) analysed on one
    BLAS thread and on two (cores() set to 2, so a one-core machine runs two too): the same verdict, counts and
    consistency codes, every eigenvalue within the sum of the two bounds, and each isolated eigenvector (relative
    gap > 1e-6) the same canonical vector to 1e-8 (its perturbation is ~ε‖A‖/gap <= 2e-10): the sign rule
    (branches.column_signs) picks the same entry whatever the thread count's round-off."""
    pytest.importorskip("threadpoolctl", reason="threadpoolctl (test extra) applies the policy")
    scene = packings.random_packing(2, 50, n_sliding=2, seed=3)
    assert scene.n_dof > threads.SMALL
    with threads.blas_threads(1):
        one = granstab.analyze(scene, metric="L", method="dense", attribution=False)
    monkeypatch.setattr(threads, "cores", lambda: 2)
    monkeypatch.setattr(threads, "runnable", lambda fresh=False: 0.0)               # two free cores, whatever the load
    assert threads.for_size(scene.n_dof) == 2
    two = granstab.analyze(scene, metric="L", method="dense", attribution=False)
    for key in ("verdict", "sufficient", "n_branches", "consistent_negative", "consistent_positive", "consistent_zero",
                "reason"):
        assert one.summary[key] == two.summary[key], key
    assert len(one.branches) == len(two.branches) == 4
    for a, b in zip(one.branches, two.branches):
        np.testing.assert_array_equal(a.codes, b.codes)
        lam = a.stability_eigenvalues
        assert np.all(np.abs(lam - b.stability_eigenvalues) <= a.accuracy + b.accuracy)
        scale = np.abs(lam).max()
        gap = np.minimum(np.r_[np.inf, np.diff(lam)], np.r_[np.diff(lam), np.inf])
        isolated = gap > 1e-6 * scale
        assert isolated.sum() > len(lam) // 2
        diff = np.abs(a.stability_vectors[:, isolated] - b.stability_vectors[:, isolated]).max()
        assert diff <= 1e-8, diff


# ------------------------------------------------------------------------------------------------- GPU only

def honest_bounds(A, got):
    """accuracy.py's per-eigenvalue bound from the reported residuals: √2‖r‖ + γ_{n+2}(‖|A|‖∞ + |λ|) (the rounding
    of the residual itself) plus the error of forming Q diag(λ) Qᵀ in floating point, 4nε·max|λ| (‖A‖₂ ≤ 1 here)."""
    n = A.shape[-1]
    scale = np.abs(A).sum(axis=-1).max(axis=-1)[:, None]
    return vector_bounds(got["lam"], got["residual"], scale, 4 * n * np.finfo(float).eps, n)


@GPU
def test_gpu_eigh_stack_agrees_with_cpu_within_the_reported_bounds():
    """On the H100 the Jacobi solver's error (5.6e-15) exceeded its bare residual (5.5e-15): only the honest bound
    (residual, its own rounding and the formation error of the test matrix) holds, on both devices."""
    A, lam = known_stack(L=3000, n=48)
    cpu = backend.eigh_stack(A, "cpu")
    gpu = backend.eigh_stack(A, "gpu")
    assert gpu["device"] == "gpu"
    assert np.all(np.abs(gpu["lam"] - lam) <= honest_bounds(A, gpu))
    assert np.all(np.abs(gpu["lam"] - cpu["lam"]) <= honest_bounds(A, gpu) + honest_bounds(A, cpu))


@GPU
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_gpu_branch_verdicts_equal_cpu(seed):
    scene = packings.random_packing(2, 16, n_sliding=8, mobilised=0.3, seed=seed)
    problem = build_problem(scene, contact_blocks(scene), rotation_length(scene))[0]
    masks = enumerate_masks(problem.sliding, scene.n_contacts)
    cpu, _ = solve_branches_lowrank(problem, masks, device="cpu")
    gpu, info = solve_branches_lowrank(problem, masks, device="gpu")
    assert info["device"] == "gpu"
    for a, b in zip(cpu, gpu):
        assert np.array_equal(a.codes, b.codes)
        assert np.all(np.abs(a.stability_eigenvalues - b.stability_eigenvalues)
                      <= a.accuracy + b.accuracy)


@GPU
@pytest.mark.parametrize("preset", ["four_disk", "two_particle", "spheres_tetrahedron", "gear_packing",
                                    "annulus_frame"])
def test_gpu_preset_verdicts_equal_cpu(preset):
    path = f"presets/{preset}.json" if preset == "annulus_frame" else f"presets/{preset}.toml"
    scene = granstab.load_scene(path)
    a = granstab.analyze(scene, device="cpu")
    b = granstab.analyze(scene, device="gpu")
    for key in ("verdict", "sufficient", "consistent_negative", "consistent_zero", "consistent_positive",
                "type2_nonuniqueness"):
        assert a.summary[key] == b.summary[key]


@GPU
def test_gpu_gram_floor_is_a_proven_and_tight_lower_bound():
    """lowrank.gram_floor on the GPU (Jacobi eigh + its own residual bound) and on the CPU (LAPACK eigvalsh): both
    at most the exact σ_min(H^i N)² (float64 SVD), and within 1e-10·‖G‖ of it."""
    from granstab.solve.lowrank import gram_floor, reduce
    scene = packings.random_packing(2, 16, n_sliding=8, mobilised=0.3, seed=2)
    problem = build_problem(scene, contact_blocks(scene), rotation_length(scene))[0]
    red = reduce(problem)
    on = np.random.default_rng(0).integers(0, 2, (64, len(problem.sliding))).astype(float)
    X = red.HN[None] + problem.A[None] * on[:, None, :] @ red.s.T
    exact = np.linalg.svd(X, compute_uv=False)[:, -1] ** 2
    for device in ("cpu", "gpu"):
        floor, gmax = gram_floor(backend.backend(device), problem.A, red, on)
        assert np.all(floor <= exact)
        assert np.all(exact - floor <= 1e-10 * gmax)
