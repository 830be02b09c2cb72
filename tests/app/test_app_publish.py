"""Issue 29: `granstab publish` (a recorded page that plays offline) and a class on one server (`--host`, `--password`).

The pair's page is checked twice: its recorded badges against the closed form λ⁽⁶⁾ = f(ρ − r) (no browser), and the
page itself in headless Chromium opened as file:// (no page error, no request leaves the file, the canvas draws, the
playback advances and the picture changes with it). The password gate is checked in the browser: a wrong word opens
nothing, the right one opens the explorer.
"""
from __future__ import annotations

import io
import re
import time

import numpy as np
import pytest
from test_app_browser import CHROMIUM, FLAGS, REPO

from granstab.cli import main

F_KR = 0.01          # presets/two_particle.toml: f/(kr) = 0.01, r = 1


@pytest.fixture(scope="module")
def pair_page(tmp_path_factory):
    from granstab_app.publish import publish
    out = tmp_path_factory.mktemp("page") / "pair.html"
    return out, publish("two_particle", out)


@pytest.fixture(scope="module")
def four_page(tmp_path_factory):
    from granstab_app.publish import publish
    out = tmp_path_factory.mktemp("page") / "four.html"
    return out, publish("four_disk", out)


def page_of(pw, tmp_path, width: int, height: int, errors: list):
    """A fresh headless Chromium of that viewport and its page, page errors and console errors into `errors`."""
    ctx = pw.chromium.launch_persistent_context(str(tmp_path / "profile"), executable_path=str(CHROMIUM),
                                                headless=True, args=FLAGS, viewport={"width": width, "height": height})
    page = ctx.new_page()
    page.on("pageerror", lambda exc: errors.append(f"pageerror: {exc}"))
    page.on("console", lambda m: errors.append(f"console: {m.text}") if m.type == "error" else None)
    return ctx, page


def test_the_pair_sweep_states_the_closed_form_verdict_at_each_step(pair_page):
    """Each step's badge: λ⁽⁶⁾/k = f/(kr)·(ρ/r − 1) (r = L = 1, the paper's Sec. 4.1) and its sign's verdict. The
    eigen-solver's error is ~1e-13 of the largest eigenvalue (≈ 4 k): 1e-10 absolute is far above it and far below
    the smallest nonzero |λ⁽⁶⁾| of the sweep (0.001)."""
    out, done = pair_page
    rho = np.array([b[0] for b in done["badges"]])
    assert done["sweep"] and done["steps"] == len(rho) >= 5 and rho.min() < 1 < rho.max() and 1.0 in rho
    lam = np.array([b[2] for b in done["badges"]])
    assert np.allclose(lam, F_KR * (rho - 1), rtol=0, atol=1e-10)
    assert [b[1] for b in done["badges"]] == ["unstable" if r < 1 else "neutral" if r == 1 else "stable" for r in rho]
    assert 0 < done["bytes"] == out.stat().st_size <= 5_000_000


def test_another_scene_plays_its_lowest_consistent_modes(four_page):
    """four_disk (the paper's Sec. 4.2) has 9 consistent negative eigenvalues: the page plays the lowest 3 distinct
    modes, in increasing order, each negative, under the UNSTABLE badge."""
    from granstab_app.publish import MODES
    _, done = four_page
    lam = [b[0] for b in done["badges"]]
    assert not done["sweep"] and len(lam) == MODES and lam == sorted(lam) and max(lam) < 0
    assert {b[1] for b in done["badges"]} == {"unstable"}


def test_publish_bad_input_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("dim = 2\n[[particles]]\nname = 'a'\nx = [0.0, 'x']\n")
    for argv, words in ((["publish", "no_such_preset", "--out", str(tmp_path / "a.html")], "no_such_preset"),
                        (["publish", str(bad), "--out", str(tmp_path / "b.html")], "bad.toml"),
                        (["publish", "four_disk", "--out", str(tmp_path / "missing" / "c.html")], "missing")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err and "Traceback" not in err, err
    assert not list(tmp_path.glob("*.html"))


def test_the_host_warning():
    from granstab_app.server import host_warning, parse_args
    assert host_warning("127.0.0.1", None) is None and host_warning("localhost", "w") is None
    open_ = host_warning("0.0.0.0", None)
    assert "every machine on the network" in open_ and "--password" in open_
    assert "asks for the --password" in host_warning("192.168.1.4", "w")
    assert parse_args(["--host", "0.0.0.0", "--password", "w"]).password == "w"


@pytest.mark.serial                     # the playback clock against real time
@pytest.mark.browser
def test_the_published_page_plays_offline(pair_page, tmp_path):
    from PIL import Image
    from playwright.sync_api import sync_playwright
    out, _ = pair_page
    errors, requests = [], []
    with sync_playwright() as pw:
        ctx, page = page_of(pw, tmp_path, 1200, 800, errors)
        try:
            page.on("request", lambda r: requests.append(r.url) if r.url.split(":")[0] not in ("file", "data", "blob")
                    else None)
            page.goto(out.as_uri())
            page.wait_for_selector("canvas", timeout=60_000)
            clock = page.locator("input.mantine-NumberInput-input").first     # the playback bar's time
            page.wait_for_function("e => parseFloat(e.value) > 0.5", arg=clock.element_handle(), timeout=60_000)
            assert "cannot be dragged" in page.locator("#granstab-note").inner_text()
            shots, times = [], []
            for _ in range(2):
                times.append(float(clock.input_value()))
                shots.append(np.asarray(Image.open(io.BytesIO(page.locator("canvas").first.screenshot()))
                                        .convert("RGB"), float))
                time.sleep(1.5)
            times.append(float(clock.input_value()))
        finally:
            ctx.close()
    assert errors == [] and requests == []
    assert times[0] < times[1] < times[2]                              # the playback advances
    drawn = np.mean(np.abs(shots[0] - shots[0][0, 0]).sum(axis=2) > 30)     # pixels unlike the corner's background
    assert drawn > 0.05, drawn                                         # the canvas draws (the surface alone ≈ 30 %)
    assert np.mean(np.abs(shots[0] - shots[1]).sum(axis=2) > 30) > 0.001   # and the picture moves with it


@pytest.mark.browser
def test_a_password_opens_the_explorer_and_a_wrong_one_nothing(tmp_path):
    from playwright.sync_api import sync_playwright

    from granstab_app.server import App
    app = App(host="127.0.0.1", port=0, presets_dir=REPO / "presets", password="s3cret")
    errors = []
    try:
        with sync_playwright() as pw:
            ctx = pw.chromium.launch_persistent_context(str(tmp_path / "profile"), executable_path=str(CHROMIUM),
                                                        headless=True, args=FLAGS,
                                                        viewport={"width": 1600, "height": 1000})
            try:
                page = ctx.new_page()
                page.on("pageerror", lambda exc: errors.append(f"pageerror: {exc}"))
                page.goto(app.url)
                page.get_by_text("asks for a password").wait_for(timeout=60_000)
                label = page.locator("label").filter(has_text=re.compile("^Password$"))
                box = label.locator("xpath=ancestor::div[.//input[contains(@class, 'mantine-TextInput-input')]][1]"
                                    ).locator("input.mantine-TextInput-input")
                box.fill("guess")
                box.press("Enter")
                page.get_by_role("button", name="Open the explorer").click()
                page.get_by_text("Wrong password").wait_for(timeout=30_000)
                assert page.locator(".granstab-verdict").count() == 0 and app.uis == {}
                box.fill("s3cret")
                box.press("Enter")
                page.wait_for_timeout(500)            # the typed word reaches the server before the click
                page.get_by_role("button", name="Open the explorer").click()
                page.wait_for_selector('.granstab-verdict[data-verdict="unstable"]', timeout=60_000)
                assert len(app.uis) == 1
            finally:
                ctx.close()
    finally:
        app.stop()
    assert errors == []


def test_an_offloaded_analysis_is_the_same_analysis():
    """A server's large scene is analysed in a worker process (app/state.py offloaded): the same verdict and
    spectrum as in the server's own process. Same code, one BLAS thread each: only the summation order of a library
    could differ, so 1e-12 of the largest |λ|."""
    from granstab_app.pools import OFFLOAD, close_pool
    from granstab_app.state import Session
    here, there = Session("annulus_frame"), Session("annulus_frame", offload=True)
    try:
        assert there.scene.n_particles >= OFFLOAD and there.error is None and here.verdict == there.verdict
        for a, b in zip(here.analysis.branches, there.analysis.branches, strict=True):
            lam, mu = np.asarray(a.stability_eigenvalues), np.asarray(b.stability_eigenvalues)
            assert np.allclose(lam, mu, rtol=0, atol=1e-12 * np.abs(lam).max())
        assert there.set_params(mu=0.4) and here.set_params(mu=0.4) and there.error is None      # a second call
        assert there.verdict == here.verdict and len(there.modes()) == len(here.modes())
    finally:
        close_pool()


def test_sessions_share_an_offloaded_analysis(monkeypatch):
    """A class on annulus_frame (issue 29): a scene two sessions reach (the preset opened, the same μ typed) is
    analysed once and shared; another μ is analysed anew; at most SHARED analyses are kept, the oldest dropped."""
    from granstab_app import pools, state
    monkeypatch.setattr(pools, "SHARED", 2)
    a, b = state.Session("annulus_frame", offload=True), state.Session("annulus_frame", offload=True)
    try:
        assert a.error is None and a.analysis is b.analysis                      # the preset's scene: analysed once
        assert a.set_params(mu=0.45) and a.analysis is not b.analysis
        assert b.set_params(mu=0.45) and b.analysis is a.analysis and b.revision == 2   # b's own revision, a's analysis
        first = a.analysis
        assert a.set_params(mu=0.46) and b.set_params(mu=0.47) and len(pools._SHARED) == 2
        assert b.set_params(mu=0.45) and b.analysis is not first and b.verdict == first.verdict.verdict   # dropped
    finally:
        pools.close_pool()
    assert not pools._SHARED


def test_the_pair_page_is_a_hand_out(pair_page):
    """Issue 36: the published pair carries what to watch (2-3 sentences), the λ⁽⁶⁾ contour, a lamp in the verdict's
    colour in every step (red, amber, green: one per step, in the recording), the plain sentence on the badge and the
    rest position's ghost while a mode plays; the note moves to the bottom on a phone."""
    out, _ = pair_page
    text = out.read_text(encoding="utf-8")
    assert "What to watch." in text and 'class="granstab-contour"' in text and "@media (max-width:600px)" in text
    assert text.count("sharper than a circle") >= 1 and "eq:" not in text.split("granstab-note", 1)[1][:4000]


def on_canvas(pose: dict, canvas, point) -> np.ndarray:
    """Pixel (x from the left, y from the top) of `point` seen by a pinhole camera at `pose` (position, look_at,
    up_direction) with viser's vertical field of view `canvas.fov` on a canvas of canvas.image_width × image_height."""
    eye, target, up = (np.array(pose[k], float) for k in ("position", "look_at", "up_direction"))
    ahead = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(ahead, up) / np.linalg.norm(np.cross(ahead, up))
    d = np.asarray(point, float) - eye
    px = 0.5 * canvas.image_height / np.tan(0.5 * canvas.fov) / (d @ ahead)      # px per unit at the point's depth
    return np.array([0.5 * canvas.image_width + px * (d @ right),
                     0.5 * canvas.image_height - px * (d @ np.cross(right, ahead))])


@pytest.mark.parametrize("page", ["pair_page", "four_page"])
def test_the_badge_and_the_particles_are_in_view_on_a_screen_and_a_phone(page, request):
    """Issue 36: the recorded badge (its anchor: its text rises ~30 px above it, its lamp over that) and every particle
    (centre ± its size across the screen) project inside the page's 1600×1000 canvas and, with the phone's camera,
    inside a 390×844 phone's width and above its note (the top PHONE_BAND). four_disk's badge hung above the canvas
    (off-screen at 1400×900), and on a phone the pair ran off both sides (fitted to 1600×1000 only)."""
    from granstab_app.publish import PHONE_BAND, PHONE_VIEWPORT, VIEWPORT
    from granstab_app.state import Session
    _, done = request.getfixturevalue(page)
    s = Session("two_particle" if done["sweep"] else "four_disk")
    if done["sweep"]:
        s.set_params(rho_r=float(done["badges"][0][0]))           # the first step: the one the cameras fit
    for pose, canvas, bottom in ((done["cameras"]["page"], VIEWPORT, VIEWPORT.image_height),
                                 (done["cameras"]["phone"], PHONE_VIEWPORT, PHONE_BAND * PHONE_VIEWPORT.image_height)):
        x, y = on_canvas(pose, canvas, done["badge_at"])
        assert 0 < x < canvas.image_width and 60 < y < bottom, (page, canvas.image_width, x, y)
        for b in s.bodies():
            for side in (-1, 1):
                point = np.append(b.x + side * np.array([max(b.axes), 0.0]), 0.0)
                x, y = on_canvas(pose, canvas, point)
                assert 0 <= x <= canvas.image_width and 0 <= y <= bottom, (page, canvas.image_width, b.name, x, y)


@pytest.mark.browser
def test_the_published_pair_fits_a_phone(pair_page, tmp_path):
    """Issue 36: on a 390×844 phone the note sits at the bottom (its inline style outranked the phone's media rule:
    it covered the whole screen from y = 8 px) and the page's first script hands viser's client the phone's camera as
    initialCamera* URL parameters; nothing overflows the width; no page or console error."""
    from playwright.sync_api import sync_playwright
    out, done = pair_page
    errors = []
    with sync_playwright() as pw:
        ctx, page = page_of(pw, tmp_path, 390, 844, errors)
        try:
            page.goto(out.as_uri())
            page.wait_for_selector("canvas", timeout=60_000)
            note = page.locator("#granstab-note").bounding_box()
            query = page.evaluate("location.search")
            wide = page.evaluate("document.documentElement.scrollWidth")
        finally:
            ctx.close()
    assert errors == [] and wide <= 390
    assert note["y"] >= 0.5 * 844 and note["y"] + note["height"] <= 844 - 40, note
    position = re.search(r"initialCameraPosition=([^&]+)", query).group(1).replace("%2C", ",")
    assert np.allclose([float(v) for v in position.split(",")], done["cameras"]["phone"]["position"], rtol=1e-5)
