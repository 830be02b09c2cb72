"""Drawing a session into one client's viser scene: particles, contacts, forces, curvature, λ⁽⁶⁾ surface, modes.

2D scenes are flat extruded shapes in the x-y plane seen from above (+z); 3D scenes are drawn as they are.
Node tree (names are per client):
  /particles/<name>            pose of the particle: transform controls when draggable, else a plain frame
  /particles/<name>/body       the animation offset (identity unless a mode is playing)
  /particles/<name>/body/mesh  the shape, in body axes;  …/body/marker  a stripe along body e1 (shows rotation)
  /particles/grains/<k>        3D grains as they are (superquadrics, clumps): shared meshes, instanced (grainview.py)
  /contacts/…                  points, normals, force arrows, osculating arcs (world axes)
  /cell                        the outline of a periodic scene's cell
  /cell/images                 its periodic images near the faces (lighter; they move with their particles' mode)
  /field/…                     the λ⁽⁶⁾ height surface of the pair, its axes and the current-state marker
"""
from __future__ import annotations

import numpy as np

from .cellview import OverlayView
from .fieldview import FieldView
from .grainview import GrainView
from .meshes import body_mesh, circle_data, digest, osculating_arcs, outline, quat_matrix, rot3, to3, wxyz
from .modes import rotation_matrix

PALETTE = [(120, 170, 230), (240, 170, 110), (150, 205, 140), (215, 150, 205), (230, 215, 120), (140, 210, 210)]
MARKER = (40, 40, 60)
COLORS = {"point": (20, 20, 20), "normal": (60, 60, 200), "compressive": (170, 0, 0), "tensile": (30, 110, 220),
          "sliding": (215, 95, 0), "osculating": (110, 40, 160)}
Z_UP = np.array([0.0, 0.0, 1.0])
SHARE_RED = np.array([150, 0, 20])      # the colour of a particle carrying the whole of an unstable mode
REST, MOTION = (120, 120, 120), (20, 120, 60)    # the rest position's ghost outline, the mode's motion arrows
SHARE_BLUE = np.array([20, 70, 150])    # … of a mode that is not unstable (red is read as danger)
MESH_MAX = 400        # particles drawn as meshes; a larger packing is one point cloud (and no osculating arcs)
MAX_ARROWS = 24       # contacts drawn with force arrows (3D meshes); more contacts: force lines (no heads)


# ------------------------------------------------------------------------------------------ the view

class SceneView(FieldView, OverlayView, GrainView):
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
        self.grains, self.grain_nodes = [], []    # 3D grains drawn as they are: instanced meshes (grainview.py)
        self._cloud_colours = None                # digest of the colours it shows
        self._cloud_of, self._cloud_arrays = None, None   # the bodies list the cloud was formed from, its arrays
        self.contacts_frame = None                # parent of every contact drawing (hidden while a mode plays)
        self.key = None                           # (model id, particle names, draggable) the tree was built for
        self.drawn = None                         # what the particles are drawn as (text.PARTICLE_LEGEND's keys)
        self.on_drag = None                       # callback(name, event) set by the panel
        self.on_pick = None                       # callback(rho_r, f_kr): a click on the λ⁽⁶⁾ surface
        self.options = {"normals": True, "forces": True, "osculating": True, "surface": True, "force_scale": 1.0}
        self.base = {}                            # particle name → Body drawn (pose of its frame)
        self._contact_keys: dict[str, bytes] = {}     # what /contacts shows now: digest per group
        self._contact_nodes: dict[str, tuple] = {}    # /contacts/… node name → (its kind, its handle): see _put
        self._cell_key: object = False            # what /cell shows now (None: nothing; False: not drawn yet)
        self.ghosts = None                        # the periodic images of /cell/images (cellview.Images)
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
        grain = bodies[0].kind if bodies and bodies[0].grain else None
        self.drawn = ("cloud" if len(bodies) > MESH_MAX and not (grain and self.dim == 3) else
                      grain or ("stripe" if self.dim == 2 else "dot"))           # what the legend names
        if self.drawn == "cloud":                    # keyed by its arrays: no per-particle tuple each redraw
            self.draw_cloud(bodies, (session.preset, session.draggable, self.dim), PALETTE[0])
            return
        size = session.size
        key = (session.preset, tuple(b.name for b in bodies), session.draggable, self.dim)
        if self.dim == 3 and grain:                  # superquadrics, clumps: instanced, any number
            self.draw_grains(bodies, key, PALETTE)
            return
        rebuilt = key != self.key
        if rebuilt:
            self.api.remove_by_name("/particles")
            self.clear_particles()
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
            mkey = (body.axes, body.sockets, body.grain, round(size, 9))
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

    def colour_particles(self, names, shares=None, colours=None, unstable: bool = True) -> None:
        """Colour each particle by its share of a mode (white 0 → dark red 1 where the mode is `unstable`, else
        white → dark blue), by given (N, 3) `colours` (the scan
        map), or by the palette; only the colours that change are sent (a point cloud: its colour array)."""
        if colours is None and shares is not None:
            top = SHARE_RED if unstable else SHARE_BLUE
            colours = np.round(np.array([250, 250, 250]) + np.asarray(shares)[:, None] * (top - 250))
        if self.cloud is not None:
            rgb = np.asarray(np.tile(PALETTE[0], (len(names), 1)) if colours is None else colours, np.uint8)
            if digest((), rgb) != self._cloud_colours:
                self._cloud_colours = digest((), rgb)
                self.cloud.colors = rgb
        self.colour_grains(names, colours, PALETTE)
        if self.cloud is not None and not self.meshes:     # the cloud's colour array is all there is to colour
            self.colours_by_mode = shares is not None
            return
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
        self.move_grains(bodies)
        for body in bodies:
            base, frame = self.base.get(body.name), self.inner.get(body.name)
            if base is None or frame is None:                # not drawn, or a point of the cloud
                continue
            R0 = rot3(base.R)
            frame.position = R0.T @ (to3(body.x) - to3(base.x))
            frame.wxyz = wxyz(R0.T @ rot3(body.R))

    def _animate_points(self, bodies) -> None:
        """The point clouds along the mode: a large packing's centres, and the periodic images, each at its
        particle's displaced position plus its lattice shift (scenes.ghost_positions)."""
        if self.cloud is not None:
            self.cloud.points = np.array([to3(b.x) for b in bodies])
        if self.ghosts is not None:
            self.ghosts.move(bodies)

    def show_rest(self, rest, peak, size: float) -> None:
        """While a mode plays: a ghost of the rest position (each 2D particle's outline, grey) and an arrow from each
        particle's body-axis tip at rest to where the mode's largest displacement takes it (`peak`: the bodies there),
        so that what moves, and which way, reads on a still picture too (the pair's rolling turns in place)."""
        self.api.remove_by_name("/rest")
        rings = [(b.x + outline(b, size, 64) @ np.asarray(b.R).T) for b in rest if len(b.axes) == 2]
        if rings and len(rings) <= MESH_MAX:
            segs = np.concatenate([np.stack([to3(r, 0.1 * size), to3(np.roll(r, -1, axis=0), 0.1 * size)], axis=1)
                                   for r in rings])
            self.api.add_line_segments("/rest/outline", segs, REST, thickness=2.0, thickness_units="screen")
        start = np.array([to3(tip(b), 0.12 * size) for b in rest])      # a rotation in place moves the tip too
        end = np.array([to3(tip(b), 0.12 * size) for b in peak])
        moving = np.linalg.norm(end - start, axis=1) > 0.02 * size
        if moving.any() and moving.sum() <= MAX_ARROWS:
            shaft = 0.03 * size
            self.api.add_arrows("/rest/motion", points=np.stack([start[moving], end[moving]], axis=1),
                                colors=MOTION, shaft_radius=shaft, head_radius=2.5 * shaft, head_length=0.15 * size)

    def stop_animation(self) -> None:
        self.api.remove_by_name("/rest")
        self._animate_points(self.base.values())
        self.move_grains(list(self.base.values()))
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

    # contacts ----------------------------------------------------------------------------------
    def draw_contacts(self, session) -> dict:
        """Points, normals, osculating arcs (the geometry) and force arrows; returns the legend numbers.

        Each of the two groups is re-sent only when what it shows changed (`digest` of its data and options): a μ
        slider move on a 143-disk frame used to re-send 1.5 MB of drawings and cost the browser ≈ 8 s."""
        scene, size, o = session.scene, session.size, self.options
        if scene is None or scene.n_contacts == 0 or session.on_map:     # a map: particles, and a
            self._draw_map_contacts(session)                                         # rigidity map's contacts
            return {"max_force": 0.0, "arrow": 0.0, "drawn": self.drawn}
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
        return {"max_force": fmax, "arrow": arrow / size, "lines": scene.n_contacts > MAX_ARROWS, "drawn": self.drawn}

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


def tip(body) -> np.ndarray:
    """The end of a body's first axis (where its drawn stripe ends): moves with its translation and its rotation."""
    return np.asarray(body.x, float) + np.asarray(body.R, float)[:, 0] * body.axes[0]
