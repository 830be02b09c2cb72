"""The end of a track: the frames' parts (frame.py) joined into frames.parquet and particles.parquet, with what
needs two frames (D²min and the contact changes over the window, motion.py; the events, quantities.py), and
events.json and summary.json (the CONTRACT of granstab/track/__init__.py).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..io.validation import run_warnings
from ..scan.clusters import DEFAULT_BOUNDARY
from .motion import contact_changes, d2min
from .quantities import stress_drops

CONTRACT = "granstab track 1"
OPTIONAL = {"lambda_min_unloading": np.nan, "lambda_min_loading": np.nan, "n_negative_unloading": -1,
            "n_negative_loading": -1, "whole_verdict": "", "whole_method": "", "soft_modes": 0,
            "soft_modes_from": "", "whole_reason": "", "whole_proven": -1, "whole_hinges_on_tolerance": -1,
            "soft_spots_count": 0, "soft_spots_frictionless_lambda_max": np.nan, "soft_spots_branch_count": 0,
            "soft_spots_frictionless_method": "", "soft_spots_frictionless_residual": np.nan,
            "scan_clusters": -1, "scan_unstable": -1, "scan_unstable_nonboundary": -1, "scan_verdicts": "",
            "rigid_largest_particles": -1, "rigid_largest_fraction": np.nan}   # when the stage was not asked for
STAGES = ("read", "frame", "whole", "scan", "rigidity")
CHANGES = ("contacts_made", "contacts_broken", "contacts_changed", "contacts_slid")


def _parts(out: Path, positions: list):
    import pyarrow.feather as feather
    parts = out / "parts"
    rows = [json.loads((parts / f"frame-{k:06d}.json").read_text(encoding="utf-8")) for k in positions]
    particles = [feather.read_table(parts / f"frame-{k:06d}.particles.arrow") for k in positions]
    contacts = []
    for k in positions:
        t = feather.read_table(parts / f"frame-{k:06d}.contacts.arrow")
        contacts.append({c: t.column(c).to_numpy(zero_copy_only=False) for c in ("key", "a", "b", "sliding")})
        contacts[-1] = {c: v.astype(str) if c != "sliding" else v.astype(bool) for c, v in contacts[-1].items()}
    return rows, particles, contacts


def _positions(table, dim: int) -> np.ndarray:
    return np.stack([table.column(a).to_numpy() for a in "xyz"[:dim]], axis=1)


def _cell(row: dict):
    return np.asarray(row["cell"], float).reshape(row["dim"], row["dim"]) if row["cell"] else None


def between(rows: list, particles: list, contacts: list, window: int, radius: float) -> tuple[list, list]:
    """Per selected frame t: the columns d2min and CHANGES (NaN where t + W is past the last frame), and the frame's
    counts of contacts made, broken and slid."""
    columns, counts = [], []
    for k, table in enumerate(particles):
        n = table.num_rows
        if k + window >= len(particles):
            columns.append({c: np.full(n, np.nan) for c in ("d2min",) + CHANGES})
            counts.append({"n_made": np.nan, "n_broken": np.nan, "n_slid": np.nan})
            continue
        later = particles[k + window]
        names0 = table.column("name").to_numpy(zero_copy_only=False).astype(str)
        names1 = later.column("name").to_numpy(zero_copy_only=False).astype(str)
        order = np.argsort(names1)
        where = np.minimum(np.searchsorted(names1[order], names0), len(names1) - 1)
        present = names1[order][where] == names0
        x0 = _positions(table, rows[k]["dim"])
        x1 = np.where(present[:, None], _positions(later, rows[k]["dim"])[order[where]], x0)
        got = {"d2min": d2min(x0, x1, present, radius, _cell(rows[k]), _cell(rows[k + window]))}
        changes = contact_changes(names0, contacts[k], contacts[k + 1:k + window + 1])
        got.update({c: np.where(present, changes[c], np.nan) for c in CHANGES})
        columns.append(got)
        counts.append({f"n_{key}": value for key, value in changes["counts"].items()})
    return columns, counts


def frames_table(rows: list, counts: list):
    """frames.parquet: one row a frame (the stages not asked for: OPTIONAL's values), seconds per stage flat."""
    import pyarrow as pa
    flat = []
    for row, count in zip(rows, counts):
        seconds = row.pop("seconds")
        flat.append({**{k: v for k, v in row.items() if k not in OPTIONAL},
                     **{k: row.get(k, fill) for k, fill in OPTIONAL.items()}, **count,
                     **{f"seconds_{s}": seconds.get(s, 0.0) for s in STAGES}})
    kinds = {"stress": pa.list_(pa.float64()), "cell": pa.list_(pa.float64()),
             "import_warnings": pa.list_(pa.string())}
    return pa.table({key: pa.array([r[key] for r in flat], type=kinds.get(key)) for key in flat[0]})


def finish(out: Path, positions: list, keys: list, stated: dict, extra: dict) -> dict:
    """Join the parts of the frames `positions` into the tables and write events.json and summary.json."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    begun = time.perf_counter()
    rows, particles, contacts = _parts(out, positions)
    radius, radius_from = stated["d2min_radius"], "--d2min-radius"
    if radius is None:
        radius = 2.5 * rows[0]["mean_contact_distance"]
        radius_from = (f"default: 2.5 × the mean contact branch length of frame {positions[0]} "
                       f"({rows[0]['mean_contact_distance']:.6g}, ≈ the mean diameter of touching particles)")
    columns, counts = between(rows, particles, contacts, stated["window"], radius)
    quantity = stated["event_quantity"]
    events, mean = stress_drops(np.array([r[quantity] for r in rows], float), np.array(positions),
                                quantity, stated["event_threshold"])
    stage_seconds = {s: float(sum(r["seconds"].get(s, 0.0) for r in rows)) for s in STAGES}
    table = pa.concat_tables([t.append_column("d2min", pa.array(c["d2min"])) for t, c in zip(particles, columns)])
    for name in CHANGES:
        table = table.append_column(name, pa.array(np.concatenate([c[name] for c in columns])))
    pq.write_table(table, out / "particles.parquet")
    report = json.loads(rows[0]["import_report"])
    pq.write_table(frames_table(rows, counts), out / "frames.parquet")
    (out / "events.json").write_text(json.dumps(events, indent=1), encoding="utf-8")
    stage_seconds["between"] = time.perf_counter() - begun
    summary = {
        "contract": CONTRACT, "source": stated["inputs"], "frames_in_input": len(keys), "frames": len(positions),
        "import_warnings": run_warnings([(r["frame"], r["import_warnings"]) for r in rows]),
        "positions": positions, "steps": [None if keys[k] is None else float(keys[k]) for k in positions],
        "options": stated,
        "defaults": {"window": 1, "d2min_radius": "2.5 mean contact branch lengths", "event_quantity":
                     "shear_stress", "event_threshold": 0.05, "soft_modes": 5, "seed": 0, "rings": 1,
                     "boundary": DEFAULT_BOUNDARY, "whole": "metric L, the all-unloading and all-loading branches "
                     "only", "rattlers": "kept in the tables; the analyses run without them (as load's default)"},
        "units": {"length": report.get("units", {}).get("length"), "force": "as in the input",
                  "stress": "force / length^(d−1) of the input, tension positive; pressure compression positive",
                  "d2min": "length²", "lambda": "the L metric's stability eigenvalues (docs/equations.md)"},
        "windows": {"window": stated["window"], "d2min_radius": radius, "d2min_radius_from": radius_from,
                    "last_frames_without_window": min(stated["window"], len(positions))},
        "thresholds": {"event_quantity": quantity, "event_threshold": stated["event_threshold"],
                       "run_mean": mean if np.isfinite(mean) else None, "rule": "a drop from one selected frame to the next larger than "
                                                 "threshold × the run's mean |quantity|"},
        "events": len(events),
        "inertial_number": None,
        "inertial_number_note": "not known to the reader (granstab reads no strain rate or pressure history); "
                                "the run's documentation states it (docs/track.md)",
        "cost": {"seconds": time.perf_counter() - extra.pop("started"), "stages": stage_seconds, **extra}}
    (out / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False), encoding="utf-8")
    return summary
