"""The periodic scene contract (issue 24): `cell`, per-contact `image`, q's copy, the file formats' round trips,
the one-line errors on bad input, and μ = 0 as a frictionless contact (F = k n⊗n in every branch)."""
from __future__ import annotations

import json

import numpy as np
import pytest

import granstab
from granstab.mechanics.stiffness import contact_blocks, stiffness
from granstab.model.errors import SceneError
from granstab.model.law import contact_stiffness
from granstab.model.scene import build_scene, equilibrium_loads
from granstab.model.vec import tangent_basis


def square_cell(n: int = 3, spacing: float = 0.999, f: float = 1e-3, mu: float = 0.5, alpha: float = 1.0,
                image: bool = True) -> dict:
    """An n×n square lattice of unit-diameter disks at centre distance `spacing` in a periodic cell of n·spacing
    per side, every contact compressed by f; the contacts that close a row or column across the seam carry
    image (1, 0) or (0, 1) (with image=False they are given without images: a wrong scene)."""
    a = spacing
    ij = np.array([(i, j) for j in range(n) for i in range(n)])
    x = ij * a
    p, q, img = [], [], []
    for s in range(len(ij)):
        for axis in range(2):
            nb = ij[s].copy()
            nb[axis] += 1
            wrap = nb[axis] == n
            nb[axis] %= n
            p.append(s)
            q.append(int(nb[1] * n + nb[0]))
            img.append(np.eye(2, dtype=int)[axis] * wrap)
    p, q, img = np.array(p), np.array(q), np.array(img)
    cell = a * n * np.eye(2)
    normal = (x[q] + img @ cell - x[p]) / a
    t = tangent_basis(normal)[:, :, 0]
    K = -(2 / a) * t[:, :, None] * t[:, None, :]
    M = len(p)
    arrays = {"p": p, "q": q, "point": x[p] + 0.5 * a * normal, "normal": normal, "curvature_p": K,
              "curvature_q": K.copy(), "force": -f * normal, "moment": np.zeros((M, 1)), "k": np.ones(M),
              "alpha": np.full(M, alpha), "mu": np.full(M, mu), "rolling": np.zeros((M, 1, 1)),
              "state": ("auto",) * M}
    names = [f"d{i}" for i in range(n * n)]
    return {"dim": 2, "names": names, "x": x, "arrays": arrays, "cell": cell, "image": img if image else None}


def make(fields: dict, **change):
    f = {**fields, **change}
    return build_scene(f["dim"], f["names"], f["x"], f["arrays"], cell=f["cell"], image=f["image"], source="sq")


def test_copy_branch_and_equilibrium_across_the_seam():
    """q's copy and the branch vector use the image: every branch is one spacing long, r^qp half of it, and
    the contacts balance every disk (zero loads and moments, eq:equil1); without the images the seam contacts'
    r^qp would cross the cell."""
    fields = square_cell()
    scene = make(fields)
    assert scene.periodic and scene.volume == pytest.approx((3 * 0.999) ** 2, rel=1e-15)
    assert np.allclose(np.linalg.norm(scene.branch, axis=1), 0.999, rtol=1e-14, atol=0)
    assert np.allclose(scene.r_qp, -0.5 * 0.999 * scene.normal, rtol=0, atol=1e-15)
    b, w = equilibrium_loads(scene)
    assert np.abs(b).max() < 1e-17 and np.abs(w).max() < 1e-17      # each disk: four equal, opposite forces
    flat = granstab.model.scene.Scene(**{**scene.__dict__, "image": np.zeros_like(scene.image), "cell": None})
    assert np.linalg.norm(flat.r_qp, axis=1).max() == pytest.approx(2.5 * 0.999, rel=1e-14)


def test_default_image_is_zeros_and_no_cell_means_not_periodic():
    scene = granstab.load_scene("presets/two_particle.toml")
    assert scene.cell is None and not scene.periodic
    assert scene.image.shape == (scene.n_contacts, 2) and scene.image.dtype.kind == "i" and not scene.image.any()
    assert np.array_equal(scene.q_copy, scene.x[scene.q])


def _toml(scene) -> str:
    d = granstab.io.schema.scene_to_dict(scene)

    def v(x):
        return json.dumps(x)

    lines = [f"dim = {d['dim']}", f"title = {v(d['title'])}", f"cell = {v(d['cell'])}"]
    for part in ("particles", "contacts"):
        for row in d[part]:
            lines += [f"[[{part}]]"] + [f"{k} = {v(val)}" for k, val in row.items()]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("suffix", ["json", "npz", "toml"])
def test_round_trip_keeps_cell_and_images(tmp_path, suffix):
    scene = make(square_cell())
    path = tmp_path / f"s.{suffix}"
    if suffix == "toml":
        path.write_text(_toml(scene))
    else:
        granstab.save_scene(scene, path)
    back = granstab.load_scene(path)
    assert np.array_equal(back.cell, scene.cell) and np.array_equal(back.image, scene.image)
    assert back.image.any()                                          # the seam contacts are there
    assert np.array_equal(back.point, scene.point) and np.array_equal(back.force, scene.force)


def _json_with(tmp_path, edit) -> str:
    data = granstab.io.schema.scene_to_dict(make(square_cell()))
    edit(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(SceneError) as err:
        granstab.load_scene(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path))
    return msg


def _set(key, value, contact=None):
    def edit(data):
        if contact is None:
            data[key] = value
        else:
            data["contacts"][contact][key] = value
    return edit


@pytest.mark.parametrize("edit, expect", [
    (_set("cell", [[1.0, 0.0]]), "scene: cell: must be 2x2 numbers"),
    (_set("cell", [[1.0, 0.0], [0.0, "a"]]), "scene: cell: must be 2x2 numbers"),
    (_set("cell", [[0.0, 2.997], [2.997, 0.0]]), "scene: cell: the lattice vectors (rows) span no positive volume"),
    (_set("cell", [[2.997, 0.0], [5.994, 0.0]]), "degenerate"),
    (_set("image", [1.5, 0], contact=1), "contacts[1] (d0-d3): image: must be 2 integers"),
    (_set("image", [1, 0, 0], contact=1), "contacts[1] (d0-d3): image: must be 2 numbers"),
    (_set("image", [0, 0], contact=4), "contacts[4] (d2-d0): point: not between x^p and q's copy"),
    (_set("image", [2, 0], contact=4), "contacts[4] (d2-d0): point: nearer another copy of q"),
    (_set("image", [1, 0], contact=1), "contacts[1] (d0-d3): point: nearer another copy of q"),
])
def test_bad_cell_and_image_are_one_line_errors(tmp_path, edit, expect):
    assert expect in _json_with(tmp_path, edit)


def test_nonzero_image_without_cell(tmp_path):
    def edit(data):
        del data["cell"]
    assert "contacts[4] (d2-d0): image: [1, 0] is not zero but the scene has no cell" in _json_with(tmp_path, edit)


def test_same_pair_twice_only_through_different_images(tmp_path):
    """A 2-disk cell: disk a touches b directly and through the image (-1, 0); the same pair and image twice is
    still a duplicate."""
    def two(images):
        contacts = [{"p": "a", "q": "b", "image": img, "point": [0.5 * s, 0.0], "normal": [s, 0.0],
                     "force": [-1e-3 * s, 0.0], "curvature_p": -2.0, "curvature_q": -2.0}
                    for img, s in images]
        return {"dim": 2, "cell": [[2.0, 0.0], [0.0, 5.0]], "defaults": {"mu": 0.0},
                "particles": [{"name": "a", "x": [0.0, 0.0]}, {"name": "b", "x": [1.0, 0.0]}], "contacts": contacts}
    scene = granstab.io.scenes.scene_from_dict(two([([0, 0], 1.0), ([-1, 0], -1.0)]))
    assert np.allclose(scene.branch, [[1, 0], [-1, 0]]) and np.abs(scene.load).max() == 0
    with pytest.raises(SceneError, match=r"contacts\[1\] \(a-b\): q: duplicate contact"):
        granstab.io.scenes.scene_from_dict(two([([-1, 0], -1.0), ([-1, 0], -1.0)]))


def test_alpha_zero_is_accepted(tmp_path):
    data = granstab.io.schema.scene_to_dict(make(square_cell()))
    for c in data["contacts"]:
        c["alpha"] = 0.0
    scene = granstab.io.scenes.scene_from_dict(data)
    assert not scene.alpha.any()


@pytest.mark.parametrize("alpha", [0.0, 0.7, 1.0])
def test_mu_zero_is_frictionless(alpha):
    """μ = 0: F = k n⊗n whatever α (no tangential stiffness), never a sliding branch; μ > 0 keeps αk tangentially."""
    rng = np.random.default_rng(3)
    n = rng.standard_normal((4, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    k = rng.uniform(0.5, 2.0, 4)
    F = contact_stiffness(n, k, np.full(4, alpha), np.zeros(4), -n, np.zeros(4, bool))
    assert np.allclose(F, k[:, None, None] * n[:, :, None] * n[:, None, :], rtol=0, atol=1e-15)
    Ff = contact_stiffness(n, k, np.full(4, alpha), np.full(4, 0.3), -n, np.zeros(4, bool))
    t = tangent_basis(n)[:, :, 0]
    assert np.allclose(np.einsum("mi,mij,mj->m", t, Ff, t), alpha * k, rtol=1e-14, atol=1e-15)

    frictionless = make(square_cell(mu=0.0, alpha=alpha))
    assert not frictionless.at_yield().any()
    reference = make(square_cell(mu=0.0, alpha=0.0))
    assert np.array_equal(stiffness(frictionless).H, stiffness(reference).H)
    blocks = contact_blocks(frictionless)
    u = np.zeros((frictionless.n_contacts, 6))
    u[:, 3:5] = tangent_basis(frictionless.normal)[:, :, 0]          # q moves tangentially: no Hm force
    assert np.abs(np.einsum("mij,mj->mi", blocks.blocks["Hm"], u)).max() < 1e-15
