"""What one frame is, macroscopically and per particle, from its contacts alone: the stress and its invariants, the
coordination, the mobilised contacts, and the baseline predictors (coordination, mobilised fraction, force, distance
to the nearest sliding contact). Pure numpy on a `Scene`; the stress is mechanics/cell.py's, written once.
"""
from __future__ import annotations

import numpy as np

from ..mechanics.cell import stress as contact_stress
from ..model.scene import Scene


def volume_of(scene: Scene) -> tuple[float, str]:
    """The volume the stress is divided by, and how it was taken: the cell's (a periodic scene), else the convex
    hull of the particle centres (an annulus's hull includes its hole: the stress is the mean over the hull)."""
    if scene.periodic:
        return scene.volume, "the periodic cell (det of its lattice vectors)"
    from scipy.spatial import ConvexHull
    if scene.n_particles <= scene.dim:
        return float("nan"), "none: too few particles for a hull"
    try:
        hull = ConvexHull(scene.x)
    except Exception:                                  # flat or degenerate sets (qhull's QhullError)
        return float("nan"), "none: the particle centres span no volume"
    return float(hull.volume), "the convex hull of the particle centres (no cell)"


def invariants(sigma: np.ndarray) -> dict:
    """pressure p = −tr σ / d (compression positive), shear stress τ = √(½ s:s) of the deviator s of sym(σ) (2D:
    (σ₁ − σ₂)/2), stress ratio τ / p."""
    sym = 0.5 * (sigma + sigma.T)
    d = len(sigma)
    pressure = -float(np.trace(sym)) / d
    dev = sym + pressure * np.eye(d)
    shear = float(np.sqrt(0.5 * np.sum(dev * dev)))
    ratio = shear / pressure if pressure != 0 else float("nan")
    return {"pressure": pressure, "shear_stress": shear, "stress_ratio": ratio}


def macroscopic(scene: Scene) -> dict:
    """The frame row's contact quantities: counts, σ (flat, row by row), its invariants, z = 2M / N over the
    particles with a contact, the mobilised (at yield) fraction of the contacts."""
    volume, how = volume_of(scene)
    sigma = contact_stress(scene, volume) if np.isfinite(volume) else np.full((scene.dim, scene.dim), np.nan)
    sliding = scene.at_yield()
    touched = np.unique(np.concatenate([scene.p, scene.q]))
    M = scene.n_contacts
    return {"n_particles": scene.n_particles, "n_contacts": M, "n_sliding": int(sliding.sum()),
            "stress": sigma.ravel().tolist(), **invariants(sigma), "volume": volume, "volume_from": how,
            "mean_contact_distance": float(np.linalg.norm(scene.branch, axis=1).mean()) if M else float("nan"),
            "z": 2.0 * M / len(touched) if len(touched) else float("nan"),
            "mobilised_fraction": float(sliding.mean()) if M else float("nan")}


def per_particle(scene: Scene) -> dict:
    """Baseline predictors per particle (N,): `coordination` (contacts), `mobilised_fraction` (of its contacts at
    yield; NaN without contacts), `force_magnitude` (mean |f| of its contacts; 0 without), `sliding_distance` (from
    its centre to the nearest contact point at yield, through the cell's images; NaN when none is at yield),
    `rattler` (no contact)."""
    N, M = scene.n_particles, scene.n_contacts
    ends = np.concatenate([scene.p, scene.q])
    coordination = np.bincount(ends, minlength=N)
    sliding = scene.at_yield()
    at = np.bincount(ends, weights=np.tile(sliding.astype(float), 2), minlength=N)
    force = np.bincount(ends, weights=np.tile(np.linalg.norm(scene.force, axis=1), 2), minlength=N)
    with np.errstate(invalid="ignore", divide="ignore"):
        mobilised = np.where(coordination > 0, at / np.maximum(coordination, 1), np.nan)
        magnitude = np.where(coordination > 0, force / np.maximum(coordination, 1), 0.0)
    return {"coordination": coordination.astype(np.int64), "mobilised_fraction": mobilised,
            "force_magnitude": magnitude, "sliding_distance": nearest(scene, scene.point[sliding]),
            "rattler": coordination == 0} if M else {
            "coordination": coordination.astype(np.int64), "mobilised_fraction": np.full(N, np.nan),
            "force_magnitude": np.zeros(N), "sliding_distance": np.full(N, np.nan), "rattler": np.ones(N, bool)}


def nearest(scene: Scene, points: np.ndarray) -> np.ndarray:
    """Distance from each particle centre to the nearest of `points` (its images in the neighbouring cells
    counted for a periodic scene); NaN everywhere when there are none."""
    if not len(points):
        return np.full(scene.n_particles, np.nan)
    from scipy.spatial import cKDTree
    return cKDTree(with_images(points, scene.cell)).query(scene.x)[0]


def with_images(points: np.ndarray, cell: np.ndarray | None) -> np.ndarray:
    """`points` and, with a cell, their copies shifted by every n @ cell, n ∈ {−1, 0, 1}^d."""
    if cell is None:
        return points
    d = len(cell)
    shifts = np.stack(np.meshgrid(*[[-1, 0, 1]] * d, indexing="ij"), axis=-1).reshape(-1, d) @ cell
    return (points[None, :, :] + shifts[:, None, :]).reshape(-1, d)


def stress_drops(values: np.ndarray, frames: np.ndarray, quantity: str, threshold: float) -> tuple[list, float]:
    """Events: each drop from one listed frame to the next larger than `threshold` × the run's mean of |values|
    (finite ones), as {frame, next_frame, quantity, drop, relative_drop} (relative to that mean); and the mean."""
    finite = values[np.isfinite(values)]
    mean = float(np.mean(np.abs(finite))) if finite.size else float("nan")
    drop = values[:-1] - values[1:]
    events = []
    if np.isfinite(mean) and mean > 0:
        for k in np.flatnonzero(drop > threshold * mean):
            events.append({"frame": int(frames[k]), "next_frame": int(frames[k + 1]), "quantity": quantity,
                           "drop": float(drop[k]), "relative_drop": float(drop[k] / mean)})
    return events, mean
