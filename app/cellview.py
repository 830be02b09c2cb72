"""What the 3D view draws besides particles and contact forces: a periodic scene's cell outline with the periodic
images near its faces, and a map's coloured contacts. A base of app/views.py's SceneView (its `api`, `_cell_key`,
`_contact_keys`, … ).
"""
from __future__ import annotations

import numpy as np

from .meshes import digest, to3
from .scenes import cell_edges, ghost_positions, periodic_images

CELL = (90, 90, 90)                     # a periodic scene's cell outline
GHOST = (200, 215, 235)                 # periodic images of the particles near the cell's faces (lighter)


class OverlayView:
    def draw_cell(self, session) -> None:
        """The outline of a periodic scene's cell (scenes.cell_edges; a periodic track's frame too) and, off a map, the
        periodic images of the particles within one mean diameter of a face (scenes.periodic_images), re-sent only
        when they change."""
        scene = session.scene
        edges = None if scene is None else cell_edges(scene)
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
        if len(images[0]) and not session.on_map:
            z = -0.1 * session.size                          # under the particles they copy
            cloud = self.api.add_point_cloud("/cell/images", points=to3(ghost_positions(scene.x, images), z),
                                             colors=GHOST, point_size=1.8 * session.size, point_shape="circle")
            self.ghosts = (cloud, scene.names, images, z)

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
