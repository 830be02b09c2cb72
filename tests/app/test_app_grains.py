"""The explorer draws grains as they are (issue 37), checked without a browser: what the view sends (a recording
stand-in for viser's scene API) against the scene file's and the engines' own data.

Independent references: the superquadric's implicit function written out here (LIGGGHTS's convention), the scene
file's quaternions turned into matrices here, YADE's members.csv read here with numpy, the distance of a point to a
polygon computed here segment by segment, and the rigid-motion formula x + a s du, R(a s dθ) R0 composed here.
Tolerances: 1e-9 relative to the grain size for points (meshes are built in float64 from cos/sin powers),
1e-12 for rotation matrices (unit quantities).
"""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

import granstab
from granstab.cli import main
from granstab.io import load
from granstab.model.grains import from_loaded, from_particles
from granstab_app.meshes import body_mesh, grain_instances
from granstab_app.modes import mode_offsets, rotation_matrix
from granstab_app.scenes import ContactModel, load_model
from granstab_app.state import Session
from granstab_app.views import SceneView

REPO = ROOT
PRESET = REPO / "presets" / "superquadric_cluster.json"
SQ = REPO / "tests" / "data" / "liggghts_superquadric"
IO = REPO / "tests" / "data" / "io"
POLYGONS = [IO / "lammps_polygons" / "atoms.dump", IO / "lammps_polygons" / "vertices.dump",
            REPO / "examples" / "lammps_body" / "data.polygons", REPO / "examples" / "lammps_body" / "in.polygons2d"]


class RecordingScene:
    """A stand-in for viser's scene API: each node's arguments and a handle whose properties the view writes."""

    def __init__(self):
        self.sent = {}

    def remove_by_name(self, name):
        self.sent = {k: v for k, v in self.sent.items() if not (k == name or k.startswith(name + "/"))}

    def __getattr__(self, name):
        def add(node, *args, **kwargs):
            handle = SimpleNamespace(on_click=lambda fn: None, on_update=lambda fn: None, visible=True, **kwargs)
            self.sent[node] = (name, args, handle)
            return handle
        return add


def matrix(q):
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) (w, x, y, z), written out here."""
    q = np.asarray(q, float) / np.linalg.norm(q, axis=1)[:, None]
    w, x, y, z = q.T
    return np.stack([np.stack([w*w + x*x - y*y - z*z, 2*(x*y - w*z), 2*(x*z + w*y)], -1),
                     np.stack([2*(x*y + w*z), w*w - x*x + y*y - z*z, 2*(y*z - w*x)], -1),
                     np.stack([2*(x*z - w*y), 2*(y*z + w*x), w*w - x*x - y*y + z*z], -1)], 1)


def superquadric_F(y, a, b, c, n1, n2):
    """LIGGGHTS's superquadric function (|y1/a|^n2 + |y2/b|^n2)^(n1/n2) + |y3/c|^n1 (1 on the surface)."""
    return (np.abs(y[:, 0] / a) ** n2 + np.abs(y[:, 1] / b) ** n2) ** (n1 / n2) + np.abs(y[:, 2] / c) ** n1


@pytest.fixture(scope="module")
def cluster():
    s = Session(str(PRESET))
    assert s.error is None, s.error
    return s


def test_superquadric_preset_is_one_instanced_mesh_per_shape_on_the_grains_poses(cluster):
    """The preset opens with its true shapes: one batched mesh per distinct (a, b, c, n1, n2) of the file, its
    vertices on the superquadric surface, one instance per grain at the file's centre and quaternion; every contact
    point lies inside both drawn grains (LIGGGHTS's contactPoint: inside both, on neither surface), which a wrong
    quaternion order or pose would break."""
    data = json.loads(PRESET.read_text())
    distinct = {tuple(p["shape"][k] for k in ("a", "b", "c", "n1", "n2")) for p in data["particles"]}
    assert cluster.analysis.summary["verdict"] == "unstable"
    attribution = granstab.analyze(cluster.scene).attribution          # why: the curvature term (Hg2) decides
    assert attribution.mechanism == "geometric"
    parts = attribution.to_dict()["work_parts"]
    assert min(parts, key=parts.get) == "Hg2" and parts["Hg2"] < 0
    view = SceneView(RecordingScene())
    view.draw_particles(cluster)
    grains = {k: v for k, v in view.api.sent.items() if k.startswith("/particles/grains/")}
    assert len(grains) == len(distinct) >= 1
    assert not any(k.endswith("/mesh") for k in view.api.sent)                 # no per-particle meshes
    x = np.array([p["x"] for p in data["particles"]])
    R = matrix([p["orientation"] for p in data["particles"]])
    shape = np.array([[p["shape"][k] for k in ("a", "b", "c", "n1", "n2")] for p in data["particles"]])
    for kind, (V, F), handle in grains.values():
        assert kind == "add_batched_meshes_simple"
        key = next(s for s in distinct if np.allclose(superquadric_F(V, *s), 1.0, rtol=0, atol=1e-9))
        mine = np.flatnonzero((shape == key).all(axis=1))
        assert np.max(np.abs(handle.batched_positions - x[mine])) <= 1e-12 * np.abs(x).max()
        assert np.max(np.abs(matrix(handle.batched_wxyzs) - R[mine])) <= 1e-12
        assert F.max() < len(V) and F.shape[1] == 3
    scene = cluster.scene
    for side, index in (("p", scene.p), ("q", scene.q)):
        y = np.einsum("mji,mj->mi", R[index], scene.point - x[index])                 # body axes
        assert np.all(superquadric_F(y, *shape[index].T) < 1.0), side                  # inside the drawn grain


def test_mode_frames_move_every_grain_rigidly(cluster):
    """Playing a mode: each instance goes to x + a s du, R(a s dθ) R0 (the rest pose composed with the mode's rigid
    motion at amplitude a, s = sin(phase)), with du, dθ the analysis' motion scaled as the explorer scales it; the
    contact drawings hide while it plays, and stopping returns every instance to its rest pose."""
    view = SceneView(RecordingScene())
    view.draw_particles(cluster)
    view.draw_contacts(cluster)
    node = view.api.sent["/particles/grains/0"][2]
    rest_x, rest_q = np.array(node.batched_positions), np.array(node.batched_wxyzs)
    mode = min((m for m in cluster.modes() if m.consistent), key=lambda m: m.eigenvalue)
    a, phase = 0.3, 1.1
    view.animate(cluster.mode_bodies(mode, a, phase))
    b = cluster.analysis.branches[mode.branch]
    du, dth = mode_offsets(cluster.scene, cluster.analysis.motion(b.stability_vectors[:, mode.index]), cluster.size)
    s = np.sin(phase)
    expect_x = cluster.scene.x + a * s * du
    expect_R = np.array([rotation_matrix(3, a * s * d) @ R0 for d, R0 in zip(dth, matrix(rest_q))])
    assert np.max(np.abs(node.batched_positions - expect_x)) <= 1e-12 * np.abs(expect_x).max()
    assert np.max(np.abs(matrix(node.batched_wxyzs) - expect_R)) <= 1e-12
    assert np.max(np.abs(node.batched_positions - rest_x)) > 0.05 * cluster.size          # it did move
    assert view.contacts_frame.visible is False
    view.stop_animation()
    assert np.array_equal(node.batched_positions, rest_x)
    assert np.max(np.abs(matrix(node.batched_wxyzs) - matrix(rest_q))) <= 1e-12
    assert view.contacts_frame.visible is True


def test_colours_by_mode_reach_every_instance(cluster):
    """Colouring by a mode's share colours each grain's instance by its particle's share (white → dark red)."""
    view = SceneView(RecordingScene())
    view.draw_particles(cluster)
    names = [b.name for b in cluster.bodies()]
    colours = np.arange(3 * len(names)).reshape(-1, 3) % 256
    view.colour_particles(names, colours=colours)
    assert np.array_equal(view.api.sent["/particles/grains/0"][2].batched_colors, colours)


def test_clump_instances_are_the_engines_member_spheres():
    """A YADE clump packing opens drawn as its member spheres: one unit-sphere mesh instanced at every member's
    centre (members.csv) with its radius as the scale; a rigid motion of the bodies moves their spheres with them
    (distances within a clump kept, centres of mass at x + du)."""
    model = load_model(IO / "yade_clumps")
    bodies = model.bodies(model.initial_params())
    assert {b.kind for b in bodies} == {"clump"}
    groups = grain_instances(bodies)
    assert len(groups) == 1 and groups[0].key == ("sphere",)
    sphere = groups[0]
    assert np.allclose(np.linalg.norm(sphere.vertices, axis=1), 1.0, rtol=0, atol=1e-12)
    members = np.genfromtxt(IO / "yade_clumps" / "members.csv", delimiter=",", names=True)
    kept = np.isin(members["body"].astype(int).astype(str), model.scene.names)
    x = np.array([b.x for b in bodies])
    R = np.array([b.R for b in bodies])
    position, _ = sphere.poses(x, R)
    engine = np.column_stack([members["x"], members["y"], members["z"], members["radius"]])[kept]
    drawn = np.column_stack([position, sphere.scale])
    assert len(drawn) == len(engine)
    order = lambda a: a[np.lexsort(a.T[::-1])]                       # noqa: E731
    assert np.max(np.abs(order(drawn) - order(engine))) <= 1e-12 * np.abs(engine).max()
    rng = np.random.default_rng(3)
    du, dth = 0.01 * rng.normal(size=x.shape), 0.2 * rng.normal(size=x.shape)
    dR = np.array([rotation_matrix(3, d) for d in dth])
    moved, _ = sphere.poses(x + du, dR @ R)
    expect = (x + du)[sphere.body] + np.einsum("kij,kj->ki", dR[sphere.body], position - x[sphere.body])
    assert np.max(np.abs(moved - expect)) <= 1e-12 * np.abs(x).max()


def test_rounded_polygons_are_drawn_by_their_rounded_outline():
    """A LAMMPS rounded-polygon packing opens drawn as its bodies: each outline point lies at the rounding radius
    from its polygon (distance to the sides, computed here), the mesh's top face is that outline, and every contact
    point of a body lies inside its outline (within the rounding radius of the polygon); a mode's grey rest ghost is
    the same outline."""
    loaded = load([str(p) for p in POLYGONS])
    grains = from_loaded(loaded)
    assert grains.kind == "rounded_polygon"
    model = ContactModel(loaded.scene, grains=grains)
    bodies = model.bodies(model.initial_params())
    scene = loaded.scene

    def distance(points, polygon):
        a, b = polygon, np.roll(polygon, -1, axis=0)
        t = np.clip(np.einsum("psd,sd->ps", points[:, None] - a, b - a) / np.sum((b - a) ** 2, axis=1), 0, 1)
        foot = a + t[..., None] * (b - a)
        return np.linalg.norm(points[:, None] - foot, axis=2).min(axis=1)

    for i, body in enumerate(bodies[:12]):
        _, vertices, radius = body.grain
        V, _ = body_mesh(body, 0.1, 1.0)
        n = (len(V) - 2) // 4
        ring = V[:n, :2]
        assert np.allclose(distance(ring, np.array(vertices)), radius, rtol=0, atol=1e-12 * (1 + radius))
        for index, arm in ((scene.p, scene.r_pq), (scene.q, scene.r_qp)):          # arms (periodic: to q's copy)
            mine = arm[index == i]
            assert np.all(distance(mine, np.array(vertices)) <= radius * (1 + 1e-9))
    view = SceneView(RecordingScene())
    view.show_rest(bodies, bodies, 1.0)                       # a mode's rest ghost: the same outlines, grey
    segments = view.api.sent["/rest/outline"][1][0]
    _, vertices, radius = bodies[0].grain
    first = segments[:len(vertices) * 8, 0, :2] - bodies[0].x    # 8 points a corner (rounded_polygon's default)
    assert np.allclose(distance(first, np.array(vertices)), radius, rtol=0, atol=1e-12 * (1 + radius))


def test_scene_files_keep_the_shapes_and_refuse_bad_ones(tmp_path, capsys):
    """convert writes each grain's shape (and orientation) into the scene JSON; reading it back gives the same
    grains as the import; a bad entry is one line naming the file, the particle and the field."""
    out = tmp_path / "clumps.json"
    assert main(["convert", str(IO / "yade_clumps"), "--out", str(out)]) == 0
    capsys.readouterr()
    data = json.loads(out.read_text())
    back = from_particles(data["particles"], 3, str(out))
    direct = from_loaded(load(IO / "yade_clumps"))
    assert back.kind == direct.kind == "clump"
    assert np.array_equal(back.body, direct.body) and np.array_equal(back.radius, direct.radius)
    assert np.max(np.abs(back.offset - direct.offset)) == 0
    granstab.load_scene(out)                                             # the core reads it
    bad = json.loads(PRESET.read_text())
    bad["particles"][2]["shape"]["n1"] = 1.5
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    name = bad["particles"][2]["name"]
    with pytest.raises(granstab.SceneError, match=rf"bad.json: particles\[2\] \('{name}'\): shape: blockiness"):
        granstab.load_scene(path)
    del bad["particles"][2]["shape"]
    path.write_text(json.dumps(bad))
    with pytest.raises(granstab.SceneError, match=r"particles\[2\].*: shape: missing"):
        granstab.load_scene(path)
    for particle in bad["particles"]:
        particle.pop("shape", None)
    path.write_text(json.dumps(bad))
    with pytest.raises(granstab.SceneError, match=r"particles\[0\].*: orientation: given without a shape"):
        granstab.load_scene(path)


def test_superquadric_semi_axes_follow_the_length_scale():
    """--length-scale scales the grains with the positions (a grain drawn at 1000× its size was the old defect)."""
    paths = [str(SQ / n) for n in ("atoms.dump", "contacts.dump", "in.settle")]
    base, scaled = load(paths), load(paths, length_scale=1000.0)
    assert np.allclose(scaled.shape[:, :3], 1000.0 * base.shape[:, :3], rtol=1e-15, atol=0)
    assert np.array_equal(scaled.shape[:, 3:], base.shape[:, 3:])


def test_disk_scenes_keep_their_per_particle_meshes():
    """A disk or sphere scene draws as before: per-particle meshes, no instanced grains."""
    s = Session("spheres_tetrahedron")
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    assert all(b.grain == () for b in s.bodies())
    assert not any(k.startswith("/particles/grains") for k in view.api.sent)
    assert sum(k.endswith("/body/mesh") for k in view.api.sent) == s.scene.n_particles
