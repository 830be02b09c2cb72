"""Grains drawn as they are (3D superquadrics and clumps): one shared mesh per distinct shape, instanced (viser's
batched meshes) at every grain's pose, and moved rigidly along a mode. A base of app/views.py's SceneView (its
`api`, `base`, `key`, … ); the disk and sphere scenes never come here. A large
packing of disks or spheres is one point cloud instead (`draw_cloud`), its arrays formed once per bodies list.

  /particles/grains/<k>   the k-th shared mesh (meshes.grain_instances), one instance per grain or member sphere
"""
from __future__ import annotations

import numpy as np

from .meshes import digest, grain_instances, rot3, to3

OPACITY = 0.6          # translucent, as the spheres (0.45) are: the contact points and forces inside stay visible


class GrainView:
    def draw_cloud(self, bodies, key, colour) -> None:
        """A large packing: one point cloud of the centres (sized by the median radius, in `colour`), no
        per-particle nodes."""
        if self._cloud_of is not bodies:           # a scan map's list is built once and never changes (scanmap.py)
            self._cloud_of, self._cloud_arrays = bodies, cloud_arrays(bodies)
        x, radii = self._cloud_arrays
        cloud = digest(key, x, radii)
        if cloud == self.key:
            return
        self.api.remove_by_name("/particles")
        self.clear_particles()
        self.key = cloud
        radius = float(np.median(radii))
        self._cloud_colours = None
        self.cloud = self.api.add_point_cloud("/particles/cloud", points=x, colors=colour, point_size=1.8 * radius,
                                 point_shape="circle")
        self.base = {b.name: b for b in bodies}

    def draw_grains(self, bodies, key, palette) -> None:
        """Draw the bodies' grains as instanced meshes (built again when the scene's grains change), at their poses."""
        key = (key, tuple(b.grain for b in bodies))
        if key != self.key:
            self.api.remove_by_name("/particles")
            self.clear_particles()
            self.key = key
            self.grains = grain_instances(bodies)
            x, R = self._poses(bodies)
            for k, group in enumerate(self.grains):
                position, quat = group.poses(x, R)
                colours = np.array([palette[i % len(palette)] for i in group.body], np.uint8)
                self.grain_nodes.append(self.api.add_batched_meshes_simple(
                    f"/particles/grains/{k}", group.vertices, group.faces, batched_wxyzs=quat,
                    batched_positions=position, batched_scales=group.scale, batched_colors=colours,
                    opacity=OPACITY, side="double", lod="off"))
        else:
            self.move_grains(bodies)
        self.base = {b.name: b for b in bodies}

    def move_grains(self, bodies) -> None:
        """Every instance at its body's pose now (a mode's frame, or the rest poses): x_b + R_b offset, R_b."""
        if not self.grain_nodes:
            return
        x, R = self._poses(bodies)
        for group, node in zip(self.grains, self.grain_nodes):
            node.batched_positions, node.batched_wxyzs = group.poses(x, R)

    def colour_grains(self, names, colours, palette) -> None:
        """Colour each grain (all its instances) by `colours` (N, 3) in the order of `names`, or by the palette."""
        if not self.grain_nodes:
            return
        order = {name: i for i, name in enumerate(names)}
        index = np.array([order[name] for name in self.base])
        rgb = (np.array([palette[i % len(palette)] for i in index]) if colours is None else
               np.asarray(colours)[index])
        for group, node in zip(self.grains, self.grain_nodes):
            node.batched_colors = rgb[group.body].astype(np.uint8)

    def clear_particles(self) -> None:
        """Forget every particle handle (after /particles was removed)."""
        self.nodes, self.inner, self.mesh_keys, self.meshes, self.markers, self.colours = {}, {}, {}, {}, {}, {}
        self.cloud, self.grains, self.grain_nodes = None, [], []

    @staticmethod
    def _poses(bodies) -> tuple[np.ndarray, np.ndarray]:
        return np.array([to3(b.x) for b in bodies]), np.array([rot3(b.R) for b in bodies])


def cloud_arrays(bodies) -> tuple[np.ndarray, np.ndarray]:
    """(centres (N, 3), drawn radii (N,)) of a point cloud's bodies: what the cloud draws, in two arrays."""
    return (to3(np.array([b.x for b in bodies], float).reshape(len(bodies), -1)),
            np.array([max(b.axes) for b in bodies], float))
