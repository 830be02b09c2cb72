"""Drawing a session into one client's viser scene: particles, contacts, forces, curvature, λ⁽⁶⁾ surface, modes.

2D scenes are flat extruded shapes in the x-y plane seen from above (+z); 3D scenes are drawn as they are.
Node tree (names are per client):
  /particles/<name>            pose of the particle: transform controls when draggable, else a plain frame
  /particles/<name>/body       the animation offset (identity unless a mode is playing)
  /particles/<name>/body/mesh  the shape, in body axes;  …/body/marker  a stripe along body e1 (shows rotation)
  /contacts/…                  points, normals, force arrows, osculating arcs (world axes)
  /cell                        the outline of a periodic scene's cell
  /cell/images                 its periodic images near the faces (lighter; they move with their particles' mode)
  /field/…                     the λ⁽⁶⁾ height surface of the pair, its axes and the current-state marker
"""
from __future__ import annotations

import numpy as np

from .models import cell_edges, ghost_positions, periodic_images
from .modes import rotation_matrix

PALETTE = [(120, 170, 230), (240, 170, 110), (150, 205, 140), (215, 150, 205), (230, 215, 120), (140, 210, 210)]
MARKER = (40, 40, 60)
CELL = (90, 90, 90)                     # a periodic scene's cell outline
GHOST = (200, 215, 235)                 # periodic images of the particles near the cell's faces (lighter)
COLORS = {"point": (20, 20, 20), "normal": (60, 60, 200), "compressive": (170, 0, 0), "tensile": (30, 110, 220),
          "sliding": (215, 95, 0), "osculating": (110, 40, 160)}
Z_UP = np.array([0.0, 0.0, 1.0])
SHARE_RED = np.array([150, 0, 20])      # the colour of a particle carrying the whole of the selected mode
MESH_MAX = 400        # particles drawn as meshes; a larger packing is one point cloud (and no osculating arcs)
MAX_ARROWS = 24       # contacts drawn with force arrows (3D meshes); more contacts: force lines (no heads)


# ------------------------------------------------------------------------------------------ geometry

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


def outline(body, size: float, n: int = 96) -> np.ndarray:
    """A 2D particle's outline in body axes (counter-clockwise, star-shaped about its centre): its ellipse, with the
    socket of each concave contact side (Body.sockets) cut in. Near such a contact the outline follows the socket's
    circle over about ±1.2 size of arc (at most ±60°, and only where seen from the centre), the particle reaching
    around its partner like a glove; elsewhere the ellipse, less what lies inside a socket circle."""
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


# ------------------------------------------------------------------------------------------ the view

class SceneView:
    """Holds one client's scene handles; every method only writes handles from session data."""

    def __init__(self, scene_api):
        self.api = scene_api
        self.nodes: dict[str, object] = {}        # particle name → frame / transform controls
        self.inner: dict[str, object] = {}        # particle name → /body frame (animation offset)
        self.mesh_keys: dict[str, tuple] = {}
        self.meshes: dict[str, object] = {}       # particle name → mesh handle
        self.markers: dict[str, object] = {}      # particle name → its body-axis marker (mesh in 2D, sphere in 3D)
        self.colours: dict[str, tuple] = {}       # particle name → colour shown now
        self.colours_by_mode = False
        self.cloud = None                         # the point cloud of a large packing (one node for all)
        self._cloud_colours = None                # digest of the colours it shows
        self.contacts_frame = None                # parent of every contact drawing (hidden while a mode plays)
        self.key = None                           # (model id, particle names, draggable) the tree was built for
        self.on_drag = None                       # callback(name, event) set by the panel
        self.on_pick = None                       # callback(rho_r, f_kr): a click on the λ⁽⁶⁾ surface
        self.options = {"normals": True, "forces": True, "osculating": True, "surface": True, "force_scale": 1.0}
        self.base = {}                            # particle name → Body drawn (pose of its frame)
        self._contact_keys: dict[str, bytes] = {}     # what /contacts shows now: digest per group
        self._contact_nodes: dict[str, tuple] = {}    # /contacts/… node name → (its kind, its handle): see _put
        self._cell_key: object = False            # what /cell shows now (None: nothing; False: not drawn yet)
        self.ghosts = None                        # (point cloud, scene names, periodic_images, z) of /cell/images
        self._field_key = None                    # (field id, scale) the λ⁽⁶⁾ surface shows; None: none drawn
        self._marker = None                       # its current-state marker
        self._field_lim = 1.0                     # the largest |λ⁽⁶⁾/k| of the surface shown (its height scale)
        self.dim = 2
        self.static = False                       # a recording (app/publish.py): no drag handles, plain frames

    # particles ---------------------------------------------------------------------------------
    def draw_particles(self, session, skip: str | None = None) -> None:
        """Build the particle tree when the scene's particles change, then write poses and meshes.
        `skip`: a particle being dragged right now (the browser owns its pose until release)."""
        bodies = session.bodies()
        self.dim = session.scene_dim
        size = session.size
        key = (session.preset, tuple(b.name for b in bodies), session.draggable, self.dim)
        if len(bodies) > MESH_MAX:
            self._draw_cloud(bodies, key)
            return
        rebuilt = key != self.key
        if rebuilt:
            self.api.remove_by_name("/particles")
            self.cloud = None
            self.nodes, self.inner, self.mesh_keys, self.meshes, self.markers, self.colours = {}, {}, {}, {}, {}, {}
            self.key = key
            for body in bodies:
                name = f"/particles/{body.name}"
                if session.draggable and not self.static:
                    node = self.api.add_transform_controls(
                        name, scale=0.55 * size, active_axes=(True, True, self.dim == 3), disable_sliders=self.dim == 2,
                        depth_test=False, opacity=0.9, position=to3(body.x, 0.0), wxyz=wxyz(body.R))
                    node.on_update(self._drag_callback(body.name))
                else:
                    node = self.api.add_frame(name, show_axes=False, position=to3(body.x), wxyz=wxyz(body.R))
                self.nodes[body.name] = node
                self.inner[body.name] = self.api.add_frame(f"{name}/body", show_axes=False)
        drawn = {} if rebuilt else self.base
        for i, body in enumerate(bodies):
            node = self.nodes[body.name]
            old = drawn.get(body.name)
            moved = old is None or not (np.array_equal(old.x, body.x) and np.array_equal(old.R, body.R))
            if body.name != skip and moved:          # unchanged poses are not re-sent
                node.position = to3(body.x)
                node.wxyz = wxyz(body.R)
            mkey = (body.axes, body.sockets, round(size, 9))
            if self.mesh_keys.get(body.name) != mkey:
                self.mesh_keys[body.name] = mkey
                self._draw_body(body, PALETTE[i % len(PALETTE)], size)
        self.base = {b.name: b for b in bodies}

    def _draw_body(self, body, colour, size: float) -> None:
        """A particle's shape and its body-axis marker, in body axes: added once, then only their vertices (and faces
        where they differ) are sent when the shape changes (a pair's ρ/r: the outline, not a new node)."""
        V, F = body_mesh(body, 0.15 * size, size)
        b, w = body.axes[1], 0.06 * size       # 2D: the marker along body e2, clear of the pair's force arrows (e1)
        Vs = to3(np.array([[-w / 2, 0.2 * b], [w / 2, 0.2 * b], [w / 2, 0.92 * b], [-w / 2, 0.92 * b]]), 0.08 * size)
        mesh, marker = self.meshes.get(body.name), self.markers.get(body.name)
        if mesh is not None:                   # the tree is rebuilt when the dimension changes (draw_particles)
            mesh.vertices, mesh.faces = V, F
            if self.dim == 2:
                marker.vertices = Vs
            else:
                marker.radius, marker.position = 0.12 * size, (body.axes[0], 0.0, 0.0)
            return
        base = f"/particles/{body.name}/body"
        self.meshes[body.name] = self.api.add_mesh_simple(
            f"{base}/mesh", V, F, color=self.colours.get(body.name, colour), flat_shading=False, side="double",
            opacity=None if self.dim == 2 else 0.45)
        self.markers[body.name] = (
            self.api.add_mesh_simple(f"{base}/marker", Vs, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), color=MARKER,
                                     side="double") if self.dim == 2 else
            self.api.add_icosphere(f"{base}/marker", radius=0.12 * size, color=MARKER, position=(body.axes[0], 0.0, 0.0)))

    def _draw_cloud(self, bodies, key) -> None:
        """A large packing: one point cloud of the centres (sized by the median radius), no per-particle nodes."""
        x = np.array([to3(b.x) for b in bodies])
        cloud = digest(key, x)
        if cloud == self.key:
            return
        self.api.remove_by_name("/particles")
        self.nodes, self.inner, self.mesh_keys, self.meshes, self.markers, self.colours = {}, {}, {}, {}, {}, {}
        self.key = cloud
        radius = float(np.median([max(b.axes) for b in bodies]))
        self._cloud_colours = None
        self.cloud = self.api.add_point_cloud("/particles/cloud", points=x, colors=PALETTE[0], point_size=1.8 * radius,
                                 point_shape="circle")
        self.base = {b.name: b for b in bodies}

    def colour_particles(self, names, shares=None, colours=None) -> None:
        """Colour each particle by its share of a mode (white 0 → dark red 1), by given (N, 3) `colours` (the scan
        map), or by the palette; only the colours that change are sent (a point cloud: its colour array)."""
        if colours is None and shares is not None:
            colours = np.round(np.array([250, 250, 250]) + np.asarray(shares)[:, None] * (SHARE_RED - 250))
        if self.cloud is not None:
            rgb = np.asarray(np.tile(PALETTE[0], (len(names), 1)) if colours is None else colours, np.uint8)
            if digest((), rgb) != self._cloud_colours:
                self._cloud_colours = digest((), rgb)
                self.cloud.colors = rgb
        for i, name in enumerate(names):
            colour = PALETTE[i % len(PALETTE)] if colours is None else tuple(int(c) for c in colours[i])
            if self.colours.get(name) != colour and name in self.meshes:
                self.meshes[name].color = colour
            self.colours[name] = colour
        self.colours_by_mode = shares is not None

    def _drag_callback(self, name):
        def _(event):
            if self.on_drag is not None:
                self.on_drag(name, event)
        return _

    def pose_of(self, name: str):
        """Position (d,) and rotation (d, d) of a particle's node as the browser left it."""
        node = self.nodes[name]
        R = quat_matrix(node.wxyz)
        x = np.asarray(node.position, float)
        if self.dim == 2:
            angle = float(np.arctan2(R[1, 0], R[0, 0]))
            return x[:2], rotation_matrix(2, angle)
        return x, R

    def animate(self, bodies) -> None:
        """Show bodies displaced along a mode: local offsets of the /body frames relative to the drawn poses. The
        contact drawings belong to the undeformed state: hidden while a mode plays (stop_animation shows them)."""
        self._contacts_visible(False)
        self._animate_points(bodies)
        for body in bodies:
            base, frame = self.base.get(body.name), self.inner.get(body.name)
            if base is None or frame is None:                # not drawn, or a point of the cloud
                continue
            R0 = rot3(base.R)
            frame.position = R0.T @ (to3(body.x) - to3(base.x))
            frame.wxyz = wxyz(R0.T @ rot3(body.R))

    def _animate_points(self, bodies) -> None:
        """The point clouds along the mode: a large packing's centres, and the periodic images, each at its
        particle's displaced position plus its lattice shift (models.ghost_positions)."""
        if self.cloud is not None:
            self.cloud.points = np.array([to3(b.x) for b in bodies])
        if self.ghosts is not None:
            cloud, names, images, z = self.ghosts
            at = {b.name: b.x for b in bodies}
            cloud.points = to3(ghost_positions(np.array([at[n] for n in names]), images), z)

    def stop_animation(self) -> None:
        self._animate_points(self.base.values())
        for frame in self.inner.values():
            frame.position = (0.0, 0.0, 0.0)
            frame.wxyz = (1.0, 0.0, 0.0, 0.0)
        self._contacts_visible(True)

    def _contacts_visible(self, visible: bool) -> None:
        """Show or hide every contact drawing at once (the /contacts frame is their parent)."""
        if self.contacts_frame is not None and self.contacts_frame.visible != visible:
            self.contacts_frame.visible = visible

    def _contacts_parent(self) -> None:
        """The /contacts frame that the contact drawings hang from (made again after /contacts was removed)."""
        if self.contacts_frame is None:
            self.contacts_frame = self.api.add_frame("/contacts", show_axes=False)

    def draw_cell(self, session) -> None:
        """The outline of a periodic scene's cell (models.cell_edges) and the periodic images of the particles within
        one mean diameter of a face (models.periodic_images), re-sent only when they change."""
        scene = session.scene
        edges = None if scene is None or session.kind == "scan_map" else cell_edges(scene)
        key = None if edges is None else digest((session.size,), edges, scene.x)
        if key == self._cell_key:
            return
        self._cell_key = key
        self.api.remove_by_name("/cell")
        self.ghosts = None
        if edges is None:
            return
        self.api.add_line_segments("/cell", to3(edges, 0.0), CELL, thickness=2.0, thickness_units="screen")
        images = periodic_images(scene, 2.0 * session.size)
        if len(images[0]):
            z = -0.1 * session.size                          # under the particles they copy
            cloud = self.api.add_point_cloud("/cell/images", points=to3(ghost_positions(scene.x, images), z),
                                             colors=GHOST, point_size=1.8 * session.size, point_shape="circle")
            self.ghosts = (cloud, scene.names, images, z)

    # contacts ----------------------------------------------------------------------------------
    def draw_contacts(self, session) -> dict:
        """Points, normals, osculating arcs (the geometry) and force arrows; returns the legend numbers.

        Each of the two groups is re-sent only when what it shows changed (`digest` of its data and options): a μ
        slider move on a 143-disk frame used to re-send 1.5 MB of drawings and cost the browser ≈ 8 s."""
        scene, size, o = session.scene, session.size, self.options
        if scene is None or scene.n_contacts == 0 or session.kind == "scan_map":     # a map: particles, and a
            self._draw_map_contacts(session)                                         # rigidity map's contacts
            return {"max_force": 0.0, "arrow": 0.0}
        if "map" in self._contact_keys:                  # back from a rigidity map: its contacts go
            self.api.remove_by_name("/contacts")
            self.contacts_frame, self._contact_keys, self._contact_nodes = None, {}, {}
        z = 0.1 * size if scene.dim == 2 else 0.0
        P = to3(scene.point, z)
        self._contacts_parent()
        geometry = digest((size, o["normals"], o["osculating"]), scene.point, scene.normal, scene.curvature_p,
                          scene.curvature_q)
        if self._contact_keys.get("geometry") != geometry:
            self._contact_keys["geometry"] = geometry
            self._draw_geometry(scene, size, P, z)
        fmag = np.linalg.norm(scene.force, axis=1)
        fmax = float(fmag.max())
        arrow = 0.6 * size * o["force_scale"]
        yielding = scene.at_yield()
        forces = digest((size, o["forces"], o["force_scale"]), scene.point, scene.normal, scene.force, yielding)
        if self._contact_keys.get("forces") != forces:
            self._contact_keys["forces"] = forces
            if o["forces"] and fmax > 0:
                self._draw_forces(scene, size, P, fmag, fmax, arrow, yielding)
            else:
                self._drop("/contacts/forces")
        return {"max_force": fmax, "arrow": arrow / size, "lines": scene.n_contacts > MAX_ARROWS}

    def _draw_map_contacts(self, session) -> None:
        """On a map, the contacts the model colours (a rigidity map: centre to centre, by cluster, floppy grey;
        `contact_colours`), above the particles; none on a scan map, nor off the map."""
        scene = session.scene
        colours = getattr(session.model, "contact_colours", None) if scene is not None else None
        key = None if colours is None else digest((session.size,), scene.x, scene.branch, colours)
        if self._contact_keys.get("map") == key and (key is not None or not self._contact_keys):
            return
        self.api.remove_by_name("/contacts")
        self.contacts_frame, self._contact_keys, self._contact_nodes = None, {}, {}
        if key is None:
            return
        self._contacts_parent()
        self._contact_keys["map"] = key
        z = 0.15 * session.size if scene.dim == 2 else 0.0
        start = scene.x[scene.p]
        segments = np.stack([to3(start, z), to3(start + scene.branch, z)], axis=1)
        self.api.add_line_segments("/contacts/clusters", segments, np.repeat(colours[:, None], 2, axis=1),
                                   thickness=3.0, thickness_units="screen")

    def _draw_geometry(self, scene, size, P, z) -> None:
        self._put("/contacts/points", "points", P, COLORS["point"], point_size=0.08 * size, point_shape="circle")
        if self.options["normals"]:
            n = to3(scene.normal, 0.0)
            self._put("/contacts/normals", "lines", np.stack([P, P + 0.5 * size * n], axis=1), COLORS["normal"],
                      thickness=2.5, thickness_units="screen")
        else:
            self._drop("/contacts/normals")
        data = circle_data(scene, size) if self.options["osculating"] and scene.n_contacts <= MESH_MAX else None
        if data is None:                                 # (arcs of thousands of contacts: clutter)
            self._drop("/contacts/osculating")
            return
        pts, cen, rad, nout, tan = data
        cen = cen + np.array([0, 0, z]) if scene.dim == 2 else cen
        self._put("/contacts/osculating", "lines", osculating_arcs(pts, cen, rad, nout, tan, size),
                  COLORS["osculating"], thickness=1.5, thickness_units="screen")

    def _put(self, name: str, kind: str, points, colors, **style) -> None:
        """Show node `name` of `kind` ("points", "lines", "arrows"): where it is there with as many points, only its
        changed properties are sent (viser skips equal ones); else it is added anew (a new node: its data, pose and
        visibility, after the old one's removal)."""
        old = self._contact_nodes.get(name)
        if old is not None and old[0] == kind and old[1].points.shape == np.shape(points):
            handle = old[1]
            handle.points, handle.colors = points, np.asarray(colors, np.uint8)
            for key, value in style.items():
                setattr(handle, key, value)
            return
        add = {"points": self.api.add_point_cloud, "lines": self.api.add_line_segments,
               "arrows": self.api.add_arrows}[kind]
        self._contact_nodes[name] = (kind, add(name, points=points, colors=colors, **style))

    def _drop(self, name: str) -> None:
        """Remove node `name` if it is shown."""
        old = self._contact_nodes.pop(name, None)
        if old is not None:
            old[1].remove()

    def _draw_forces(self, scene, size, P, fmag, fmax, arrow, yielding) -> None:
        f = to3(scene.force, 0.0) / fmax * arrow                  # f^pq: on p; -f^pq on q
        fn = np.sum(scene.force * scene.normal, axis=1)
        color = np.where(yielding[:, None], COLORS["sliding"],
                         np.where((fn > 0)[:, None], COLORS["tensile"], COLORS["compressive"]))
        keep = fmag > 1e-12 * fmax
        starts = np.concatenate([P[keep], P[keep]])
        ends = np.concatenate([P[keep] + f[keep], P[keep] - f[keep]])
        colors = np.concatenate([color[keep], color[keep]]).astype(np.uint8)
        if scene.n_contacts > MAX_ARROWS:      # arrow meshes cost the browser ~25 ms each to rebuild: lines instead
            self._put("/contacts/forces", "lines", np.stack([starts, ends], axis=1),
                      np.repeat(colors[:, None], 2, axis=1), thickness=3.0, thickness_units="screen")
            return
        shaft = 0.035 * size
        self._put("/contacts/forces", "arrows", np.stack([starts, ends], axis=1), colors,
                  shaft_radius=shaft, head_radius=2.5 * shaft, head_length=min(0.15 * size, 0.3 * arrow))

    # the λ⁽⁶⁾ surface --------------------------------------------------------------------------
    def field_frame(self, field, size: float):
        """Where the surface sits: below the pair, x over ρ/r in [-1, 3]·r, y over f/(kr) in [-4.6, -2]·r."""
        x0, x1, y0, y1 = -1.0 * size, 3.0 * size, -4.6 * size, -2.0 * size

        def place(rho_r, f_kr):
            X = x0 + (np.asarray(rho_r) - field.rho_r[0]) / (field.rho_r[-1] - field.rho_r[0]) * (x1 - x0)
            Y = y0 + (np.asarray(f_kr) - field.f_kr[0]) / (field.f_kr[-1] - field.f_kr[0]) * (y1 - y0)
            return X, Y
        return place, (x0, x1, y0, y1)

    def draw_field(self, session, field, current) -> None:
        """The λ⁽⁶⁾/k field as a coloured height surface (red < 0, blue > 0) with the current state marked: the surface
        is sent once per field, then only the marker moves (its position: one small message per slider move)."""
        if field is None or not self.options["surface"]:
            self.clear_field()
            return
        size = session.field_scale      # fixed per pair: the cached surface and the marker share it
        key = (id(field), size)
        if self._field_key != key:
            self._field_key = key
            self._draw_surface(field, size)
        place, _ = self.field_frame(field, size)
        rho_r, f_kr, lam = current
        cx, cy = place(rho_r, f_kr)
        cz = (0.0 if lam is None else float(np.clip(lam / self._field_lim, -1.5, 1.5))) * 0.8 * size
        self._marker.position = (float(cx), float(cy), cz + 0.05 * size)

    def _draw_surface(self, field, size: float) -> None:
        """The surface, its frame, axis labels and the current-state marker (placed by draw_field)."""
        import trimesh
        place, (x0, x1, y0, y1) = self.field_frame(field, size)
        lim = self._field_lim = float(np.abs(field.lam).max()) or 1.0       # the height scale (1: a zero field)
        R, F = np.meshgrid(field.rho_r, field.f_kr)
        X, Y = place(R, F)
        Z = field.lam / lim * 0.8 * size
        V = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
        nr, nf = len(field.rho_r), len(field.f_kr)
        idx = np.arange(nr * nf).reshape(nf, nr)
        a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
        faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
        v = field.lam.reshape(-1) / lim
        colors = diverging(np.sign(v) * np.sqrt(np.abs(v)))     # √ stretch: the small values near 0 show too
        mesh = trimesh.Trimesh(V, faces, vertex_colors=colors, process=False)
        surface = self.api.add_mesh_trimesh("/field/surface", mesh)
        surface.on_click(lambda event: self._picked(event, field, place, Z))
        self.api.add_line_segments("/field/frame", np.array([
            [[x0, y0, 0], [x1, y0, 0]], [[x1, y0, 0], [x1, y1, 0]], [[x1, y1, 0], [x0, y1, 0]],
            [[x0, y1, 0], [x0, y0, 0]]]), (90, 90, 90), thickness=1.5, thickness_units="screen")
        self.api.add_label("/field/xlabel", "ρ/r →", position=(0.5 * (x0 + x1), y0 - 0.25 * size, 0))
        self.api.add_label("/field/ylabel", "f/(kr) ↑", position=(x0 - 0.55 * size, 0.5 * (y0 + y1), 0))
        self.api.add_label("/field/title", "λ⁽⁶⁾/k: red < 0 < blue", position=(0.5 * (x0 + x1), y1 + 0.25 * size, 0))
        self._marker = self.api.add_icosphere("/field/current", radius=0.09 * size, color=(255, 200, 0))

    def _picked(self, event, field, place, Z) -> None:
        """A click on the surface: march along the ray to where it meets the height field, report (ρ/r, f/(kr))."""
        if self.on_pick is None:
            return
        hit = ray_heightfield(np.asarray(event.ray_origin), np.asarray(event.ray_direction), field, place, Z)
        if hit is not None:
            self.on_pick(*hit)

    def clear_field(self) -> None:
        """No surface (another scene, or switched off): removed once, nothing sent while there is none."""
        if self._field_key is not None:
            self._field_key = self._marker = None
            self.api.remove_by_name("/field")



def digest(small, *arrays) -> bytes:
    """A short digest of a small tuple and some arrays: what a drawing shows, to skip re-sending it unchanged."""
    import hashlib
    h = hashlib.blake2b(repr(small).encode(), digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.digest()


def ray_heightfield(origin, direction, field, place, Z, n: int = 2000):
    """First crossing of the ray with the surface z = Z(ρ/r, f/(kr)) placed by `place`, as (ρ/r, f/(kr)) or None."""
    from scipy.interpolate import RegularGridInterpolator
    xs, _ = place(field.rho_r, field.f_kr[0])
    _, ys = place(field.rho_r[0], field.f_kr)
    height = RegularGridInterpolator((ys, xs), Z, bounds_error=False, fill_value=np.nan)
    span = 4.0 * max(xs[-1] - xs[0], ys[-1] - ys[0]) + np.linalg.norm(origin)
    t = np.linspace(0.0, span, n)
    pts = origin + t[:, None] * direction / np.linalg.norm(direction)
    gap = pts[:, 2] - height(pts[:, [1, 0]])
    inside = np.flatnonzero(np.isfinite(gap[:-1]) & np.isfinite(gap[1:]) & (np.sign(gap[:-1]) != np.sign(gap[1:])))
    if inside.size == 0:
        return None
    k = inside[0]
    w = gap[k] / (gap[k] - gap[k + 1])
    x, y = (pts[k] + w * (pts[k + 1] - pts[k]))[:2]
    rho = field.rho_r[0] + (x - xs[0]) / (xs[-1] - xs[0]) * (field.rho_r[-1] - field.rho_r[0])
    f = field.f_kr[0] + (y - ys[0]) / (ys[-1] - ys[0]) * (field.f_kr[-1] - field.f_kr[0])
    return float(rho), float(f)


def diverging(v: np.ndarray) -> np.ndarray:
    """RGBA uint8 of values in [-1, 1]: red (negative) – white (0) – blue (positive), like the contour plot."""
    v = np.clip(np.asarray(v, float), -1, 1)[:, None]
    red, white, blue = np.array([178, 24, 43]), np.array([247, 247, 247]), np.array([33, 102, 172])
    rgb = np.where(v < 0, white + (-v) * (red - white), white + v * (blue - white))
    return np.concatenate([rgb, np.full((len(rgb), 1), 255)], axis=1).astype(np.uint8)
