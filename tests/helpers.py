"""Test support: generic random clusters in the contact-level format, and rigid transformations of scenes."""
from __future__ import annotations

from pathlib import Path

import numpy as np

import granstab
from granstab.model.vec import tangent_basis

TESTS = Path(__file__).resolve().parent     # tests/: the rooms' folders (tests/<room>/, docs/design.md), helpers
ROOT = TESTS.parent                         # the repository
DATA = TESTS / "data"                       # the tests' data, shared by the rooms


def random_cluster(dim: int, n_particles: int = 5, seed: int = 0, moments: bool = True, rolling: float = 0.0,
                   scale: float = 1.0, f_over_k: float = 0.01, states: str = "auto") -> dict:
    """A well-connected cluster with generic data: random positions, contact points between centres, normals
    near the centre line, random convex curvatures, forces inside the friction cone (compressive), contact
    moments in 3D. Lengths scale with `scale`, forces with scale·f_over_k (k = 1), so f/(kr) is fixed."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.5, 1.5, (n_particles, dim)) * scale
    pairs = [(i, j) for i in range(n_particles) for j in range(i + 1, n_particles)]
    contacts = []
    for i, j in pairs:
        axis = x[j] - x[i]
        lam = rng.uniform(0.35, 0.65)
        point = x[i] + lam * axis
        n = axis / np.linalg.norm(axis) + 0.2 * rng.standard_normal(dim)
        n /= np.linalg.norm(n)
        T = tangent_basis(n)
        fn = -f_over_k * scale * rng.uniform(0.5, 1.5)
        ft = T @ rng.uniform(-0.3, 0.3, dim - 1) * abs(fn)
        c = {"p": f"b{i}", "q": f"b{j}", "point": point.tolist(), "normal": n.tolist(),
             "force": (fn * n + ft).tolist(), "mu": 0.5, "state": states}
        if dim == 2:
            c["curvature_p"] = -1.0 / (scale * rng.uniform(0.3, 2.0))
            c["curvature_q"] = -1.0 / (scale * rng.uniform(0.3, 2.0))
            if moments:
                c["moment"] = float(rng.uniform(-0.2, 0.2) * abs(fn) * scale)
        else:
            for key in ("curvature_p", "curvature_q"):
                R = T @ np.linalg.qr(rng.standard_normal((2, 2)))[0]
                K = R @ np.diag(-1.0 / (scale * rng.uniform(0.3, 2.0, 2))) @ R.T
                c[key] = (0.5 * (K + K.T)).tolist()
            if moments:
                c["moment"] = (rng.uniform(-0.2, 0.2, 3) * abs(fn) * scale).tolist()
        if rolling:
            c["rolling_stiffness"] = rolling * scale ** 2 if dim == 2 else (rolling * scale ** 2 * np.eye(3)).tolist()
        contacts.append(c)
    return {"dim": dim, "defaults": {"k": 1.0, "alpha": 0.7, "mu": 0.5},
            "particles": [{"name": f"b{i}", "x": x[i].tolist()} for i in range(n_particles)],
            "contacts": contacts}


def rotation(dim: int, seed: int = 1) -> np.ndarray:
    """A random proper rotation matrix."""
    rng = np.random.default_rng(seed)
    if dim == 2:
        a = rng.uniform(0, 2 * np.pi)
        return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q if np.linalg.det(Q) > 0 else -Q


def rotate_scene_dict(data: dict, Q: np.ndarray) -> dict:
    """The same scene seen rotated by Q: positions, points, normals, forces, moments (3D) and K → Q K Qᵀ."""
    dim = data["dim"]
    out = {**data, "particles": [], "contacts": []}
    for p in data["particles"]:
        out["particles"].append({**p, "x": (Q @ np.array(p["x"])).tolist()})
    for c in data["contacts"]:
        c = dict(c)
        for key in ("point", "normal", "force"):
            c[key] = (Q @ np.array(c[key])).tolist()
        if dim == 3:
            for key in ("curvature_p", "curvature_q"):
                c[key] = (Q @ np.array(c[key]) @ Q.T).tolist()
            if "moment" in c:
                c["moment"] = (Q @ np.array(c["moment"])).tolist()
        out["contacts"].append(c)
    return out


def dof_rotation(dim: int, n_particles: int, Q: np.ndarray) -> np.ndarray:
    """Block-diagonal R acting on [du, dθ] of every particle (dθ is a scalar about e3 in 2D)."""
    block = np.eye(3) if dim == 2 else np.zeros((6, 6))
    if dim == 2:
        block[:2, :2] = Q
    else:
        block[:3, :3] = Q
        block[3:, 3:] = Q
    return np.kron(np.eye(n_particles), block)


def scene(data: dict) -> granstab.Scene:
    return granstab.scene_from_dict(data, source="<test>")


# a shape-based scene used by the app tests: two flat-tipped ellipses (tip radius 2, half-length 1) pressed
# tip to tip, rho/r > 1, stable
FLAT_PAIR = """\
dim = 2
title = "two ellipses, flat contact"
[defaults]
k = 1.0
alpha = 1.0
mu = 0.5
[[particles]]
name = "a"
x = [0.0, 0.0]
shape = { kind = "ellipse", a = 1.0, b = 1.4142135623730951 }
[[particles]]
name = "b"
x = [1.99, 0.0]
shape = { kind = "ellipse", a = 1.0, b = 1.4142135623730951 }
"""


def result_part(d: dict) -> dict:
    """An `analyze --json` object without what depends on the machine and its load (timings, the estimate in
    `cost`: solve/plan.py MEASURED) or on the input's reading (`import`): two runs of one scene give the same."""
    from granstab.solve.plan import MEASURED
    out = {k: v for k, v in d.items() if k not in ("import", "timings")}
    if "cost" in out:
        out["cost"] = {k: v for k, v in out["cost"].items() if k not in MEASURED}
    return out
