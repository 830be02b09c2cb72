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
