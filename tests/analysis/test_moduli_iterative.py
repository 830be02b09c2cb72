"""moduli above the dense limit (issue 41): GMRES on H preconditioned by sym(H)'s multifrontal factor (solve/cellsolve.py)
gives SuperLU's moduli within the bound it reports; the bound holds where the solve is stopped early; the chunked
assembly (solve/cellparts.py) gives the one-shot assembly's parts; the energy Hessian's moduli through this path."""
import importlib

import numpy as np
import pytest
from test_periodic import harmonic_moduli, jammed

from granstab.mechanics.cell import cell_parts
from granstab.mechanics.stiffness import assemble_parts, contact_blocks
from granstab.solve import cellsolve
from granstab.solve.cellparts import cell_system
from granstab_bench.periodic_child import periodic_packing

mod = importlib.import_module("granstab.moduli")      # the module (granstab.moduli the attribute is the function)


def both(scene, monkeypatch):
    """The moduli by the default path (GMRES above DENSE_MAX) and by SuperLU (the iterative path switched off)."""
    iterative = mod.moduli(scene)
    monkeypatch.setattr(mod, "ITERATIVE_MIN", 10 ** 9)
    direct = mod.moduli(scene)
    monkeypatch.undo()
    return iterative, direct


@pytest.fixture(scope="module")
def packing():
    scene = periodic_packing(1200, 1)                    # 3,600 dofs: above DENSE_MAX; one contact at yield
    assert scene.n_dof > mod.DENSE_MAX
    return scene


def test_gmres_and_superlu_agree_within_the_reported_bound(packing, monkeypatch):
    it, lu = both(packing, monkeypatch)
    assert it.solve["method"].startswith("GMRES") and lu.solve["method"].startswith("SuperLU")
    assert it.solve["inverse_bound"] > 0 and it.solve["floor"] <= it.solve["estimate"]
    assert lu.errors["moduli_bound"] is None                      # no bound of ‖H⁻¹‖ without sym(H)'s factor
    scale = max(np.abs(b.mandel).max() for b in lu.branches)
    for a, b in zip(it.branches, lu.branches):
        assert a.name == b.name and np.all(np.abs(a.mandel - b.mandel) <= a.bound)
        assert a.bound.max() < 1e-6 * scale                        # and the bound says something
    assert it.verdicts["fixed_cell"]["verdict"] == lu.verdicts["fixed_cell"]["verdict"] == "stable"


def test_the_bound_holds_when_gmres_stops_early(packing, monkeypatch):
    """A loose GMRES tolerance: the moduli move away from SuperLU's by far more than round-off, and the bound (from
    the recomputed residual) still covers the difference."""
    monkeypatch.setattr(cellsolve, "GMRES_TOL", 1e-2)
    rough = mod.moduli(packing)
    monkeypatch.undo()
    monkeypatch.setattr(mod, "ITERATIVE_MIN", 10 ** 9)
    lu = mod.moduli(packing)
    scale = max(np.abs(b.mandel).max() for b in lu.branches)
    for a, b in zip(rough.branches, lu.branches):
        diff = np.abs(a.mandel - b.mandel)
        assert diff.max() > 1e-12 * scale                         # a real error …
        assert np.all(diff <= a.bound)                            # … within the bound


def test_small_packings_report_a_dense_bound_the_iterative_path_respects(monkeypatch):
    """Below DENSE_MAX the bound rests on sym(H)'s dense eigenvalues; forcing the iterative path gives the same
    moduli within both bounds."""
    scene = periodic_packing(300, 1)
    dense = mod.moduli(scene)
    monkeypatch.setattr(mod, "DENSE_MAX", 0)
    monkeypatch.setattr(mod, "ITERATIVE_MIN", 0)
    forced = mod.moduli(scene)
    assert forced.solve["method"].startswith("GMRES") and dense.solve["method"].startswith("SuperLU")
    for a, b in zip(forced.branches, dense.branches):
        assert np.all(np.abs(a.mandel - b.mandel) <= np.minimum(a.bound, b.bound) * 2)
        assert b.bound.max() > 0


@pytest.mark.parametrize("dim, phi", [(2, 0.88), (3, 0.68)])
def test_energy_hessian_moduli_through_the_iterative_path(dim, phi, monkeypatch):
    """Frictionless harmonic packings: the independent energy Hessian's moduli (complex step, tests/mechanics) within
    the reported bound plus the reference's own round-off (1e-12 of max|C|)."""
    scene = jammed(dim, phi)
    monkeypatch.setattr(mod, "DENSE_MAX", 0)
    monkeypatch.setattr(mod, "ITERATIVE_MIN", 0)
    result = mod.moduli(scene)
    reference = harmonic_moduli(scene)
    scale = np.abs(reference).max()
    assert result.solve["method"].startswith("GMRES")
    assert np.all(np.abs(result.mandel - reference) <= result.branches[0].bound + 1e-12 * scale)
    assert result.branches[0].bound.max() < 1e-8 * scale


def test_chunked_assembly_equals_the_one_shot_parts():
    """cell_system over chunks of 100 contacts against stiffness.contact_blocks + cell.cell_parts of all at once."""
    scene = periodic_packing(300, 2)
    system = cell_system(scene, chunk=100)
    assert scene.n_contacts > 300
    blocks = contact_blocks(scene)
    H = assemble_parts(scene, blocks)["H"]
    parts = cell_parts(scene, blocks, system.sliding)
    scale = abs(H).max()
    assert abs(system.H - H).max() <= 1e-14 * scale
    assert np.all(system.H_error.toarray() >= 0) and system.H_error.max() < 1e-12 * scale
    for name in ("Xi", "Xi_left", "B", "A_cell", "S_cell"):
        want = getattr(parts, name)
        assert np.abs(getattr(system.parts, name) - want).max() <= 1e-14 * max(np.abs(want).max(), 1e-300), name
    assert len(system.sliding) == 2 and system.A.shape == (scene.n_dof, 2)


def test_the_preconditioner_is_held_in_float32_only(packing):
    """sym(H)'s factor is kept in float32 once eliminated (half the memory at 10⁶ disks) and solves sym(H) to
    float32's accuracy (1e-4 relative here, cond ~1e3); the count-only elimination keeps no factor at all."""
    import scipy.sparse as sp

    H = cell_system(packing).H
    keep = np.arange(2, packing.n_dof)                          # one particle's translations grounded, as moduli does
    Hk = H[keep][:, keep].tocsr()
    factor = cellsolve.symmetric_factor(packing, Hk, keep)
    assert factor.mf.definite and factor.mf.single
    assert {G.dtype for G, *_ in factor.mf.factors} == {np.dtype(np.float32)}
    b = np.random.default_rng(0).standard_normal((len(keep), 2))
    x = factor.solve(b)
    Hs = 0.5 * (Hk + Hk.T)
    assert np.abs(Hs @ x - b).max() < 1e-4 * np.abs(b).max() and sp.issparse(Hs)
    count = cellsolve.symmetric_factor(packing, Hk, keep, factors=False).mf
    assert count.negative == 0 and count.nnz == 0


def test_the_floor_proven_in_a_forked_process_is_the_serial_one(packing, monkeypatch):
    """From PARALLEL_MIN kept dofs the proof of τ (an inertia count) runs in a forked process beside GMRES: the same
    τ, moduli and bounds as in this process."""
    serial = mod.moduli(packing)
    monkeypatch.setattr(cellsolve, "PARALLEL_MIN", 0)
    forked = mod.moduli(packing)
    assert serial.solve["floor"] == forked.solve["floor"] > 0
    for a, b in zip(serial.branches, forked.branches):
        assert np.array_equal(a.mandel, b.mandel) and np.array_equal(a.bound, b.bound)
