"""Moduli of a periodic superquadric packing (issue 37: "moduli (periodic superquadrics if LIGGGHTS can make them)").
LIGGGHTS 3.8 with superquadrics runs fully periodic boxes and fix deform: examples/liggghts_superquadric/in.periodic
compresses 40 blocky, elongated grains (3 × 2 × 1.5 mm, n = 4) without gravity to a 15.5 mm cell and holds them
until at rest (kinetic energy ~3e-12 J); its dumps are tests/data/liggghts_superquadric/periodic. The scene is
periodic (seam contacts kept with their images), every grain balances, and `granstab moduli` gives a stress equal to
the virial of the dumped forces and branch vectors computed here from the raw dumps (minimum images)."""
import json

import numpy as np
from helpers import DATA  # noqa: E402

import granstab
import granstab.io
from granstab.cli import main

D = DATA / "liggghts_superquadric" / "periodic"
L = 0.0155                                       # the cell's side (in.periodic's fix deform)


def raw_virial() -> np.ndarray:
    """σ = (1/V) Σ f^{12} ⊗ (x_2 − x_1) (tension positive), x_2 the minimum image, from the dumps' rows."""
    atoms = np.loadtxt(D / "atoms.dump", skiprows=9)
    contacts = np.loadtxt(D / "contacts.dump", skiprows=9, ndmin=2)
    x = {int(r[0]): r[2:5] for r in atoms}
    branch = np.array([x[int(b)] - x[int(a)] for a, b in contacts[:, :2]])
    branch -= L * np.round(branch / L)
    return np.einsum("ci,cj->ij", contacts[:, 3:6], branch) / L**3


def test_liggghts_makes_periodic_superquadrics_and_moduli_reads_them(capsys):
    loaded = granstab.io.load(D)
    scene, report = loaded.scene, loaded.report
    assert scene.periodic and scene.n_contacts == 128 and scene.n_particles == 40
    np.testing.assert_allclose(scene.cell, np.eye(3) * L, rtol=1e-12)
    # at rest without gravity: per grain |Σf| / Σ|f| median 3.8e-6 (measured), 1e-4 allowed
    assert report["imbalance"]["force"]["median"] <= 1e-4 and report["imbalance"]["moment"]["median"] <= 1e-4
    sigma = raw_virial()
    m = granstab.moduli(scene)
    # 6 of the 128 forces are projected onto the cone (by ≤ 2.7 % of their size): ≤ 5e-3 of |σ| allowed
    assert np.abs(m.stress - sigma).max() <= 5e-3 * np.abs(sigma).max()
    assert np.trace(sigma) < 0 and m.bulk > 0 and m.shear > 0
    assert m.zero_modes["translations"] == 3 and m.zero_modes["mechanisms"] == 0
    assert m.errors["residual"] <= 1e-12
    assert main(["moduli", str(D), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert abs(out["bulk"] - m.bulk) <= 1e-9 * m.bulk
