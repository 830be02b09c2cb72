"""A measured photoelastic packing (143 disks, 240 contacts; RigidLibrary annulus, experiment 10, frame 1)."""
import json

import numpy as np
from helpers import ROOT  # noqa: E402

import granstab

PRESET = ROOT / "presets" / "annulus_frame.json"


def test_annulus_frame_analyses_cleanly():
    scene = granstab.load_scene(PRESET)
    assert (scene.n_particles, scene.n_contacts, scene.dim) == (143, 240, 2)
    result = granstab.analyze(scene)
    d = result.to_dict()
    assert d["n_sliding"] == 0 and len(d["branches"]) == 1           # no contact at yield: one branch
    (branch,) = result.branches
    assert branch.n_zero == 3 and branch.uniqueness_n_zero == 3       # two translations and a rotation
    assert len(d["branches"][0]["stability_eigenvalues"]) == 3 * 143
    for name, value in d["errors"].items():
        assert value <= 1e-12, name                                   # identities and residuals at round-off
    assert d["errors"]["equilibrium_residual"] == 0.0                 # loads follow from the measured forces
    assert all(t > 0 for t in d["timings"].values()) and d["timings"]["total"] >= d["timings"]["branches"]
    # the measured forces do not balance: the derived loads are not zero, and they are what Hg3 uses
    assert np.abs(scene.load).max() > 0.1 * np.abs(scene.force).max()


def test_annulus_round_trips_through_the_scene_format(tmp_path):
    scene = granstab.load_scene(PRESET)
    path = tmp_path / "again.json"
    path.write_text(json.dumps(granstab.scene_to_dict(scene)))
    again = granstab.load_scene(path)
    H0, H1 = granstab.stiffness(scene).H, granstab.stiffness(again).H
    assert np.abs(H0 - H1).max() <= 1e-14 * np.abs(H0).max()
