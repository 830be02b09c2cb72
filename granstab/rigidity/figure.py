"""The rigidity figure (matplotlib, the `scan` extra, as the scan's map): the force chains (each contact's branch
vector, width ∝ |f|), then per model the contacts coloured by rigid cluster (largest first: blue, orange, green,
… cyclically), floppy contacts grey."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.scene import Scene
from ..scan.figure import particle_radii


def write_figure(scene: Scene, result: dict, path) -> Path:
    """Write the figure to `path` (.png or .svg) and return it."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Circle

    models = [m for m in ("physical", "generic") if m in result]
    fig, axes = plt.subplots(1, len(models) + 1, figsize=(5.5 * (len(models) + 1), 5.5), squeeze=False)
    r = particle_radii(scene)
    for ax in axes[0]:
        ax.add_collection(PatchCollection([Circle(c, rad) for c, rad in zip(scene.x[:, :2], r)],
                                          facecolor="whitesmoke", edgecolor="0.6", linewidth=0.2))
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    f = np.linalg.norm(scene.force, axis=1)
    segments, _ = contact_segments(scene, result[models[0]]["contacts"])
    width = np.minimum(1.2 * f / max(f.mean(), 1e-300), 3.0)
    axes[0, 0].add_collection(LineCollection(segments, colors="k", linewidths=width))
    axes[0, 0].autoscale_view()
    axes[0, 0].set_title("force chains (width ∝ |f|, capped at 2.5 mean)", fontsize=9)
    for ax, model in zip(axes[0, 1:], models):
        res = result[model]
        segments, labels = contact_segments(scene, res["contacts"])
        colours = cluster_colours(labels, plt.get_cmap("tab10"))
        floppy = labels < 0
        ax.add_collection(LineCollection(segments[floppy], colors="0.7", linewidths=0.5))
        ax.add_collection(LineCollection(segments[~floppy], colors=colours[~floppy], linewidths=1.6))
        ax.autoscale_view()
        sizes = [len(c["particles"]) for c in res["clusters"][:3]]
        ax.set_title(f"{model}: {len(res['clusters'])} rigid clusters (largest {sizes}), "
                     f"{res['floppy_modes']['count']} floppy modes", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90 if path.suffix.lower() == ".png" else None)
    plt.close(fig)
    return path


def contact_segments(scene: Scene, contacts: list):
    """Centre-to-centre segments (q's periodic copy) of the scene's contacts and their labels; wall contacts (to a
    wall body) are left out."""
    m = scene.n_contacts
    labels = np.array([c[2] for c in contacts[:m]], int)
    start = scene.x[scene.p][:, :2]
    end = (scene.x[scene.p] + scene.branch)[:, :2]
    return np.stack([start, end], axis=1), labels


def cluster_colours(labels: np.ndarray, cmap) -> np.ndarray:
    """RGBA per contact: cluster 0 (the largest) the first colour of `cmap`, and so on cyclically."""
    return np.asarray(cmap(np.mod(np.maximum(labels, 0), cmap.N)))
