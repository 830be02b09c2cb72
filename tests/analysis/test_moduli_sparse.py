"""moduli's fixed-cell check beyond the dense limit (issue 38: it said "not computed" above 3,000 dofs): the inertia
of sym(H) by sparse block elimination gives the dense check's verdict and its count of negative eigenvalues; and
moduli takes the import options (--timestep)."""
import dataclasses
import importlib

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

from granstab.model.packings import jammed

mod = importlib.import_module("granstab.moduli")      # the module (granstab.moduli the attribute is the function)


def dense_and_sparse(scene, monkeypatch):
    """The fixed-cell check dense and sparse, and the solver (its kept dofs' H) they read."""
    solvers = []
    real = mod._factor

    def keep(*args):
        solvers.append(real(*args))
        return solvers[-1]

    monkeypatch.setattr(mod, "_factor", keep)
    dense = mod.moduli(scene).verdicts["fixed_cell"]
    monkeypatch.setattr(mod, "DENSE_MAX", 0)                 # every packing takes the sparse check
    sparse = mod.moduli(scene).verdicts["fixed_cell"]
    monkeypatch.undo()
    return dense, sparse, solvers[-1]


@pytest.mark.parametrize("dim,n", [(2, 60), (3, 40)])
def test_the_sparse_fixed_cell_check_agrees_with_the_dense_one(dim, n, monkeypatch):
    scene = jammed(dim, n, seed=1)
    dense, sparse, _ = dense_and_sparse(scene, monkeypatch)
    assert dense["verdict"] == sparse["verdict"] == "stable" and sparse["negative_count"] == 0
    # forces × 40 (loads with them: still in equilibrium): the geometric stiffness makes sym(H) indefinite
    strong = dataclasses.replace(scene, force=40 * scene.force, load=40 * scene.load,
                                 load_moment=40 * scene.load_moment)
    dense, sparse, solver = dense_and_sparse(strong, monkeypatch)
    assert dense["verdict"] == sparse["verdict"] == "unstable"
    # the count: the dense eigenvalues of sym(H) on the kept dofs below the dense tolerance
    H = solver.H.toarray()
    lam = np.linalg.eigvalsh(0.5 * (H + H.T))
    assert sparse["negative_count"] == int(np.sum(lam < -dense["tolerance"])) > 0
    assert "not computed" not in str(sparse)


@pytest.mark.dem
def test_moduli_reads_the_timestep_asked_for(tmp_path, capsys):
    """moduli had no --timestep (nor any import option): a LAMMPS periodic run's frame 7000 (tilt 0), not the one read by default."""
    import json
    import subprocess

    from granstab.cli import main
    from granstab.io import load
    shear = ROOT / "examples" / "dem" / "in.shear2d_periodic"
    subprocess.run(["lmp", "-in", str(shear), "-log", "none", "-screen", "none"], cwd=tmp_path, check=True,
                   timeout=120)
    files = [tmp_path / "atoms_shear2d.dump", tmp_path / "contacts_shear2d.dump", shear]
    assert main(["moduli", *map(str, files), "--timestep", "7000", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    want = mod.moduli(load(files, timestep=7000).scene)
    first = mod.moduli(load(files).scene)
    assert got["pressure"] == pytest.approx(want.pressure, rel=1e-12)
    assert abs(first.pressure - want.pressure) > 1e-6 * abs(want.pressure)     # another frame: the test can fail
