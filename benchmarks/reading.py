"""Reading scene files (issue 9, "Speed"): the column-wise reader against today's per-contact reader and
numpy.loadtxt, side by side in one run, for JSON and the binary NPZ format; writing both; peak memory per contact.

Scenes are 2D random packings (granstab.model.packings) of about 10³…10⁶ contacts. Times are medians over repeats
(one run where a single run takes seconds). Rows:

- `load JSON (columns)`: granstab.load_scene on the .json file: read, scan, json.loads, column-wise checks.
- `load JSON (per contact)`: the same file through the reader as it was before this change (one Reader, one
  np.array and its checks per field per contact: kept below as the reference; run up to REFERENCE_MAX contacts).
- `load NPZ`: granstab.load_scene on the .npz file (the same fields as whole arrays, the same checks).
- `numpy.loadtxt`: the contacts' 14 numeric columns as a whitespace table, parsed without any checks: what a
  plain table costs.
- `build in memory`: granstab.build_scene on the arrays (range, friction and balance checks only): the floor.
- `save JSON`, `save NPZ`: granstab.save_scene.
Memory: tracemalloc's peak while loading, per contact, at two sizes (constant ⇒ O(contacts)).
"""
from __future__ import annotations

import json
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

import granstab
from granstab.io import load_scene
from granstab.io.entries import Reader, read_law
from granstab.io.scenes import save_scene
from granstab.io.schema import (
    CONTACT_KEYS,
    PARTICLE_KEYS,
    TOP_KEYS,
    _base_law,
    read_header,
    read_particles,
)
from granstab.model import packings
from granstab.model.scene import LAW_KEYS, STATES, build_scene

from .timing import repeats

QUICK_SIZES = (1_000, 10_000)
FULL_SIZES = (10_000, 100_000, 1_000_000)
REFERENCE_MAX = 120_000       # the per-contact reference takes ~minutes beyond this
CONTACTS_PER_PARTICLE = 2.7   # of the 2D random packings (measured; the sizes below are the actual counts)


def median_time(fn, budget: float = 2.0, most: int = 5) -> tuple[float, int]:
    """Median wall time of fn() and the number of runs (up to `most`, while the total is under `budget`)."""
    times, most = [], repeats(most)
    while len(times) < most and (not times or sum(times) < budget):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), len(times)


def peak_bytes(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def previous_reader(data: dict, source: str = "<scene>"):
    """The contact-level reader as it was before the column-wise one: a Python loop over contacts, one Reader
    per entry and one np.array per field (reference only)."""
    top, dim, title = read_header(data, source, TOP_KEYS)
    r = 1 if dim == 2 else 3
    law = read_law(Reader(source, "defaults", data.get("defaults", {}), set(LAW_KEYS)), dim, _base_law(dim))

    def read_particle(rd, name):
        load = rd.array("load", (dim,)) if rd.has("load") else None
        moment = rd.array("moment", () if dim == 2 else (3,)) if rd.has("moment") else None
        return name, rd.array("x", (dim,)), load, moment

    names, x, loads, moments = zip(*read_particles(top, data, PARTICLE_KEYS, read_particle))
    index = {name: i for i, name in enumerate(names)}
    cols = {key: [] for key in ("p", "q", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "k",
                                "alpha", "mu", "rolling", "state")}
    seen = {}
    for c, item in enumerate(data.get("contacts", [])):
        rd = Reader(source, f"contacts[{c}]", item, CONTACT_KEYS)
        pn, qn = rd.text("p"), rd.text("q")
        pair = frozenset((pn, qn))
        if pn not in index or qn not in index or pn == qn or pair in seen:
            rd.fail("q", "bad pair")
        seen[pair] = c
        cols["p"].append(index[pn])
        cols["q"].append(index[qn])
        cols["point"].append(rd.array("point", (dim,)))
        normal = rd.array("normal", (dim,))
        if abs(float(np.linalg.norm(normal)) - 1.0) > 1e-6:
            rd.fail("normal", "must be a unit vector")
        cols["normal"].append(normal)
        t = np.array([-normal[1], normal[0]])
        for key in ("curvature_p", "curvature_q"):
            cols[key].append(float(rd.array(key, ())) * np.outer(t, t))
        cols["force"].append(rd.array("force", (dim,)))
        cols["moment"].append(rd.array("moment", (), 0.0).reshape(1))
        own = read_law(rd, dim, law)
        for key in ("k", "alpha", "mu"):
            cols[key].append(own[key])
        cols["rolling"].append(own["rolling_stiffness"])
        state = rd.text("state", "auto")
        if state not in STATES:
            rd.fail("state", "bad state")
        cols["state"].append(state)
    M = len(cols["p"])
    arrays = {key: np.array(value).reshape(M, *np.shape(value[0])) if M else np.zeros((0,))
              for key, value in cols.items() if key != "state"}
    arrays["p"], arrays["q"] = arrays["p"].astype(np.intp), arrays["q"].astype(np.intp)
    arrays["moment"] = arrays["moment"].reshape(M, r)
    arrays["state"] = tuple(cols["state"])
    return build_scene(dim, list(names), np.array(x).reshape(-1, dim), arrays, list(loads), list(moments),
                       title=title, source=source)


def table_columns(scene) -> np.ndarray:
    """The contacts' numeric columns for numpy.loadtxt: p q point(2) normal(2) κp κq force(2) moment k α μ."""
    scalar = granstab.io.schema.scene_arrays(scene)
    return np.column_stack([scene.p, scene.q, scene.point, scene.normal, scalar["contacts/curvature_p"],
                            scalar["contacts/curvature_q"], scene.force, scene.moment, scene.k, scene.alpha,
                            scene.mu])


def one_size(target: int, folder: Path, memory: bool) -> dict:
    scene = packings.random_packing(2, int(target / CONTACTS_PER_PARTICLE), seed=1)
    M = scene.n_contacts
    json_path, npz_path, txt_path = folder / "s.json", folder / "s.npz", folder / "s.txt"
    row = {"contacts": M, "particles": scene.n_particles}
    row["save JSON"] = median_time(lambda: save_scene(scene, json_path))
    row["save NPZ"] = median_time(lambda: save_scene(scene, npz_path))
    np.savetxt(txt_path, table_columns(scene))
    row["json_mb"] = json_path.stat().st_size / 1e6
    row["npz_mb"] = npz_path.stat().st_size / 1e6
    row["load JSON (columns)"] = median_time(lambda: load_scene(json_path))
    row["load NPZ"] = median_time(lambda: load_scene(npz_path))
    row["numpy.loadtxt"] = median_time(lambda: np.loadtxt(txt_path))
    arrays = {k: getattr(scene, k) for k in ("p", "q", "point", "normal", "curvature_p", "curvature_q", "force",
                                             "moment", "k", "alpha", "mu", "rolling", "state")}
    row["build in memory"] = median_time(lambda: build_scene(2, scene.names, scene.x, arrays))
    if M <= REFERENCE_MAX:
        row["load JSON (per contact)"] = median_time(
            lambda: previous_reader(json.loads(json_path.read_text()), str(json_path)), budget=0.0, most=1)
    back = load_scene(npz_path)
    row["npz_round_trip_exact"] = all(np.array_equal(getattr(back, k), getattr(scene, k))
                                      for k in ("x", "p", "q", "point", "normal", "force", "k", "load"))
    if memory:
        row["peak_bytes_per_contact"] = {"JSON": peak_bytes(lambda: load_scene(json_path)) / M,
                                         "NPZ": peak_bytes(lambda: load_scene(npz_path)) / M}
    return row


TIMED = ("load JSON (columns)", "load JSON (per contact)", "load NPZ", "numpy.loadtxt", "build in memory",
         "save JSON", "save NPZ")


def run(quick: bool = False) -> dict:
    sizes = QUICK_SIZES if quick else FULL_SIZES
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, target in enumerate(sizes):
            rows.append(one_size(target, Path(tmp), memory=i < 2))
    for row in rows:
        for key in TIMED:
            if key in row:
                row[key] = {"seconds": row[key][0], "runs": row[key][1]}
        ref = row.get("load JSON (per contact)")
        if ref:
            row["speed-up JSON columns vs per contact"] = ref["seconds"] / row["load JSON (columns)"]["seconds"]
        row["speed-up NPZ vs JSON columns"] = row["load JSON (columns)"]["seconds"] / row["load NPZ"]["seconds"]
    return {"quick": quick, "rows": rows}


def markdown(results: dict) -> str:
    rows = results["rows"]
    head = ["contacts", "JSON MB", "NPZ MB", *TIMED, "columns vs per contact", "NPZ vs JSON"]
    lines = ["## Reading scene files", "",
             "2D random packings; medians of up to 5 runs (1 where a run takes seconds), seconds. *per contact*: the "
             "reader before the column-wise one (benchmarks/reading.py keeps it as the reference), run up to "
             f"{REFERENCE_MAX:,} contacts. numpy.loadtxt parses the 14 numeric contact columns without any check."
             + (" Quick run: small sizes only." if results["quick"] else ""), "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        cells = [f"{row['contacts']:,}", f"{row['json_mb']:.1f}", f"{row['npz_mb']:.1f}"]
        cells += [f"{row[k]['seconds']:.3g}" if k in row else "—" for k in TIMED]
        ref = row.get("speed-up JSON columns vs per contact")
        cells += [f"{ref:.1f}×" if ref else "—", f"{row['speed-up NPZ vs JSON columns']:.1f}×"]
        lines.append("| " + " | ".join(cells) + " |")
    mem = [(row["contacts"], row["peak_bytes_per_contact"]) for row in rows if "peak_bytes_per_contact" in row]
    lines += ["", "Peak memory while loading (tracemalloc), bytes per contact: "
              + "; ".join(f"{M:,} contacts: JSON {m['JSON']:.0f}, NPZ {m['NPZ']:.0f}" for M, m in mem)
              + " (per contact it does not grow with size: memory O(contacts)).",
              "NPZ round trip exact (x, p, q, point, normal, force, k, load): "
              + ", ".join(str(row["npz_round_trip_exact"]) for row in rows) + "."]
    return "\n".join(lines) + "\n"
