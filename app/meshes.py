"""The explorer's drawing geometry, numpy only: 2D/3D conversions, rotations as quaternions, particle meshes (an
extruded 2D outline with its sockets, an ellipsoid) and the osculating circles of every contact. app/views.py puts
them in the viser scene.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from granstab.model.outline import rounded_polygon


def to3(v: np.ndarray, z: float = 0.0) -> np.ndarray:
    """(…, 2) → (…, 3) with the given z; 3D input is returned as is."""
    v = np.asarray(v, float)
    if v.shape[-1] == 3:
        return v
    return np.concatenate([v, np.full(v.shape[:-1] + (1,), z)], axis=-1)


def rot3(R: np.ndarray) -> np.ndarray:
    R = np.asarray(R, float)
    if R.shape == (3, 3):
        return R
    out = np.eye(3)
    out[:2, :2] = R
    return out


def wxyz(R: np.ndarray) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation matrix (2D: about e3)."""
    R = rot3(R)
    w = np.sqrt(max(0.0, 1.0 + np.trace(R))) / 2
    if w > 1e-6:
        return np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)])
    i = int(np.argmax(np.diag(R)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = np.sqrt(max(0.0, 1.0 + R[i, i] - R[j, j] - R[k, k])) * 2
    q = np.zeros(4)
    q[0] = (R[k, j] - R[j, k]) / s
    q[1 + i] = s / 4
    q[1 + j] = (R[j, i] + R[i, j]) / s
    q[1 + k] = (R[k, i] + R[i, k]) / s
    return q


def quaternions(R: np.ndarray) -> np.ndarray:
    """Quaternions (N, 4) (w, x, y, z) of rotation matrices (N, 3, 3), vectorised (scipy's Rotation: many grains'
    instances at once; `wxyz` stays the one-body path of the disk and sphere scenes)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(np.asarray(R, float)).as_quat()[:, [3, 0, 1, 2]]


def quat_matrix(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def extruded_outline(ring: np.ndarray, thickness: float):
    """Vertices (4n+2, 3) and faces of a closed outline (n, 2), counter-clockwise and star-shaped about the origin,
    extruded along z by `thickness` (centred). The sides have vertices of their own: shared with the faces, their
    smoothed normals shade a face's long thin triangles (a socket's rim) in stripes."""
    n = len(ring)
    h = thickness / 2
    V = np.concatenate([to3(ring, h), to3(ring, -h), [[0, 0, h], [0, 0, -h]], to3(ring, h), to3(ring, -h)])
    i = np.arange(n)
    j = (i + 1) % n
    top = np.stack([np.full(n, 2 * n), i, j], axis=1)
    bottom = np.stack([np.full(n, 2 * n + 1), n + j, n + i], axis=1)
    i, j = i + 2 * n + 2, j + 2 * n + 2
    side = np.concatenate([np.stack([i, n + i, n + j], axis=1), np.stack([i, n + j, j], axis=1)])
    return V, np.concatenate([top, bottom, side]).astype(np.uint32)


def ellipsoid(axes, n_lat: int = 24, n_lon: int = 48):
    """Vertices and faces of an ellipsoid with semi-axes `axes` (UV sphere scaled)."""
    th = np.linspace(0, np.pi, n_lat + 1)
    ph = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    V = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3) * np.asarray(axes)
    faces = []
    for i in range(n_lat):
        for j in range(n_lon):
            a, b = i * n_lon + j, i * n_lon + (j + 1) % n_lon
            c, d = a + n_lon, b + n_lon
            faces += [[a, c, b], [b, c, d]]
    return V, np.array(faces, dtype=np.uint32)


def body_mesh(body, thickness: float, size: float):
    if len(body.axes) == 2:
        return extruded_outline(outline(body, size), thickness)
    return ellipsoid(body.axes)


@dataclass(frozen=True)
class Instances:
    """One shared mesh drawn many times (viser's batched meshes): vertices (V, 3) and faces (F, 3) in body axes,
    and per instance the body it belongs to (K,) (an index into the bodies), its offset from that body's centre
    in body axes (K, 3) and its uniform scale (K,)."""

    key: tuple
    vertices: np.ndarray
    faces: np.ndarray
    body: np.ndarray
    offset: np.ndarray
    scale: np.ndarray

    def poses(self, x: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Instance positions (K, 3) and quaternions (K, 4) for body centres x (N, 3) and rotations R (N, 3, 3):
        x_b + R_b offset, R_b (a body moves and turns rigidly with its parts)."""
        Rb = R[self.body]
        return x[self.body] + np.einsum("kij,kj->ki", Rb, self.offset), quaternions(Rb)


def grain_instances(bodies, resolution: int = 16) -> list[Instances]:
    """The 3D grains of `bodies` (models.grain_bodies) as instanced meshes: one mesh per distinct superquadric
    (granstab.model.surface.mesh, the one shape kernel), one unit sphere for every clump's member spheres (scaled
    by each sphere's radius)."""
    from granstab.model.surface import Superquadric, mesh
    groups: dict[tuple, list] = {}
    for i, body in enumerate(bodies):
        if body.kind == "superquadric":
            groups.setdefault(body.grain, []).append((i, (0.0, 0.0, 0.0), 1.0))
        else:
            groups.setdefault(("sphere",), []).extend((i, part[:3], part[3]) for part in body.grain[1])
    out = []
    for key, items in groups.items():
        shape = Superquadric(*key[1:]) if key[0] == "superquadric" else Superquadric(1.0, 1.0, 1.0)
        V, F = mesh(shape, resolution)
        body, offset, scale = zip(*items)
        out.append(Instances(key, V, F.astype(np.uint32), np.array(body), np.array(offset, float), np.array(scale)))
    return out


def outline(body, size: float, n: int = 96) -> np.ndarray:
    """A 2D particle's outline in body axes (counter-clockwise, star-shaped about its centre): its ellipse, with the
    socket of each concave contact side (Body.sockets) cut in. Near such a contact the outline follows the socket's
    circle over about ±1.2 size of arc (at most ±60°, and only where seen from the centre), the particle reaching
    around its partner like a glove; elsewhere the ellipse, less what lies inside a socket circle. A rounded polygon
    (models.grain_bodies): its rounded outline (granstab.model.outline.rounded_polygon, the one kernel)."""
    if body.kind == "rounded_polygon":
        _, vertices, radius = body.grain
        return rounded_polygon(np.array(vertices), radius)
    a, b = body.axes[0], body.axes[1]
    arcs = [arc for arc in (socket_arc(*socket, size) for socket in body.sockets) if arc is not None]

    def base(angle):                                 # the ellipse along each direction, cut back by the sockets
        u = np.stack([np.cos(angle), np.sin(angle)], axis=1)
        r = a * b / np.hypot(b * u[:, 0], a * u[:, 1])
        for _, c, rho in arcs:                       # the ray t·u meets |y - c| = ρ at t = u·c ∓ √((u·c)² - c² + ρ²)
            half = u @ c
            disc = half ** 2 - (c @ c - rho ** 2)
            t = half - np.sqrt(np.maximum(disc, 0.0))
            r = np.where((disc >= 0) & (t > 0), np.minimum(r, t), r)
        return r[:, None] * u

    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    theta = np.arctan2(b * np.sin(t), a * np.cos(t))     # evenly in the ellipse's parameter: its tips well drawn
    keep = np.ones(n, bool)
    points, angles, ranks = [], [], []
    for arc, _, _ in arcs:
        ang = np.arctan2(arc[:, 1], arc[:, 0])       # monotonic along the seen part of a circle
        if np.angle(np.exp(1j * (ang[-1] - ang[0]))) < 0:
            arc, ang = arc[::-1], ang[::-1]          # counter-clockwise
        span = np.mod(ang[-1] - ang[0], 2 * np.pi)
        keep &= np.mod(theta - ang[0], 2 * np.pi) > span     # the socket replaces the ellipse over its directions
        ends = ang[[0, -1]]                          # radial sides: the ellipse, then the socket, then the ellipse
        points += [base(ends[:1]), arc, base(ends[1:])]
        angles += [ends[:1], ang, ends[1:]]
        ranks += [[0], np.ones(len(ang)), [2]]
    points.append(base(theta[keep]))
    angles.append(theta[keep])
    ranks.append(np.ones(keep.sum()))
    order = np.lexsort((np.concatenate(ranks), np.mod(np.concatenate(angles), 2 * np.pi)))
    return np.concatenate(points)[order]


def fans(rings: list) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Closed outlines (each (n_g, 2), star-shaped about its origin) as one filled mesh: each a fan of triangles about
    its centre. Returns ((owner (V,): the outline of each vertex, points (V, 2) in its body axes), faces (F, 3))."""
    owner, points, faces, start = [], [], [], 0
    for g, ring in enumerate(rings):
        n = len(ring)
        i = np.arange(n)
        owner.append(np.full(n + 1, g))
        points.append(np.concatenate([[[0.0, 0.0]], ring]))
        faces.append(start + np.stack([np.zeros(n, int), 1 + i, 1 + (i + 1) % n], axis=1))
        start += n + 1
    return (np.concatenate(owner), np.concatenate(points)), np.concatenate(faces).astype(np.uint32)


def socket_arc(cx: float, cy: float, rho: float, angle: float, size: float, m: int = 48):
    """The drawn part of a socket (Body.sockets: its circle's centre c relative to the particle's centre, radius ρ,
    direction from c to the contact): (points (m, 2) on the circle, c, ρ), or None where the particle's centre is
    inside the circle or does not see the contact point. The arc spans ±1.2 size (at most ±60°) about the contact,
    within 0.9 of the half-angle seen from the centre (the outline stays star-shaped about it)."""
    c = np.array([cx, cy])
    d = float(np.hypot(cx, cy))
    if d <= rho:
        return None
    towards = np.arctan2(-cy, -cx)                   # from c to the particle's centre
    seen = 0.9 * np.arccos(rho / d)
    at = np.angle(np.exp(1j * (angle - towards)))    # the contact, relative to `towards`
    half = min(np.pi / 3, 1.2 * size / rho)
    if abs(at) >= seen:
        return None
    alpha = towards + np.linspace(max(at - half, -seen), min(at + half, seen), m)
    return c + rho * np.stack([np.cos(alpha), np.sin(alpha)], axis=1), c, rho


def osculating_arcs(points, centres, radii, normals_out, planes, size: float, n: int = 40) -> np.ndarray:
    """Line segments (K·n, 2, 3) of osculating arcs: circle of radius ρ about `centres` through `points`, in the
    plane spanned by the outward normal and `planes` (unit tangents), over an arc length of about ±1.2 size."""
    segs = []
    for _p, c, rho, nout, t in zip(points, centres, radii, normals_out, planes):
        half = min(0.8 * np.pi, 1.2 * size / rho)
        ang = np.linspace(-half, half, n)
        arc = c + rho * (np.cos(ang)[:, None] * nout + np.sin(ang)[:, None] * t)
        segs.append(np.stack([arc[:-1], arc[1:]], axis=1))
    return np.concatenate(segs) if segs else np.zeros((0, 2, 3))


def circle_data(scene, size: float):
    """Centres, radii, outward normals and tangents of the osculating circles of both sides of every contact
    (convex directions only: principal radii ρ = -1/κ > 0; flat or concave directions are skipped)."""
    from granstab.model.vec import tangent_basis
    pts, cen, rad, nout, tan = [], [], [], [], []
    T = tangent_basis(scene.normal)                                   # (M, d, d-1)
    for _side, K, sign in (("p", scene.curvature_p, -1.0), ("q", scene.curvature_q, 1.0)):
        Kt = np.swapaxes(T, 1, 2) @ K @ T
        lam, V = np.linalg.eigh(0.5 * (Kt + np.swapaxes(Kt, 1, 2)))
        for c in range(scene.n_contacts):
            for i in range(lam.shape[1]):
                if lam[c, i] >= -1e-12:
                    continue
                rho = -1.0 / lam[c, i]
                n_out = -sign * scene.normal[c]      # unit vector from the centre of curvature to the point
                pts.append(scene.point[c])
                cen.append(scene.point[c] + sign * rho * scene.normal[c])
                rad.append(rho)
                nout.append(n_out)
                tan.append(T[c] @ V[c, :, i])
    if not pts:
        return None
    return tuple(to3(np.array(a)) for a in (pts, cen)) + (np.array(rad),) + tuple(to3(np.array(a)) for a in (nout, tan))


def digest(small, *arrays) -> bytes:
    """A short digest of a small tuple and some arrays: what a drawing shows, to skip re-sending it unchanged."""
    import hashlib
    h = hashlib.blake2b(repr(small).encode(), digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.digest()
