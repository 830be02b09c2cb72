"""The scan's figures (matplotlib, the `scan` extra): the packing coloured by the share of the clusters containing
each particle that are unstable for a reason of the packing (mechanism frictional, geometric or mixed), particles
whose clusters are unstable only by the cut (mechanism boundary) hatched, and the mechanism histogram (2D: disks;
3D: a projection and a slice through the middle); and a histogram of λ_min.

Colours are the explorer's (granstab_app.scanmap): white (0) → dark red (1), grey for a particle in no cluster.
Maps of more than RASTER_ABOVE particles are rasterised inside the SVG (a 20,000-disk vector map was 13.5 MB)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..mechanics.attribution import MECHANISMS
from ..model.scene import Scene
from .clusters import particle_shares
from .output import read_map

WHITE, RED, GREY = (250 / 255, 250 / 255, 250 / 255), (176 / 255, 20 / 255, 20 / 255), (150 / 255,) * 3
RASTER_ABOVE = 2000     # particles: above, the disks are drawn as an image inside the SVG
PIXELS_ABOVE = 200_000  # particles: above, a disk is under a pixel of the map, which is drawn as pixels (_pixels)
PIXELS = 1000           # pixels along the map's longer side then (the figure's axes are ~600 px wide at 110 dpi)
HATCH = "////"          # particles whose containing clusters are unstable only by the cut (mechanism boundary)


def particle_radii(scene: Scene) -> np.ndarray:
    """Drawing radius: median distance from a particle's reference point to its contact points (disks, spheres;
    from q's copy across a periodic seam, Scene.r_qp); particles without contacts get the median of the others."""
    d = np.linalg.norm(np.r_[scene.r_pq, scene.r_qp], axis=1)
    owner = np.r_[scene.p, scene.q]
    order = np.lexsort((d, owner))                       # by particle, then by distance: each group sorted
    counts = np.bincount(owner, minlength=scene.n_particles)
    start = np.cumsum(counts) - counts
    low = d[order][np.minimum(start + (counts - 1) // 2, max(len(d) - 1, 0))] if len(d) else np.zeros(len(counts))
    high = d[order][np.minimum(start + counts // 2, max(len(d) - 1, 0))] if len(d) else low
    r = np.where(counts > 0, np.where(counts % 2 == 1, low, (low + high) / 2), np.nan)   # np.median's middle(s)
    return np.where(np.isfinite(r), r, np.nanmedian(r) if np.isfinite(r).any() else 1.0)


def colormap():
    """White → dark red with grey for 'in no cluster' (NaN): the explorer's map colours."""
    from matplotlib.colors import LinearSegmentedColormap
    return LinearSegmentedColormap.from_list("granstab_unstable", [WHITE, RED]).with_extremes(bad=GREY)


def map_fractions(scene: Scene, clusters: dict) -> tuple[np.ndarray, np.ndarray]:
    """Per particle: the share of the clusters containing it that are unstable by the packing (mechanism other than
    boundary; NaN: in no cluster), and the share unstable by the cut alone (mechanism boundary)."""
    sizes = np.array([len(m) for m in clusters["members"]], dtype=np.int64)
    flat = np.concatenate([np.asarray(m, dtype=np.int64) for m in clusters["members"]] + [np.zeros(0, np.int64)])
    unstable = np.asarray(clusters["verdict"]) == "unstable"
    label = np.asarray(clusters.get("mechanism", np.full(len(sizes), "")), dtype=object)
    boundary = unstable & (label == "boundary")
    return particle_shares(flat, sizes, scene.n_particles, unstable & ~boundary, boundary)[1:]


def write_figures(scene: Scene, out_dir) -> list[Path]:
    """map.png/.svg and lambda_min.png/.svg in out_dir."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = read_map(out_dir)
    packing, by_cut = map_fractions(scene, data["clusters"])
    r = particle_radii(scene)
    views = [np.ones(scene.n_particles, bool)]
    if scene.dim == 3:
        z = scene.x[:, 2]
        views.append(np.abs(z - np.median(z)) <= np.median(r))
    fig, axes = plt.subplots(1, len(views), figsize=(6.5 * len(views), 7.4), squeeze=False)
    for ax, keep, title in zip(axes[0], views, ("projection on x-y", "slice |z - median z| <= r")):
        draw = _pixels if keep.sum() > PIXELS_ABOVE else _disks
        pc = draw(ax, scene.x[keep, :2], r[keep], packing[keep], by_cut[keep] > 0)
        ax.set_title(title if scene.dim == 3 else "local stability map")
        fig.colorbar(pc, ax=ax, shrink=0.7, label="share of its clusters unstable by the packing")
        _depends(ax, scene, data["clusters"], keep, r)
    _legend(axes[0][-1], data["summary"])
    s = data["summary"]
    fig.suptitle(f"{s['clusters']} clusters, rings = {s['options']['rings']}, boundary "
                 f"{s['options'].get('boundary', 'loads')}: " + ", ".join(f"{c} {v}" for v, c in s["verdicts"].items()),
                 fontsize=10)
    paths = _save(fig, Path(out_dir) / "map")
    paths += _lambda_histogram(plt, np.asarray(data["clusters"].get("lambda_min", []), dtype=float), Path(out_dir))
    return paths


def _disks(ax, centres, radii, value, hatched):
    """The disks (one EllipseCollection in data units) coloured by `value` (NaN grey), those `hatched` overlaid with
    HATCH where `value` is 0; rasterised above RASTER_ABOVE disks."""
    from matplotlib.collections import EllipseCollection
    big = len(centres) > RASTER_ABOVE

    def disks(which, **style):
        d = 2 * radii[which]
        return ax.add_collection(EllipseCollection(d, d, np.zeros(len(d)), units="xy", offsets=centres[which],
                                                   offset_transform=ax.transData, rasterized=big, **style))

    pc = disks(slice(None), cmap=colormap(), edgecolor="k", linewidth=0.2)
    pc.set_array(np.ma.masked_invalid(value))
    pc.set_clim(0, 1)
    only_cut = hatched & ~(value > 0)
    if only_cut.any():
        disks(only_cut, facecolor="none", edgecolor=GREY, hatch=HATCH, linewidth=0.0)
    pad = radii.max(initial=0.0)
    ax.set_xlim(centres[:, 0].min() - pad, centres[:, 0].max() + pad)
    ax.set_ylim(centres[:, 1].min() - pad, centres[:, 1].max() + pad)
    ax.set_aspect("equal")
    return pc


def _pixels(ax, centres, radii, value, hatched):
    """The map as an image of at most PIXELS × PIXELS pixels (above PIXELS_ABOVE particles, where a disk is smaller
    than a pixel and 10⁶ disks took minutes to draw): each pixel coloured by the largest `value` of the particles
    whose centres fall in it (an unstable one is never averaged away), grey where they are all in no cluster, clear
    where there is none; hatched HATCH where one is unstable only by the cut and none by the packing."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    pad = radii.max(initial=0.0)
    lo, hi = centres.min(axis=0) - pad, centres.max(axis=0) + pad
    span = np.maximum(hi - lo, 1e-300)
    shape = np.maximum(np.round(PIXELS * span / span.max()).astype(int), 1)            # (nx, ny)
    cell = np.minimum(((centres - lo) / span * shape).astype(np.int64), shape - 1)
    flat = cell[:, 1] * shape[0] + cell[:, 0]
    best = np.full(shape.prod(), -np.inf)
    np.maximum.at(best, flat, np.where(np.isnan(value), -1.0, value))                # -1: in no cluster
    cut = np.zeros(shape.prod(), dtype=bool)
    cut[flat[hatched & ~(value > 0)]] = True
    cmap = colormap()
    rgba = cmap(np.clip(best, 0.0, 1.0))
    rgba[best == -1.0] = (*GREY, 1.0)
    rgba[np.isneginf(best), 3] = 0.0
    extent = (lo[0], hi[0], lo[1], hi[1])
    ax.imshow(rgba.reshape(shape[1], shape[0], 4), origin="lower", extent=extent, interpolation="nearest")
    only_cut = (cut & (best <= 0.0)).reshape(shape[1], shape[0])
    if only_cut.any():
        ax.contourf(np.linspace(lo[0], hi[0], shape[0]), np.linspace(lo[1], hi[1], shape[1]), only_cut.astype(float),
                    levels=[0.5, 1.5], colors="none", hatches=[HATCH])
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    return ScalarMappable(norm=Normalize(0, 1), cmap=cmap)


DEPENDS_HATCH = "xxxx"


def _depends(ax, scene, clusters: dict, keep, radii) -> None:
    """The centres of clusters whose verdict depends on the data (data_robust, issue 42): hatched DEPENDS_HATCH and
    ringed."""
    from matplotlib.collections import EllipseCollection
    flags = np.asarray(clusters.get("data_robust", []), dtype=object) == "depends"
    if not flags.any():
        return
    mark = np.zeros(scene.n_particles, dtype=bool)
    mark[np.asarray(clusters["center"])[flags]] = True
    mark &= keep
    d = 2 * radii[mark]
    ax.add_collection(EllipseCollection(d, d, np.zeros(len(d)), units="xy", offsets=scene.x[mark, :2],
                                        offset_transform=ax.transData, facecolor="none", edgecolor="k",
                                        hatch=DEPENDS_HATCH, linewidth=1.0))


def _legend(ax, summary: dict) -> None:
    """What the colours and the hatching mean, and the mechanism histogram of the unstable clusters."""
    from matplotlib.patches import Patch
    counts = summary.get("mechanisms", {})
    handles = [Patch(facecolor=RED, edgecolor="k", label="unstable by the packing (colour)"),
               Patch(facecolor=WHITE, edgecolor=GREY, hatch=HATCH,
                     label="unstable only by the cut: dead loads at the rim (boundary)"),
               Patch(facecolor=GREY, edgecolor="k", label="in no scanned cluster")]
    if summary.get("options", {}).get("uncertainty"):
        handles.append(Patch(facecolor="none", edgecolor="k", hatch=DEPENDS_HATCH, linewidth=1.0,
                             label="centre of a cluster whose verdict depends on the data (docs/uncertainty.md)"))
    handles += [Patch(facecolor="none", edgecolor="none", label=f"{m}: {counts.get(m, 0)} clusters")
                for m in MECHANISMS]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.04), ncol=2, fontsize=7, frameon=False,
              title="unstable clusters by mechanism (docs/attribution.md)", title_fontsize=7)


def _lambda_histogram(plt, lam: np.ndarray, out_dir: Path) -> list[Path]:
    """lambda_min.png/.svg: λ_min on an asinh axis, linear within ±s (s the median |λ_min|, stated on the axis),
    logarithmic beyond; the axis spans the data."""
    lam = lam[np.isfinite(lam)]
    fig, ax = plt.subplots(figsize=(6.5, 4))
    s = float(np.median(np.abs(lam))) if lam.size else 1.0
    s = s if s > 0 else 1.0
    if lam.size:
        t = np.arcsinh(lam / s)
        edges = np.linspace(t.min(), t.max(), 41) if t.max() > t.min() else np.array([t[0] - 1, t[0] + 1])
        ax.hist(lam, bins=s * np.sinh(edges), color="steelblue")
        ax.set_xscale("asinh", linear_width=s)
        pad = 0.02 * (t.max() - t.min() or 1.0)
        ax.set_xlim(s * np.sinh(t.min() - pad), s * np.sinh(t.max() + pad))
        ticks = np.r_[-s * 10.0 ** np.arange(6), 0.0, s * 10.0 ** np.arange(6)]
        ticks = np.sort(ticks[(ticks >= lam.min()) & (ticks <= lam.max())] if lam.min() < 0 < lam.max() else
                        ticks[(ticks >= lam.min() - s) & (ticks <= lam.max() + s)])
        ax.set_xticks(ticks, [f"{v:.2g}" for v in ticks], fontsize=8, rotation=30)
        ax.minorticks_off()
        ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel(f"lowest stability eigenvalue λ_min (asinh axis: linear within ±{s:.3g}, the median |λ_min|; "
                  "logarithmic beyond)", fontsize=8)
    ax.set_ylabel("clusters")
    return _save(fig, out_dir / "lambda_min")


def _save(fig, stem: Path) -> list[Path]:
    import matplotlib.pyplot as plt
    fig.tight_layout()
    paths = [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    for p in paths:
        fig.savefig(p, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return paths
