"""The evidence behind the scan's default boundary (issue 25, docs/attribution.md): on a finite window of a real
packing held at its boundary, each interior cluster's verdict under --boundary loads, fixed and embedded:R
(R = 0 … 4) against the whole window's answer (embedded with R past the window: every particle free but the held
boundary, only the cluster's own contacts sliding, the verdict on the modes mostly inside the cluster), with the
mechanism histogram of each. Run by hand (not a `granstab bench` topic: it writes docs/attribution/):

    python -m granstab_bench.attribution_study SCENE NAME [--size S] [--centre X,Y] [--out docs/attribution]
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

import granstab
from granstab.scan import read_map, scan, subscene
from granstab.scan.clusters import adjacency, members

WHOLE = 99            # embedded rings that reach past any window used here: the whole window


def window(scene, size: float, centre=None):
    """The particles within a square of side `size` about `centre` (default the median position) as a finite
    packing, the particles one contact beyond held fixed (scene.fixed): a packing held at its boundary."""
    centre = np.median(scene.x, axis=0) if centre is None else np.asarray(centre, dtype=float)
    inside = np.flatnonzero(np.all(np.abs(scene.x - centre) <= size / 2, axis=1))
    graph = adjacency(scene)
    ring = np.setdiff1d(np.flatnonzero(np.asarray(graph[inside].sum(axis=0)).ravel() > 0), inside)
    return subscene(scene, inside, title=f"{size:g}-wide window of {scene.source}", hold=ring)


def interior(scene, hops: int = 2) -> np.ndarray:
    """Particles at least `hops` contacts from a held one: their clusters and rims are the window's own."""
    held = np.flatnonzero(scene.fixed)
    near = np.unique(np.concatenate(members(scene, held, hops))) if held.size else np.zeros(0, int)
    return np.setdiff1d(np.flatnonzero(~scene.fixed), near)


def study(scene, out: Path, boundaries) -> dict:
    """Scan the window's interior centres under each boundary (one worker); verdicts and mechanisms per boundary
    and the agreement with the whole window's verdict."""
    centres = interior(scene)
    names = [scene.names[i] for i in centres]
    results = {}
    for label, boundary in boundaries:
        start = time.perf_counter()
        scan(scene, out / label.replace(":", "_"), centers=names, boundary=boundary, workers=1, figures=False)
        rows = read_map(out / label.replace(":", "_"))["clusters"]
        verdict = dict(zip(rows["center"].tolist(), rows["verdict"]))
        results[label] = {"verdict": verdict, "mechanism": Counter(rows["mechanism"]),
                          "seconds": time.perf_counter() - start}
    whole = results["whole"]["verdict"]
    for r in results.values():
        v = r["verdict"]
        r["unstable"] = sum(x == "unstable" for x in v.values())
        r["agree"] = sum(v[c] == whole[c] for c in whole)
        r["false_unstable"] = sum(v[c] == "unstable" and whole[c] != "unstable" for c in whole)
        r["missed"] = sum(v[c] != "unstable" and whole[c] == "unstable" for c in whole)
    return {"n_particles": scene.n_particles, "n_held": int(scene.fixed.sum()), "n_centres": len(centres),
            "n_sliding": int(scene.at_yield().sum()), "boundaries": {
                k: {key: (dict(val) if isinstance(val, Counter) else val) for key, val in r.items() if key != "verdict"}
                for k, r in results.items()}}


def table(name: str, got: dict) -> str:
    """The convergence table (markdown)."""
    lines = [f"**{name}**{got.get('where', '')}: a window of {got['n_particles']} particles ({got['n_held']} held at its boundary, "
             f"{got['n_sliding']} sliding contacts), {got['n_centres']} interior clusters (1 ring).", "",
             "| boundary | unstable | agree with whole | unstable, whole not | missed | mechanisms | s |",
             "|---|---|---|---|---|---|---|"]
    for label, r in got["boundaries"].items():
        mech = ", ".join(f"{k} {v}" for k, v in sorted(r["mechanism"].items()) if k)
        lines.append(f"| {label} | {r['unstable']} | {r['agree']}/{got['n_centres']} | {r['false_unstable']} | "
                     f"{r['missed']} | {mech or '–'} | {r['seconds']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("name")
    p.add_argument("--size", type=float, default=20.0, help="side of the window, in the scene's lengths")
    p.add_argument("--centre", default=None, help="X,Y of the window's centre (default: the median position)")
    p.add_argument("--out", default="docs/attribution")
    args = p.parse_args(argv)
    centre = None if args.centre is None else [float(v) for v in args.centre.split(",")]
    scene = window(granstab.load_scene(args.scene), args.size, centre)
    work = Path(tempfile.mkdtemp(prefix=f"attribution-study-{args.name}-"))
    boundaries = [("loads", "loads"), ("fixed", "fixed")] + [(f"embedded:{R}", f"embedded:{R}") for R in range(5)] \
        + [("whole", f"embedded:{WHOLE}")]
    got = study(scene, work, boundaries)
    got["where"] = f" ({args.size:g} wide" + ("" if centre is None else f" about ({args.centre})") + ")"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"convergence-{args.name}.json").write_text(json.dumps(got, indent=1), encoding="utf-8")
    print(table(args.name, got))


if __name__ == "__main__":
    main()
