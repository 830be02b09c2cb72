"""What the 3D view draws besides particles and contact forces: a periodic scene's cell outline with the periodic
images near its faces, and a map's coloured contacts. A base of app/views.py's SceneView (its `api`, `_cell_key`,
`_contact_keys`, … ).
"""
from __future__ import annotations

import numpy as np

from .meshes import digest, fans, grain_instances, outline, rot3, to3
from .scenes import IMAGE_REACH, Body, cell_edges, ghost_positions, periodic_images

CELL = (90, 90, 90)                     # a periodic scene's cell outline
GHOST = (200, 215, 235)                 # periodic images of the particles near the cell's faces (lighter)
GHOST_OPACITY = 0.15                    # 3D grains' images: faint beside the grains (0.6), which they surround


class Images:
    """The periodic images drawn beside the cell (`periodic_images`: ghost g copies particle index[g], shifted by
    shift[g]) and how they follow their particles: a point cloud of disks and spheres; grains as they are, each
    image with its particle's shape and orientation at the shifted position (3D: instanced meshes,
    meshes.grain_instances; 2D rounded polygons: their outlines, filled, in one mesh)."""

    def __init__(self, api, bodies, names, images, z: float, size: float):
        self.names, self.images, self.z = names, images, z
        index = images[0]
        self.groups, self.rings = [], None
        if not (bodies and bodies[0].grain):
            self.handles = [api.add_point_cloud("/cell/images", points=self._poses(bodies)[0], colors=GHOST,
                                                point_size=1.8 * size, point_shape="circle")]
        elif len(bodies[0].axes) == 3:
            self.groups = grain_instances([bodies[i] for i in index])
            x, R = self._poses(bodies)
            self.handles = []
            for k, group in enumerate(self.groups):
                position, quat = group.poses(x, R)
                self.handles.append(api.add_batched_meshes_simple(
                    f"/cell/images/{k}", group.vertices, group.faces, batched_wxyzs=quat, batched_positions=position,
                    batched_scales=group.scale, batched_colors=np.tile(np.array(GHOST, np.uint8), (len(group.body), 1)),
                    opacity=GHOST_OPACITY, side="double", lod="off"))
        else:
            self.rings, faces = fans([outline(bodies[i], size) for i in index])
            self.handles = [api.add_mesh_simple("/cell/images", self._outlines(bodies), faces, color=GHOST,
                                                side="double")]

    def _poses(self, bodies) -> tuple[np.ndarray, np.ndarray]:
        """Each image's position (G, 3) and rotation (G, 3, 3): its particle's, shifted by its lattice vector."""
        at = {b.name: b for b in bodies}
        mine = [at[n] for n in self.names]
        x = to3(ghost_positions(np.array([b.x for b in mine]), self.images), self.z)
        return x, np.array([rot3(mine[i].R) for i in self.images[0]])

    def _outlines(self, bodies) -> np.ndarray:
        """The 2D images' fan vertices (meshes.fans) in the world: x_g + R_g v."""
        x, R = self._poses(bodies)
        ghost, local = self.rings
        return x[ghost] + np.einsum("kij,kj->ki", R[ghost], to3(local))

    def move(self, bodies) -> None:
        """Every image at its particle's pose now (a mode's frame, or the rest poses), shifted: a periodic mode
        moves every copy of a particle alike."""
        if self.groups:
            x, R = self._poses(bodies)
            for group, handle in zip(self.groups, self.handles):
                handle.batched_positions, handle.batched_wxyzs = group.poses(x, R)
        elif self.rings is not None:
            self.handles[0].vertices = self._outlines(bodies)
        else:
            self.handles[0].points = self._poses(bodies)[0]


class OverlayView:
    def draw_cell(self, session) -> None:
        """The outline of a periodic scene's cell (scenes.cell_edges; a periodic track's frame too) and, off a map, the
        periodic images of the particles within one mean diameter of a face (scenes.periodic_images), re-sent only
        when they change."""
        scene = session.scene
        edges = None if scene is None else cell_edges(scene)
        key = None if edges is None else digest((session.size, repr(self.key)), edges, scene.x)
        if key == self._cell_key:
            return
        self._cell_key = key
        self.api.remove_by_name("/cell")
        self.ghosts = None
        if edges is None:
            return
        self.api.add_line_segments("/cell", to3(edges, 0.0), CELL, thickness=2.0, thickness_units="screen")
        images = periodic_images(scene, IMAGE_REACH * session.size)
        if len(images[0]) and not session.on_map:             # 2D: under the particles they copy
            bodies = [self.base.get(name) or Body(name, "point", (), x, np.eye(scene.dim))      # as drawn
                      for name, x in zip(scene.names, scene.x)]
            self.ghosts = Images(self.api, bodies, scene.names, images,
                                 -0.1 * session.size if scene.dim == 2 else 0.0, session.size)

    def _draw_map_contacts(self, session) -> None:
        """On a map, the contacts the model colours (a rigidity map: centre to centre, by cluster, floppy grey;
        `contact_colours`), above the particles; none on a scan map, nor off the map."""
        scene = session.scene
        colours = session.model.contact_colours if session.on_map and scene is not None else None
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
