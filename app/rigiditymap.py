"""A rigidity result (`granstab rigidity INPUT --out DIR`) as a map of the explorer, in the scan map's style: the
packing with each contact (centre to centre) and each particle coloured by its rigid cluster (the largest first:
blue, orange, green, … as the rigidity figure), floppy contacts and particles in no cluster grey; a click opens the particle's neighbourhood
(one contact ring, the scan's cut) as a contact-level model. The folder's own packing.npz is drawn, so the
contact labels of rigidity.json point into exactly that scene."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import granstab
from granstab.model.grains import cut

from .scanmap import CUT_GREY, ScanMapModel
from .scenes import ContactModel

TAB10 = np.array([[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189], [140, 86, 75],
                  [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207]], np.uint8)   # matplotlib's tab10


LIGHT_GREY = CUT_GREY        # particles in no cluster: lighter than the floppy contacts over them
FLOPPY = (100, 100, 100)     # floppy contacts: darker than GREY, to stand out over light grey particles


def tint(rgb: np.ndarray) -> np.ndarray:
    """A cluster colour lightened for the particles: 40 % of it, 60 % white."""
    return np.round(0.4 * rgb + 0.6 * 255).astype(np.uint8)


def particle_clusters(scene: granstab.Scene, contacts: list) -> np.ndarray:
    """(N,) the label of the largest cluster each particle is in (a hinge is in several: the lowest label, the
    largest cluster), -1 in none; contacts [p, q, label] by name, wall bodies ignored."""
    index = {name: i for i, name in enumerate(scene.names)}
    label = np.full(scene.n_particles, np.iinfo(np.int64).max)
    for p, q, c in contacts:
        for name in (p, q):
            if c >= 0 and name in index:
                label[index[name]] = min(label[index[name]], c)
    return np.where(label == np.iinfo(np.int64).max, -1, label)


@dataclass
class RigidityMapModel(ScanMapModel):
    """The packing of a rigidity folder and one model's clusters (`model`: physical where present)."""

    result: dict = field(default_factory=dict)
    model: str = "physical"

    @property
    def labels(self) -> np.ndarray:
        return particle_clusters(self.scene, self.result[self.model]["contacts"])

    @property
    def colours(self) -> np.ndarray:
        """(N, 3) uint8 per particle: its cluster's colour lightened (`tint`), so that the contacts drawn over it
        in full colour stand out; light grey in no cluster."""
        labels = self.labels
        rgb = tint(TAB10[np.mod(np.maximum(labels, 0), len(TAB10))])
        rgb[labels < 0] = LIGHT_GREY
        return rgb

    @property
    def contact_colours(self) -> np.ndarray:
        """(M, 3) uint8 per contact of the packing: its cluster's colour, dark grey when floppy (label -1)."""
        labels = np.array([c[2] for c in self.result[self.model]["contacts"][:self.scene.n_contacts]], int)
        rgb = TAB10[np.mod(np.maximum(labels, 0), len(TAB10))].copy()
        rgb[labels < 0] = FLOPPY
        return rgb

    @property
    def report(self) -> str:
        r = self.result[self.model]
        sizes = ", ".join(str(len(c["particles"])) for c in r["clusters"][:3])
        return (f"rigidity {self.path} of {self.result['source']} ({self.model} model): {len(r['clusters'])} rigid "
                f"clusters (largest {sizes or 'none'} particles), {r['floppy_modes']['count']} floppy modes, "
                f"{r['self_stresses']} self-stresses")

    @property
    def headline(self) -> tuple[str, str]:
        """(title, badge) of the page's headline: a map of rigid clusters, not a verdict."""
        return (f"rigid clusters of {self.scene.n_particles} particles: click one (or type its name) to open it",
                "rigidity map")

    @property
    def details(self) -> str:
        return (f"**Rigidity map.** {self.report}.\n\nColour: the rigid cluster of each particle (largest first: blue, "
                "orange, green, …; a hinge particle takes its largest cluster's colour); grey: in no rigid cluster "
                "(floppy). Click a particle, or type its name under *Scene*, to open its neighbourhood here; *Back "
                "to the map* returns.")

    @property
    def legend(self) -> str:
        return ("**Legend** — contact (centre to centre) colour: its rigid cluster (the largest blue, then orange, "
                "green, red, …, cyclically); grey: floppy. Particles: their cluster's colour, lighter; light grey "
                "in no rigid cluster (docs/rigidity.md).")

    def cluster(self, name: str) -> ContactModel:
        """The particle's one-ring neighbourhood (the scan's cut, loads at the boundary) as a contact model."""
        from granstab.scan.clusters import cluster
        if name not in self.scene.names:
            raise granstab.SceneError(f"{self.path}: no particle {name!r} in its packing")
        center = self.scene.names.index(name)
        label = int(self.labels[center])
        where = f"rigid cluster {label}" if label >= 0 else "no rigid cluster"
        sub = cluster(self.scene, center, 1, "loads", title=f"neighbourhood of {name} ({where}) from "
                                                          f"{Path(self.path).name}")
        return ContactModel(sub, report=f"particle {name}: in {where} of the {self.model} model",
                            grains=cut(self.grains, self.scene, sub))


def load_rigidity_map(path) -> RigidityMapModel:
    """The model of a rigidity folder; one-line SceneError when it cannot be read."""
    from granstab.rigidity.output import read_result
    packing, result = read_result(path)
    scene = packing.scene
    model = "physical" if "physical" in result else "generic"
    N = scene.n_particles
    return RigidityMapModel(scene, np.full(N, np.nan), np.zeros(N), np.full(N, "", dtype=object), {}, result,
                            str(path), grains=packing.grains, result=result, model=model)
