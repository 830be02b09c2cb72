"""Browser checks of issue 13's defects (headless Debian chromium via Playwright): no page error over many loads,
only the panels a scene uses, a way back from a dragged pair, labels, and uploads that never show server paths.

Each page listens to `pageerror` and console errors; any one fails the test. The λ⁽⁶⁾ contour used to be mounted
before its side panel docked, and about 40 % of loads then threw `_redrawFromAutoMarginCount`: LOADS loads make a
pass by chance before the fix unlikely (0.6^5 ≈ 8 %; it failed on the first run here before the fix). The contour is
now a picture (a plotly plot in a panel that comes and goes left that error behind on quick switches); the spectrum
plot is the page's one plotly plot.
"""
from __future__ import annotations

import os
import re
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from test_app_browser import CHROMIUM, FLAGS, REPO, verdict_on_page, wait_for

from granstab_app.text import preset_label

pytestmark = pytest.mark.browser
LOADS = 5
SWITCHES = 6


@pytest.fixture(scope="module")
def app(explorer):
    return explorer("two_particle.toml", "ellipses_sharp.toml", "four_disk.toml", "annulus_frame.json",
                    "spheres_tetrahedron.toml", "hand_in_glove.toml")


@pytest.fixture(scope="module")
def playwright():
    from playwright.sync_api import sync_playwright
    assert CHROMIUM.exists(), "Debian chromium is required: bash .ci/run installs it (apt-get install -y chromium)"
    with sync_playwright() as pw:
        yield pw


@pytest.fixture(scope="module")
def browser(playwright, tmp_path_factory):
    ctx = playwright.chromium.launch_persistent_context(str(tmp_path_factory.mktemp("profile")),
                                                         executable_path=str(CHROMIUM), headless=True, args=FLAGS,
                                                         viewport={"width": 1600, "height": 1000})
    yield ctx
    ctx.close()


def open_page(browser, app, errors):
    page = browser.new_page()
    page.on("pageerror", lambda exc: errors.append(f"pageerror: {exc}"))
    page.on("console", lambda msg: errors.append(f"console: {msg.text}") if msg.type == "error" else None)
    page.goto(app.url)
    return page


def close_page(page, errors, shot: str) -> None:
    """Save the picture as `shot` in $GRANSTAB_APP_SHOTS when set (docs/ is made that way), close, no page error."""
    shots = os.environ.get("GRANSTAB_APP_SHOTS")
    if shots:
        for close in page.locator("button.mantine-Notification-closeButton").all():    # viser's notices
            close.click()
        page.wait_for_timeout(3000)
        page.screenshot(path=str(Path(shots) / shot))
    page.close()
    assert errors == []


def shows_last_sent(page, ui, timeout=60.0) -> int:
    """Wait until the page's badge shows the revision the server last wrote into it (the headline's data-revision),
    and still does after a quiet second: a session's revision number is no promise that a verdict for it was sent (a
    page event or a typing pause still queued on a loaded machine runs later and writes another)."""
    def last_sent():
        with ui.lock:
            return re.search(r'data-revision="(\d+)"', ui.headline.content).group(1)

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        sent = last_sent()
        if page.locator(".granstab-verdict").get_attribute("data-revision") == sent:
            page.wait_for_timeout(1000)
            if last_sent() == sent:
                return int(sent)
        page.wait_for_timeout(200)
    raise AssertionError(f"the page never showed the verdict the server sent last ({timeout:.0f} s)")


def ui_of(app, page):
    return wait_for(lambda: next((u for u in list(app.uis.values())
                                  if page.locator(f'[id="{u.preset._impl.uuid}"]').count()), None), what="the tab's UI")


def test_no_page_error_over_many_loads(app, browser):
    errors: list[str] = []
    for _ in range(LOADS):
        page = open_page(browser, app, errors)
        verdict_on_page(page, "unstable", timeout=60_000)
        # the λ⁽⁶⁾ contour is shown and the spectrum plot has drawn (120 s, as the other waits of a loaded machine: the
        # contour once took over 60 s with two Chromiums on the 2 cores)
        page.wait_for_selector(".granstab-contour img", timeout=120_000)
        page.wait_for_selector(".js-plotly-plot .scatterlayer", timeout=120_000)
        page.wait_for_timeout(1000)                                           # a pending redraw would fire by now
        page.close()
    assert errors == []


def test_the_star_sits_on_the_contour_where_the_sliders_are(app, browser):
    """The ★ is an element of its own under the contour's picture (sent at each move, the 49 kB picture once per
    field), moved up over it by CSS: its centre must land where the sliders' (ρ/r, f/(kr)) lie on the picture's plot
    area. Tolerance 3 px: the glyph is 26 px, the grid's ρ/r step about 6 px on the panel's picture."""
    from granstab_app.browser import number_box
    from granstab_app.field import field_picture
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    page.get_by_role("tab", name="λ⁽⁶⁾ field").click()
    for rho_r in (None, 2.4):
        if rho_r is not None:
            box = number_box(page, ui.sliders["rho_r"])
            box.fill(f"{rho_r:g}")
            box.press("Enter")
            wait_for(lambda r=rho_r: ui.session.params["rho_r"] == r, what="ρ/r on the server")
            shows_last_sent(page, ui)
        field, (mark_rho, mark_f) = ui.session.field(), (ui.session.params["rho_r"], ui.session.params["f_kr"])
        _, (x0, y0, x1, y1) = field_picture(field)
        u = (mark_rho - field.rho_r[0]) / (field.rho_r[-1] - field.rho_r[0])
        v = (mark_f - field.f_kr[0]) / (field.f_kr[-1] - field.f_kr[0])
        picture = page.locator(".granstab-contour img").bounding_box()
        star = page.locator(".granstab-star").bounding_box()
        centre = (star["x"] + star["width"] / 2, star["y"] + 0.52 * star["height"])     # translate(-50%, -52%)
        expected = (picture["x"] + (x0 + u * (x1 - x0)) * picture["width"],
                    picture["y"] + (1 - y0 - v * (y1 - y0)) * picture["height"])
        assert np.hypot(centre[0] - expected[0], centre[1] - expected[1]) <= 3.0, (rho_r, centre, expected)
    page.close()
    assert errors == []


def test_panels_labels_and_reset(app, browser):
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    s = ui.session
    tab = page.get_by_role("tab", name="λ⁽⁶⁾ field")
    tab.wait_for(timeout=20_000)
    page.get_by_role("tab", name="Export").click()
    page.get_by_role("button", name="λ⁽⁶⁾ contour (.png)").wait_for(timeout=20_000)
    page.get_by_role("tab", name="Scene").click()

    # a non-pair preset: no λ⁽⁶⁾ tab, no contour export, no λ⁽⁶⁾ surface checkbox
    page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
    page.get_by_role("option", name=preset_label("four_disk")).click()
    wait_for(lambda: s.preset == "four_disk", what="four_disk on the server")
    page.get_by_role("tab", name="Eigenmodes").wait_for(timeout=20_000)
    wait_for(lambda: page.get_by_role("tab", name="λ⁽⁶⁾ field").count() == 0, what="the λ⁽⁶⁾ tab to go")
    page.get_by_role("tab", name="Export").click()
    page.get_by_role("button", name="Analysis (.json)").wait_for(timeout=20_000)
    assert page.get_by_role("button", name="λ⁽⁶⁾ contour (.png)").count() == 0
    page.get_by_role("tab", name="Display").click()
    page.get_by_text("Force arrows").wait_for(timeout=20_000)
    assert page.get_by_text("λ⁽⁶⁾ height surface").count() == 0
    page.get_by_role("tab", name="Scene").click()

    # pull the sharp ellipses apart: "no contact", not NEUTRAL and not "tips touching"
    page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
    page.get_by_role("option", name=preset_label("ellipses_sharp")).click()
    wait_for(lambda: s.preset == "ellipses_sharp" and s.analysis is not None, what="ellipses_sharp")
    with ui.lock:                   # the page's refresh for the new preset has finished (it holds the lock)
        name = s.scene.names[1]
    ui.view.nodes[name].position = (8.0, 0.0, 0.0)
    ui._on_drag(name, SimpleNamespace(phase="end"))
    verdict_on_page(page, "no-contact")
    assert page.get_by_text("tips touching").count() == 0
    assert page.get_by_text("NEUTRAL").count() == 0

    # back to the pair, drag it, Reset: the ρ/r, f/(kr) sliders and the verdict return
    page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
    page.get_by_role("option", name=preset_label("two_particle")).click()
    verdict_on_page(page, "unstable")
    wait_for(lambda: s.kind == "two_particle", what="the pair")
    with ui.lock:
        pass
    ui.view.nodes["q"].position = (1.98, 0.4, 0.0)
    ui._on_drag("q", SimpleNamespace(phase="end"))
    wait_for(lambda: s.kind == "shapes", what="the drag")
    page.get_by_role("button", name="Reset", exact=True).click()
    verdict_on_page(page, "unstable")
    wait_for(lambda: s.kind == "two_particle", what="the pair back")
    assert ui.sliders["rho_r"].visible and s.params["rho_r"] == 0.5

    page.close()
    assert errors == []


def test_rejected_uploads_say_why(app, browser, tmp_path):
    """A file that cannot be opened (bad JSON) and one over MAX_UPLOAD, picked in the page's file chooser: each gets a
    red "Not opened: NAME" notice with the reason, beside viser's own notice of the transfer (which says the bytes
    arrived: viser's public API cannot change it, docs/viser-gaps.md); the oversize file is never parsed (refused
    by its size once viser has buffered it: there is no public hook at the start of an upload), the button works
    again, no server path shows, and a good file afterwards opens."""
    from granstab_app.state import MAX_UPLOAD
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    s = ui.session
    parsed = []                                    # every file the session was asked to read
    load = s.load_preset
    s.load_preset = lambda path: parsed.append(Path(path).name) or load(path)
    bad, big = tmp_path / "my_scene.json", tmp_path / "big_scene.json"
    bad.write_text("{not json")
    big.write_bytes(b" " * (MAX_UPLOAD + 1))
    for path, reason in ((bad, "malformed JSON"), (big, "5.0 MB is over the 5 MB limit")):
        page.locator("input[type=file]").first.set_input_files(str(path))
        notice = page.locator(".mantine-Notification-root").filter(has_text=f"Not opened: {path.name}")
        notice.filter(has_text=reason).wait_for(timeout=20_000)
        page.locator(".granstab-error").filter(has_text=path.name).filter(has_text=reason).wait_for(timeout=20_000)
        page.wait_for_timeout(1000)
        assert notice.count() == 1
        assert page.get_by_role("button", name="Open scene file").is_enabled()
        shown = " ".join(page.locator(".mantine-Notification-root, .granstab-error").all_inner_texts())
        assert "granstab-upload" not in shown and "/tmp" not in shown and str(tmp_path) not in shown
        for close in reversed(page.locator("button.mantine-Notification-closeButton").all()):   # last first: the
            if close.count():                                      # indices of those before stay; viser's upload
                close.click(timeout=5_000)                         # notice may have closed itself meanwhile
    assert parsed == [bad.name]
    assert s.preset == "two_particle" and s.kind == "two_particle"         # the current scene stays
    good = tmp_path / "uploaded_flat.toml"
    good.write_text((REPO / "presets" / "two_particle_flat.toml").read_text())
    page.locator("input[type=file]").first.set_input_files(str(good))
    verdict_on_page(page, "stable")
    assert s.preset == "uploaded_flat.toml (opened)"
    assert page.get_by_text("granstab-upload").count() == 0
    page.close()
    assert errors == []


def test_unstable_frame_shows_where_the_mode_lives(app, browser):
    """annulus_frame is UNSTABLE: the lowest consistent negative mode is selected and the particles are coloured by
    their share of it (some dark, some white), with the colour legend in the mode text. GRANSTAB_APP_SHOTS=folder
    saves the picture there (docs/app-mode-share.png is made that way)."""
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
    page.get_by_role("option", name=preset_label("annulus_frame")).click()
    wait_for(lambda: ui.session.preset == "annulus_frame", timeout=60, what="annulus_frame")
    verdict_on_page(page, "unstable", timeout=120_000)
    page.get_by_text("Particle colour: its share").wait_for(timeout=120_000)
    with ui.lock:
        mode = ui._current_mode()
        consistent = [m for m in ui.session.modes() if m.consistent]
        colours = np.array(list(ui.view.colours.values()), float)
    assert mode.consistent and mode.eigenvalue < 0 and mode.eigenvalue == min(m.eigenvalue for m in consistent)
    assert len(colours) == 143
    # 143 particles: the spectrum plot (seconds of browser work per update) is off until asked for: hidden, or empty
    # where the pair before it mounted one (unmounting a plot with a redraw pending is a page error)
    assert ui.show_spectrum.visible and not ui.show_spectrum.value
    assert not ui.spectrum.visible or len(ui.spectrum.figure.data) == 0
    # and the plot the pair mounted is a blank strip, not empty axes (it showed a grid with ticks −1…1 and 0…4)
    page.wait_for_function("() => { const p = document.querySelector('.js-plotly-plot');"
                           " return p && p.getBoundingClientRect().height < 60; }", timeout=30_000)
    assert page.locator(".js-plotly-plot .xtick, .js-plotly-plot .ytick").count() == 0
    assert colours[:, 1].min() < 60 and colours[:, 1].max() > 240      # a particle carrying it all, one at rest
    close_page(page, errors, "app-mode-share.png")


ANNULUS = REPO.parent / "shared" / "data" / "rigidlibrary" / "DataAnnulus" / "10"


def test_open_a_real_packing_from_the_page(app, browser):
    """A RigidLibrary annulus folder (1617 disks, 20 frames) typed into *Path on server*: opened once, when typed (not
    at every letter), drawn as one point cloud, not analysed until asked, its validation report shown, and a frame
    slider that reads another frame."""
    from granstab_app.browser import number_box
    folder = ANNULUS if ANNULUS.is_dir() else Path("/work/shared/data/rigidlibrary/DataAnnulus/10")
    assert folder.is_dir(), f"the photoelastic annulus data are needed: {folder}"
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    opened = []                                   # every attempt to open something, as a user types the path
    load = ui.session.load_preset
    ui.session.load_preset = lambda name: opened.append(name) or load(name)
    box = page.locator("input.mantine-TextInput-input:visible").first  # the only visible text box: Path on server
    box.click()
    page.keyboard.type(str(folder), delay=40)     # letter by letter: each one reaches the server
    box.press("Enter")
    verdict_on_page(page, "not-analysed", timeout=120_000)
    page.get_by_text("Not analysed yet: Analyse the whole packing").wait_for(timeout=30_000)   # the Eigenmodes panel
    assert opened == [str(folder)]                # once, not at every prefix (it was 37 attempts, each an error)
    s = ui.session
    assert s.scene.n_particles == 1617 and s.analysis is None and s.model.frame == 1
    page.get_by_text("Import report").wait_for(timeout=30_000)
    page.get_by_text("rigidlibrary-annulus, frame 1").first.wait_for(timeout=30_000)
    assert list(ui.view.nodes) == [] and ui.frame.visible and ui.frame.max == 20
    frame = number_box(page, ui.frame)
    frame.fill("2")
    frame.press("Enter")
    page.get_by_text("rigidlibrary-annulus, frame 2").first.wait_for(timeout=60_000)
    assert s.model.frame == 2 and s.scene.n_particles == 1620
    close_page(page, errors, "app-packing.png")


@pytest.fixture(scope="module")
def scan_dir(tmp_path_factory):
    """A scan of a 9×9 lattice with one planted sharp particle (p40): its cluster is unstable, the rest stable."""
    import json as _json

    from test_scan import planted_lattice

    import granstab
    from granstab.scan import scan
    folder = tmp_path_factory.mktemp("scan")
    scene, _ = planted_lattice(40, 0.4)
    packing = folder / "lattice.json"
    packing.write_text(_json.dumps(granstab.scene_to_dict(scene)))
    scan(granstab.load_scene(packing), folder / "scan", boundary="loads", workers=1, figures=False)
    return folder / "scan"


@pytest.mark.serial                     # a measured frame time
def test_a_large_packing_stays_responsive(app, browser, tmp_path):
    """A 10⁴-disk lattice (29,601 contacts) typed into *Path on server*: drawn, not analysed, and the page keeps
    drawing frames quickly: force lines and normals are off above LINES_MAX contacts until ticked (the legend says
    so), and the mode controls, with no mode to pick, are hidden. Before: both on, 0.38 s per frame (10⁵ disks: 10 s,
    the page stopped answering clicks), Mode "(none)", Play and the sliders shown."""
    import json as _json

    import granstab
    from granstab.model import packings
    from granstab_app.panel.display import LINES_MAX
    scene = packings.lattice(2, 100)
    assert scene.n_contacts > LINES_MAX
    path = tmp_path / "lattice-1e4.json"
    path.write_text(_json.dumps(granstab.scene_to_dict(scene)))
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    page.locator("input.mantine-TextInput-input:visible").first.fill(str(path))   # Path on server
    verdict_on_page(page, "not-analysed", timeout=120_000)
    page.get_by_text(f"off above {LINES_MAX:,} contacts").wait_for(timeout=30_000)
    assert not ui.show["forces"].value and not ui.show["normals"].value
    assert page.locator("label:visible").get_by_text("Mode", exact=True).count() == 0
    page.wait_for_timeout(2000)                    # the drawing has arrived
    seconds = page.evaluate("""() => new Promise(done => { const t0 = performance.now(); let n = 0;
        const frame = () => (++n === 5) ? done((performance.now() - t0) / 5000) : requestAnimationFrame(frame);
        requestAnimationFrame(frame); })""")
    assert seconds < 0.15, f"{seconds:.2f} s per frame"
    page.close()
    assert errors == []


def open_map(browser, app, folder, errors, badge="scan-map"):
    """A new page, its first preset shown, then `folder` (a scan or a rigidity result) typed into *Path on server*
    and shown as a map under `badge`: the page and its UI."""
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    box = page.locator("input.mantine-TextInput-input:visible").first  # Path on server
    box.fill(str(folder))
    box.press("Enter")
    verdict_on_page(page, badge, timeout=120_000)
    return page, ui


def test_scan_map_in_the_page(app, browser, scan_dir):
    """A scan folder typed into *Path on server*: the packing coloured by the map (the planted sharp particle dark red),
    its cluster opened by name (UNSTABLE, as the scan's row), and *Back to the map*."""
    errors: list[str] = []
    page, ui = open_map(browser, app, scan_dir, errors)
    page.get_by_text("click one (or type its name) for its cluster").wait_for(timeout=30_000)
    page.get_by_text("A map has no modes").wait_for(timeout=30_000)      # the Eigenmodes panel says why
    from granstab_app.scanmap import fraction_colours  # p40's own cluster geometric, its six neighbours' boundary:
    shade = tuple(int(c) for c in fraction_colours(np.array([1 / 7]))[0])      # 1 of 7 unstable for a packing reason
    assert tuple(ui.view.colours["p40"]) == shade and ui.view.colours["p00"] == (250, 250, 250)
    name = page.locator("input.mantine-TextInput-input:visible").nth(1)   # Open cluster of
    name.fill("p40")                      # a text box sends its value as it changes: the cluster opens, the box goes
    verdict_on_page(page, "unstable", timeout=120_000)
    assert ui.session.kind == "contacts" and ui.session.scene.n_particles == 7
    ui.play.value = True                   # a playing mode hides the contact drawings of the undeformed state
    wait_for(lambda: ui.view.contacts_frame.visible is False, timeout=30, what="contacts hidden while playing")
    ui.play.value = False
    wait_for(lambda: ui.view.contacts_frame.visible is True, timeout=30, what="contacts shown again")
    page.get_by_role("button", name="Back to the map").click()
    verdict_on_page(page, "scan-map", timeout=120_000)
    close_page(page, errors, "app-scan-map.png")


def test_quick_switches_in_and_out_of_the_pair(app, browser, scan_dir):
    """Only the pair has the λ⁽⁶⁾ contour: switching pair → another preset → pair → scan map → pair again and again,
    with ρ/r typed on the pair between switches, from the page (pauses of 0-250 ms) and then with no gap at all (from
    the server side, as queued events run), the page must show no page error and no console error. It failed (6
    rounds from the server side: 56-72 console errors "Tried to update non-existent component", the contour, the
    field note, the spectrum, the mode menu): the side panel was removed and rebuilt on every switch in or out of
    the pair, and the page applies a batch's removals before its updates. (Unmounting a plotly plot with a redraw
    pending is the `_redrawFromAutoMarginCount` page error.)"""
    from granstab_app.browser import number_box
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)

    def pick(name):
        page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
        page.get_by_role("option", name=preset_label(name), exact=True).click()

    def rho(*values):
        box = number_box(page, ui.sliders["rho_r"])
        for value in values:
            box.fill(value)
            box.press("Enter")

    for i, pause in enumerate((0, 100, 250)):   # ms between a switch and the next: the race needs its moment
        rho("0.7", "1.3")
        pick(("four_disk", "ellipses_sharp")[i % 2])
        page.wait_for_timeout(pause)
        pick("two_particle")
        page.wait_for_timeout(pause)
        rho("0.9", "2.1")
        path = page.locator("input.mantine-TextInput-input:visible").first      # Path on server
        path.fill(f"{scan_dir}{'/' * (i % 2)}")      # the same folder spelled anew: the box holds last round's text
        path.press("Enter")
        verdict_on_page(page, "scan-map", timeout=60_000)     # opened once the typing rests (0.6 s)
        page.wait_for_timeout(pause)
        pick("two_particle")
        page.wait_for_timeout(pause)
    for i in range(SWITCHES):        # as fast as events can come: one after the other on the server, no gap at all
        ui.sliders["rho_r"].value = 0.6 + 0.01 * i      # (a handle set from Python runs its callback at once)
        ui.preset.value = preset_label(("four_disk", "ellipses_sharp")[i % 2])
        ui.preset.value = preset_label("two_particle")
        ui.sliders["rho_r"].value = 1.6 + 0.01 * i
        ui.path._impl.value = str(scan_dir)              # a typed path, opened as its resting timer opens it
        ui.run(ui._open_path)
        ui.preset.value = preset_label("two_particle")
    wait_for(lambda: ui.session.preset == "two_particle", timeout=60, what="the pair at the end")
    shows_last_sent(page, ui)      # events the page queued may still run: wait on what the server sent last
    page.wait_for_timeout(1000)    # a pending redraw would fire by now
    page.close()
    assert errors == []


def test_a_pick_made_while_another_loads_is_kept(app, browser, monkeypatch):
    """A user picks four_disk, then two_particle while four_disk still loads: viser sets the dropdown's value at once
    (its websocket thread) and queues the callback behind the running one. The running refresh must not write the
    older pick back over the newer one. It did (the page stayed on four_disk: the second pick was lost; seen as the
    ρ/r box never coming back in test_quick_switches_in_and_out_of_the_pair)."""
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    load = ui.session.load_preset

    def load_and_pick_again(name):
        ok = load(name)
        if name == "four_disk":
            ui.preset._impl.value = preset_label("two_particle")          # the next pick arrives while this one loads
        return ok

    monkeypatch.setattr(ui.session, "load_preset", load_and_pick_again)
    ui.preset._impl.value = preset_label("four_disk")                       # the first pick, as viser records it
    ui.run(ui._load_preset)                                   # its callback
    ui.run(ui._load_preset)                                   # the second pick's callback, queued behind it
    assert ui.session.preset == "two_particle" and ui.preset.value == preset_label("two_particle")
    verdict_on_page(page, "unstable")
    page.close()
    assert errors == []


def test_a_pick_after_typing_a_path_wins(app, browser, scan_dir):
    """A path typed, then a preset picked before the typing has rested: the preset stays (the typed path used to
    open 0.6 s later, over the user's later pick)."""
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    page.locator("input.mantine-TextInput-input:visible").first.fill(str(scan_dir))    # Path on server
    page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
    page.get_by_role("option", name=preset_label("four_disk")).click()
    wait_for(lambda: ui.session.preset == "four_disk", timeout=60, what="four_disk")
    page.wait_for_timeout(1500)                                 # well past the typing pause
    assert ui.session.preset == "four_disk"
    page.close()
    assert errors == []


def test_controls_stay_put(app, browser):
    """The controls under the headline never move: the title and the reason each keep two lines whatever their text.
    The preset box sat 23 px lower under a two-line title (four_disk, annulus_frame, gear_packing, hand_in_glove,
    spheres_tetrahedron: y = 226 against 203 px on the pair)."""
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    preset = page.locator(f'[id="{ui.preset._impl.uuid}"]')

    def settled():
        with ui.lock:
            revision = ui.session.revision
        page.wait_for_selector(f'.granstab-verdict[data-revision="{revision}"]', timeout=60_000)
        return preset.bounding_box()["y"]

    where = {"two_particle": settled()}
    with ui.lock:
        pass
    ui.view.nodes["q"].position = (1.98, 0.4, 0.0)               # a dragged pair: "(dragged)" lengthens the title
    ui._on_drag("q", SimpleNamespace(phase="end"))
    where["dragged pair"] = settled()
    preset.click()
    page.get_by_role("option", name=preset_label("four_disk")).click()
    wait_for(lambda: ui.session.preset == "four_disk", timeout=60, what="four_disk")
    where["four_disk"] = settled()
    assert len(set(where.values())) == 1, where
    page.close()
    assert errors == []


def test_display_controls_per_scene(app, browser):
    """Only the display controls a scene uses: colouring by a mode needs more than two particles (the pair's two
    always share it evenly: the checkbox did nothing there), the 2D view menu does nothing on a 3D scene; and the
    scene line says whether particles can be dragged (contact-level scenes said nothing, their particles just did
    not move)."""
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    seen = {}
    for name in ("two_particle", "four_disk", "spheres_tetrahedron"):
        if ui.session.preset != name:
            page.get_by_role("tab", name="Scene").click()
            page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
            page.get_by_role("option", name=preset_label(name), exact=True).click()
            wait_for(lambda name=name: ui.session.preset == name, timeout=60, what=name)
        with ui.lock:
            revision = ui.session.revision
        page.wait_for_selector(f'.granstab-verdict[data-revision="{revision}"]', timeout=60_000)
        page.get_by_role("tab", name="Scene").click()
        page.get_by_text("scene · ").wait_for(timeout=20_000)
        dragging = (page.get_by_text("Drag a particle").count() == 1, page.get_by_text("cannot be dragged").count() == 1)
        page.get_by_role("tab", name="Display").click()
        page.get_by_text("Force arrows").wait_for(timeout=20_000)
        labels = set(page.locator("label:visible").all_inner_texts())
        seen[name] = ("Colour particles by the selected mode" in labels, "View" in labels, dragging)
    assert seen == {"two_particle": (False, True, (True, False)),
                    "four_disk": (True, True, (False, True)),
                    "spheres_tetrahedron": (True, False, (False, True))}, seen
    page.close()
    assert errors == []


def test_pair_opens_oblique_and_a_picked_view_stays(app, browser):
    """The pair opens in the oblique view (its λ⁽⁶⁾ height surface is flat seen from above: it opened top-down), the
    other 2D presets top-down; a view picked in the View menu is kept when the preset changes."""
    from granstab_app.camera import OBLIQUE, TOP
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    menu = page.locator(f'[id="{ui.camera_view._impl.uuid}"]')

    def pick(name):
        page.get_by_role("tab", name="Scene").click()
        page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
        page.get_by_role("option", name=preset_label(name), exact=True).click()
        wait_for(lambda: ui.session.preset == name, timeout=60, what=name)
        with ui.lock:                          # its refresh, camera included, has run
            revision = ui.session.revision
        page.wait_for_selector(f'.granstab-verdict[data-revision="{revision}"]', timeout=60_000)
        page.get_by_role("tab", name="Display").click()
        menu.wait_for(timeout=20_000)
        wait_for(lambda: menu.input_value() == ui.camera_view.value, what="the View menu on the page")
        return ui.camera_view.value

    page.get_by_role("tab", name="Display").click()
    seen = {"opened on two_particle": menu.input_value()}
    up = ui.client.camera.up_direction
    for name in ("four_disk", "ellipses_sharp", "two_particle"):
        seen[name] = pick(name)
    assert seen == {"opened on two_particle": OBLIQUE, "four_disk": TOP, "ellipses_sharp": TOP,
                    "two_particle": OBLIQUE}, seen
    assert np.allclose(up, (0, 0, 1))                           # the oblique camera: z up, seen from the front
    menu.click()
    page.get_by_role("option", name=TOP, exact=True).click()     # the user's own choice
    wait_for(lambda: ui._view_picked and ui.camera_view.value == TOP, what="the picked view")
    assert (pick("four_disk"), pick("two_particle")) == (TOP, TOP)
    page.close()
    assert errors == []


def test_the_camera_frames_every_body_by_its_own_size(app, browser):
    """hand_in_glove: q (radius 2) is larger than the mean size (1.5); the view is centred on the bodies' own extents
    (x from -1.2 r_p to x_q + 1.2 r_q: centre 2.1 r_p) and far enough to hold them (q was cut by the side panel)."""
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    page.get_by_role("tab", name="Scene").click()
    page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
    page.get_by_role("option", name=preset_label("hand_in_glove"), exact=True).click()
    wait_for(lambda: ui.session.preset == "hand_in_glove", timeout=60, what="hand_in_glove")
    with ui.lock:                                    # its refresh, camera included, has run
        bodies = ui.session.bodies()
        look_at, position = np.asarray(ui.client.camera.look_at), np.asarray(ui.client.camera.position)
    lo = min(b.x[0] - 1.2 * max(b.axes) for b in bodies)
    hi = max(b.x[0] + 1.2 * max(b.axes) for b in bodies)
    assert (lo, hi) == pytest.approx((-1.2, 5.4), abs=1e-9)
    assert look_at[0] == pytest.approx(0.5 * (lo + hi), abs=1e-6 * (hi - lo))
    assert np.linalg.norm(position - look_at) >= 0.8 * (hi - lo)
    page.close()
    assert errors == []


def test_two_tabs_are_independent(app, browser):
    """Two tabs on one server: a preset picked in one leaves the other's scene and verdict as they were."""
    errors: list[str] = []
    first, second = open_page(browser, app, errors), open_page(browser, app, errors)
    for page in (first, second):
        verdict_on_page(page, "unstable", timeout=60_000)
    ui1, ui2 = ui_of(app, first), ui_of(app, second)
    assert ui1 is not ui2 and ui1.session is not ui2.session
    first.locator(f'[id="{ui1.preset._impl.uuid}"]').click()
    first.get_by_role("option", name=preset_label("four_disk")).click()
    wait_for(lambda: ui1.session.preset == "four_disk", timeout=60, what="four_disk in the first tab")
    verdict_on_page(first, "unstable", timeout=120_000)
    second.wait_for_timeout(1000)
    assert ui2.session.preset == "two_particle" and ui2.session.scene.n_particles == 2
    assert second.locator(".granstab-verdict").get_attribute("data-revision") == str(ui2.session.revision)
    second.close()
    close_page(first, errors, "app-two-tabs.png")


def test_export_downloads_in_one_click(app, browser, tmp_path):
    """*Export* → *Scene file (.json)*: one click saves the file under its full name (no notification link to click),
    and the file reloads to the same verdict."""
    errors: list[str] = []
    page = open_page(browser, app, errors)
    verdict_on_page(page, "unstable", timeout=60_000)
    ui = ui_of(app, page)
    page.get_by_role("tab", name="Export").click()
    with page.expect_download(timeout=60_000) as info:
        page.get_by_role("button", name="Scene file (.json)").click()
    download = info.value
    expected, content = ui.session.export_scene()
    assert download.suggested_filename == expected
    saved = tmp_path / expected
    download.save_as(saved)
    assert saved.read_bytes() == content
    import granstab
    assert granstab.analyze(granstab.load_scene(saved)).summary["verdict"] == ui.session.verdict == "unstable"
    close_page(page, errors, "app-export.png")


def _overlap(a, b) -> bool:
    return a["x"] < b["x"] + b["width"] and b["x"] < a["x"] + a["width"] and \
        a["y"] < b["y"] + b["height"] and b["y"] < a["y"] + a["height"]


# every visible control (buttons, dropdowns, sliders, checkboxes, number and text boxes) and every visible input, each
# with its box and a key: tag, role and label (a button's text, else its row's label: stable across remounts)
_CONTROLS = """() => {
  const shown = e => { const r = e.getBoundingClientRect();
    return r.width > 0 && r.height > 0 && e.checkVisibility({visibilityProperty: true})
      && r.bottom > 0 && r.top < innerHeight && r.right > 0 && r.left < innerWidth; };
  const box = e => { const r = e.getBoundingClientRect(); return {x: r.x, y: r.y, width: r.width, height: r.height}; };
  const label = e => { let row = e;
    while (row && !row.querySelector("label")) row = row.parentElement;
    return e.tagName === "BUTTON" ? e.innerText || e.getAttribute("aria-label") || "" : row ? row.innerText : ""; };
  const key = e => [e.tagName, e.getAttribute("role") || e.type || "", label(e).split("\\n")[0]].join(" ");
  const pick = sel => [...document.querySelectorAll(sel)].filter(shown).map(e => ({key: key(e), box: box(e)}));
  return {controls: pick("button, input, textarea, select, [role=slider]"), inputs: pick("input, textarea, select")};
}"""
_TOOLTIPS = """() => [...document.querySelectorAll("[role=tooltip]")].filter(e => e.getBoundingClientRect().width > 0)
  .map(e => { const r = e.getBoundingClientRect();
              return {text: e.innerText, box: {x: r.x, y: r.y, width: r.width, height: r.height}}; })"""


def _tooltips_of(page, control, before: list) -> list:
    """Rest the pointer on `control` until a hint would open (viser: after 500 ms) and read the open tooltips. The
    pointer comes straight from the control hovered before, whose tooltips (`before`) have closed by then (their
    fade-out done); where one is still there (a slider and its number box share their row's hint), the pointer
    leaves for the badge until every tooltip has closed, then comes back. The page runs on Playwright's clock:
    fast_forward jumps the delay, firing each due timer once (run_for would draw every 3D frame in between: seconds
    on 143 disks); a few ms of real time let React render."""
    b = control["box"]
    for _ in range(2):
        page.mouse.move(b["x"] + b["width"] / 2, b["y"] + b["height"] / 2)
        page.clock.fast_forward(600)
        page.wait_for_timeout(20)
        tips = page.evaluate(_TOOLTIPS)
        if not any(tip in before for tip in tips):
            return tips
        _left_alone(page, before, f"a hint, for {control['key']}")
        before = []
    raise AssertionError(f"no reading of {control['key']}'s hint")


def _left_alone(page, before: list, where: str) -> None:
    """The pointer on the verdict badge (no hint, and not the 3D view, where a move raycasts every particle): every
    tooltip closes."""
    rest = page.locator(".granstab-verdict").bounding_box()
    page.mouse.move(rest["x"] + 5, rest["y"] + 5)
    for _ in range(5):
        page.clock.fast_forward(400)
        page.wait_for_timeout(20)
        if not page.evaluate(_TOOLTIPS):
            return
    raise AssertionError(f"a tooltip stayed open after the pointer left {where}: {before}")


def _covered_inputs(page, hovered: dict) -> list:
    """In each tab of both panels: every visible control hovered, every tooltip checked against every visible input.
    A tooltip's box follows from its control's box and hint (the app never changes a hint), so each (control, box)
    is hovered once over the whole test (`hovered`); the overlap check runs against each tab's own inputs."""
    covered = []
    for tab in page.get_by_role("tab").all():
        name = tab.inner_text()
        tab.click()
        page.clock.fast_forward(300)
        page.wait_for_timeout(100)
        state, tips = page.evaluate(_CONTROLS), []
        for control in state["controls"]:
            seen = (control["key"], *(round(v) for v in control["box"].values()))
            if seen not in hovered:
                hovered[seen] = tips = _tooltips_of(page, control, tips)
            covered += [(f"the hint of {control['key']} ({tip['text'][:40]!r}) covers {box['key']}", name)
                        for tip in hovered[seen] for box in state["inputs"] if _overlap(tip["box"], box["box"])]
        if tips:
            _left_alone(page, tips, f"the {name} tab's last hint")
    return covered


def test_no_tooltip_covers_an_input(playwright, tmp_path):
    """Hover hints must never cover an input: every shipped preset, picked from the page the way a user picks it
    (the pointer then rests over the controls), every tab of both panels, every visible control hovered; no
    tooltip's box may intersect a visible input's box. It failed on: the *Open path* hint over the preset box, the
    *Amplitude* hint over the mode box, the *View* hint over the arrow-length number box (before those, a slider's
    hint over the number box above it after a preset pick: gear_packing). A browser context of its own: Playwright's
    clock (installed for a whole context) jumps the hover delays."""
    from granstab_app.browser import chromium
    from granstab_app.server import App
    every = App(host="127.0.0.1", port=0)                               # all of presets/
    errors: list[str] = []
    ctx = chromium(playwright, tmp_path / "profile")
    try:
        ctx.clock.install()
        page = open_page(ctx, every, errors)
        verdict_on_page(page, "unstable", timeout=60_000)
        ui = ui_of(every, page)
        # the slow page (143 disks) last: most of its controls sit where they were hovered already
        names = sorted(ui.session.presets(), key=lambda n: n == "annulus_frame")
        hovered: dict = {}
        covered = {c: f"{names[0]}, {tab} tab" for c, tab in reversed(_covered_inputs(page, hovered))}
        for name in names[1:]:
            page.get_by_role("tab", name="Scene").click()
            page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
            page.get_by_role("option", name=preset_label(name), exact=True).click()
            wait_for(lambda name=name: ui.session.preset == name, timeout=60, what=name)
            page.wait_for_selector(f'.granstab-verdict[data-revision="{ui.session.revision}"]',
                                   timeout=120_000)
            for c, tab in _covered_inputs(page, hovered):
                covered.setdefault(c, f"{name}, {tab} tab")
        assert names[0] == "two_particle" and len(names) >= 12 and "gear_packing" in names
        assert not covered, "\n".join(f"{where}: {c}" for c, where in covered.items())
        page.close()
        assert errors == []
    finally:
        ctx.close()
        every.stop()


def test_rigidity_map_in_the_page(app, browser, tmp_path):
    """`granstab rigidity … --out DIR` typed into *Path on server*: the packing coloured by rigid cluster in the scan
    map's style (the small annulus frame 2 at μ = 0.05: clusters of 5, 5 and 3 disks, the rest floppy grey), a
    particle's neighbourhood opened by name, and *Back to the map*."""
    import json as _json

    from granstab.cli import main
    from granstab_app.rigiditymap import FLOPPY, LIGHT_GREY, TAB10, tint
    out = tmp_path / "rigidity"
    assert main(["rigidity", str(REPO / "tests" / "data" / "io" / "annulus"), "--frame", "2", "--mu", "0.05",
                 "--out", str(out), "--json"]) == 0
    clusters = _json.loads((out / "rigidity.json").read_text())["physical"]["clusters"]
    assert [len(c["particles"]) for c in clusters] == [5, 5, 3]
    rigid = {name for c in clusters for name in c["particles"]}
    errors: list[str] = []
    page, ui = open_map(browser, app, out, errors, badge="rigidity-map")    # the badge names the map, not a scan's
    page.get_by_text("rigid clusters of 31 particles").wait_for(timeout=30_000)
    for k, c in enumerate(clusters):            # every member of the clusters 0-2 (no hinge here) in its colour
        for name in c["particles"]:
            assert tuple(ui.view.colours[name]) == tuple(int(v) for v in tint(TAB10[k]))
    floppy = [n for n in ui.session.scene.names if n not in rigid]
    assert len(floppy) == 31 - 13 and all(tuple(ui.view.colours[n]) == LIGHT_GREY for n in floppy)
    labels = [c[2] for c in _json.loads((out / "rigidity.json").read_text())["physical"]["contacts"]]
    drawn = ui.session.model.contact_colours                 # the contacts, centre to centre, by cluster
    assert ui.view.contacts_frame is not None and len(drawn) == len(labels) == 31
    assert all(tuple(rgb) == (FLOPPY if k < 0 else tuple(int(v) for v in TAB10[k])) for rgb, k in zip(drawn, labels))
    name = page.locator("input.mantine-TextInput-input:visible").nth(1)   # Open cluster of
    name.fill(clusters[0]["particles"][0])
    wait_for(lambda: ui.session.kind == "contacts", timeout=120, what="the neighbourhood opened")
    page.get_by_role("button", name="Back to the map").click()
    verdict_on_page(page, "rigidity-map", timeout=120_000)
    close_page(page, errors, "app-rigidity-map.png")
