"""A tracked folder in the explorer (issue 27, "In the app"): a frame at a time as its scan map, the Frame slider, the
λ_min(t)/stress(t) plot with the frame now and the events, the next window's D²min as an overlay, and a particle's
cluster at that frame — the session (no browser) and one short browser run.

The sequence is test_track's three frames of a 4×4 lattice and a rattler, with the forces ×100 so that frame 1 has
unstable clusters (at ×1 every cluster is stable, and the map would be white whatever it showed).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyarrow")
import pyarrow.parquet as pq  # noqa: E402
from test_track import DELTA, RATTLER, write_sequence  # noqa: E402

from granstab.cli import main  # noqa: E402
from granstab.scan import read_map  # noqa: E402
from granstab_app.scanmap import GREY, fraction_colours  # noqa: E402
from granstab_app.state import Session  # noqa: E402
from granstab_app.trackmap import BLUE, WHITE, TrackModel  # noqa: E402
from granstab_app.trackview import track_figure  # noqa: E402

FORCE = 100.0           # the sequence's forces scaled: frame 1 has 2 unstable clusters (checked below)


def tracked(folder: Path, *options: str) -> Path:
    """`granstab track` (the CLI, in this process) of the sequence with forces × FORCE into folder/out."""
    particles, contacts = write_sequence(folder)
    table = np.loadtxt(contacts, delimiter=",", skiprows=1)
    table[:, 3:] *= FORCE
    np.savetxt(contacts, table, delimiter=",", header="frame,id1,id2,fx,fy", comments="")
    out = folder / "out"
    assert main(["track", str(particles), str(contacts), "--out", str(out), "--mu", "0.5", "--d2min-radius", "2.1",
                 "--workers", "1", *options]) == 0
    return out


@pytest.fixture(scope="module")
def track_dir(tmp_path_factory):
    return tracked(tmp_path_factory.mktemp("track"), "--scan", "--whole")


def test_a_track_opens_frame_by_frame_as_its_scan_maps(track_dir):
    """Each frame: every particle of particles.parquet at its position (the rattler too, grey: in no cluster), the
    others in the colours of the frame's own scan folder, which are red exactly on the members of its unstable
    clusters (mechanism not boundary); the plot marks the frame and the event."""
    s = Session()
    assert s.open_typed(str(track_dir))                            # typed into *Path on server*
    assert s.error is None and isinstance(s.model, TrackModel) and s.kind == "scan_map" and s.analysis is None
    assert s.model.frames == [0, 1, 2] and s.model.headline[1] == "track"
    rows = pq.read_table(track_dir / "particles.parquet").to_pydict()
    assert s.set_frame(1) and s.model.frame == 1
    at = {n: (x, y) for f, n, x, y in zip(rows["frame"], rows["name"], rows["x"], rows["y"]) if f == 1}
    drawn = {b.name: b.x for b in s.bodies()}
    assert drawn.keys() == at.keys() and len(drawn) == 17
    assert all(np.array_equal(drawn[n], at[n]) for n in at)        # positions as tracked, bit for bit
    scan = track_dir / "scans" / "frame-000001"
    own = dict(zip(Session(str(scan)).scene.names, map(tuple, Session(str(scan)).map_colours)))
    colours = dict(zip([b.name for b in s.bodies()], map(tuple, s.map_colours)))
    assert colours[str(RATTLER)] == GREY and all(colours[n] == own[n] for n in own)
    c = read_map(scan)["clusters"]
    names = read_map(scan)["particles"]["name"]
    bad = (np.asarray(c["verdict"]) == "unstable") & (np.asarray(c["mechanism"]) != "boundary")
    assert bad.sum() == 2                                          # the sequence as this test needs it
    inside = {names[i] for m in np.asarray(c["members"], dtype=object)[bad] for i in m}
    white = tuple(int(v) for v in fraction_colours(np.array([0.0]))[0])
    assert {n for n in own if colours[n] != white} == inside
    figure = track_figure(s.model.series())
    frames = pq.read_table(track_dir / "frames.parquet").to_pydict()
    lines = [sh for sh in figure.layout.shapes if sh.type == "line"]
    bands = [(sh.x0, sh.x1) for sh in figure.layout.shapes if sh.type == "rect"]
    events = json.loads((track_dir / "events.json").read_text())
    assert {ln.x0 for ln in lines} == {1} and set(bands) == {(e["frame"], e["next_frame"]) for e in events} != set()
    stress = next(tr for tr in figure.data if tr.name == "shear_stress")
    loading = next(tr for tr in figure.data if tr.name == "λ_min loading")
    assert list(stress.y) == frames["shear_stress"] and list(loading.y) == frames["lambda_min_loading"]


def test_d2min_overlay_and_a_cluster_at_a_frame(track_dir):
    """The overlay (computed only when on): frame 0 → 1 moves particle 6 off the affine motion by δ (D²min 4|δ|²,
    test_track's closed form): dark blue, a far corner white; frame 1 → 2 is affine to round-off (D²min ~1e-31):
    white everywhere, not its round-off at full scale. A click ray over particle 9 at frame 1 opens its cluster (unstable,
    frictional) as the frame's scan analysed it; *Back to the map* returns to frame 1; the rattler was no centre."""
    s = Session(str(track_dir))
    assert s.model.overlay_points() is None
    assert s.model.show_d2min(True)
    x, colours = s.model.overlay_points()
    names = s.model.names
    by = dict(zip(names, map(tuple, colours)))
    assert s.model.d2min[names.index("6")] == pytest.approx(4 * DELTA @ DELTA, rel=1e-9)
    assert by["6"] == tuple(BLUE) and by["16"] == tuple(WHITE) and len(x) == 17
    assert s.set_frame(1)
    assert np.nanmax(s.model.d2min) < 1e-25 and {tuple(c) for c in s.model.overlay_points()[1]} == {tuple(WHITE)}
    i = s.model.names.index("9")                                   # centre of an unstable (frictional) cluster
    top = [*s.model.x[i] + [0.3, -0.2], 50.0]
    assert s.pick(top, [0.0, 0.0, -1.0]) == "9"
    assert s.open_cluster("9") and s.kind == "contacts" and "frame-000001" in s.scene.title
    got = read_map(track_dir / "scans" / "frame-000001")
    c, names = got["clusters"], list(got["particles"]["name"])
    row = list(c["center"]).index(names.index("9"))
    assert s.verdict == c["verdict"][row] == "unstable"              # analyze of the cluster = the scan's row
    assert s.analysis.summary["consistent_negative"] == c["consistent_negative"][row] > 0
    assert {names[j] for j in c["members"][row]} <= set(s.scene.names)     # with its embedding ring
    assert s.back_to_map() and s.model.frame == 1 and s.model.overlay
    assert not s.open_cluster(str(RATTLER)) and "no centre" in s.error


def test_a_track_without_scan_draws_grey_and_opens_no_cluster(tmp_path):
    """No --scan: no packing per frame; grey particles (in no scanned cluster) of half the frame's mean contact
    distance, the rattler the largest disk that touches none of them, no λ_min (no --whole: the plot says so), and a click says in one line what would keep clusters."""
    out = tracked(tmp_path)
    s = Session(str(out))
    frames = pq.read_table(out / "frames.parquet").to_pydict()
    assert s.error is None and {tuple(c) for c in s.map_colours} == {GREY}
    half = 0.5 * frames["mean_contact_distance"][0]
    bodies = {b.name: b for b in s.bodies()}
    rattler = bodies.pop(str(RATTLER))
    gap = min(np.linalg.norm(rattler.x - b.x) for b in bodies.values()) - half     # touches its nearest neighbour
    assert {b.axes[0] for b in bodies.values()} == {half} and rattler.axes[0] == pytest.approx(gap, rel=1e-12)
    assert not s.open_cluster("6") and "--scan" in s.error
    figure = track_figure(s.model.series())
    assert [tr.name for tr in figure.data] == ["shear_stress"]
    assert any("--whole" in a.text for a in figure.layout.annotations)


@pytest.mark.browser
def test_a_track_in_the_page(track_dir, tmp_path):
    """`granstab-app --preset DIR` on the track: the D²min overlay ticked (dots sent), the Frame slider moved to
    frame 1 (map and plot follow), the overlay unticked (dots removed), then a real click on particle 9's disk in the
    canvas opens its cluster (UNSTABLE, the scan's row). GRANSTAB_APP_SHOTS=DIR keeps the two pictures
    (app-track-d2min.png: frame 0 with the overlay; app-track.png: frame 1's map)."""
    from playwright.sync_api import sync_playwright
    from test_app_browser import verdict_on_page, wait_for

    from granstab_app.browser import chromium, number_box
    from granstab_app.server import App
    app = App(host="127.0.0.1", port=0, preset=str(track_dir))
    errors: list[str] = []
    try:
        with sync_playwright() as pw:
            ctx = chromium(pw, tmp_path / "profile")
            page = ctx.new_page()
            page.on("pageerror", lambda exc: errors.append(f"pageerror: {exc}"))
            page.on("console", lambda msg: errors.append(f"console: {msg.text}") if msg.type == "error" else None)
            page.goto(app.url)
            verdict_on_page(page, "track", timeout=60_000)
            ui = wait_for(lambda: next(iter(app.uis.values()), None), what="the tab's UI")
            s = ui.session
            page.wait_for_selector(".js-plotly-plot .scatterlayer", timeout=30_000)     # the λ_min/stress plot
            page.get_by_label("D²min of the next window").check()
            wait_for(lambda: s.model.overlay and ui.track._dots is not None, what="the D²min dots")
            page.get_by_text("D²min overlay").wait_for(timeout=20_000)              # its legend
            for close in page.locator("button.mantine-Notification-closeButton").all():    # viser's notices
                close.click()
            picture(page, "app-track-d2min.png")
            assert (ui.frame.min, ui.frame.max, ui.frame.value) == (0, 2, 0)      # the frames' own numbers (was 1…3)
            box = number_box(page, ui.frame)
            box.fill("1")
            box.press("Enter")
            wait_for(lambda: s.model.frame == 1, what="frame 1 on the server")
            with ui.lock:                                   # its refresh has run: the plot marks frame 1
                assert {sh.x0 for sh in ui.track.plot.figure.layout.shapes if sh.type == "line"} == {1}
            page.get_by_text("track out, frame 1 (step 2)").first.wait_for(timeout=20_000)
            page.get_by_label("D²min of the next window").uncheck()             # frame 1's map, dots gone
            wait_for(lambda: not s.model.overlay and ui.track._dots is None, what="the dots removed")
            picture(page, "app-track.png")
            with ui.lock:
                cam = ui.client.camera
                centre, look, fov = np.asarray(cam.position), np.asarray(cam.look_at), float(cam.fov)
                target = s.model.x[s.model.names.index("9")]
            canvas = page.locator("canvas").first.bounding_box()
            ppu = 0.5 * canvas["height"] / ((centre[2] - look[2]) * np.tan(0.5 * fov))   # top-down view: px / length
            page.mouse.click(canvas["x"] + 0.5 * canvas["width"] + (target[0] - look[0]) * ppu,
                             canvas["y"] + 0.5 * canvas["height"] - (target[1] - look[1]) * ppu)
            verdict_on_page(page, "unstable", timeout=60_000)
            assert s.kind == "contacts" and "frame-000001" in s.scene.title and s.map is not None
            assert not ui.track.toggle.visible            # the track's controls belong to its frames
            ctx.close()
    finally:
        app.stop()
    assert errors == []


def picture(page, name: str) -> None:
    """The page as `name` in $GRANSTAB_APP_SHOTS when set (docs/app-track*.png are made that way)."""
    import os
    shots = os.environ.get("GRANSTAB_APP_SHOTS")
    if shots:
        page.wait_for_timeout(1500)                  # the drawing has arrived
        page.screenshot(path=str(Path(shots) / name))


def test_a_periodic_track_shows_its_cell_and_its_frame_numbers(track_dir):
    """Issue 36: a periodic track's frame is drawn with its cell outline (the map had none) and no periodic images
    (the map colours particles only); the Frame slider runs over the frames' own numbers (0 … 2, it ran 1 … 3)."""
    from types import SimpleNamespace

    from granstab_app.panel.scene import frame_axis
    from granstab_app.views import SceneView
    s = Session()
    assert s.open_typed(str(track_dir)) and s.model.cell is None and s.scene.cell is None
    assert frame_axis(s.model.frames) == (0, 2, 1) and frame_axis([3, 5, 9]) == (1, 3, 1)
    cell = np.array([[12.0, 0.0], [0.0, 12.0]])
    s.model.table["cell"] = np.array([cell.ravel().tolist()] * len(s.model.frames), dtype=object)
    scene = s.model.build({})
    assert np.array_equal(scene.cell, cell)
    calls = []
    api = SimpleNamespace(remove_by_name=lambda name: calls.append(("remove", name)),
                          add_line_segments=lambda name, points, *a, **k: calls.append(("add", name, points.shape)),
                          add_point_cloud=lambda name, points, **k: calls.append(("add", name, points.shape)))
    SceneView(api).draw_cell(SimpleNamespace(scene=scene, on_map=True, size=0.5))
    assert calls == [("remove", "/cell"), ("add", "/cell", (4, 2, 3))]


def test_no_drawn_particle_hides_under_its_neighbour(tmp_path):
    """Issue 36: all disks of a track's map are drawn at one depth, so no two may overlap (an overlap hid part of a
    particle's colour). Without --scan they were all half the mean contact distance: in frames 1 and 2 of the
    sheared lattice neighbours overlapped by up to 0.106 (radii 0.35 … 1.01); now every pair's gap is ≥ −1e-9 of
    its distance, and frame 0 (a touching lattice) keeps its radii."""
    s = Session(str(tracked(tmp_path)))
    for frame in s.model.frames:
        assert frame == s.model.frame or s.set_frame(frame)
        bodies = s.bodies()
        x, r = np.array([b.x for b in bodies]), np.array([b.axes[0] for b in bodies])
        i, j = np.triu_indices(len(r), 1)
        d = np.linalg.norm(x[i] - x[j], axis=1)
        assert np.all(r > 0) and np.all(r[i] + r[j] <= d * (1 + 1e-9)), frame
