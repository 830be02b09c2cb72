"""The scan's figures (matplotlib, the `scan` extra): the packing coloured by the fraction of unstable clusters
containing each particle (2D: disks; 3D: a projection and a slice through the middle), and a histogram of λ_min."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.scene import Scene
from .output import read_map


def particle_radii(scene: Scene) -> np.ndarray:
    """Drawing radius: median distance from a particle's reference point to its contact points (disks, spheres);
    particles without contacts get the median of the others."""
    d = np.linalg.norm(np.r_[scene.point - scene.x[scene.p], scene.point - scene.x[scene.q]], axis=1)
    owner = np.r_[scene.p, scene.q]
    order = np.argsort(owner, kind="stable")
    counts = np.bincount(owner, minlength=scene.n_particles)
    groups = np.split(d[order], np.cumsum(counts)[:-1])
    r = np.array([np.median(g) if g.size else np.nan for g in groups])
    return np.where(np.isfinite(r), r, np.nanmedian(r) if np.isfinite(r).any() else 1.0)


def write_figures(scene: Scene, out_dir) -> list[Path]:
    """map.png/.svg and lambda_min.png/.svg in out_dir."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle

    data = read_map(out_dir)
    frac = np.asarray(data["particles"]["unstable_fraction"], dtype=float)
    r = particle_radii(scene)
    cmap = plt.get_cmap("coolwarm").copy()
    cmap.set_bad("lightgrey")
    views = [("x", "y", np.ones(scene.n_particles, bool))]
    if scene.dim == 3:
        z = scene.x[:, 2]
        views.append(("x", "y", np.abs(z - np.median(z)) <= np.median(r)))
    fig, axes = plt.subplots(1, len(views), figsize=(6.5 * len(views), 6), squeeze=False)
    for ax, (_, _, keep), title in zip(axes[0], views, ("projection on x-y", "slice |z - median z| <= r")):
        patches = [Circle(c, rad) for c, rad in zip(scene.x[keep, :2], r[keep])]
        pc = PatchCollection(patches, cmap=cmap, edgecolor="k", linewidth=0.2)
        pc.set_array(np.ma.masked_invalid(frac[keep]))
        pc.set_clim(0, 1)
        ax.add_collection(pc)
        ax.autoscale_view()
        ax.set_aspect("equal")
        ax.set_title(title if scene.dim == 3 else "local stability map")
        fig.colorbar(pc, ax=ax, shrink=0.8, label="fraction of unstable clusters containing the particle "
                                                   "(grey: in none)")
    fig.suptitle(f"{data['summary']['clusters']} clusters, rings = {data['summary']['options']['rings']}: "
                 + ", ".join(f"{v} {c}" for v, c in data["summary"]["verdicts"].items()))
    paths = _save(fig, Path(out_dir) / "map")
    lam = np.asarray(data["clusters"].get("lambda_min", []), dtype=float)
    lam = lam[np.isfinite(lam)]
    fig, ax = plt.subplots(figsize=(6.5, 4))
    if lam.size:
        scale = np.median(np.abs(lam)) or 1.0
        ax.hist(np.arcsinh(lam / scale), bins=40, color="steelblue")
        ticks = np.array([-1e3, -1e2, -10, -1, 0, 1, 10, 1e2, 1e3])
        ax.set_xticks(np.arcsinh(ticks), [f"{t:g}" for t in ticks])
        ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel(f"lowest stability eigenvalue λ_min / {scale if lam.size else 1:.3g} (asinh scale)")
    ax.set_ylabel("clusters")
    paths += _save(fig, Path(out_dir) / "lambda_min")
    return paths


def _save(fig, stem: Path) -> list[Path]:
    import matplotlib.pyplot as plt
    fig.tight_layout()
    paths = [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    for p in paths:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return paths
