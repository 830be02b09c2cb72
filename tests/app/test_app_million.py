"""A scan map's bodies built once (issue 41: a 10⁶-particle map asked for its one-Body-a-particle list on every
redraw, for the particle size and on each click; 0.74 s of CPU a build at 10⁵ particles)."""
import json

import numpy as np

import granstab
from granstab.scan import scan
from granstab_app.scanmap import load_scan_map
from granstab_app.scenes import ContactModel


def test_a_scan_maps_bodies_are_built_once(tmp_path):
    """The second call returns the same list (no rebuild: fails on the old code, which built a new one each call),
    equal body for body to a fresh build of the folder's packing (names, kinds, radii, positions exactly)."""
    from test_scan import planted_lattice
    scene, _ = planted_lattice(12, 0.4)
    packing = tmp_path / "lattice.json"
    packing.write_text(json.dumps(granstab.scene_to_dict(scene)))
    scan(granstab.load_scene(packing), tmp_path / "scan", boundary="loads", workers=1, figures=False)
    model = load_scan_map(tmp_path / "scan")
    first = model.bodies({})
    assert model.bodies({}) is first
    fresh = ContactModel(model.scene).bodies({})
    assert [(b.name, b.kind, b.axes) for b in first] == [(b.name, b.kind, b.axes) for b in fresh]
    assert all(np.array_equal(a.x, b.x) for a, b in zip(first, fresh)) and len(first) == scene.n_particles
