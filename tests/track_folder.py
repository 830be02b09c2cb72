"""A synthetic track folder in the output contract of `granstab track` (frames.parquet, particles.parquet,
events.json, summary.json), with planted answers: particles whose `unstable_fraction` is high are the ones whose
D²min is large, λ_min dips below zero the frame before each stress drop, and `random` is noise. n_negative_unloading carries the
contract's fill −1 (not computed)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

N_FRAMES, SIDE, WINDOW = 24, 8, 2
EVENTS = (6, 14, 19)            # the drop runs from frame e to e + 1


def write(out: Path, seed: int = 0) -> dict:
    """Write the folder; return the planted truth (positions of the events, the mask of planted movers)."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    n = SIDE * SIDE
    grid = np.stack(np.meshgrid(np.arange(SIDE), np.arange(SIDE)), -1).reshape(-1, 2).astype(float)
    shear = np.cumsum(np.where(np.isin(np.arange(N_FRAMES) - 1, EVENTS), -0.3, 0.1)) + 1.0
    lam = np.where(np.isin(np.arange(N_FRAMES), EVENTS), -0.05, 0.2 + 0.01 * rng.random(N_FRAMES))
    frames = {"frame": np.arange(N_FRAMES), "step": 500 * np.arange(N_FRAMES), "n_particles": np.full(N_FRAMES, n),
              "n_contacts": np.full(N_FRAMES, 2 * n), "n_sliding": rng.integers(0, 9, N_FRAMES),
              "stress": [[-2.0, s, s, -2.0] for s in shear], "shear_stress": shear, "pressure": np.full(N_FRAMES, 2.0),
              "stress_ratio": shear / 2.0, "z": 4 + 0.1 * rng.random(N_FRAMES),
              "mobilised_fraction": rng.random(N_FRAMES), "lambda_min_unloading": lam + 0.1,
              "lambda_min_loading": lam, "n_negative_unloading": np.full(N_FRAMES, -1),
              "n_negative_loading": (lam < 0).astype(int), "dim": np.full(N_FRAMES, 2),
              "cell": [[] for _ in range(N_FRAMES)], "mean_contact_distance": np.ones(N_FRAMES),
              "whole_proven": np.isin(np.arange(N_FRAMES), EVENTS).astype(int),
              "whole_hinges_on_tolerance": (np.arange(N_FRAMES) == EVENTS[1]).astype(int)}
    pq.write_table(pa.table(frames), out / "frames.parquet")
    movers = rng.random((N_FRAMES, n)) < 0.15
    d2 = np.where(movers, 1.0 + rng.random((N_FRAMES, n)), 0.01 * rng.random((N_FRAMES, n)))
    d2[N_FRAMES - WINDOW:] = np.nan                                    # the window runs past the end
    unstable = np.where(movers, 0.5 + 0.5 * rng.random((N_FRAMES, n)), 0.5 * rng.random((N_FRAMES, n)))
    f = np.repeat(np.arange(N_FRAMES), n)
    xy = grid[None] + 0.05 * rng.standard_normal((N_FRAMES, n, 2))
    particles = {"frame": f, "name": [str(i) for i in np.tile(np.arange(n), N_FRAMES)],
                 "x": xy[..., 0].ravel(), "y": xy[..., 1].ravel(), "d2min": d2.ravel(),
                 "contacts_changed": np.zeros(N_FRAMES * n, int), "rattler": np.zeros(N_FRAMES * n, bool),
                 "unstable_fraction": unstable.ravel(), "unstable_fraction_nonboundary": unstable.ravel() / 2,
                 "cluster_lambda_min": -unstable.ravel(), "soft_participation": np.full(N_FRAMES * n, np.nan),
                 "coordination": rng.integers(2, 6, N_FRAMES * n), "mobilised_fraction": rng.random(N_FRAMES * n),
                 "force_magnitude": rng.random(N_FRAMES * n), "sliding_distance": rng.random(N_FRAMES * n),
                 "random": rng.random(N_FRAMES * n)}
    pq.write_table(pa.table(particles), out / "particles.parquet")
    events = [{"frame": e, "next_frame": e + 1, "quantity": "shear_stress", "drop": 0.3,
               "relative_drop": float(0.3 / shear[e])} for e in EVENTS]
    (out / "events.json").write_text(json.dumps(events))
    (out / "summary.json").write_text(json.dumps({"windows": {"window": WINDOW}, "frames": list(range(N_FRAMES))}))
    return {"movers": movers, "events": EVENTS}
