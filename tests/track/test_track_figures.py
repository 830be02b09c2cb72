"""granstab.track.figures on a synthetic folder in the track contract (tests/track_folder.py): the three figures as
PNG and SVG, the maps at the frames the largest events start from, the ROC panels of the targets with both classes
and their AUCs equal to prediction.json's."""
from __future__ import annotations

import json

import numpy as np
from track_folder import EVENTS, write

from granstab.track import figures, predict


def test_figures_of_a_contract_folder(tmp_path):
    write(tmp_path)
    paths = figures.write(tmp_path, frames=[EVENTS[0]])       # one map row: the figures' cost is in the disks
    assert sorted(p.name for p in paths) == sorted(f"{s}.{e}" for s in ("timeline", "maps", "roc")
                                                   for e in ("png", "svg"))
    for p in paths:
        head = p.read_bytes()[:8]
        assert head.startswith(b"\x89PNG") if p.suffix == ".png" else b"<?xml" in head
        assert 5_000 < p.stat().st_size < 2_000_000, (p, p.stat().st_size)
    found, ctx = predict.cases(tmp_path)
    events = json.loads((tmp_path / "events.json").read_text())
    particles = predict.read_columns(tmp_path / "particles.parquet")
    assert figures.chosen_frames(ctx, particles, events) == list(EVENTS)     # all three events, all with a window
    svg = (tmp_path / "timeline.svg").read_text()
    assert "3 events (drops of shear_stress)" in svg and "all-loading" in svg
    assert "signed log scale" in svg and "verdict proven" in svg           # issue 39: both branches readable
    roc = (tmp_path / "roc.svg").read_text()
    # contacts_changed has no positives in this folder: no panel; the others carry prediction.json's AUCs
    assert "contacts_changed" not in roc and "d2min_top10" in roc and "event" in roc
    rows = predict.run(tmp_path)["rows"]
    want = next(r["auc"] for r in rows if (r["target"], r["predictor"]) == ("rearranges", "unstable_fraction"))
    assert f"unstable_fraction {want:.2f}" in roc


def test_drawing_radii_half_the_nearest_distance_without_a_radius_column():
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]])
    assert figures.drawing_radii(xy, {}, np.ones(3, bool)).tolist() == [0.5, 0.5, 1.0]
    assert figures.drawing_radii(xy, {"radius": np.array([0.2, 0.3, 0.4])}, np.ones(3, bool)).tolist() == [0.2, 0.3,
                                                                                                          0.4]
