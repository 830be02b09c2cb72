"""The natural experiment of issue 42 (docs/uncertainty.md): RigidLibrary's annulus experiments 6 and 10 hold one
set of positions (byte-identical files) with two force solutions. Both are scanned alike; per cluster (by its
centre's name, the cluster's scene having the same particles and contacts in both) the verdicts are compared, and
beside the fraction that changes stands what `scan --force-uncertainty REL` predicts at the spread between the
solutions (REL: the median per-contact |f⁶ − f¹⁰| / |f¹⁰|): the share that depends on the data (a lower bound of
the change: a counter-example exists) and the share not proven to hold (an upper bound). Also the held-out check:
every cluster called "holds" whose other solution lies within the band, contact by contact, has the same verdict
under it, and every "depends" row's counter-example reproduces the other verdict. Run by hand:

    python -m granstab_bench.uncertainty_study [--frame 1] [--rel R] [--centers every:K] [--boundary B]
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np

import granstab
from granstab.mechanics.uncertainty import Band
from granstab.model.scene import SceneError
from granstab.scan import read_map, scan
from granstab.scan.clusters import adjacency, cluster
from granstab.scan.run import _sub_index
from granstab.uncertainty import counterexample_from_flat, counterexample_scene, data_robustness

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "rigidlibrary" / "DataAnnulus"


def pair_keys(scene) -> list:
    """Each contact as the unordered pair of its particles' names."""
    return [frozenset((scene.names[p], scene.names[q])) for p, q in zip(scene.p, scene.q)]


def forces_in(scene, other) -> np.ndarray | None:
    """The forces of `other`'s contacts in `scene`'s contact order and orientation (f^pq on p by q), or None where
    the two contact sets differ."""
    keys, theirs = pair_keys(scene), {k: i for i, k in enumerate(pair_keys(other))}
    if set(keys) != set(theirs) or set(scene.names) != set(other.names):
        return None
    index = np.array([theirs[k] for k in keys])
    same = np.array([scene.names[p] == other.names[other.p[j]] for p, j in zip(scene.p, index)])
    return np.where(same[:, None], other.force[index], -other.force[index])


def median_spread(a, b) -> float:
    """The median per-contact |f_b − f_a| / |f_a| over the contacts both solutions have."""
    theirs = {k: i for i, k in enumerate(pair_keys(b))}
    rel = []
    for i, k in enumerate(pair_keys(a)):
        if k in theirs:
            j = theirs[k]
            fb = b.force[j] if a.names[a.p[i]] == b.names[b.p[j]] else -b.force[j]
            rel.append(np.linalg.norm(fb - a.force[i]) / np.linalg.norm(a.force[i]))
    return float(np.median(rel))


def spread_band(a, b):
    """Scene a with `force_err` the spread |f_b − f_a| of each contact in both solutions (a hair wider), |f_a| where b
    lacks it: `scan --force-uncertainty file` then gives each cluster the other solution's distance as its band, so
    the other solution lies in the band by construction wherever a cluster has the same contacts in both."""
    theirs = {k: i for i, k in enumerate(pair_keys(b))}
    err = np.linalg.norm(a.force, axis=1).copy()
    for i, k in enumerate(pair_keys(a)):
        if k in theirs:
            j = theirs[k]
            fb = b.force[j] if a.names[a.p[i]] == b.names[b.p[j]] else -b.force[j]
            err[i] = np.linalg.norm(fb - a.force[i])
    return replace(a, force_err=err * (1 + 1e-9))


def compare(a, b, rows_a: dict, rows_b: dict, options: dict) -> list[dict]:
    """Per centre scanned in both: the verdicts, data_robust of `a`, and (where the cluster's scene has the same
    particles and contacts in both) the other solution's forces in a's order and whether each is within a's band."""
    rel, abs_ = options["uncertainty"].get("rel", 0.0), options["uncertainty"].get("abs", 0.0)
    ga, gb = adjacency(a), adjacency(b)
    index_b = {name: i for i, name in enumerate(b.names)}
    verdict_b = {b.names[c]: v for c, v in zip(rows_b["center"], rows_b["verdict"])}
    out = []
    for i, c in enumerate(rows_a["center"]):
        name = a.names[c]
        if name not in verdict_b:
            continue
        sub_a = cluster(a, c, options["rings"], options["boundary"], graph=ga)
        sub_b = cluster(b, index_b[name], options["rings"], options["boundary"], graph=gb)
        other = forces_in(sub_a, sub_b)
        band = sub_a.force_err if options["uncertainty"].get("per_contact") else \
            rel * np.linalg.norm(sub_a.force, axis=1) + abs_
        within = None if other is None else bool(np.all(np.linalg.norm(other - sub_a.force, axis=1) <= band))
        out.append({"centre": name, "verdict_a": rows_a["verdict"][i], "verdict_b": verdict_b[name],
                    "robust": rows_a["data_robust"][i], "same_contacts": other is not None, "within": within,
                    "counterexample": rows_a["counterexample"][i], "scene_a": sub_a, "other": other,
                    "inside": _sub_index(sub_a, a, rows_a["members"][i])})
    return out


def held_out(pairs: list[dict], metric: str = "L") -> dict:
    """The held-out check: holds and within the band ⇒ the same verdict; depends ⇒ its counter-example's `analyze`
    gives another verdict than the data's, proven. Returns the counts and the violations (centre names)."""
    holds = [p for p in pairs if p["robust"] == "holds" and p["within"]]
    wrong = [p["centre"] for p in holds if p["verdict_a"] != p["verdict_b"]]
    failed = []
    depends = [p for p in pairs if p["robust"] == "depends"]
    for p in depends:
        scene = counterexample_scene(p["scene_a"], counterexample_from_flat(p["scene_a"], p["counterexample"]))
        got = granstab.analyze(scene, metric=metric, attribution=False).verdict
        if got.verdict == p["verdict_a"] or not got.sufficient:
            failed.append(p["centre"])
    return {"holds_within_band": len(holds), "holds_changed": wrong, "depends": len(depends),
            "depends_not_reproduced": failed}


def solutions(frame: int) -> tuple:
    """The two force solutions of one annulus frame: experiment 10's scene, experiment 6's."""
    return tuple(granstab.load(str(DATA / e), frame=frame).scene for e in ("10", "6"))


def at_the_spread(pairs: list[dict], boundary: str) -> dict:
    """Each cluster with the same contacts in both solutions analysed with the band that is the spread itself, contact
    by contact (Band.per_contact = |f⁶ − f¹⁰|, a hair wider): the other solution lies in the band by construction, so
    a "holds" must keep its verdict; the counts of holds / depends / undecided and of verdicts that change in each."""
    embedded = boundary.startswith("embedded")
    out = Counter()
    for p in pairs:
        if not p["same_contacts"]:
            continue
        scene = p["scene_a"]
        band = Band(per_contact=np.linalg.norm(p["other"] - scene.force, axis=1) * (1 + 1e-9))
        try:
            got = data_robustness(scene, band, max_sliding=8, inside=(p["inside"], 0.5) if embedded else None)
            robust = got.robust if got.verdict == p["verdict_a"] else "undecided"
        except (SceneError, ValueError):
            robust = "undecided"
        out[robust] += 1
        out[f"{robust}_changed"] += p["verdict_a"] != p["verdict_b"]
    return dict(out)


def study(frame: int, rel: float | None, centers, boundary: str, rings: int = 1, scenes=None,
          spread: bool = False) -> dict:
    """Both solutions scanned alike (rel: the band; None: the median spread; "spread": each contact's own spread,
    `spread_band`, through the scan's per-contact band) at the same centres, compared and checked. scenes:
    `solutions(frame)`, if at hand; spread: also `at_the_spread`."""
    a, b = scenes or solutions(frame)
    if rel == "spread":
        a = spread_band(a, b)
        band = {"per_contact": True, "search": True}
    else:
        rel = median_spread(a, b) if rel is None else rel
        band = {"rel": rel, "abs": 0.0, "search": True}
    options = {"rings": rings, "boundary": boundary, "uncertainty": band}
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        scan(a, Path(tmp) / "a", centers=centers, rings=rings, boundary=boundary, workers=1, figures=False,
             attribution=False, uncertainty=options["uncertainty"])
        seconds = time.perf_counter() - start
        rows_a = read_map(Path(tmp) / "a")["clusters"]
        names = [a.names[c] for c in rows_a["center"] if a.names[c] in set(b.names)]
        scan(b, Path(tmp) / "b", centers=names, rings=rings, boundary=boundary, workers=1, figures=False,
             attribution=False)
        rows_b = read_map(Path(tmp) / "b")["clusters"]
    pairs = compare(a, b, rows_a, rows_b, options)
    same = [p for p in pairs if p["same_contacts"]]
    robust = Counter(p["robust"] for p in same)
    changed = sum(p["verdict_a"] != p["verdict_b"] for p in same)
    n = max(len(same), 1)
    return {"frame": frame, "rel": rel, "boundary": boundary, "clusters": len(pairs), "same_contacts": len(same),
            "changed": changed, "changed_fraction": changed / n, "holds": robust["holds"],
            "depends": robust["depends"], "undecided": robust["undecided"],
            "predicted_at_least": robust["depends"] / n, "predicted_at_most": 1 - robust["holds"] / n,
            "check": held_out(pairs), "scan_seconds": seconds,
            "at_the_spread": at_the_spread(pairs, boundary) if spread else None}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frame", type=int, default=1)
    p.add_argument("--rel", default=None, help="the band (default: the median spread; 'spread': each contact's own)")
    p.add_argument("--centers", default="all")
    p.add_argument("--boundary", default="embedded:1")
    p.add_argument("--spread", action="store_true", help="also each cluster with the spread itself as its band")
    args = p.parse_args(argv)
    rel = args.rel if args.rel in (None, "spread") else float(args.rel)
    print(json.dumps(study(args.frame, rel, args.centers, args.boundary, spread=args.spread), indent=1))


if __name__ == "__main__":
    main()
