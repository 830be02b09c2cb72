"""Grains keep their shapes wherever a scene goes (issue 37): a scan folder's packing.npz, NPZ scenes, the periodic
images beside the cell, and the legend; checked without a browser (test_app_grains.RecordingScene records what
the view sends).

Independent references: the superquadric function, quaternion matrices and polygon distances of test_app_grains
(written out there), LIGGGHTS's atoms.dump read here with numpy (id, x, quaternion, semi-axes, blockiness), the
lattice shifts n @ cell recomputed here from the images' positions. Tolerances: 1e-12 relative to the packing's
extent for positions (float64 sums), 1e-12 for rotation matrices (unit quantities), 1e-9 for points on a surface
(meshes built from cos/sin powers), 1e-12·(1 + r) for outline distances.
"""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from helpers import DATA, ROOT
from test_app_grains import POLYGONS, RecordingScene, matrix, superquadric_F

import granstab
from granstab.cli import main
from granstab.io import load
from granstab.io.scenes import save_scene
from granstab.model.grains import from_loaded
from granstab_app.modes import rotation_matrix
from granstab_app.scanmap import load_scan_map
from granstab_app.scenes import load_model
from granstab_app.state import Session
from granstab_app.text import legend_markdown
from granstab_app.views import SceneView

SQ = DATA / "liggghts_superquadric"
SQ_FILES = [str(SQ / n) for n in ("atoms.dump", "contacts.dump", "in.settle")]
PERIODIC = SQ / "periodic"


def dump_grains(path, frame: int = 0) -> dict:
    """{id: (x (3,), quaternion (4,) w x y z, shape (5,) a b c n1 n2)} of a LIGGGHTS atoms.dump's `frame`-th frame."""
    lines = path.read_text().split("ITEM: TIMESTEP")[1 + frame].splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("ITEM: ATOMS"))
    cols = lines[head].split()[2:]
    rows = np.array([line.split() for line in lines[head + 1:] if line.strip()], float)      # one frame's rows
    col = {name: rows[:, cols.index(name)] for name in cols}
    x = np.column_stack([col["x"], col["y"], col["z"]])
    q = np.column_stack([col[f"quat{k}"] for k in (1, 2, 3, 4)])
    shape = np.column_stack([col[k] for k in ("shapex", "shapey", "shapez", "blockiness1", "blockiness2")])
    return {str(int(i)): (x[j], q[j], shape[j]) for j, i in enumerate(col["id"])}


def drawn_grains(view, names) -> list:
    """Per instanced mesh the view sent: (its vertices, the names of its instances' grains, positions, matrices)."""
    out = []
    for node in (k for k in view.api.sent if k.startswith("/particles/grains/")):
        _, (V, _F), handle = view.api.sent[node]
        group = view.grains[int(node.rsplit("/", 1)[1])]
        out.append((V, [names[b] for b in group.body], np.asarray(handle.batched_positions),
                    matrix(handle.batched_wxyzs)))
    return out


def assert_drawn_as_dumped(view, names, dumped, scale) -> int:
    """Every drawn instance is its grain as LIGGGHTS dumped it: the mesh on that grain's superquadric surface, the
    instance at its dumped centre and orientation. Returns how many grains were drawn."""
    count = 0
    for V, mine, position, R in drawn_grains(view, names):
        for name, x, Ri in zip(mine, position, R):
            x0, q0, shape = dumped[name]
            assert np.allclose(superquadric_F(V, *shape), 1.0, rtol=0, atol=1e-9), name
            assert np.max(np.abs(x - x0)) <= 1e-12 * scale, name
            assert np.max(np.abs(Ri - matrix([q0])[0])) <= 1e-12, name
            count += 1
    return count


@pytest.fixture(scope="module")
def scanned(tmp_path_factory):
    out = tmp_path_factory.mktemp("scan_sq") / "scan"
    assert main(["scan", *SQ_FILES, "--out", str(out), "--centers", "every:40", "--workers", "1"]) == 0
    return out


def test_a_scan_folder_keeps_the_grains_and_its_clusters_are_drawn_as_they_are(scanned):
    """`granstab scan` of a LIGGGHTS superquadric packing keeps each grain's semi-axes, blockiness and orientation in
    packing.npz (grains/… arrays, equal to the dump's); the explorer's map draws them, and the cluster opened from the
    map draws each of its grains with its dumped shape at its dumped centre and orientation (numbers, per grain)."""
    dumped = dump_grains(SQ / "atoms.dump")
    scale = np.abs(np.array([v[0] for v in dumped.values()])).max()
    with np.load(scanned / "packing.npz") as npz:
        names = [str(n) for n in npz["particles/name"]]
        assert str(npz["grains/kind"]) == "superquadric"
        assert np.array_equal(npz["grains/shape"], np.array([dumped[n][2] for n in names]))
        q = np.array([dumped[n][1] for n in names])
        assert np.max(np.abs(matrix(npz["grains/orientation"]) - matrix(q))) <= 1e-12
    s = Session(str(scanned))
    assert s.error is None and s.on_map
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    assert assert_drawn_as_dumped(view, s.scene.names, dumped, scale) == s.scene.n_particles
    centre = s.scene.names[sorted(s.model.members)[1]]
    assert s.open_cluster(centre), s.error
    assert s.model.grains.kind == "superquadric" and not s.on_map
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    assert assert_drawn_as_dumped(view, s.scene.names, dumped, scale) == s.scene.n_particles > 3
    assert not any(k.endswith("/mesh") for k in view.api.sent)              # no sphere stand-ins


def test_a_scan_of_round_grains_keeps_no_shapes(tmp_path):
    """A sphere packing's scan folder has no grains/… arrays: only what a scene needs is kept."""
    out = tmp_path / "scan"
    files = [str(SQ / "spheres" / n) for n in ("atoms.dump", "contacts.dump", "in.settle_spheres")]
    assert main(["scan", *files, "--out", str(out), "--centers", "every:100", "--workers", "1"]) == 0
    with np.load(out / "packing.npz") as npz:
        assert not [k for k in npz.files if k.startswith("grains/")] and "particles/x" in npz.files
    assert load_scan_map(out).grains is None


@pytest.mark.parametrize("inputs", [SQ_FILES, [str(DATA / "io" / "yade_clumps")], [str(p) for p in POLYGONS]],
                         ids=["superquadric", "clump", "rounded_polygon"])
def test_npz_and_json_scenes_keep_the_shapes_exactly(tmp_path, inputs, capsys):
    """`granstab convert … --out scene.npz` (and .json) keeps every grain's shape and orientation: read back, the
    grains equal the import's bit for bit (superquadrics' semi-axes and blockiness, clumps' member spheres, polygons'
    vertices and rounding radius); the explorer opens the NPZ with them."""
    direct = from_loaded(load(inputs))
    for suffix in ("npz", "json"):
        out = tmp_path / f"scene.{suffix}"
        assert main(["convert", *inputs, "--out", str(out)]) == 0
        back = load(out).grains
        assert back.kind == direct.kind and back.dim == direct.dim
        for field in ("orientation", "shape", "body", "offset", "radius"):
            a, b = getattr(back, field), getattr(direct, field)
            assert (a is None and b is None) or np.array_equal(a, b), (suffix, field)
    capsys.readouterr()
    model = load_model(tmp_path / "scene.npz")
    assert model.grains.kind == direct.kind
    assert [b.grain for b in model.bodies({})][:5] == [b.grain for b in load_model(tmp_path / "scene.json").bodies({})][:5]


def test_npz_grains_are_checked_in_one_line(tmp_path):
    """A bad grains/… array is refused in one line naming the file, the array and the particle."""
    loaded = load(SQ_FILES)
    path = tmp_path / "scene.npz"
    save_scene(loaded.scene, path, shapes=from_loaded(loaded))
    arrays = dict(np.load(path))
    name = str(arrays["particles/name"][7])

    def refused(change, match):
        bad = {**arrays, **change}
        np.savez(tmp_path / "bad.npz", **{k: v for k, v in bad.items() if v is not None})
        with pytest.raises(granstab.SceneError, match=match):
            granstab.load_scene(tmp_path / "bad.npz")

    shape = arrays["grains/shape"].copy()
    shape[7, 3] = 1.5
    refused({"grains/shape": shape}, rf"bad.npz: grains/shape\[7\] \(particle '{name}'\): blockiness n1, n2 must be >= 2")
    q = arrays["grains/orientation"].copy()
    q[7] = 0
    refused({"grains/orientation": q}, rf"grains/orientation\[7\] \(particle '{name}'\): must be a finite nonzero")
    refused({"grains/shape": None}, r"bad.npz: grains/shape: missing of a superquadric scene")
    refused({"grains/kind": np.array("clump"), "grains/shape": None},
            r"bad.npz: grains/body: missing of a clump scene")
    refused({"grains/shape": shape[:10]}, r"grains/shape: must be numbers of shape \(250, 5\)")


def test_periodic_images_are_drawn_with_their_grains_shape_and_orientation():
    """A periodic superquadric packing: every image near the cell's faces is its grain's mesh (the grain's shape) at
    x + n @ cell (a lattice shift, n in {-1, 0, 1}³) with the grain's orientation; a mode frame moves each image as
    its grain (x + du, the same rotation dR R), and stopping puts it back."""
    s = Session(str(PERIODIC))
    assert s.error is None and s.scene.cell is not None
    dumped = dump_grains(PERIODIC / "atoms.dump")
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    view.draw_contacts(s)
    view.draw_cell(s)
    nodes = [k for k in view.api.sent if k.startswith("/cell/images/")]
    assert nodes and "/cell/images" not in view.api.sent                   # meshes, no point cloud of disks
    cell = s.scene.cell
    count = 0
    x = {n: x for n, x in zip(s.scene.names, s.scene.x)}
    for node in nodes:
        kind, (V, _F), handle = view.api.sent[node]
        assert kind == "add_batched_meshes_simple"
        group = view.ghosts.groups[int(node.rsplit("/", 1)[1])]
        for g, position, R in zip(group.body, handle.batched_positions, matrix(handle.batched_wxyzs)):
            name = s.scene.names[view.ghosts.images[0][g]]
            n = (position - x[name]) @ np.linalg.inv(cell)                   # the lattice shift, in cells
            assert np.max(np.abs(n - np.round(n))) <= 1e-9 and np.any(np.round(n) != 0) and np.all(np.abs(n) < 1.5)
            assert np.allclose(superquadric_F(V, *dumped[name][2]), 1.0, rtol=0, atol=1e-9)
            assert np.max(np.abs(R - matrix([dumped[name][1]])[0])) <= 1e-12
            count += 1
    assert count == len(view.ghosts.images[0]) > 10
    rng = np.random.default_rng(5)                                          # a rigid motion of every grain, as a
    moved = [replace(b, x=b.x + 0.1 * s.size * rng.normal(size=3),          # mode's frame moves them
                     R=rotation_matrix(3, 0.3 * rng.normal(size=3)) @ b.R) for b in s.bodies()]
    at = {b.name: b for b in moved}
    view.animate(moved)
    handle = view.api.sent[nodes[0]][2]
    group = view.ghosts.groups[0]
    index, shift = view.ghosts.images
    for g, position, R in zip(group.body, handle.batched_positions, matrix(handle.batched_wxyzs)):
        body = at[s.scene.names[index[g]]]
        assert np.max(np.abs(position - (body.x + shift[g]))) <= 1e-12 * np.abs(cell).max()
        assert np.max(np.abs(R - body.R)) <= 1e-12
    view.stop_animation()
    base = {n: b for n, b in zip(s.scene.names, s.bodies())}
    assert np.max(np.abs(handle.batched_positions[0] - (base[s.scene.names[index[group.body[0]]]].x
                                                       + shift[group.body[0]]))) <= 1e-12 * np.abs(cell).max()


def test_periodic_rounded_polygon_images_are_their_outlines(tmp_path):
    """A periodic LAMMPS rounded-polygon packing (an NPZ scene): the images are one filled mesh of outlines, each point
    of an image's outline at its polygon's rounding radius from the polygon shifted by a lattice vector."""
    loaded = load([str(p) for p in POLYGONS])
    path = tmp_path / "polygons.npz"
    save_scene(loaded.scene, path, shapes=from_loaded(loaded))
    s = Session(str(path))
    assert s.error is None and s.model.grains.kind == "rounded_polygon"
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    view.draw_cell(s)
    kind, (V, F), _ = view.api.sent["/cell/images"]
    assert kind == "add_mesh_simple" and F.max() < len(V)
    owner, _ = view.ghosts.rings
    index, shift = view.ghosts.images
    bodies = s.bodies()
    checked = 0
    for g in range(len(index)):
        _, vertices, radius = bodies[index[g]].grain
        polygon = s.scene.x[index[g]] + shift[g] + np.array(vertices)           # body axes = the scene's (2D)
        ring = V[owner == g][1:, :2]                                            # [0] is the fan's centre
        a, b = polygon, np.roll(polygon, -1, axis=0)
        t = np.clip(np.einsum("psd,sd->ps", ring[:, None] - a, b - a) / np.sum((b - a) ** 2, axis=1), 0, 1)
        d = np.linalg.norm(ring[:, None] - (a + t[..., None] * (b - a)), axis=2).min(axis=1)
        assert np.allclose(d, radius, rtol=0, atol=1e-12 * (1 + radius) * np.abs(s.scene.cell).max())
        checked += 1
    assert checked == len(index) > 5


@pytest.mark.parametrize("source, words, not_words", [
    (str(ROOT / "presets" / "superquadric_cluster.json"), "each superquadric as the file gives it", "Dark"),
    (str(DATA / "io" / "yade_clumps"), "each clump as its member spheres", "Dark"),
    ("spheres_tetrahedron", "Dark dot", "stripe"),
    ("two_particle", "Dark stripe", "Grains"),
    (str(PERIODIC), "periodic images", "Dark"),
])
def test_the_legend_says_what_each_grain_kind_is_drawn_as(source, words, not_words):
    """The legend names what the view drew: superquadric meshes, clumps' spheres, a 3D sphere's dot, a 2D stripe,
    the periodic images; never "Dark stripe" for a 3D grain (the old legend said it for every scene)."""
    s = Session(source)
    assert s.error is None, s.error
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    legend = view.draw_contacts(s)
    text = legend_markdown(s.scene, view.options, legend, False, 5000, 400)
    assert words in text and not_words not in text, text


def test_a_rounded_polygon_legend(tmp_path, capsys):
    """A rounded-polygon scene's legend says so (and keeps its 2D body-axis stripe)."""
    out = tmp_path / "polygons.json"
    assert main(["convert", *[str(p) for p in POLYGONS], "--out", str(out)]) == 0
    capsys.readouterr()
    assert json.loads(out.read_text())["particles"][0]["shape"]["kind"] == "rounded_polygon"
    s = Session(str(out))
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    text = legend_markdown(s.scene, view.options, view.draw_contacts(s), False, 5000, 400)
    assert "each rounded polygon as the file gives it" in text and "periodic images" in text


def test_a_tracked_frames_cluster_is_drawn_as_it_is(tmp_path, capsys):
    """`granstab track … --scan` keeps each frame's grains in its scan folder: the frame's map and the cluster opened
    from it draw every scanned grain with its dumped shape, centre and orientation (one frame of the loading run)."""
    D = SQ / "load"
    out = tmp_path / "track"
    assert main(["track", str(D / "atoms.dump"), str(D / "contacts.dump"), str(SQ / "in.settle"), "--scan",
                 "--out", str(out), "--frames", "40000:40000", "--no-figures", "--workers", "1"]) == 0
    capsys.readouterr()
    s = Session(str(out))
    assert s.error is None and s.on_map
    dumped = dump_grains(D / "atoms.dump")
    scale = np.abs(np.array([v[0] for v in dumped.values()])).max()
    view = SceneView(RecordingScene())
    view.draw_particles(s)                                  # the frame's map: every scanned grain as it is
    scanned = len(s.model.scan_map().scene.names)
    assert assert_drawn_as_dumped(view, s.scene.names, dumped, scale) == scanned > 100
    centre = s.model.scan_map().scene.names[17]
    assert s.open_cluster(centre), s.error
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    assert assert_drawn_as_dumped(view, s.scene.names, dumped, scale) == s.scene.n_particles > 3


def test_a_rigidity_folder_keeps_the_grains(tmp_path, capsys):
    """`granstab rigidity … --out DIR` keeps the grains in its packing.npz: the rigidity map and the neighbourhood
    opened from it draw each grain with its dumped shape, centre and orientation."""
    out = tmp_path / "rigidity"
    assert main(["rigidity", *SQ_FILES, "--out", str(out)]) == 0
    capsys.readouterr()
    dumped = dump_grains(SQ / "atoms.dump")
    scale = np.abs(np.array([v[0] for v in dumped.values()])).max()
    s = Session(str(out))
    assert s.error is None and s.on_map
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    assert assert_drawn_as_dumped(view, s.scene.names, dumped, scale) == s.scene.n_particles
    assert s.open_cluster(s.scene.names[30]), s.error
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    assert assert_drawn_as_dumped(view, s.scene.names, dumped, scale) == s.scene.n_particles > 3
