"""LIGGGHTS superquadrics: the reader's conventions on the engine's own run, the stored curvature against an
independent evaluation, and the packing through convert, extract + analyze, scan and export.

Data: tests/data/liggghts_superquadric/, made by examples/liggghts_superquadric (LIGGGHTS 3.8.0 built with
superquadrics by build.sh; in.settle: 250 grains, semi-axes 3 × 2 × 1.5 mm, n1 = n2 = 4, settled under gravity in a
box; in.rotated: one grain turned by `set ... quat 0 0 1 90`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import DATA  # noqa: E402
from test_surface import mp_truth

import granstab
from granstab.cli import main
from granstab.model import surface
from granstab.model.errors import SceneError
from granstab.model.vec import quaternion_matrix

DATA = DATA / "liggghts_superquadric"
FILES = [DATA / "atoms.dump", DATA / "contacts.dump", DATA / "in.settle"]


@pytest.fixture(scope="module")
def loaded():
    return granstab.io.load(FILES)


def atoms_table():
    lines = (DATA / "atoms.dump").read_text().splitlines()
    names = lines[8].split()[2:]
    return dict(zip(names, np.loadtxt(lines[9:], ndmin=2).T))


def contacts_table():
    """The local dump's 15 columns (compute pg all pair/gran/local id force force_normal force_tangential
    contactPoint): id1 id2 periodic-flag, force, force_normal, force_tangential, contactPoint."""
    lines = (DATA / "contacts.dump").read_text().splitlines()
    return np.loadtxt(lines[9:], ndmin=2)


def test_the_packing_is_what_the_issue_asks(loaded):
    a = atoms_table()
    axes = np.stack([a["shapex"], a["shapey"], a["shapez"]], axis=1)
    assert len(a["id"]) >= 200
    assert np.all(axes.max(axis=1) / axes.min(axis=1) >= 1.5)
    assert np.all(np.minimum(a["blockiness1"], a["blockiness2"]) >= 3)
    assert loaded.report["format"] == "liggghts-superquadric"
    assert loaded.report["contacts"]["in_file"] == len(contacts_table())     # every contact kept
    assert loaded.scene.n_contacts == len(contacts_table())


def test_quaternion_order_is_w_x_y_z():
    """in.rotated: `set atom 1 quat 0 0 1 90` (axis z, 90°) dumps quat1..4 = (cos 45°, 0, 0, sin 45°)."""
    lines = (DATA / "rotated.dump").read_text().splitlines()
    row = dict(zip(lines[8].split()[2:], map(float, lines[9].split())))
    q = np.array([row["quat1"], row["quat2"], row["quat3"], row["quat4"]])
    assert np.allclose(q, [np.sqrt(0.5), 0, 0, np.sqrt(0.5)], rtol=0, atol=1e-6)
    R = quaternion_matrix(q[None])[0]
    assert np.allclose(R @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-6)     # body x (the long axis) turned onto world y


def test_contact_points_lie_inside_both_grains_on_neither_surface(loaded):
    """With (w, x, y, z) every dumped contact point is inside both grains, at a depth above zero and below 2 % of the
    grain; read as the conjugate rotation (the wrong order's typical effect) most fall outside."""
    depth = loaded.report["geometry"]["depth_over_size"]
    assert 0 < depth["max"] <= 0.02
    c = contacts_table()
    a = atoms_table()
    index = {int(i): k for k, i in enumerate(a["id"])}
    p = np.array([index[int(i)] for i in c[:, 0]])
    quat = np.stack([a["quat1"], a["quat2"], a["quat3"], a["quat4"]], axis=1)
    axes = np.stack([a["shapex"], a["shapey"], a["shapez"]], axis=1)
    x = np.stack([a["x"], a["y"], a["z"]], axis=1)
    blk = np.stack([a["blockiness1"], a["blockiness2"]], axis=1)
    for conj, inside in ((False, True), (True, False)):
        R = quaternion_matrix(quat[p] * ([1, -1, -1, -1] if conj else 1))
        _, _, dist = surface.foot_points(np.einsum("mji,mj->mi", R, c[:, 12:15] - x[p]), axes[p], blk[p])
        if inside:
            assert np.all(dist < 0) and np.all(-dist > 1e-9 * axes.max())
        else:
            assert np.mean(dist > 0) > 0.3


def test_force_normal_is_along_the_centre_line_not_the_surface_normal(loaded):
    c = contacts_table()
    a = atoms_table()
    index = {int(i): k for k, i in enumerate(a["id"])}
    x = np.stack([a["x"], a["y"], a["z"]], axis=1)
    p = np.array([index[int(i)] for i in c[:, 0]])
    q = np.array([index[int(i)] for i in c[:, 1]])
    line = x[q] - x[p]
    line /= np.linalg.norm(line, axis=1)[:, None]
    fn, force = c[:, 6:9], c[:, 3:6]
    big = np.linalg.norm(fn, axis=1) > 1e-6 * np.linalg.norm(force, axis=1).max()
    assert np.abs(np.cross(fn[big], line[big])).max() <= 1e-6 * np.linalg.norm(fn[big], axis=1).max()
    assert np.allclose(fn + c[:, 9:12], force, rtol=0, atol=1e-9 * np.abs(force).max())
    # the surface normal is far from the centre line for these elongated grains
    names = [int(n) for n in loaded.scene.names]
    order = {n: k for k, n in enumerate(names)}
    sp = np.array([order[int(i)] for i in c[:, 0]])
    sq = np.array([order[int(i)] for i in c[:, 1]])
    key = {(a_, b_): k for k, (a_, b_) in enumerate(zip(loaded.scene.p, loaded.scene.q))}
    rows = np.array([key[(i, j)] for i, j in zip(sp, sq)])
    cosine = np.sum(loaded.scene.normal[rows] * line, axis=1)
    assert np.degrees(np.arccos(cosine.min())) >= 10.0


def test_radius_is_the_bounding_sphere():
    """LIGGGHTS's `radius` of a superquadric is its bounding sphere: about the farthest surface point from the
    centre (a blocky grain's corners reach beyond its longest semi-axis), not a semi-axis. LIGGGHTS's own estimate
    lies 1e-4 above the farthest vertex of a fine mesh (whose spacing puts the true maximum within 1e-6 of it)."""
    a = atoms_table()
    keys = np.unique(np.stack([a["shapex"], a["shapey"], a["shapez"], a["blockiness1"], a["blockiness2"]], 1), axis=0)
    for key in keys:
        same = np.all(np.stack([a["shapex"], a["shapey"], a["shapez"], a["blockiness1"], a["blockiness2"]], 1) == key,
                      axis=1)
        verts, _ = surface.mesh(surface.Superquadric(*key), resolution=400)
        reach = np.linalg.norm(verts, axis=1).max()
        assert np.all((a["radius"][same] >= reach) & (a["radius"][same] <= reach * (1 + 2e-4)))
        assert reach > 1.05 * key[:3].max()


def test_balance_residuals_from_the_arms(loaded):
    """Every grain away from the walls balances its contact forces and weight, and their moments about its centre
    with the reader's arms (centre → contactPoint): the check that points and arms are right. The run stops at
    rest, not exactly in equilibrium: medians below 1 %. Arms along the centre line (a sphere reader's) leave
    moment residuals ten times larger."""
    imbalance = loaded.report["imbalance"]
    assert imbalance["particles"] >= 50
    assert imbalance["force"]["median"] <= 0.01
    assert imbalance["moment"]["median"] <= 0.01
    scene = loaded.scene
    counted = loaded.wall_flags == 0
    arm = scene.point - scene.x[scene.p]
    e = scene.branch / np.linalg.norm(scene.branch, axis=1)[:, None]
    for arms, bound in ((arm, 0.01), (np.sum(arm * e, axis=1)[:, None] * e, None)):
        arm_q = arms - scene.branch
        torque = np.zeros((scene.n_particles, 3))
        scale = np.zeros(scene.n_particles)
        np.add.at(torque, scene.p, np.cross(arms, scene.force))
        np.add.at(torque, scene.q, np.cross(arm_q, -scene.force))
        fmag = np.linalg.norm(scene.force, axis=1)
        np.add.at(scale, scene.p, np.linalg.norm(arms, axis=1) * fmag)
        np.add.at(scale, scene.q, np.linalg.norm(arm_q, axis=1) * fmag)
        residual = np.median(np.linalg.norm(torque[counted], axis=1) / scale[counted])
        if bound is not None:
            assert residual <= bound
            reader = residual
        else:
            assert residual >= 10 * reader


def test_stored_curvature_equals_an_independent_evaluation(loaded):
    """curvature_p and curvature_q of a sample of contacts against mpmath (F written afresh, its derivatives by
    numerical differentiation at 40 digits, the foot point by a root finder): 1e-8 of |W|."""
    import mpmath as mp
    mp.mp.dps = 40
    a = atoms_table()
    scene = loaded.scene
    index = {int(i): k for k, i in enumerate(a["id"])}
    rows = np.linspace(0, scene.n_contacts - 1, 6).astype(int)
    for c in rows:
        for side, K in (("p", scene.curvature_p[c]), ("q", scene.curvature_q[c])):
            i = index[int(scene.names[getattr(scene, side)[c]])]
            quat = np.array([a["quat1"][i], a["quat2"][i], a["quat3"][i], a["quat4"][i]])
            R = quaternion_matrix(quat[None])[0]
            axes = np.array([a["shapex"][i], a["shapey"][i], a["shapez"][i]])
            n1, n2 = a["blockiness1"][i], a["blockiness2"][i]
            y = R.T @ (scene.point[c] - np.array([a["x"][i], a["y"][i], a["z"][i]]))
            s, nu, dist = surface.foot_points(y[None], axes, np.array([n1, n2]))
            _, g = surface.implicit(s, axes, np.array([n1, n2]), order=1)
            Kb, _, _ = mp_truth(y, axes, n1, n2, s[0], -dist[0] / np.linalg.norm(g[0]))
            n = scene.normal[c]
            P = np.eye(3) - np.outer(n, n)
            expect = P @ (R @ Kb @ R.T) @ P
            assert np.abs(K - expect).max() <= 1e-8 * np.abs(np.linalg.eigvalsh(Kb)).max()


def test_convert_extract_analyze_scan_export(tmp_path):
    scene_path = tmp_path / "scene.json"
    assert main(["convert", *map(str, FILES), "--out", str(scene_path)]) == 0
    scene = granstab.load_scene(scene_path)
    loaded = granstab.io.load(FILES)
    assert scene.n_contacts == loaded.scene.n_contacts
    np.testing.assert_allclose(scene.curvature_p, loaded.scene.curvature_p, rtol=0,
                               atol=1e-12 * np.abs(loaded.scene.curvature_p).max())
    centre = scene.names[int(np.argmax(np.bincount(np.r_[scene.p, scene.q])))]
    cluster = tmp_path / "cluster.json"
    assert main(["extract", str(scene_path), "--center", centre, "--out", str(cluster)]) == 0
    assert main(["analyze", str(cluster)]) == 0
    assert main(["scan", str(scene_path), "--out", str(tmp_path / "scan"), "--centers", "every:25"]) == 0
    out = tmp_path / "out"
    for fmt in ("xyz", "dump", "vtp"):
        assert main(["export", *map(str, FILES), "--out", str(out), "--out-format", fmt]) == 0
    check_export(out, loaded)


def check_export(out: Path, loaded) -> None:
    """OVITO reads Aspherical Shape and Orientation from the extended XYZ and the dump (its float32: one rounding),
    Superquadric Roundness where mapped; vtk reads the shape tensor, whose eigenvalues are the semi-axes."""
    from ovito import io as ovito_io
    from test_export import read_vtp, vtk_arrays
    shape = loaded.shape
    xyzw = loaded.orientation[:, [1, 2, 3, 0]]
    f32 = 4 * np.finfo(np.float32).eps
    for path in (out / "atoms.xyz", out / "atoms.atoms.dump"):
        data = ovito_io.import_file(str(path)).compute(0)
        assert np.allclose(np.asarray(data.particles["Aspherical Shape"]), shape[:, :3], rtol=f32, atol=0)
        assert np.allclose(np.asarray(data.particles["Orientation"]), xyzw, rtol=0, atol=f32)
    header = (out / "atoms.xyz").read_text().splitlines()[1]
    words = header.split("Properties=")[1].split()[0].split(":")
    props = list(zip(words[::3], map(int, words[2::3])))
    assert ("superquadric_roundness", 2) in props
    named = {"species": ["Particle Type"], "pos": ["Position.X", "Position.Y", "Position.Z"],
             "superquadric_roundness": ["Superquadric Roundness.Phi", "Superquadric Roundness.Theta"]}
    cols = [c for name, width in props
            for c in named.get(name, [name] if width == 1 else [f"{name}.{k + 1}" for k in range(width)])]
    data = ovito_io.import_file(str(out / "atoms.xyz"), columns=cols).compute(0)
    assert np.allclose(np.asarray(data.particles["Superquadric Roundness"]), 2.0 / shape[:, 3:], rtol=f32, atol=0)
    arrays = vtk_arrays(read_vtp(out / "atoms.particles.vtp").GetPointData())
    T = arrays["shape_tensor"].reshape(-1, 3, 3)
    assert np.allclose(np.linalg.eigvalsh(T), np.sort(shape[:, :3], axis=1), rtol=1e-10, atol=0)   # |q| = 1 ± 1e-12


def test_bad_input_is_one_line(tmp_path):
    text = (DATA / "atoms.dump").read_text().splitlines()
    cols = text[8].split()[2:]
    k = cols.index("blockiness1")
    row = text[9].split()
    row[k] = "1.5"
    (tmp_path / "atoms.dump").write_text("\n".join(text[:9] + [" ".join(row)] + text[10:]) + "\n")
    with pytest.raises(SceneError, match=r"atoms.dump: line 10: blockiness1: must be >= 2"):
        granstab.io.load([tmp_path / "atoms.dump", FILES[1], FILES[2]])
    text[8] = text[8].replace(" shapex", " sx")
    (tmp_path / "atoms.dump").write_text("\n".join(text) + "\n")
    with pytest.raises(SceneError, match="shapex"):
        granstab.io.load([tmp_path / "atoms.dump", FILES[1], FILES[2]], format="liggghts-superquadric")


def test_report_is_json(loaded):
    report = json.loads(json.dumps(loaded.report, default=float))
    assert report["geometry"]["normals_disagree_deg"]["max"] >= 0


def test_hertz_law_from_the_overlaps(loaded):
    """`model hertz tangential history`: k = 1.5 F_n/δ with δ the contact point's depths in both grains; α = 2(1 −
    ν)/(2 − ν) = 0.8235 for ν = 0.3; μ = coefficientFriction = 0.5. The overlap is LIGGGHTS's own: F_n against
    Hertz's (4/3) E* √R* δ^(3/2) (E* = Y/(2(1 − ν²)), R from each grain's mean curvature) has a median within 20 %
    of 1 (LIGGGHTS's effective radius of a superquadric contact is its own; its tangential history adds scatter)."""
    scene = loaded.scene
    law = loaded.report["law"]
    assert law["alpha"]["value"] == pytest.approx(2 * 0.7 / 1.7, rel=1e-15)
    assert law["mu"]["value"] == 0.5
    fn = -np.sum(scene.force * scene.normal, axis=1)
    delta = 1.5 * fn / scene.k
    radius = [2.0 / -np.trace(K, axis1=1, axis2=2) for K in (scene.curvature_p, scene.curvature_q)]
    r_eff = radius[0] * radius[1] / (radius[0] + radius[1])
    e_star = 1e7 / (2 * (1 - 0.3**2))
    ratio = fn / (4 / 3 * e_star * np.sqrt(r_eff) * delta**1.5)
    assert 0.8 <= np.median(ratio) <= 1.2


def test_periodic_box_takes_the_minimum_image(tmp_path):
    """A periodic box (pp pp pp): the pairs moved onto the y boundary and the grains beyond it wrapped to the other
    side keep their contacts; the arms are the minimum images from the centres to the contact points, so the
    normals and curvatures are those of the unwrapped pairs and the points the same modulo the box (to the printed
    precision, %.12g of the box size)."""
    from granstab_bench.superquadrics import write_pairs
    atoms, local = write_pairs(tmp_path, 12)
    plain = granstab.io.load([atoms, local])
    lines = atoms.read_text().splitlines()
    lines[4], lines[6] = "ITEM: BOX BOUNDS pp pp pp", "-10 10"
    rows = [r.split() for r in lines[9:]]
    for r in rows:
        y = float(r[3]) + 10.0
        r[3] = f"{y - 20.0 if y >= 10.0 else y:.12g}"
    (tmp_path / "wrapped.dump").write_text("\n".join(lines[:9] + [" ".join(r) for r in rows]) + "\n")
    contacts = local.read_text().splitlines()
    rows = [r.split() for r in contacts[9:]]
    for r in rows:
        r[13] = f"{float(r[13]) + 10.0:.12g}"
    (tmp_path / "contacts.dump").write_text("\n".join(contacts[:9] + [" ".join(r) for r in rows]) + "\n")
    wrapped = granstab.io.load([tmp_path / "wrapped.dump", tmp_path / "contacts.dump"])
    assert wrapped.scene.cell is not None and wrapped.scene.n_contacts == 12
    assert np.any(np.abs(wrapped.scene.branch[:, 1]) < np.abs(wrapped.scene.x[wrapped.scene.q, 1]
                                                                - wrapped.scene.x[wrapped.scene.p, 1]))  # seams
    moved = wrapped.scene.point - plain.scene.point - [0.0, 10.0, 0.0]
    np.testing.assert_allclose(moved[:, [0, 2]], 0.0, atol=1e-9)
    np.testing.assert_allclose((moved[:, 1] + 10.0) % 20.0 - 10.0, 0.0, atol=1e-9)
    np.testing.assert_allclose(wrapped.scene.normal, plain.scene.normal, rtol=0, atol=1e-8)
    np.testing.assert_allclose(wrapped.scene.curvature_p, plain.scene.curvature_p, rtol=0,
                               atol=1e-8 * np.abs(plain.scene.curvature_p).max())
