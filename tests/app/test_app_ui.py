"""The explorer's panels driven in-process, without a browser: a headless websocket page (granstab_app.headless)
builds a real tab, and the test works its handles and reads what the page would show (issue 26)."""
from __future__ import annotations

import time

import pytest

from granstab_app.headless import HeadlessPage
from granstab_app.server import App
from granstab_app.text import preset_label


@pytest.fixture(scope="module")
def app():
    running = App(host="127.0.0.1", port=0)
    yield running
    running.stop()


def settle(ui, until, timeout=120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with ui.lock:
            if until():
                return
        time.sleep(0.05)
    raise TimeoutError("the page did not settle")


def test_a_failed_path_is_cleared_while_the_next_one_opens(app, tmp_path, monkeypatch):
    with HeadlessPage(app) as page:
        ui = page.ui
        ui.path.value = str(tmp_path / "missing.toml")
        settle(ui, lambda: "granstab-error" in ui.message.content)
        seen = []
        opening = ui.session.open_typed

        def spy(text):
            seen.append((ui.message.visible, ui.message.content))
            return opening(text)
        monkeypatch.setattr(ui.session, "open_typed", spy)
        ui.path.value = "four_disk"
        settle(ui, lambda: ui.session.preset == "four_disk")
        assert len(seen) == 1
        visible, content = seen[0]
        assert visible and "granstab-loading" in content and "Opening four_disk" in content
        assert "granstab-error" not in content
        assert not ui.message.visible                                   # opened: no message left


def test_check_other_metrics_shows_it_runs_and_a_move_supersedes_it(app, monkeypatch):
    import threading

    import granstab_app.pools as state
    with HeadlessPage(app) as page:
        ui, s = page.ui, page.ui.session
        ui.run(ui._check_metrics)
        assert "checking L/10, L and 10L" in ui.details.content          # said before the work is done
        settle(ui, lambda: s.metrics is not None)
        assert s.metrics["revision"] == s.revision and "checking" not in ui.details.content
        moved, family = threading.Event(), state.metric_family
        monkeypatch.setattr(state, "metric_family", lambda scene: moved.wait(60) and family(scene))
        ui.run(ui._check_metrics)                                        # a check, and a move before it ends
        ui.sliders["rho_r"].value = 1.5                                  # not blocked by the check
        assert s.params["rho_r"] == 1.5 and s.verdict == "stable"
        moved.set()
        settle(ui, lambda: ui._checking is None)
        time.sleep(0.5)
        assert s.metrics is None                                          # the old check's result was dropped
        assert "*Check other metrics* below" in ui.details.content


def test_a_closed_page_cancels_its_typing_pause(app):
    with HeadlessPage(app) as page:
        ui = page.ui
        ui.path.value = "four_disk"                                      # opened 1 s after the last letter
        assert len(ui._timers) == 1
        timer = next(iter(ui._timers))
    assert not ui._timers and timer.finished.is_set()


CHAIN = "dim = 2\ntitle = \"a chain of 12 disks\"\n[defaults]\nk = 1.0\nalpha = 0.5\nmu = 0.3\n" + "".join(
    f"[[particles]]\nname = \"d{i}\"\nx = [{2.0 * i}, 0.0]\n" for i in range(12)) + "".join(
    f"[[contacts]]\np = \"d{i}\"\nq = \"d{i + 1}\"\npoint = [{2.0 * i + 1}, 0.0]\nnormal = [1.0, 0.0]\n"
    "curvature_p = -1.0\ncurvature_q = -1.0\nforce = [-0.01, 0.0]\n" for i in range(11))


def test_an_opened_scene_fits_the_free_canvas(app, tmp_path):
    """A long chain (24 radii by 2), seen from above: every disk's extreme lies within the part of the canvas that
    the side panels leave free (they cover COVERED_PX of its width), for the page's field of view and size."""
    import numpy as np

    from granstab_app.camera import COVERED_PX, TOP
    (tmp_path / "chain.toml").write_text(CHAIN)
    with HeadlessPage(app) as page:
        ui = page.ui
        ui.path.value = str(tmp_path / "chain.toml")
        settle(ui, lambda: ui.session.scene.n_particles == 12)
        ui.camera_view.value = TOP
        ui.run(ui.set_camera)
        cam = ui.client.camera
        x = np.array([b.x for b in ui.session.bodies()])
        r = np.array([max(b.axes) for b in ui.session.bodies()])
        eye, at = np.asarray(cam.position), np.asarray(cam.look_at)
        height = eye[2]
        t = np.tan(0.5 * cam.fov)
        half_w = height * t * (cam.image_width - COVERED_PX) / cam.image_height     # free half-width at z = 0
        assert np.all(np.abs(x[:, 0] - at[0]) + r <= half_w)
        assert np.all(np.abs(x[:, 1] - at[1]) + r <= height * t)


def test_one_slider_move_reports_once(app, monkeypatch):
    """Issue 40: a refresh reads the report three times (headline, reason, mode counts); it is computed once per
    revision, so one slider move on four_disk solves the Type-1 load response once (it ran three times)."""
    from granstab.mechanics import verdicts
    calls = []
    solve = verdicts.load_response
    monkeypatch.setattr(verdicts, "load_response", lambda *a, **k: calls.append(1) or solve(*a, **k))
    with HeadlessPage(app) as page:
        ui = page.ui
        ui.preset.value = preset_label("four_disk")
        settle(ui, lambda: ui.session.preset == "four_disk" and ui.session.analysis is not None)
        calls.clear()
        revision = ui.session.revision
        ui.sliders["alpha"].value = 0.9
        settle(ui, lambda: ui.session.revision == revision + 1 and "granstab-verdict" in ui.headline.content)
        with ui.lock:
            assert len(ui.session.analysis.branches) >= 2 and len(calls) == 1


def test_the_preset_menu_shows_titles_and_keeps_the_stems(app):
    """Issue 36: the Preset menu lists titles with their stems ("Four disks (the paper's Sec. 4.2) (four_disk)"),
    not bare file stems; picking one opens the preset under its stem (the name `?preset=NAME` links and the
    session use)."""
    from granstab_app.text import PRESETS, preset_label
    four, two = preset_label("four_disk"), preset_label("two_particle")
    assert four.startswith(PRESETS["four_disk"][0]) and four.endswith("(four_disk)")
    with HeadlessPage(app) as page:
        ui = page.ui
        with ui.lock:
            options = tuple(ui.preset.options)
            assert ui.preset.value == two and ui.session.preset == "two_particle"
        assert four in options and "four_disk" not in options
        assert "two_particle" not in options and len(set(options)) == len(options)
        ui.preset.value = four
        settle(ui, lambda: ui.session.preset == "four_disk" and ui.session.analysis is not None)
        with ui.lock:
            assert ui.preset.value == four
