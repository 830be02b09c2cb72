"""Issue 26 in the browser (headless Debian Chromium): the page's title, inputs found by their labels (Playwright's
get_by_label, as a screen reader names them), the k slider of a stiff scene, and a failed path's error gone once the
next path opened. One page; GRANSTAB_APP_SHOTS=DIR saves its picture."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from test_app_browser import CHROMIUM, FLAGS, REPO, verdict_on_page, wait_for

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def app(explorer):
    stiff = (REPO / "presets" / "four_disk.toml").read_text().replace("k = 1.0", "k = 1000.0")
    return explorer("two_particle.toml", files={"stiff_four_disk.toml": stiff})


def test_title_labels_and_the_k_box(app, tmp_path):
    from playwright.sync_api import sync_playwright
    assert CHROMIUM.exists(), "Debian chromium is required (apt-get install -y chromium)"
    with sync_playwright() as pw:
        ctx = pw.chromium.launch_persistent_context(str(tmp_path / "profile"), executable_path=str(CHROMIUM),
                                                    headless=True, args=FLAGS, viewport={"width": 1600, "height": 1000})
        try:
            page = ctx.new_page()
            page.goto(app.url)
            verdict_on_page(page, "unstable", timeout=120_000)
            wait_for(lambda: page.title() == "granstab explorer", timeout=30, what="the page title")
            path = page.get_by_label("Path on server", exact=True)
            assert path.count() == 1
            path.fill(str(tmp_path / "missing.toml"))
            page.wait_for_selector(".granstab-error", timeout=60_000)
            path.fill("stiff_four_disk")
            k = page.get_by_label("k", exact=True)                      # the slider's number box
            wait_for(lambda: k.count() == 1 and k.input_value() == "1000", timeout=120, what="the stiff scene's k")
            assert page.locator(".granstab-error").count() == 0
            slider = page.get_by_label("k slider", exact=True)
            assert float(slider.get_attribute("aria-valuemax")) == 10_000
            assert float(slider.get_attribute("aria-valuenow")) == 1000
            shots = os.environ.get("GRANSTAB_APP_SHOTS")
            if shots:
                page.screenshot(path=str(Path(shots) / "a11y.png"))
        finally:
            ctx.close()
