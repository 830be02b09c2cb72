"""The explorer draws grains as they are in real headless Chromium (issue 37): the superquadric preset and a YADE
clump packing open with their instanced meshes, a mode frame moves them, and the page shows no page error or console
error. Screenshots: not blank and the 3D canvas rendered (pixel variance); GRANSTAB_APP_SHOTS=folder keeps them."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402
from test_app_grains import POLYGONS  # noqa: E402

from granstab.cli import main
from granstab_app.browser import CHROMIUM, FLAGS, chromium

REPO = ROOT
pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    """An explorer on a presets folder of the superquadric preset and the YADE clump fixture, converted."""
    from granstab_app.server import App
    folder = tmp_path_factory.mktemp("grain_presets")
    assert main(["convert", str(REPO / "tests" / "data" / "io" / "yade_clumps"), "--out",
                 str(folder / "clumps.json")]) == 0
    assert main(["convert", *map(str, POLYGONS), "--out", str(folder / "polygons.json")]) == 0
    shutil.copy(REPO / "presets" / "superquadric_cluster.json", folder)
    running = App(host="127.0.0.1", port=0, presets_dir=folder, preset="superquadric_cluster")
    yield running
    running.stop()


def wait_until(page, predicate, what, timeout=90.0):
    for _ in range(int(timeout / 0.2)):
        if predicate():
            return
        page.wait_for_timeout(200)
    raise AssertionError(f"timed out waiting for {what}")


def rendered(shot: Path) -> None:
    from PIL import Image
    img = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    h, w, _ = img.shape
    centre = img[int(0.25 * h):int(0.75 * h), int(0.35 * w):int(0.65 * w)]     # the 3D canvas between the panels
    assert centre.std() > 10.0, f"{shot.name}: the 3D scene did not render"


def watched_page(ctx, errors: list):
    """A new tab whose page errors and console errors are appended to `errors`."""
    page = ctx.new_page()
    page.on("pageerror", lambda exc: errors.append(f"pageerror: {exc}"))
    page.on("console", lambda m: errors.append(f"console: {m.text}") if m.type == "error" else None)
    return page


def show(ctx, app, preset: str, kind: str, errors: list, folder: Path) -> dict:
    """Open `preset` in a new tab (?preset=), wait for its analysis and its instanced grains, screenshot it (and, for
    the superquadrics, a frame of the lowest mode); returns {name: screenshot}."""
    page = watched_page(ctx, errors)
    page.goto(app.url + f"/?preset={preset}")
    page.wait_for_selector('.granstab-verdict[data-verdict="unstable"]', timeout=120_000)
    wait_until(page, lambda: any(u.session.preset == preset and u.session.analysis is not None
                                 for u in list(app.uis.values())), f"{preset} analysed on the server")
    ui = next(u for u in list(app.uis.values()) if u.session.preset == preset)
    s = ui.session
    assert s.model.grains.kind == kind and s.error is None
    wait_until(page, lambda: len(ui.view.grain_nodes) >= 1, f"{preset}'s grains drawn")
    distinct = {b.grain for b in s.bodies()} if kind == "superquadric" else {("sphere",)}
    assert len(ui.view.grain_nodes) == len(distinct)
    for close in page.locator("button.mantine-Notification-closeButton").all():
        close.click()
    page.wait_for_timeout(3000)
    shots = {preset: folder / f"grains_{preset}.png"}
    page.screenshot(path=str(shots[preset]))
    if kind == "superquadric":                              # a frame of the lowest mode, sent as the animation does
        mode = min((m for m in s.modes() if m.consistent), key=lambda m: m.eigenvalue)
        with ui.lock:
            ui.view.animate(s.mode_bodies(mode, 0.5, 0.5 * np.pi))
        page.wait_for_timeout(3000)
        shots["mode"] = folder / "grains_mode.png"
        page.screenshot(path=str(shots["mode"]))
        with ui.lock:
            ui.view.stop_animation()
    page.close()
    return shots


def test_grains_open_drawn_as_they_are(app, tmp_path, capsys):
    from playwright.sync_api import sync_playwright
    assert CHROMIUM.exists(), "Debian chromium is required: bash .ci/run installs it (apt-get install -y chromium)"
    capsys.readouterr()
    errors: list[str] = []
    shots = {}
    with sync_playwright() as pw:
        ctx = pw.chromium.launch_persistent_context(str(tmp_path / "profile"), executable_path=str(CHROMIUM),
                                                    headless=True, args=FLAGS, viewport={"width": 1600, "height": 1000})
        try:
            for preset, kind in (("superquadric_cluster", "superquadric"), ("clumps", "clump")):
                shots.update(show(ctx, app, preset, kind, errors, tmp_path))
        finally:
            ctx.close()
    assert errors == []
    for shot in shots.values():
        rendered(shot)
    target = os.environ.get("GRANSTAB_APP_SHOTS")
    if target:
        for shot in shots.values():
            shutil.copy(shot, Path(target) / shot.name)


def outline_distance(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance of each point (P, 2) to a closed polygon's sides (n, 2), written out here."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    t = np.clip(np.einsum("psd,sd->ps", points[:, None] - a, b - a) / np.sum((b - a) ** 2, axis=1), 0, 1)
    return np.linalg.norm(points[:, None] - (a + t[..., None] * (b - a)), axis=2).min(axis=1)


def test_rounded_polygons_open_drawn_by_their_outlines(app, tmp_path, capsys):
    """A LAMMPS rounded-polygon packing (converted to scene.json) opens in Chromium drawn as its bodies: every outline
    the server sent (each particle's mesh, and the periodic images' mesh) lies at the rounding radius from its
    polygon (within 8 float32 epsilons of the largest coordinate: viser sends float32), the page's legend says what is drawn (rounded polygons, periodic
    images), and the canvas renders; no page or console error. Screenshot at 1024×768."""
    from playwright.sync_api import sync_playwright
    capsys.readouterr()
    errors: list[str] = []
    with sync_playwright() as pw:
        ctx = chromium(pw, tmp_path / "profile", 1024, 768)
        try:
            page = watched_page(ctx, errors)
            page.goto(app.url + "/?preset=polygons")
            page.wait_for_selector(".granstab-verdict[data-verdict]", timeout=120_000)
            wait_until(page, lambda: any(u.session.preset == "polygons" and u.session.analysis is not None
                                         and u.view.ghosts is not None for u in list(app.uis.values())),
                       "the polygons analysed and drawn")
            ui = next(u for u in list(app.uis.values()) if u.session.preset == "polygons")
            page.get_by_text("each rounded polygon as the file gives it").first.wait_for(timeout=30_000)
            assert page.get_by_text("periodic images of the particles near its faces").count() >= 1
            for close in page.locator("button.mantine-Notification-closeButton").all():
                close.click()
            page.wait_for_timeout(3000)
            shot = tmp_path / "grains_polygons_1024x768.png"
            page.screenshot(path=str(shot))
        finally:
            ctx.close()
    assert errors == []
    rendered(shot)
    s = ui.session
    bodies = {b.name: b for b in s.bodies()}
    for name, mesh in ui.view.meshes.items():                       # each particle: its sent top-face outline
        _, vertices, radius = bodies[name].grain
        V = np.asarray(mesh.vertices)
        ring = V[:(len(V) - 2) // 4, :2]
        tol = 8 * np.finfo(np.float32).eps * np.abs(V).max()
        assert np.allclose(outline_distance(ring, np.array(vertices)), radius, rtol=0, atol=tol), name
    assert len(ui.view.meshes) == s.scene.n_particles
    owner, _ = ui.view.ghosts.rings
    index, shift = ui.view.ghosts.images
    sent = np.asarray(ui.view.ghosts.handles[0].vertices)[:, :2]
    for g in range(len(index)):                                     # each image: its polygon, shifted by n @ cell
        _, vertices, radius = bodies[s.scene.names[index[g]]].grain
        polygon = s.scene.x[index[g]] + shift[g] + np.array(vertices)
        tol = 8 * np.finfo(np.float32).eps * np.abs(sent).max()
        assert np.allclose(outline_distance(sent[owner == g][1:], polygon), radius, rtol=0, atol=tol)
    assert len(index) > 5
    target = os.environ.get("GRANSTAB_APP_SHOTS")
    if target:
        shutil.copy(shot, Path(target) / shot.name)
