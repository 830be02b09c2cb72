"""Headless Debian Chromium for the browser tests and the latency benchmark (Playwright, never `playwright install`).

`chromium(playwright, profile_dir)` opens a persistent context with the flags the project uses;
`number_box(page, slider)` is the number input beside a viser slider (typing there moves the slider without
turning the camera, which arrow keys on the handle do)."""
from __future__ import annotations

import re
from pathlib import Path

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-unsafe-swiftshader"]


def chromium(playwright, profile_dir, width: int = 1600, height: int = 1000):
    if not CHROMIUM.exists():
        raise RuntimeError("Debian chromium is required (apt-get install -y chromium)")
    return playwright.chromium.launch_persistent_context(str(profile_dir), executable_path=str(CHROMIUM),
                                                         headless=True, args=FLAGS,
                                                         viewport={"width": width, "height": height})


def number_box(page, handle):
    """The number input beside a viser slider, found by the slider's label (its public `label`; labels are unique in
    the explorer): the nearest element around the label that holds a number input is the slider's row."""
    label = page.locator("label").filter(has_text=re.compile(f"^{re.escape(handle.label)}$"))
    row = label.locator("xpath=ancestor::div[.//input[contains(@class, 'mantine-NumberInput-input')]][1]")
    return row.locator("input.mantine-NumberInput-input")
