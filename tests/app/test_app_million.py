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


class _Counted:
    """A Body whose centre counts its reads (the cloud must form its arrays once, not on every redraw)."""

    reads = 0

    def __init__(self, body):
        self._body, self.name, self.kind, self.axes, self.R, self.grain = body, body.name, body.kind, body.axes, \
            body.R, body.grain

    @property
    def x(self):
        _Counted.reads += 1
        return self._body.x


def test_a_large_maps_cloud_is_its_centres_and_colours_formed_once():
    """A 2D map of 3·MESH_MAX disks drawn as one point cloud: its points are every body's centre in order (z = 0),
    its colours the map's (N, 3) array row for row, its size 1.8 × the median radius; a redraw and a recolouring
    read no centre again (fails on the old code: it walked the bodies on every redraw) and send nothing unchanged."""
    from types import SimpleNamespace

    from granstab_app.scenes import Body
    from granstab_app.views import MESH_MAX, SceneView
    rng = np.random.default_rng(41)
    n = 3 * MESH_MAX
    x, radius = rng.uniform(-50, 50, (n, 2)), rng.uniform(0.5, 1.5, n)
    bodies = [_Counted(Body(f"p{i}", "disk", (r, r), xi, np.eye(2))) for i, (xi, r) in enumerate(zip(x, radius))]
    sent = []

    def add_point_cloud(name, points, colors, point_size, **_):
        sent.append(name)
        return SimpleNamespace(points=points, colors=colors, point_size=point_size)

    api = SimpleNamespace(add_point_cloud=add_point_cloud, remove_by_name=lambda name: None)
    session = SimpleNamespace(bodies=lambda: bodies, scene_dim=2, preset="scan", draggable=False, size=1.0)
    view = SceneView(api)
    _Counted.reads = 0
    view.draw_particles(session)
    cloud = view.cloud
    assert np.array_equal(cloud.points, np.column_stack([x, np.zeros(n)])) and view.drawn == "cloud"
    assert cloud.point_size == 1.8 * np.median(radius)
    colours = rng.integers(0, 256, (n, 3)).astype(np.uint8)
    names = [b.name for b in bodies]
    view.colour_particles(names, colours=colours)
    assert np.array_equal(cloud.colors, colours) and cloud.colors.dtype == np.uint8
    view.draw_particles(session)
    view.colour_particles(names, colours=colours)
    assert _Counted.reads == n and view.cloud is cloud and sent == ["/particles/cloud"]
    shuffled = colours[::-1].copy()
    view.colour_particles(names, colours=shuffled)
    assert np.array_equal(cloud.colors, shuffled)
