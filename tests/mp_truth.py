"""Test support: the stiffness H and the spectrum of sym(𝓗) evaluated in high precision (mpmath) from a scene's own
float data, written independently of granstab's arrays (per contact, the paper's equations, no numpy arithmetic).

Used as the truth for the accuracy bounds (tests/mechanics/test_bounds_truth.py): every input number is taken exactly as
stored (mpf of a float is exact) and every operation after it is done with mp.dps digits, so the only difference
between granstab's answer and this one is granstab's rounding. Only what the harness needs is written: elastic
contacts, no contact moments (3D), no rolling stiffness, the L metric (D = diag(1, 1/L), L the mean contact radius),
rotations about the exact centroid (eq:dtrigid).
"""
from __future__ import annotations

import mpmath as mp


def vec(a) -> mp.matrix:
    return mp.matrix([mp.mpf(float(v)) for v in a])


def mat(a) -> mp.matrix:
    return mp.matrix([[mp.mpf(float(v)) for v in row] for row in a])


def cross_x(a: mp.matrix) -> mp.matrix:
    """X(a) with X(a) b = a × b: (1, 2) in 2D (the e3 component), (3, 3) in 3D."""
    if a.rows == 2:
        return mp.matrix([[-a[1], a[0]]])
    return mp.matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


def place(M: mp.matrix, block: mp.matrix, r0: int, c0: int) -> None:
    for i in range(block.rows):
        for j in range(block.cols):
            M[r0 + i, c0 + j] += block[i, j]


def tangent(n: mp.matrix) -> mp.matrix:
    """An orthonormal basis (d, d-1) of the plane normal to n (exact Gram-Schmidt in mp)."""
    d = n.rows
    nh = n / mp.norm(n)
    if d == 2:
        return mp.matrix([[-nh[1]], [nh[0]]])
    cols = []
    for e in range(3):
        v = mp.matrix([1 if i == e else 0 for i in range(3)])
        v = v - (nh.T * v)[0] * nh
        for c in cols:
            v = v - (c.T * v)[0] * c
        if mp.norm(v) > mp.mpf("0.1"):
            cols.append(v / mp.norm(v))
        if len(cols) == 2:
            break
    T = mp.matrix(3, 2)
    for j, c in enumerate(cols):
        for i in range(3):
            T[i, j] = c[i]
    return T


def contact_block(d: int, x_p, x_q, point, normal, force, Kp, Kq, k, alpha) -> mp.matrix:
    """The contact's block of H = Hg1 + Hg2 + Hg3 + Hm over [du^p, dθ^p, du^q, dθ^q] (eq:piece, eq:final1)."""
    r = 1 if d == 2 else 3
    n_loc = 2 * (d + r)
    eye = mp.eye(d)
    n, f = normal, force
    r_pq, r_qp = point - x_p, point - x_q
    Bu, Bt = mp.matrix(d, n_loc), mp.matrix(r, n_loc)
    place(Bu, -eye, 0, 0)
    place(Bu, -cross_x(r_pq).T, 0, d)                    # -dθ^p × r^pq (eq:dudef)
    place(Bu, eye, 0, d + r)
    place(Bu, cross_x(r_qp).T, 0, 2 * d + r)
    place(Bt, -mp.eye(r), 0, d)                          # δθ_def = dθ^q - dθ^p (eq:dtdef)
    place(Bt, mp.eye(r), 0, 2 * d + r)
    nn = n * n.T
    T = tangent(n)
    Kp_t = T * (T.T * Kp * T) * T.T
    Kq_t = T * (T.T * Kq * T) * T.T
    G = T * mp.inverse(T.T * (Kp + Kq) * T) * T.T        # (K^p + K^q)^+ on the tangent plane (eq:rolling)
    twist = cross_x(n).T * Bt                            # δθ_def × n
    du_t = (eye - nn) * Bu
    st_pq = -G * (twist - Kq_t * du_t)
    st_qp = -G * (twist + Kp_t * du_t)
    dr_pq = nn * Bu / 2 + st_pq                          # eq:Drpq, eq:dsn
    dr_qp = -nn * Bu / 2 + st_qp
    Cf = (f.T * n)[0] * eye - n * f.T                      # f × (δn × n) = Cf δn (eq:Dfpq)
    df_pq = Cf * (-Kp_t * st_pq)                         # δn^pq = -K^p δs^t t (eq:Dnpq)
    df_qp = Cf * (-Kq_t * st_qp)
    if d == 3:                                           # the twirl term (eq:A3, erratum 1)
        twirl = -(cross_x(f) * n) * (n.T * Bt) / 2
        df_pq, df_qp = df_pq + twirl, df_qp + twirl
    H = mp.matrix(n_loc, n_loc)
    for r0, rr, df in ((0, r_pq, df_pq), (d + r, r_qp, df_qp)):            # Hg2 = -A1 A2 (eq:equilibrium4)
        place(H, -df, r0, 0)
        place(H, -cross_x(rr) * df, r0 + d, 0)
    place(H, cross_x(f) * dr_pq, d, 0)                   # Hg1: -δr × f (eq:Hg1)
    place(H, -cross_x(f) * dr_qp, 2 * d + r, 0)
    place(H, -cross_x(f).T, 0, d)                        # Hg3: dθ × b, dθ × w (eq:Hg3)
    place(H, cross_x(f).T, d + r, 2 * d + r)
    if d == 3:
        tau_p, tau_q = cross_x(r_pq) * f, -(cross_x(r_qp) * f)
        place(H, -cross_x(tau_p).T, d, d)
        place(H, -cross_x(tau_q).T, 2 * d + r, 2 * d + r)
    F = k * (alpha * eye + (1 - alpha) * nn)               # elastic contact law (eq:ContactF)
    dfm = F * Bu
    place(H, -dfm, 0, 0)                                 # Hm = -A1 F B (eq:Hm)
    place(H, -cross_x(r_pq) * dfm, d, 0)
    place(H, dfm, d + r, 0)
    place(H, cross_x(r_qp) * dfm, 2 * d + r, 0)
    return H


def stiffness(scene, curvature_p=None, curvature_q=None) -> mp.matrix:
    """H (n_dof, n_dof) of an elastic scene in physical dofs; curvature_p/q: mp tensors per contact to use instead of
    the scene's (e.g. formed in mp from the scalars a file gave)."""
    d = scene.dim
    per = d + (1 if d == 2 else 3)
    H = mp.matrix(scene.n_dof, scene.n_dof)
    for c in range(scene.n_contacts):
        p, q = int(scene.p[c]), int(scene.q[c])
        Kp = curvature_p[c] if curvature_p is not None else mat(scene.curvature_p[c])
        Kq = curvature_q[c] if curvature_q is not None else mat(scene.curvature_q[c])
        B = contact_block(d, vec(scene.x[p]), vec(scene.x[q]), vec(scene.point[c]), vec(scene.normal[c]),
                          vec(scene.force[c]), Kp, Kq, mp.mpf(float(scene.k[c])), mp.mpf(float(scene.alpha[c])))
        for a, pa in enumerate((p, q)):
            for b, pb in enumerate((p, q)):
                for i in range(per):
                    for j in range(per):
                        H[pa * per + i, pb * per + j] += B[a * per + i, b * per + j]
    return H


def spectrum(scene, H: mp.matrix) -> list:
    """The eigenvalues of sym(𝓗) = P sym(H̃) P in the L metric (eq:newstiffnesses), ascending: d + r exact zeros (the
    rigid motions) and the eigenvalues of Qᵀ sym(H̃) Q on an orthonormal basis Q of their complement."""
    d, N = scene.dim, scene.n_particles
    r = 1 if d == 2 else 3
    per = d + r
    n = N * per
    radii = [mp.norm(vec(scene.point[c]) - vec(scene.x[s[c]])) for c in range(scene.n_contacts)
             for s in (scene.p, scene.q)]
    L = mp.fsum(radii) / len(radii)
    Ht = mp.matrix(n, n)
    for i in range(n):
        for j in range(n):
            si = 1 / L if i % per >= d else 1
            sj = 1 / L if j % per >= d else 1
            Ht[i, j] = si * sj * (H[i, j] + H[j, i]) / 2
    xs = [vec(scene.x[i]) for i in range(N)]
    centre = mp.matrix(d, 1)
    for x in xs:
        centre += x
    centre = centre / N
    R = mp.matrix(n, d + r)
    for i, x in enumerate(xs):
        for a in range(d):
            R[i * per + a, a] = 1
        rel = x - centre
        for a in range(r):
            e = mp.matrix([1 if b == a else 0 for b in range(3)])
            du = cross_x(e) * rel if d == 3 else mp.matrix([-rel[1], rel[0]])       # e_a × (x - c)
            for b in range(d):
                R[i * per + b, d + a] = du[b]
            R[i * per + d + a, d + a] = L
    Q, _ = mp.qr(R, mode="full")
    Qc = Q[:, d + r:]
    A = Qc.T * Ht * Qc
    A = (A + A.T) / 2
    return sorted([mp.mpf(0)] * (d + r) + list(mp.eigsy(A, eigvals_only=True)))
