"""The rigorous position bound (issue 42, granstab/mechanics/nonaffine.py, `granstab.uncertainty._nonaffine`) against
the exact nonlinear geometry: random moves within the band (every centre and contact point by up to LEN, the normal
turned with the centre line, the curvature tensors turned with it and each principal radius moved by up to 2·LEN),
the perturbed scene's stiffness formed anew, and

  ‖P̃'S'P̃' − P̃SP̃‖₂ <= e_x          (S = sym(D H D) of each branch, P̃ the projector off the rigid motions)
  |q'(ṽ) − q(ṽ)| <= work(v)       (the fixed unit vector's work, q'(y) = yᵀP̃'S'P̃'y)

never fails, over many samples: far from the origin, tiny and huge length scales, nearly flat and nearly
hand-in-glove curvatures, 2D and 3D, sliding contacts. On the paper's pair the bound is compared with the actual
change."""
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import granstab
from granstab.mechanics.assembly import Assembly
from granstab.mechanics.branches import RIGID
from granstab.mechanics.rigid import dof_scale, rotation_columns, translation_columns
from granstab.mechanics.stiffness import contact_blocks, geometric
from granstab.mechanics.uncertainty import Band, mobilisation
from granstab.paper import four_disk
from granstab.uncertainty import _Data, _nonaffine, _scaled, data_robustness

sys.path.insert(0, str(Path(__file__).parent))
from test_vertices_3d import pair as spheres  # noqa: E402


def pair(rho=0.5, f=0.01, r=1.0, shift=0.0):
    """The paper's two-particle cluster (Sec. 4.1): disks of arm r, radii of curvature ρ, normal force f."""
    return granstab.scene_from_dict({
        "dim": 2, "particles": [{"name": "p", "x": [shift, shift]}, {"name": "q", "x": [shift + 2 * r, shift]}],
        "contacts": [{"p": "p", "q": "q", "point": [shift + r, shift], "normal": [1.0, 0.0],
                      "curvature_p": -1 / rho, "curvature_q": -1 / rho, "force": [-f, 0.0], "k": 1.0, "alpha": 1.0,
                      "state": "elastic"}]})


def rotation(a, b):
    """The smallest rotation taking the unit vector a to b (2D or 3D)."""
    if len(a) == 2:
        t = np.arctan2(b[1], b[0]) - np.arctan2(a[1], a[0])
        return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    v, c = np.cross(a, b), float(a @ b)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1 + c)


def radii_moved(K, R, moves):
    """R K' Rᵀ with K's principal radii 1/κ each moved by the given amounts (flat directions stay flat)."""
    lam, V = np.linalg.eigh(0.5 * (K + K.T))
    big = np.abs(lam) > 1e-300
    new = np.where(big, 1.0 / np.where(big, 1.0 / np.where(big, lam, 1.0) + moves[:len(lam)], 1.0), 0.0)
    return R @ (V * new) @ V.T @ R.T


def moved(scene, length, rng):
    """A random scene within the band: centres and points within `length` (some on its edge), normals along the moved
    centre lines' turn, curvature tensors turned and their radii moved by up to 2·length."""
    d = scene.dim

    def ball(n):
        v = rng.normal(size=(n, d))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        return v * length * np.where(rng.random(n) < 0.3, 1.0, rng.random(n) ** (1 / d))[:, None]
    x = scene.x + ball(scene.n_particles)
    point = scene.point + ball(scene.n_contacts)
    out = replace(scene, x=x, point=point)
    normal, Kp, Kq = [], [], []
    for c in range(scene.n_contacts):
        b0, b1 = scene.branch[c], out.branch[c]
        R = rotation(b0 / np.linalg.norm(b0), b1 / np.linalg.norm(b1))
        normal.append(R @ scene.normal[c])
        Kp.append(radii_moved(scene.curvature_p[c], R, rng.uniform(-2, 2, d) * length))
        Kq.append(radii_moved(scene.curvature_q[c], R, rng.uniform(-2, 2, d) * length))
    Kp, Kq = np.array(Kp), np.array(Kq)
    return replace(out, normal=np.array(normal), curvature_p=Kp, curvature_q=Kq, curvature_sum=Kp + Kq)


def projected(scene, L, sliding):
    """P̃ S P̃ (dense) of the branch with the `sliding` contacts sliding, in the L metric's scaled dofs."""
    cb = contact_blocks(scene)
    hm = cb.blocks["Hm"] + sliding[:, None, None] * cb.slide_left[:, :, None] * cb.slide_right[:, None, :]
    blocks = geometric(cb.blocks) + hm
    H = Assembly(scene.p, scene.q, scene.dof_per_particle, scene.n_dof)(blocks).toarray()
    D = dof_scale(scene.n_particles, scene.dim, L)
    S = D[:, None] * H * D[None, :]
    S = 0.5 * (S + S.T)
    Q, _ = np.linalg.qr(np.concatenate([translation_columns(scene.n_particles, scene.dim),
                                        rotation_columns(scene.x, L)], axis=1))
    P = np.eye(scene.n_dof) - Q @ Q.T
    return P @ S @ P, P


def check(scene, length, samples, seed=0, vector=None):
    """(largest ratio of the actual change to the bound over the samples: matrix, vector work, eigenvalues: the
    sorted spectra of P̃SP̃ and P̃'S'P̃', rigid zeros included, elementwise)."""
    L = float(np.mean(np.linalg.norm(scene.r_pq, axis=1)))
    band = Band(position=length)
    res = granstab.analyze(scene, metric="L", rotation_length=L, attribution=False, keep="all")
    knot = next(k for k in _nonaffine(_Data.of(scene, band), res, mobilisation(scene, band), 0.0) if k[0] == 1.0)
    sliding = scene.at_yield()
    A, P = projected(scene, L, sliding)
    u = None
    if vector is not None:
        u = _scaled(res, vector)
        u /= np.linalg.norm(u)
    rng = np.random.default_rng(seed)
    worst = [0.0, 0.0, 0.0]
    spectrum = np.linalg.eigvalsh(A)
    for _ in range(samples):
        other = moved(scene, length, rng)
        B, P2 = projected(other, L, sliding)
        worst[0] = max(worst[0], np.linalg.norm(B - A, 2) / knot[1])
        worst[2] = max(worst[2], np.abs(np.linalg.eigvalsh(B) - spectrum).max() / knot[1])
        if u is not None:
            worst[1] = max(worst[1], abs(u @ B @ u - u @ A @ u) / knot[3](vector))
    return worst


def lowest_vector(scene, L=None):
    res = granstab.analyze(scene, metric="L", rotation_length=L, attribution=False, keep="all")
    b = res.branches[0]
    j = int(np.argmin(np.where(b.codes != RIGID, b.stability_eigenvalues, np.inf)))
    return b.stability_vectors[:, j], b.stability_eigenvalues[j]


@pytest.mark.parametrize("name, scene, length", [
    ("pair", pair(), 0.01),
    ("pair far from the origin", pair(shift=1e6), 0.01),
    ("pair, tiny lengths", pair(rho=0.5e-6, f=1e-8, r=1e-6), 1e-8),
    ("pair, huge lengths", pair(rho=0.5e6, f=1e4, r=1e6), 1e4),
    ("nearly flat", pair(rho=1e6), 0.01),
    ("nearly hand-in-glove", granstab.scene_from_dict({
        "dim": 2, "particles": [{"name": "p", "x": [0.0, 0.0]}, {"name": "q", "x": [2.0, 0.0]}],
        "contacts": [{"p": "p", "q": "q", "point": [1.0, 0.0], "normal": [1.0, 0.0], "curvature_p": 1.0,
                      "curvature_q": -0.9, "force": [-0.01, 0.0], "k": 1.0, "alpha": 1.0, "state": "elastic"}]}),
     0.002),
    ("four disks, sliding contacts", four_disk.scene(), 1e-3),
    ("four disks far away", replace(four_disk.scene(), x=four_disk.scene().x + 3e5,
                                    point=four_disk.scene().point + 3e5), 1e-3),
    ("3D spheres", spheres(10.0), 0.01),
])
def test_the_bound_holds_for_the_exact_geometry(name, scene, length):
    """Over 60 random moves within the band (30 % on its edge) the projected stiffness never moves by more than the
    bound (ratio <= 1), nor does any eigenvalue (the sorted spectra, Weyl), nor the lowest mode's work by more than
    its vector bound; the matrix ratio is above 1e-4 (the bound is not vacuous: it sees the change's scale)."""
    v, _ = lowest_vector(scene, float(np.mean(np.linalg.norm(scene.r_pq, axis=1))))
    matrix, work, eigenvalues = check(scene, length, 60, vector=v)
    assert 1e-4 < matrix <= 1.0, name
    assert work <= 1.0 and eigenvalues <= 1.0, name


def test_the_bound_is_the_right_size_on_the_paper_pair():
    """The pair (ρ/r = 0.5, f/(kr) = 0.01: unstable, λ⁽⁶⁾ = f(ρ − r) = −0.005), position band LEN = 0.005, 200
    samples: the matrix bound is within 5× of the largest sampled change of P̃SP̃ (measured 3.7×), the lowest mode's
    work bound within 50× of its largest sampled change (measured 23×). The margin the bound proves is 0.9 there
    (undecided), 1/110 of the old first-order estimate (r − ρ)/LEN = 100, which was no promise; at LEN = 0.001 the
    margin is > 4: `holds`, proven."""
    scene = pair()
    v, lam = lowest_vector(scene, 1.0)
    matrix, work, _ = check(scene, 0.005, 200, vector=v)
    assert 1 / 5 < matrix <= 1.0 and 1 / 50 < work <= 1.0
    got = data_robustness(scene, Band(position=0.001), metric="L", rotation_length=1.0)
    assert got.robust == "holds" and got.margin > 4 and got.nonaffine > 0
    far = data_robustness(scene, Band(position=0.005), metric="L", rotation_length=1.0, search=False)
    assert far.robust == "undecided" and 0.5 < far.margin < 1
