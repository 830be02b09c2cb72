"""The figures of docs/shapes.md ("what shape changes, shown"), from the two tracked loading runs.

    D=tests/data/liggghts_superquadric; LAW="--contact-k 677 --alpha 0.8235 --mu 0.5"
    granstab track $D/load/atoms.dump $D/load/contacts.dump $D/in.settle --scan --out track_sq $LAW
    granstab track $D/load/spheres/atoms.dump $D/load/spheres/contacts.dump $D/spheres/in.settle_spheres \
        --scan --out track_sph $LAW
    python examples/liggghts_superquadric/figures.py track_sq track_sph docs/shapes

writes load_lambda_min.png (the clusters' λ_min per frame, both shapes), load_mechanisms.png (the unstable clusters
of each frame by mechanism) and load_maps.png (side view x–z of the first and last frame, each grain drawn as its
silhouette and coloured by the lowest λ_min of the scan clusters containing it: track's cluster_lambda_min), and
prints the table of docs/shapes.md.
"""
from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402
from matplotlib.collections import PatchCollection  # noqa: E402
from matplotlib.patches import Circle, Polygon  # noqa: E402
from scipy.spatial import ConvexHull  # noqa: E402

import granstab.io  # noqa: E402
from granstab.model import surface  # noqa: E402
from granstab.model.vec import quaternion_matrix  # noqa: E402

WEIGHT = (1, 2, 4, 8)            # the grains' weight in each frame, in units of the settled one (in.load)
MECHANISMS = ("boundary", "frictional", "geometric", "mixed")
LINEAR = 1.0                     # the asinh axes are linear within ±1 N/m
TICKS = [-100, -10, -1, 0, 1, 10, 100]


def frames(folder: Path) -> list[dict]:
    """Per frame of a track folder: its scan's clusters (λ_min, mechanism) and its per-particle table."""
    out = []
    particles = pq.read_table(folder / "particles.parquet").to_pydict()
    pframe = np.array(particles["frame"])
    for k, scan in enumerate(sorted((folder / "scans").iterdir())):
        c = pq.read_table(scan / "clusters.parquet").to_pydict()
        rows = pframe == k
        out.append({"lambda": np.array(c["lambda_min"]), "mechanism": np.array(c["mechanism"]),
                    "particles": {key: np.array(v)[rows] for key, v in particles.items()}})
    return out


def lambda_figure(runs: dict, path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), sharey=True)
    for ax, (name, run) in zip(axes, runs.items()):
        for w, frame, colour in zip(WEIGHT, run, plt.cm.viridis(np.linspace(0, 0.85, len(run)))):
            lam = np.sort(frame["lambda"])
            ax.step(lam, np.arange(1, len(lam) + 1) / len(lam), where="post", color=colour,
                    label=f"weight × {w}: {np.sum(lam < 0)} of {len(lam)} unstable")
        ax.set_xscale("asinh", linear_width=LINEAR)
        ax.set_xticks(TICKS, [f"{t:g}" for t in TICKS])
        ax.axvline(0, color="k", lw=0.6)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel(f"cluster λ_min (N/m; asinh axis, linear within ±{LINEAR:g})", fontsize=8)
        ax.legend(fontsize=7, loc="upper left")
        ax.tick_params(labelsize=7)
    axes[0].set_ylabel("fraction of clusters with λ_min below", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def mechanism_figure(runs: dict, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(9, 3.4))
    width, colours = 0.38, dict(zip(MECHANISMS, ("0.75", "tab:blue", "tab:red", "tab:purple")))
    for s, (name, run) in enumerate(runs.items()):
        bottom = np.zeros(len(run))
        for mech in MECHANISMS:
            counts = np.array([np.sum((f["lambda"] < 0) & (f["mechanism"] == mech)) for f in run])
            ax.bar(np.arange(len(run)) + (s - 0.5) * width, counts, width * 0.95, bottom=bottom, color=colours[mech],
                   edgecolor="k", lw=0.4, hatch="//" if s else None, label=f"{name}: {mech}")
            bottom += counts
        ax.set_ylim(0, max(ax.get_ylim()[1], 1.08 * bottom.max()))
    ax.set_xticks(range(len(WEIGHT)), [f"weight × {w}" for w in WEIGHT], fontsize=8)
    ax.set_ylabel("unstable clusters (of ~250)", fontsize=8)
    geometric = sum(np.sum((f["lambda"] < 0) & (f["mechanism"] == "geometric")) for r in runs.values() for f in r)
    ax.set_title(f"unstable clusters by mechanism (left bars superquadrics, hatched right bars spheres; "
                 f"geometric in all frames: {geometric})", fontsize=8)
    ax.legend(fontsize=6, ncol=1, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def silhouettes(loaded) -> list:
    """The x–z silhouette of every grain: a superquadric's projected mesh hull, a sphere's circle."""
    x = loaded.scene.x
    if loaded.shape is None:                              # solid spheres: I = 2/5 m r²
        radius = np.sqrt(2.5 * loaded.scene.inertia[:, 0, 0] / loaded.scene.mass)
        return [Circle((p[0], p[2]), r) for p, r in zip(x, radius)]
    rot = quaternion_matrix(loaded.orientation)
    out = []
    for p, R, shape in zip(x, rot, loaded.shape):
        verts = surface.mesh(surface.Superquadric(*shape), 12)[0] @ R.T
        xz = verts[:, [0, 2]]
        out.append(Polygon(p[[0, 2]] + xz[ConvexHull(xz).vertices], closed=True))
    return out


def maps_figure(runs: dict, inputs: dict, path: Path) -> None:
    fig, axes = plt.subplots(2, 2, figsize=(10, 4.4), sharex=True, sharey=True, layout="constrained")
    norm = matplotlib.colors.AsinhNorm(linear_width=LINEAR, vmin=-20, vmax=20)
    for row, (name, run) in zip(axes, runs.items()):
        source = granstab.io.open(inputs[name])
        for ax, k in zip(row, (0, len(run) - 1)):
            loaded = source.read(source.frames[k])
            table = run[k]["particles"]
            lam = dict(zip(table["name"], table["cluster_lambda_min"]))
            values = np.array([lam.get(n, np.nan) for n in loaded.scene.names], float)
            patches = PatchCollection(silhouettes(loaded), cmap="RdBu", norm=norm, edgecolor="k", linewidth=0.2)
            patches.set_array(np.ma.masked_invalid(values))
            ax.add_collection(patches)
            ax.set_aspect("equal")
            ax.set_title(f"{name}, weight × {WEIGHT[k]}:\n{np.sum(values < 0)} of {len(values)} grains in an unstable "
                         "cluster", fontsize=8)
            ax.tick_params(labelsize=7)
        row[0].set_ylabel("z (m)", fontsize=8)
    for ax in axes[-1]:
        ax.set_xticks([-0.02, -0.01, 0, 0.01, 0.02])
        ax.set_xlabel("x (m): side view, all grains", fontsize=8)
    axes[0][0].autoscale_view()
    bar = fig.colorbar(patches, ax=axes, shrink=0.8, ticks=TICKS[1:-1])
    bar.set_label("lowest λ_min of the clusters\ncontaining the grain (N/m)", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(runs: dict) -> None:
    for name, run in runs.items():
        for w, f in zip(WEIGHT, run):
            lam, mech = f["lambda"], f["mechanism"]
            counts = Counter(mech[lam < 0])
            pct = " / ".join(f"{v:.3g}" for v in np.percentile(lam, [5, 25, 50, 75, 95]))
            print(f"| {name} | × {w} | {len(lam)} | {pct} | {np.sum(lam < 0)} | "
                  + ", ".join(f"{m} {counts[m]}" for m in MECHANISMS if counts[m]) + " |")


def main(track_sq: str, track_sph: str, out: str) -> None:
    runs = {"superquadrics": frames(Path(track_sq)), "spheres": frames(Path(track_sph))}
    inputs = {name: [Path(p) for p in json.loads((Path(folder) / "summary.json").read_text())["source"]]
              for name, folder in (("superquadrics", track_sq), ("spheres", track_sph))}
    Path(out).mkdir(parents=True, exist_ok=True)
    lambda_figure(runs, Path(out) / "load_lambda_min.png")
    mechanism_figure(runs, Path(out) / "load_mechanisms.png")
    maps_figure(runs, inputs, Path(out) / "load_maps.png")
    table(runs)


if __name__ == "__main__":
    main(*sys.argv[1:4])
