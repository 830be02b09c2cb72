"""A finished scan (`granstab scan … --out DIR`) as a model of the explorer: the whole packing coloured by the
per-particle map, and the cluster of any particle as a contact-level model of its own (no viser).

The packing is the scan folder's own (packing.npz: a copied or moved folder opens as well); each cluster is cut
from it by `granstab.scan.cluster`, the function the scan itself analysed, so the explorer shows exactly the
cluster that the scan's row describes. Particles are indices inside; names appear only on screen.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import granstab
from granstab.model.grains import cut

from .params import defaults
from .protocols import MapModel
from .scenes import Body, ContactModel

WHITE, RED, GREY = np.array([250, 250, 250]), np.array([176, 20, 20]), (150, 150, 150)
CUT_GREY = (205, 205, 205)   # unstable only by the cut (mechanism boundary): lighter than GREY (in no cluster)


def is_scan_dir(path) -> bool:
    """A folder that a scan wrote (summary.json and options.json in it)."""
    path = Path(path)
    return path.is_dir() and (path / "summary.json").is_file() and (path / "options.json").is_file()


def fraction_colours(fraction: np.ndarray) -> np.ndarray:
    """(N, 3) uint8: white (0: no cluster containing the particle is unstable) → dark red (1: all are); grey: in
    no scanned cluster (NaN)."""
    f = np.clip(np.nan_to_num(fraction, nan=0.0), 0.0, 1.0)[:, None]
    rgb = np.round(WHITE + f * (RED - WHITE)).astype(np.uint8)
    rgb[np.isnan(fraction)] = GREY
    return rgb


def map_colours(packing: np.ndarray, by_cut: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 of the default map (docs/attribution.md): `fraction_colours` of the share of a particle's
    clusters unstable by the packing (mechanism frictional, geometric or mixed); CUT_GREY where none is, but some
    are unstable by the cut alone (mechanism boundary): the scan's map.png hatches the same particles."""
    rgb = fraction_colours(packing)
    rgb[(by_cut > 0) & ~(packing > 0)] = CUT_GREY
    return rgb


@dataclass
class ScanMapModel(MapModel):
    """The scanned packing and its map: `fraction` (per particle, the share of its clusters unstable by the
    packing, mechanism not boundary; NaN: in no cluster), `by_cut` (the share unstable by the cut alone), `own`
    (the verdict of each particle's own cluster, '' if it was no centre), `members` (centre → member particles,
    as indices into the packing)."""

    scene: granstab.Scene
    fraction: np.ndarray
    by_cut: np.ndarray
    own: np.ndarray
    members: dict
    summary: dict
    path: str
    grains: object = None          # the grains' true shapes the scan kept (model.grains.Grains), else None
    _bodies: list | None = field(default=None, init=False, repr=False)    # built once (`bodies`)
    kind = "scan_map"
    draggable = False
    params_used = ()

    def initial_params(self) -> dict:
        return defaults()

    def build(self, P: dict) -> granstab.Scene:
        return self.scene

    @property
    def colours(self) -> np.ndarray:
        """(N, 3) uint8: the map's colours (`map_colours`)."""
        return map_colours(self.fraction, self.by_cut)

    def bodies(self, P: dict) -> list[Body]:
        """The packing's bodies, built once: the map never moves (not draggable), and every redraw, the particle
        size and each click asked for them again (0.74 s of CPU a build for 10⁵ particles, one Body each)."""
        if self._bodies is None:
            self._bodies = ContactModel(self.scene, grains=self.grains).bodies(P)
        return self._bodies

    @property
    def report(self) -> str:
        s = self.summary
        counts = ", ".join(f"{n} {v}" for v, n in sorted(s["verdicts"].items()))
        return (f"scan {self.path} of {s['source']}: {s['clusters']} clusters (rings {s['options']['rings']}, "
                f"metric {s['options']['metric']}): {counts}; {s['partial_branches']} with branches: partial")

    def cluster(self, name: str) -> ContactModel:
        """The cluster whose centre is `name`, as the scan analysed it, its boundary included (a `fixed` scan holds
        the next ring fixed; one-line SceneError if it has none)."""
        from granstab.scan.clusters import cluster
        center = self.scene.names.index(name) if name in self.scene.names else -1
        if center not in self.members:
            raise granstab.SceneError(f"{self.path}: particle {name!r} was no centre of this scan "
                                      f"({len(self.members)} centres)")
        rings = self.summary["options"]["rings"]
        boundary = self.summary["options"].get("boundary", "loads")          # scans before --boundary: loads
        title = (f"cluster of {name} ({rings} ring{'s' * (rings > 1)}, boundary {boundary}) from scan "
                 f"{Path(self.path).name}")
        sub = cluster(self.scene, center, rings, boundary, title=title)
        return ContactModel(sub, report=f"cluster of particle {name}: its own verdict in the scan "
                                        f"{self.own[center] or '—'}; {len(self.members[center])} particles",
                            grains=cut(self.grains, self.scene, sub))

    def pick(self, origin, direction) -> str | None:
        """The particle under a click ray (`pick_particle`), or None."""
        i = pick_particle(self.scene.x, np.array([max(b.axes) for b in self.bodies({})]), origin, direction)
        return None if i is None else self.scene.names[i]


def pick_particle(x: np.ndarray, radius: np.ndarray, origin, direction) -> int | None:
    """The index of the particle (centres `x` (N, d), drawn radii (N,)) under a click ray (2D: where the ray meets
    the plane z = 0; 3D: the centre nearest the ray), if the ray passes within its drawn radius; else None."""
    o, d = np.asarray(origin, float), np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    x3 = np.zeros((len(x), 3))
    x3[:, :x.shape[1]] = x
    if x.shape[1] == 2:
        if abs(d[2]) < 1e-12:
            return None
        hit = o - o[2] / d[2] * d
        dist = np.linalg.norm(x3 - hit, axis=1)
    else:
        t = np.maximum((x3 - o) @ d, 0.0)
        dist = np.linalg.norm(x3 - (o + t[:, None] * d), axis=1)
    i = int(np.argmin(dist / radius))
    return i if dist[i] <= radius[i] else None


def load_scan_map(path) -> ScanMapModel:
    """The model of a scan folder, its packing the folder's own; one-line SceneError when it cannot be read."""
    from granstab.scan import open_packing, read_map
    from granstab.scan.figure import map_fractions
    path = Path(path)
    data = read_map(path)
    packing = open_packing(path)
    scene = packing.scene
    particles = data["particles"]
    if list(particles["name"]) != list(scene.names):
        raise granstab.SceneError(f"{path}: particles: the names do not match those of its packing (was the folder "
                                  "changed since the scan?)")
    clusters = data["clusters"]
    members = {int(c): np.asarray(row, dtype=np.int64) for c, row in zip(clusters["center"], clusters["members"])}
    packing_share, by_cut = map_fractions(scene, clusters)      # the figure's shares: scans without mechanism, all packing
    return ScanMapModel(scene, packing_share, by_cut, np.asarray(particles["own_verdict"], dtype=object), members,
                        data["summary"], str(path), grains=packing.grains)
