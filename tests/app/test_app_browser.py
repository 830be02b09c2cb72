"""End to end: the explorer in real headless Chromium (Debian's /usr/bin/chromium), driven by Playwright.

Starts the app in-process on a free port with a presets folder of two scenes (the slider-driven pair and a
shape-based flat pair), loads the page, types into the ρ/r slider's number box, switches preset from the page,
and checks both what the page shows (the verdict badge carries data-verdict) and the server-side session.
A second tab must keep its own state. Screenshot: not blank (pixel variance); GRANSTAB_APP_SCREENSHOT=path
also saves it there (docs/app.png is made that way).
"""
from __future__ import annotations

import os
import shutil
import time
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import (
    FLAT_PAIR,
    ROOT,  # noqa: E402
)

from granstab_app.browser import CHROMIUM, FLAGS, number_box
from granstab_app.text import preset_label

REPO = ROOT

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def presets(tmp_path_factory):
    folder = tmp_path_factory.mktemp("presets")
    shutil.copy(REPO / "presets" / "two_particle.toml", folder)
    (folder / "flat_pair.toml").write_text(FLAT_PAIR, encoding="utf-8")
    return folder


@pytest.fixture(scope="module")
def app(presets):
    from granstab_app.server import App
    running = App(host="127.0.0.1", port=0, presets_dir=presets)
    yield running
    running.stop()


def wait_for(predicate, timeout=20.0, what="condition"):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def verdict_on_page(page, verdict, timeout=20_000):
    page.wait_for_selector(f'.granstab-verdict[data-verdict="{verdict}"]', timeout=timeout)


@pytest.mark.serial                     # verdicts awaited within deadlines (load-sensitive)
def test_explorer_end_to_end(app, tmp_path):
    from playwright.sync_api import sync_playwright

    assert CHROMIUM.exists(), "Debian chromium is required: bash .ci/run installs it (apt-get install -y chromium)"

    with sync_playwright() as pw:
        ctx = pw.chromium.launch_persistent_context(str(tmp_path / "profile"), executable_path=str(CHROMIUM),
                                                    headless=True, args=FLAGS,
                                                    viewport={"width": 1600, "height": 1000})
        try:
            page, other = ctx.new_page(), ctx.new_page()      # two tabs, loading side by side
            page.goto(app.url)
            other.goto(app.url)
            verdict_on_page(page, "unstable", timeout=40_000)          # the pair opens at ρ/r = 0.5, f/(kr) = 0.01
            verdict_on_page(other, "unstable", timeout=40_000)
            wait_for(lambda: len(app.uis) == 2, what="two sessions")
            # each tab shows only its own client's widgets (ids are per-client handle uuids)
            ui = next(u for u in app.uis.values() if page.locator(f'[id="{u.preset._impl.uuid}"]').count())
            second = next(u.session for u in app.uis.values() if u is not ui)
            s = ui.session
            assert (s.preset, s.kind, s.verdict) == ("two_particle", "two_particle", "unstable")
            assert s.params["rho_r"] == 0.5

            # several quick slider entries: the last one wins (λ⁽⁶⁾ = f (ρ - r) = 0.01 · 0.5, r = k = 1)
            box = number_box(page, ui.sliders["rho_r"])
            for value in ("0.6", "0.8", "2.2", "1.5"):
                box.fill(value)
                box.press("Enter")
            verdict_on_page(page, "stable")
            wait_for(lambda: s.params["rho_r"] == 1.5 and s.verdict == "stable", timeout=90,
                     what="ρ/r = 1.5 on the server")          # generous: a loaded 2-core machine, software WebGL
            time.sleep(0.5)
            assert s.params["rho_r"] == 1.5 and s.verdict == "stable"
            assert s.rolling_eigenvalue() == pytest.approx(0.005, abs=1e-12)

            box.fill("1")
            box.press("Enter")
            verdict_on_page(page, "neutral")
            assert wait_for(lambda: s.verdict == "neutral", what="neutral on the server")

            # the other tab kept its own session, still at the preset's ρ/r = 0.5
            assert second.params["rho_r"] == 0.5 and second.verdict == "unstable"
            assert other.locator('.granstab-verdict[data-verdict="unstable"]').count() == 1
            other.close()

            # a drag release (server side of the gizmo): the pair becomes shapes, contacts follow the geometry
            ui.view.nodes["q"].position = (1.98, 0.05, 0.0)
            ui._on_drag("q", SimpleNamespace(phase="end"))
            page.get_by_text("dragging turned the pair into shapes").wait_for(timeout=20_000)
            assert s.kind == "shapes" and s.scene.n_contacts == 1 and s.error is None
            assert s.scene.x[1] == pytest.approx([1.98, 0.05], abs=1e-12)

            # switch preset from the page: the shape-based flat pair is stable
            page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
            page.get_by_role("option", name=preset_label("flat_pair")).click()
            verdict_on_page(page, "stable")
            wait_for(lambda: s.preset == "flat_pair", what="the preset switch on the server")
            assert s.kind == "shapes" and s.verdict == "stable" and s.scene.n_contacts == 1
            assert not ui.sliders["rho_r"].visible and ui.sliders["mobilised"].visible
            assert ui.errors_shown == 0 and s.error is None

            # back to the pair for the picture
            page.locator(f'[id="{ui.preset._impl.uuid}"]').click()
            page.get_by_role("option", name=preset_label("two_particle")).click()
            verdict_on_page(page, "unstable")
            close = page.locator("button.mantine-Notification-closeButton")
            if close.count():
                close.first.click()
            time.sleep(2.0)
            shot = tmp_path / "granstab_app.png"
            page.screenshot(path=str(shot))
        finally:
            ctx.close()

    from PIL import Image
    img = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    assert img.std() > 20.0, "screenshot is blank"
    h, w, _ = img.shape
    centre = img[int(0.25 * h):int(0.6 * h), int(0.4 * w):int(0.62 * w)]   # the 3D canvas between the panels
    assert centre.std() > 10.0, "the 3D scene did not render"
    target = os.environ.get("GRANSTAB_APP_SCREENSHOT")
    if target:
        shutil.copy(shot, target)
