"""H of a clump pair (a bent trimer and a dimer of spheres touching at two points) against the complex-step
derivative of the EXACT nonlinear statics of the two rigid clumps, read through the clump reader.

The exact model (independent of granstab's stiffness and of its clump reader): members move rigidly with their
clump (c = x + E(c0 − x0), E = expm([θ]×)); each member pair has the exact sphere normal n = (c_b − c_a)/|c_b −
c_a|, overlap δ = R_a + R_b − |c_b − c_a|, contact point c_a + (R_a − δ/2) n; force on a's clump f = −kδ n +
αk (I − n⊗n)(a_q − a_p) with tangential anchors moving with the clumps; loads b, w hold each clump (moments about
its centre of mass). The scene is made by writing the clump tables (bodies.csv, members.csv, contacts.csv) and
reading them with granstab.io.load, so the reader's arms, normals and curvatures (ρ = R − δ/2 of the member) are
what is checked.

Tolerances (as tests/mechanics/test_fd_exact.py): both matrices carry round-off of a few eps·‖H‖: ‖H − H_exact‖ ≤ 1e-12 ‖H‖;
the geometric part Hg ~ (f/k)‖H‖ is checked to 1e-9 relative to itself.
"""
import numpy as np
import pytest
from exact_geometry import CSTEP, cross, dot, mv, rotation
from scipy.spatial.transform import Rotation

import granstab

K, ALPHA = 1.0, 0.7
TRIMER = np.array([[-0.9, -0.3, 0.0], [0.0, 0.2, 0.1], [0.9, -0.3, 0.0]])     # body frame, radii below
TRIMER_R = np.array([0.5, 0.6, 0.5])
DIMER_R = np.array([0.55, 0.45])


def configuration(level):
    """The trimer (turned) and the dimer resting on its two end members: the dimer's members placed along two
    normals from the trimer's ends so that the contacts overlap by `level` and 0.7 `level`; the dimer is the rigid
    body those two members make (its body axes those of the world)."""
    R_a = Rotation.from_rotvec([0.1, -0.2, 0.05]).as_matrix()
    trimer = TRIMER @ R_a.T
    normals = np.array([[0.2, 0.1, 1.0], [-0.1, 0.2, 1.0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    overlap = np.array([level, 0.7 * level])
    dimer = trimer[[0, 2]] + (TRIMER_R[[0, 2]] + DIMER_R - overlap)[:, None] * normals
    return R_a, trimer, dimer


def exact_loads(body_x0, body_R0, member_body, member_c0, member_r, a, b, anchors_p, anchors_q, u, theta):
    """[b, w] of the two clumps (…, 2, 6) for translations u (…, 2, 3) and rotation vectors θ (…, 2, 3)."""
    E = rotation(theta)
    x = body_x0 + u
    pa, pb = member_body[a], member_body[b]
    ca = x[..., pa, :] + mv(E[..., pa, :, :], member_c0[a] - body_x0[pa])
    cb = x[..., pb, :] + mv(E[..., pb, :, :], member_c0[b] - body_x0[pb])
    d = cb - ca
    dist = np.sqrt(dot(d, d))
    n = d / dist[..., None]
    delta = member_r[a] + member_r[b] - dist
    point = ca + (member_r[a] - delta / 2)[..., None] * n
    ap = x[..., pa, :] + mv(E[..., pa, :, :], anchors_p - body_x0[pa])
    aq = x[..., pb, :] + mv(E[..., pb, :, :], anchors_q - body_x0[pb])
    s = aq - ap
    f = (-K * delta)[..., None] * n + ALPHA * K * (s - dot(s, n)[..., None] * n)
    Ip, Iq = np.eye(2)[:, pa], np.eye(2)[:, pb]
    bl = np.einsum("nm,...md->...nd", Iq - Ip, f)
    w = -np.einsum("nm,...md->...nd", Ip, cross(point - x[..., pa, :], f)) \
        - np.einsum("nm,...md->...nd", Iq, cross(point - x[..., pb, :], -f))
    return np.concatenate([bl, w], axis=-1)


def write_tables(folder, bodies, members, contacts):
    (folder / "bodies.csv").write_text("body,x,y,z,mass,quatw,quati,quatj,quatk,inertia1,inertia2,inertia3\n"
                                       + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in bodies))
    (folder / "members.csv").write_text("id,body,x,y,z,radius\n"
                                        + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in members))
    (folder / "contacts.csv").write_text("id1,id2,fx,fy,fz,cx,cy,cz,kn,kt,mu\n"
                                         + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in contacts))


@pytest.mark.parametrize("level", [1e-3, 1e-2, 1e-1])
def test_clump_pair_stiffness_matches_exact_derivative(level, tmp_path):
    R_a, trimer, dimer = configuration(level)
    R_b = np.eye(3)
    member_c0 = np.concatenate([trimer, dimer])
    member_r = np.concatenate([TRIMER_R, DIMER_R])
    member_body = np.array([0, 0, 0, 1, 1])
    # centres of mass: the clumps' reference points (any point of the body would do for H; the reader takes these)
    body_x0 = np.array([member_c0[:3].mean(0) + [0.05, -0.02, 0.01], member_c0[3:].mean(0) + [0.0, 0.03, -0.02]])
    a, b = np.array([0, 2]), np.array([3, 4])
    d = member_c0[b] - member_c0[a]
    n = d / np.linalg.norm(d, axis=1)[:, None]
    delta = member_r[a] + member_r[b] - np.linalg.norm(d, axis=1)
    assert np.all(delta > 0) and np.isclose(delta.max(), level, rtol=1e-12)
    point = member_c0[a] + (member_r[a] - delta / 2)[:, None] * n
    tangent = np.cross(n, [0.3, 0.8, 0.5])
    tangent /= np.linalg.norm(tangent, axis=1)[:, None]
    f_t = 0.3 * K * delta[:, None] * tangent
    s = f_t / (ALPHA * K)
    force = -K * delta[:, None] * n + f_t
    quat = Rotation.from_matrix(np.stack([R_a, R_b])).as_quat()[:, [3, 0, 1, 2]]          # w first
    write_tables(tmp_path,
                 [[1, *body_x0[0], 3.0, *quat[0], 0.4, 0.9, 1.0], [2, *body_x0[1], 2.0, *quat[1], 0.3, 0.6, 0.6]],
                 [[10 + i, 1 + member_body[i], *member_c0[i], member_r[i]] for i in range(5)],
                 [[10 + a[c], 10 + b[c], *force[c], *point[c], K, ALPHA * K, 1.0] for c in range(2)])
    loaded = granstab.io.load(tmp_path)
    scene = loaded.scene
    assert scene.n_contacts == 2 and list(scene.p) == [0, 0] and list(scene.q) == [1, 1]   # one pair, two points
    np.testing.assert_allclose(scene.x, body_x0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(scene.point, point, rtol=0, atol=1e-15)
    args = (body_x0, np.stack([R_a, R_b]), member_body, member_c0, member_r, a, b, point - s / 2, point + s / 2)
    L0 = exact_loads(*args, np.zeros((2, 3)), np.zeros((2, 3)))
    np.testing.assert_allclose(np.concatenate([scene.load, scene.load_moment], 1), L0, rtol=0, atol=1e-14)
    u, th = np.zeros((12, 2, 3), complex), np.zeros((12, 2, 3), complex)
    for j in range(12):
        body, comp = divmod(j, 6)
        (u if comp < 3 else th)[j, body, comp % 3] = 1j * CSTEP
    H_exact = (exact_loads(*args, u, th).imag / CSTEP).reshape(12, -1).T
    st = granstab.stiffness(scene)
    Hg = st.Hg1 + st.Hg2 + st.Hg3
    assert np.linalg.norm(st.H - H_exact) <= 1e-12 * np.linalg.norm(st.H)
    assert np.linalg.norm(H_exact - st.Hm - Hg) <= 1e-9 * np.linalg.norm(Hg)
    assert 0.1 * level <= np.linalg.norm(Hg) / np.linalg.norm(st.Hm) <= 10 * level     # Hg resolved, ~ f/k

