"""One browser tab's GUI: panels, their callbacks, and the loop that plays an eigenmode.

Callbacks only read handles, call the session (app/state.py) and write handles and views. They run on viser's
thread pool, concurrently and possibly out of order, so each takes `lock` and RE-READS the current handle values
inside it: when several slider events queue up, whichever runs last computes the latest values and the others
find nothing changed (last value wins). Every callback goes through `run`, which turns any exception into a
message in the page; nothing a user does reaches the server as an exception.
"""
from __future__ import annotations

import base64
import html
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .field import field_picture
from .params import PARAMS
from .trackview import TrackPanel
from .views import MESH_MAX, SceneView

TITLE = "granstab explorer"
# The page's title, and every input named by its label (viser 1.1's labels point at ids that its inputs lack, so
# Playwright's get_by_label and screen readers found none): run once by the browser as the HTML element mounts (an
# image that fails to load runs its onerror), then on every change of the page. docs/viser-gaps.md says why.
PAGE_FIXES = ('<img alt="" src="data:," style="display:none" onerror="'
              "document.title='" + TITLE + "';"
              "if(!window.granstabLabels){window.granstabLabels=1;"
              "const name=()=>{document.querySelectorAll('label').forEach(l=>{"
              "const text=l.textContent.trim();let a=l;if(!text)return;"
              "for(let i=0;i<5&amp;&amp;a;i++){a=a.parentElement;"
              "const inputs=a?a.querySelectorAll('input:not([type=hidden]),textarea,[role=slider]'):[];"
              "if(inputs.length){inputs.forEach(x=>{if(!x.getAttribute('aria-label'))"
              "x.setAttribute('aria-label',x.getAttribute('role')==='slider'?text+' slider':text)});break}}})};"
              "name();new MutationObserver(name).observe(document.body,{childList:true,subtree:true})}"
              '">')
NEGATIVE, OTHER = "#c0392b", "#2c3e50"      # spectrum markers: consistent negative eigenvalues, the rest
VERDICT_COLOR = {"stable": "#1e8449", "neutral": "#b7950b", "unstable": "#c0392b", None: "#555555"}
DRAG_INTERVAL = 0.15      # s between analyses while a particle is being dragged (release always analyses)
FRAME = 1 / 20            # s per animation frame
MODES_PER_BRANCH = 24     # the mode picker lists the lowest non-rigid modes of each branch
TYPING_PAUSE = 1.0        # s a text box rests before what it names is opened (0.6 opened a prefix on a loaded machine)
SEND_PAUSE = 0.02         # s the scene waits after the verdict was flushed, for it to leave in a window of its own
SPECTRUM_PARTICLES = 30   # above this the spectrum plot is off until asked for (seconds of browser work per update)
LINES_MAX = 5_000         # contacts: above this force lines and normals are off until asked for (seconds per frame
                          # in a browser without a GPU: 10⁴ disks 0.38 s, 10⁵ disks 10 s)
PLOT_LOOK = {"layout": {"plot_bgcolor": "#E5ECF6", "font": {"color": "#2a3f5f"}, "xaxis": {"gridcolor": "white"},
                        "yaxis": {"gridcolor": "white", "zerolinecolor": "white"}}}
                          # plotly's default look in 0.2 kB: its default template is 7.1 kB of the spectrum's 8.1 kB,
                          # sent again with every slider move that changes an eigenvalue
SPECTRUM_ASPECT, BLANK_ASPECT = 1.3, 0.1    # height/width of the spectrum plot, and of the blank strip while it is off
COVERED_PX = 430 + 400    # the side panels' widths over the canvas (set_width in _build/_build_side)
TOP, OBLIQUE = "top-down", "oblique (heights readable)"     # the 2D camera views
TWO_LINES = "line-height:1.3em;height:2.6em;overflow:hidden;display:-webkit-box;-webkit-line-clamp:2;" \
            "-webkit-box-orient:vertical"                   # a headline line's box: two lines, whatever its text


class ClientUI:
    """GUI, views and callbacks of one client; `session` is its state (app.state.Session)."""

    def __init__(self, client, session):
        self.client = client
        self.session = session
        self.lock = threading.RLock()
        self.view = SceneView(client.scene)
        self.view.on_drag = self._on_drag
        self.view.on_pick = lambda rho_r, f_kr: self.run(self._pick_field, rho_r, f_kr)
        self._quiet_thread: int | None = None   # the thread writing handles: its own echo callbacks are ignored
        self._last_drag = 0.0
        self._closed = False
        self._sliding = threading.Lock()          # guards the two flags below (_slider_moved)
        self._slider_busy = self._slider_again = False
        self.released = threading.Event()         # set by the server once a closed tab's memory is handed back
        self._timers: set[threading.Timer] = set()    # typing pauses pending (cancelled on close)
        self._checking: int | None = None         # the revision whose metric family is being checked
        self._player: threading.Thread | None = None
        self._mode_keys: dict[str, tuple] = {}
        self.selected: tuple | None = None
        self._modes_of = None                     # the model whose modes are listed (selection kept within it)
        self.errors_shown = 0
        self._listening = False                   # a scene click callback is registered (scan map only)
        self._picks = 0                           # presets picked and files uploaded (a typed path waits: _after_typing)
        self._lines_default = None                # the scene size class the force-line default was last set for
        self._shown: dict[str, object] = {}       # what the page shows, by slider key, "preset", "frame", "metric":
                                                  # a user's entry or a value written here (see _show)
        self._view_picked = False                 # the user chose a 2D view: kept over each scene's default view
        self._build()
        self.run(self.refresh, camera=True)

    # --------------------------------------------------------------------------------------- layout
    def _build(self) -> None:
        # no HDR environment map (seconds of main-thread work in a software-rendered browser); the default lights
        # without shadows are enough for flat shapes seen from above and for translucent 3D bodies
        self.client.scene.configure_environment_map(hdri=None)
        self.client.scene.configure_default_lights(enabled=True, cast_shadow=False)
        gui = self.client.gui
        gui.configure_theme(control_width="large", show_share_button=False)
        # hover hints: viser opens one above its input (below where no room), over the neighbouring inputs, so only
        # the Metric menu, first in its tab, has one; labels and the text beside say the rest (viser 1.1 shows no
        # hints on buttons)
        self.headline = gui.add_html("")
        self.message = gui.add_html("", visible=False)
        tabs = gui.add_tab_group()
        with tabs.add_tab("Scene"):
            self.preset = gui.add_dropdown("Preset", options=self.session.presets() or ["(none)"],
                                           initial_value=self._preset_option())
            self.preset.on_update(self._picking(self._load_preset))
            self.upload = gui.add_upload_button("Open scene file", mime_type="*/*")
            self.upload.on_upload(self._picking(self._upload))
            self.path = gui.add_text("Path on server", initial_value="", disabled=not self.session.typed_paths)
            self.path.on_update(self._after_typing(self._open_path))
            self.frame = gui.add_slider("Frame", min=1, max=2, step=1, initial_value=1, visible=False)
            self.frame.on_update(lambda _: self.run(self._pick_frame))
            self.track = TrackPanel(gui, self.client.scene, self.run, self.refresh)     # a tracked folder's frame
            self.analyse = gui.add_button("Analyse the whole packing", visible=False)
            self.analyse.on_click(lambda _: self.run(self._analyse))
            self.cluster_name = gui.add_text("Open cluster of", initial_value="", visible=False)
            self.cluster_name.on_update(self._after_typing(lambda: self._open_cluster(self.cluster_name.value.strip())))
            self.back = gui.add_button("Back to the map", visible=False)
            self.back.on_click(lambda _: self.run(self._back_to_map))
            self.sliders = {}
            for key, p in PARAMS.items():
                # what each slider is stands in the scene line below them
                h = gui.add_slider(p.label, min=p.lo, max=p.hi, step=p.step, initial_value=p.default)
                h.on_update(lambda _: self._slider_moved())
                self.sliders[key] = h
            self.reset = gui.add_button("Reset", visible=False)
            self.reset.on_click(lambda _: self.run(self._reset_poses))
            self.info = gui.add_markdown("")
        with tabs.add_tab("Verdict"):
            self.metric = gui.add_dropdown("Metric", options=["L", "inertia"], initial_value="L", visible=False,
                                           hint="L: rotations scaled by the mean contact radius; inertia: the "
                                                "kinetic-energy metric (λ = ω², frequencies), for scenes with masses")
            self.metric.on_update(lambda _: self.run(self._set_metric))
            self.details = gui.add_markdown("")
            check = gui.add_button("Check other metrics")
            check.on_click(lambda _: self.run(self._check_metrics))
        with tabs.add_tab("Display"):
            self.show = {key: gui.add_checkbox(label, initial_value=True) for key, label in (
                ("forces", "Force arrows"), ("normals", "Contact normals"), ("osculating", "Osculating circles"),
                ("surface", "λ⁽⁶⁾ height surface (pair)"), ("shares", "Colour particles by the selected mode"))}
            self.force_scale = gui.add_slider("Arrow length ×", min=0.2, max=3.0, step=0.1, initial_value=1.0)
            for h in (*self.show.values(), self.force_scale):
                h.on_update(lambda _: self.run(self._display))
            self.camera_view = gui.add_dropdown("View", options=[TOP, OBLIQUE], initial_value=TOP)
            self.camera_view.on_update(self._pick_view)
            gui.add_button("Reset view").on_click(lambda _: self.run(self._set_camera))
        with tabs.add_tab("Export"):
            gui.add_markdown("Download the current scene (reloads to the same analysis), the analysis, the contour.")
            self.exports = {}
            for key, label, fn in (("scene", "Scene file (.json)", self.session.export_scene),
                                   ("analysis", "Analysis (.json)", self.session.export_analysis),
                                   ("contour", "λ⁽⁶⁾ contour (.png)", self.session.export_contour)):
                self.exports[key] = gui.add_button(label)
                self.exports[key].on_click(self._download(fn))
        self.legend = gui.add_markdown("")
        gui.add_html(PAGE_FIXES)

        self._build_side()
        gui.main_panel.dock_right()
        gui.main_panel.set_width(400)

    def _build_side(self) -> None:
        """The left column: the λ⁽⁶⁾ field panel (shown for the pair only) above the Eigenmodes panel, built once and
        never removed. Removing a panel right after its contents were written is a console error (the page applies a
        batch's removals before its updates: "Tried to update non-existent component"), and unmounting a plotly
        plot with a redraw pending the `_redrawFromAutoMarginCount` page error. Panels are docked BEFORE their plots
        are added: docking remounts a panel's contents."""
        gui = self.client.gui
        self.side = gui.add_panel()
        self.side.dock_left()
        self.side.set_width(430)
        with self.side.add_tab("Eigenmodes"):               # the mode controls first: the plot is tall
            self.mode_pick = gui.add_dropdown("Mode", options=["(none)"], initial_value="(none)")
            self.mode_pick.on_update(lambda _: self.run(self._pick_mode))
            self.play = gui.add_checkbox("Play", initial_value=False)
            self.play.on_update(lambda _: self.run(self._toggle_play))
            self.amplitude = gui.add_slider("Amplitude (particle sizes)", min=0.0, max=0.6, step=0.01,
                                            initial_value=0.2)
            self.speed = gui.add_slider("Speed (cycles/s)", min=0.1, max=2.0, step=0.1, initial_value=0.5)
            self.mode_info = gui.add_markdown("")
            self.show_spectrum = gui.add_checkbox("Spectrum plot", initial_value=True)
            self.show_spectrum.on_update(lambda _: self.run(self._write_modes))
            self._spectrum_default = None        # the scene size the checkbox default was last set for
            self._spectrum_shown = None          # what the spectrum plot shows now (a redraw only on a change)
            self.spectrum = gui.add_plotly(_empty_figure(), aspect=SPECTRUM_ASPECT, visible=False)
            self.track.add_plot(gui)                         # a track's λ_min(t)/stress(t): no modes on its map
        self.field_panel = gui.add_panel()
        self.field_panel.dock_above(self.side)
        with self.field_panel.add_tab("λ⁽⁶⁾ field"):
            self.field_note = gui.add_markdown("")
            self.contour = gui.add_html("")        # a picture, not a plotly plot: this panel comes and goes
            self.star = gui.add_html("")           # the current state over it (contour_star)
            self._contour_of = None                # the field the picture shows

    def _preset_option(self) -> str:
        options = self.session.presets()
        return self.session.preset if self.session.preset in options else (options[0] if options else "(none)")

    # --------------------------------------------------------------------------------------- plumbing
    @contextmanager
    def _quiet(self):
        """Write handles without reacting to them: setting a value from Python runs its callbacks synchronously in
        this thread, and those echoes must not recompute. Other threads' (users') events wait for the lock."""
        self._quiet_thread = threading.get_ident()
        try:
            yield
        finally:
            self._quiet_thread = None

    def _echo(self) -> bool:
        return self._quiet_thread == threading.get_ident()

    def run(self, fn, *args, **kwargs):
        """Call fn under the lock; an exception becomes a message in the page (and never reaches viser)."""
        if self._closed or self._echo():
            return None
        with self.lock:
            try:
                return fn(*args, **kwargs)
            except Exception as exc:  # noqa: BLE001
                self.errors_shown += 1
                self._show_message(f"{type(exc).__name__}: {' '.join(str(exc).split())}")
                return None

    def _slider_moved(self) -> None:
        """A slider's event. A tab's slider events are coalesced: while its slider callback runs, a new event only
        marks it to run once more (reading the latest values), so that a dragged slider holds one of viser's pool
        threads (32 for every tab of the server), not one per event waiting for the tab's lock while a large scene
        is analysed."""
        if self._closed or self._echo():
            return
        with self._sliding:
            self._slider_again = True
            if self._slider_busy:
                return
            self._slider_busy = True
        try:
            while True:
                with self._sliding:
                    if not self._slider_again:
                        self._slider_busy = False        # under the lock: a later event starts its own run
                        return
                    self._slider_again = False
                self.run(self._apply_sliders)          # `run` turns any Exception into a message in the page
        except BaseException:
            with self._sliding:
                self._slider_busy = False
            raise

    def _picking(self, fn):
        """The callback of a control that picks a scene (preset, upload): counted as it arrives, before it waits
        for the lock (a path typed before it then stays unopened: _after_typing), then run."""
        def update(_):
            if not self._echo():
                self._picks += 1
            self.run(fn)
        return update

    def _after_typing(self, fn):
        """An on_update for a text box (it reports every letter): `fn` runs, through `run`, once the text has rested
        TYPING_PAUSE s, so a path typed letter by letter is opened once, not at every prefix (each one a red error,
        some a folder to search or another file); not at all if a preset was picked or a file uploaded meanwhile
        (the last thing the user chose wins)."""
        timer = None

        def update(_):
            nonlocal timer
            if timer is not None:
                timer.cancel()
                self._timers.discard(timer)
            if self._closed:
                return
            picks = self._picks

            def fire():
                self._timers.discard(mine)
                if self._picks == picks:
                    self.run(fn)
            timer = mine = threading.Timer(TYPING_PAUSE, fire)
            timer.daemon = True
            self._timers.add(timer)
            timer.start()
        return update

    def _loading(self, name: str) -> None:
        """While a scene opens: the last error goes, and the page says what is opening (sent at once)."""
        self.message.content = (f'<div class="granstab-loading" style="color:#555;font-style:italic;padding:2px 8px">'
                                f"Opening {html.escape(name)} …</div>")
        self.message.visible = True
        self.client.flush()

    def _show_message(self, text: str | None) -> None:
        self.message.content = (f'<div class="granstab-error" style="color:#b03a2e;font-weight:600;padding:2px 8px">'
                                f"{html.escape(text)}</div>") if text else ""
        self.message.visible = bool(text)

    def close(self) -> None:
        """The tab is gone: nothing runs for it any more. Pending typing pauses are cancelled, the animation thread
        ends (joined), a callback running now finishes first (the lock); its state is then unreferenced."""
        self._closed = True
        for timer in list(self._timers):
            timer.cancel()
        self._timers.clear()
        player = self._player
        if player is not None and player is not threading.current_thread():
            player.join(timeout=5.0)
        with self.lock:
            self._player = None

    # --------------------------------------------------------------------------------------- callbacks
    def _apply_sliders(self) -> None:
        values = {key: self.sliders[key].value for key in self.session.used_params}
        self._shown.update(values)              # what the page shows: not written back (see _show)
        if self.session.set_params(**values):
            self.refresh()

    def _set_metric(self) -> None:
        self._shown["metric"] = self.metric.value
        if self.session.set_metric(self.metric.value):
            self.refresh()

    def _load_preset(self) -> None:
        name = self._shown["preset"] = self.preset.value
        if name == self.session.preset:
            return
        if name not in self.session.presets():          # the menu's options only (a forged value is no path)
            self._show_message(f"{name}: not a preset of this server")
            return
        self._loading(name)
        ok = self.session.load_preset(name)
        self.view.key = None
        self.refresh(camera=ok)

    def _pick_view(self, _) -> None:
        """The View menu: the user's choice, noted as it arrives (a scene opening meanwhile keeps it), then shown."""
        if not self._echo():
            self._view_picked = True
        self.run(self._set_camera)

    def _upload(self) -> None:
        """Open the file sent from the page; one that cannot be opened (over MAX_UPLOAD: refused unread) gets a red
        notice with the reason beside viser's own notice of the transfer (docs/viser-gaps.md: uploads)."""
        up = self.upload.value
        self._loading(Path(up.name).name)
        ok = self.session.load_upload(up.name, up.content)
        if not ok:
            self.client.add_notification(f"Not opened: {Path(up.name).name}", self.session.error, color="red",
                                         with_close_button=True, auto_close_seconds=None)
        self.view.key = None
        self.refresh(camera=ok)

    def _open_path(self) -> None:
        path = self.path.value.strip()
        if not path or path == self.session.preset:
            return
        self._loading(path)
        ok = self.session.open_typed(path)
        self.view.key = None
        self.refresh(camera=ok)

    def _pick_frame(self) -> None:
        frames = getattr(self.session.model, "frames", None)
        self._shown["frame"] = int(self.frame.value)
        if frames and self.session.set_frame(frames[int(self.frame.value) - 1]):
            self.refresh()

    def _open_cluster(self, name: str) -> None:
        if name and self.session.open_cluster(name):
            self.view.key = None
            self.refresh(camera=True)
        elif name:
            self._show_message(self.session.error)

    def _back_to_map(self) -> None:
        if self.session.back_to_map():
            self.view.key = None
            self.refresh(camera=True)

    def _map_click(self, event) -> None:
        """A click in the scene while the scan map is shown: open the cluster of the particle under it."""
        name = self.session.pick(event.ray_origin, event.ray_direction)
        if name is not None:
            self._open_cluster(name)

    def _analyse(self) -> None:
        self.session.analyse()
        self.refresh()

    def _pick_field(self, rho_r: float, f_kr: float) -> None:
        """A click on the λ⁽⁶⁾ surface sets ρ/r and f/(kr), snapped to the slider steps (Session.pick_field)."""
        if self.session.pick_field(rho_r, f_kr):
            self.refresh()

    def _reset_poses(self) -> None:
        self.session.reset_poses()
        self.refresh()

    def _display(self) -> None:
        self.view.options.update({key: h.value for key, h in self.show.items()})
        self.view.options["force_scale"] = self.force_scale.value
        if not self.view.options["surface"]:
            self.view.clear_field()
        self.refresh(particles=False)

    def _on_drag(self, name: str, event) -> None:
        """Gizmo events: analyse at most every DRAG_INTERVAL while dragging (skipping if busy), always on release."""
        if self._closed or self._echo():
            return
        phase = getattr(event, "phase", "end")
        now = time.monotonic()
        if phase == "start":
            self.run(self._stop_play)
            return
        if phase == "update":
            if now - self._last_drag < DRAG_INTERVAL or not self.lock.acquire(blocking=False):
                return
            try:
                self._last_drag = now
                self.run(self._moved, name, dragging=True)
            finally:
                self.lock.release()
            return
        self.run(self._moved, name, dragging=False)

    def _moved(self, name: str, dragging: bool) -> None:
        x, R = self.view.pose_of(name)
        self.session.move(name, x, R)
        self.refresh(skip=name if dragging else None)

    def _download(self, fn):
        def _(event):
            def send():
                filename, content = fn()
                (event.client or self.client).send_file_download(filename, content, save_immediately=True)
            self.run(send)
        return _

    def _pick_mode(self) -> None:
        self.selected = self._mode_keys.get(self.mode_pick.value)
        self._describe_mode()

    def _toggle_play(self) -> None:
        if self.play.value and (self._player is None or not self._player.is_alive()):
            self._player = threading.Thread(target=self._play_loop, daemon=True)
            self._player.start()

    def _stop_play(self) -> None:
        if getattr(self, "play", None) is not None and self.play.value:
            with self._quiet():
                self.play.value = False

    def _play_loop(self) -> None:
        """Animate the selected mode while Play is on (no work at all when paused)."""
        start = time.monotonic()
        while not self._closed and self.play.value:
            with self.lock:
                try:
                    mode = self._current_mode()
                    if mode is not None:
                        phase = 2 * np.pi * self.speed.value * (time.monotonic() - start)
                        bodies = self.session.mode_bodies(mode, self.amplitude.value, phase)
                        with self.client.atomic():
                            self.view.animate(bodies)
                except Exception as exc:  # noqa: BLE001
                    self._show_message(f"animation: {' '.join(str(exc).split())}")
                    break
            time.sleep(FRAME)
        if not self._closed:
            with self.lock:
                self.view.stop_animation()

    def _current_mode(self):
        if self.selected is None:
            return None
        return next((m for m in self.session.modes() if (m.branch, m.index) == self.selected), None)

    # --------------------------------------------------------------------------------------- refresh
    def refresh(self, camera: bool = False, particles: bool = True, skip: str | None = None) -> None:
        """Write every handle from the session: the verdict first, sent on its own (what a slider move is for), then
        the scene (only the parts that changed are re-sent: SceneView keys each drawing by its data), plots and modes.
        Each part is written as one atomic group: viser then wakes its event loop once per group, not once per
        message (a pair's move writes about 20)."""
        s = self.session
        with self.client.atomic():
            self._sync_controls()
            self._write_verdict()
        self._send_now()
        with self.client.atomic():
            if particles:
                with self._quiet():                      # gizmo poses written here are not drags
                    self.view.draw_particles(s, skip=skip)
            legend = self.view.draw_contacts(s)
            self.view.draw_cell(s)
            field = s.field() if self.view.options["surface"] else None
            current = (s.params.get("rho_r"), s.params.get("f_kr"), s.rolling_eigenvalue())
            if field is None:
                self.view.clear_field()
            else:
                self.view.draw_field(s, field, current)
            self._write_legend(legend)
            self._write_field()
            self._write_modes()
        self.track.refresh(s)
        if camera:
            if not self._view_picked:       # the pair opens oblique: its λ⁽⁶⁾ height surface is flat seen from above
                with self._quiet():
                    self.camera_view.value = OBLIQUE if s.field() is not None else TOP
            self._set_camera()

    def _send_now(self) -> None:
        """Send what is queued (the verdict and the other panels' text) in a websocket window of its own: flush, then
        give viser's event loop SEND_PAUSE to take it before the scene's messages queue up. The browser applies a
        window of GUI messages at once, but one that also holds scene messages only at its next 3D frame: on a large
        scene in a software-rendered browser that kept the new verdict ≈ 0.5–1 s behind the particle colours of the
        same window. viser has no public signal that a window left, so the pause is fixed (docs/viser-gaps.md)."""
        self.client.flush()
        time.sleep(SEND_PAUSE)

    def _check_metrics(self) -> None:
        """*Check other metrics*: says at once that it runs and about how long, then runs off the lock (a slider
        stays live); the result is kept only if nothing moved meanwhile (Session.keep_metrics), else the row says
        the check was superseded."""
        s = self.session
        if s.scene is None or s.analysis is None or self._checking == s.revision:
            return
        self._checking = s.revision
        self._write_verdict()
        self.client.flush()
        threading.Thread(target=self._family, args=(s.scene, s.revision), daemon=True).start()

    def _family(self, scene, revision: int) -> None:
        from .state import metric_family
        try:
            metrics = metric_family(scene)
        except Exception as exc:  # noqa: BLE001 — shown in the page
            self.run(self._show_message, f"Check other metrics: {' '.join(str(exc).split())}")
            metrics = None
        self.run(self._family_done, metrics, revision)

    def _family_done(self, metrics, revision: int) -> None:
        if self._checking == revision:
            self._checking = None
        if metrics is not None and self.session.keep_metrics(metrics, revision) is not None:
            self._write_verdict()

    def _sync_controls(self) -> None:
        """Slider visibility/values and the preset list follow the session without firing callbacks."""
        s = self.session
        with self._quiet():
            options = s.presets()
            if s.preset not in options:
                options = [*options, s.preset]
            if tuple(self.preset.options) != tuple(options):
                self.preset.options = options
            self._show("preset", self.preset, s.preset)
            used = set(s.used_params)
            for key, h in self.sliders.items():
                h.visible = key in used
                if key in used:
                    p = s.param(key)                     # k follows the scene's scale (params.Param.around)
                    if (h.min, h.max, h.step) != (p.lo, p.hi, p.step):
                        h.min, h.max, h.step = p.lo, p.hi, p.step
                    self._show(key, h, s.params[key])
            self.reset.visible = s.resettable
            frames = getattr(s.model, "frames", None)
            self.frame.visible = bool(frames) and len(frames) > 1
            if self.frame.visible:
                self.frame.max = len(frames)
                self._show("frame", self.frame, frames.index(s.model.frame) + 1 if s.model.frame in frames else 1)
            self.analyse.visible = s.deferred
            on_map = s.kind == "scan_map"
            self.cluster_name.visible, self.back.visible = on_map, s.map is not None
            if on_map != self._listening:             # scene clicks are only listened to on the map
                self._listening = on_map
                if on_map:
                    self.client.scene.on_click()(lambda event: self.run(self._map_click, event))
                else:
                    self.client.scene.remove_click_callback()
            self.metric.visible = len(s.metric_choices) > 1
            self._show("metric", self.metric, s.metric)
            many = s.scene is not None and s.scene.n_contacts > LINES_MAX
            if many != self._lines_default:           # a new size class: its default (lines off when many)
                self._lines_default = many
                for key in ("forces", "normals"):
                    self.show[key].value = self.view.options[key] = not many
            pair = s.kind == "two_particle"
            self.show["surface"].visible = self.exports["contour"].visible = self.field_panel.visible = pair
            self.show["shares"].visible = self.colours_by_mode        # a pair's two particles share a mode evenly
            self.camera_view.visible = s.scene_dim == 2                # a 3D scene has one view: Reset view

    def _show(self, key: str, handle, value) -> None:
        """Write `value` into `handle` only when the session changed it (a preset, a reset, a cleaned entry, a file
        opened), never because the handle differs: the handle may already hold a newer entry whose callback is queued,
        and writing the older value back drops that entry (seen: the last of quick slider entries lost; a preset
        picked right after another one reverted to the first)."""
        if self._shown.get(key) != value:
            handle.value = self._shown[key] = value

    def _write_verdict(self) -> None:
        s = self.session
        r = s.report()
        verdict = r["verdict"]
        apart = s.scene is not None and s.scene.n_contacts == 0
        title = s.scene.title if s.scene is not None else str(s.preset)
        if s.deferred:
            title = f"{title} — {s.scene.n_particles} particles: drawn, not analysed (Analyse the whole packing)"
            verdict = "not analysed"
        if s.kind == "scan_map":      # a scan's map, a track's frame (its own headline) or a rigidity map
            title, verdict = getattr(s.model, "headline", None) or (
                f"{s.scene.n_particles} particles: click one (or type its name) for its cluster", "scan map")
        if apart and s.kind != "scan_map":       # pulled apart: the file's title ("tips touching") no longer holds, nor does a verdict
            title, verdict = "no contact: the particles are apart (every motion is free)", "no contact"
        reason = ("" if verdict in (None, "no contact", "not analysed", "scan map", "rigidity map", "track")
                  else s.headline()[1])
        self.headline.content = (
            f'<div class="granstab-verdict" data-verdict="{(verdict or "none").replace(" ", "-")}" '
            f'data-revision="{s.revision}" style="background:'
            f'{VERDICT_COLOR.get(verdict, "#555")};color:white;font-weight:700;font-size:1.35em;padding:4px 10px;'
            f'border-radius:6px;letter-spacing:0.05em">{(verdict or "no verdict").upper()}</div>'
            # title and reason: two lines at most, always two lines tall (the full text on hover): the controls
            # below never jump when one of them wraps (a preset switch, a slider, a drag)
            f'<div title="{html.escape(title)}" style="font-style:italic;margin:4px 2px 0 2px;{TWO_LINES}">'
            f'{html.escape(title)}</div>'
            f'<div title="{html.escape(reason)}" style="margin:2px 2px 4px 2px;font-size:0.92em;{TWO_LINES}">'
            f'{html.escape(reason)}</div>')
        self._show_message(s.error)
        note = r.get("notice")
        params = ", ".join(f"{PARAMS[k].label} = {s.params[k]:g} ({PARAMS[k].hint})" for k in s.used_params)
        report = getattr(s.model, "report", "")
        drag = ("" if s.kind == "scan_map" else " Drag a particle by its arrows (the arc turns it): contacts and "
                "forces follow the geometry." if s.draggable else " Its contacts are given in the file (points, "
                "normals, curvatures, forces), not shapes: the particles cannot be dragged.")
        kind = verdict if s.kind == "scan_map" else s.kind.replace("_", " ")      # a map says which map
        self.info.content = (f"{note}\n\n" if note else "") + (
            f"{kind} scene" + (f" · {params}." if params else ".")) + drag + (
            f"\n\n**Import report**\n\n{wrapped(report)}" if report else "")
        if s.kind == "scan_map" and hasattr(s.model, "details"):
            self.details.content = s.model.details
        elif s.kind == "scan_map":
            self.details.content = (f"**Scan map.** {s.model.report}.\n\nColour: the fraction of the clusters "
                                    "containing a particle that are unstable (white 0 → dark red 1; grey: in no "
                                    "scanned cluster). Click a particle, or type its name under *Scene*, to open its "
                                    "cluster here; *Back to the map* returns.")
        elif s.deferred:
            self.details.content = "Not analysed yet: a large packing is analysed only on request."
        elif r["verdict"] is None:
            self.details.content = f"**Analysis failed:** {s.error}\n\n(last attempt {r['elapsed'] * 1e3:.1f} ms)"
        else:
            pos, zero, neg = r["counts"]
            name, worst = r["worst_error"]
            rows = [
                "| | |", "|---|---|",
                f"| verdict | **{r['verdict']}** ({'sufficient condition met' if r['sufficient'] else 'not proven'}) |",
                f"| consistent modes | {self._mode_counts()} |",
                f"| Type-1 non-uniqueness | {r['type1']} |",
                f"| Type-2 non-uniqueness | {'yes' if r['type2'] else 'no'} |",
                f"| verdict hinges on S tolerance | {'yes' if r['hinges'] else 'no'} |",
                f"| particles · contacts · at yield | {r['n_particles']} · {r['n_contacts']} · {r['n_sliding']} |",
                f"| branches (2^Ms) | {r['n_branches']} |",
                f"| largest error estimate | {worst:.1e} ({name}) |",
                f"| analysis time | {r['analysis_time'] * 1e3:.1f} ms (with scene: {r['elapsed'] * 1e3:.1f} ms) |",
            ]
            rows.insert(6, f"| metric | {self._metric_row()} |")
            if r.get("attribution"):
                rows.insert(2, f"| why (docs/attribution.md) | {r['attribution']} |")
            if r["dynamics"] is not None:
                d = r["dynamics"]
                rows.insert(7, "| lowest frequencies ω = √λ | " + (", ".join(f"{w:.4g}" for w in d["frequencies"])
                                                                    or "none") + " (1/time: √(k/m)) |")
                rows.insert(8, "| growth rates √(−λ) | " + (", ".join(f"{g:.4g}" for g in d["growth_rates"])
                                                             or "none: no resolved negative λ") + " |")
            warn = "".join(f"\n\n**Warning:** {w}" for w in r["warnings"])
            self.details.content = f"**Why:** {r['reason']}\n\n" + "\n".join(rows) + warn

    def _mode_counts(self) -> str:
        """Consistent modes by sign, each mode once (Session.distinct_modes), and the core's per-branch count where a
        mode recurs in several branches."""
        d = self.session.distinct_modes()
        pos, zero, neg = self.session.report()["counts"]
        text = f"{d['negative']} negative · {d['zero']} zero · {d['positive']} positive"
        if (neg, zero, pos) != (d["negative"], d["zero"], d["positive"]):
            text += f" (over the branches: {neg} · {zero} · {pos}, a mode counted in each branch it appears in)"
        return text

    def _metric_row(self) -> str:
        """The metric-robustness flag of the core (summary["metric_robust"]) once checked, the check running, else how
        to check."""
        m = self.session.metrics
        if self._checking == self.session.revision:
            return (f"checking L/10, L and 10L{' and inertia' if self.session.scene.mass is not None else ''} … "
                    f"(about {max(self.session.family_estimate(), 0.1):.1g} s; a slider move supersedes it)")
        if m is None or m["revision"] != self.session.revision:
            return (f"{self.session.metric} only: *Check other metrics* below runs L/10, L, 10L (and inertia with "
                    "masses)")
        if m["robust"]:
            return ("this verdict is proven for every rotation length (and the inertia metric where masses are known), "
                    f"not only those tried ({', '.join(x['metric'] for x in m['metrics'])})")
        return " · ".join(f"{x['metric']}: {x['verdict']} ({x['consistent_negative']} negative)"
                          for x in m["metrics"])

    def _write_legend(self, legend: dict) -> None:
        if self.session.kind == "scan_map" and hasattr(self.session.model, "legend"):
            self.legend.content = self.session.model.legend
            return
        if self.session.kind == "scan_map":
            self.legend.content = ("**Legend** — particle colour: the share of the scanned clusters containing it that "
                                   "are unstable by the packing (mechanism frictional, geometric or mixed; white 0 → "
                                   "dark red 1). Light grey: unstable only through `boundary` clusters (the dead "
                                   "loads at the cut, docs/attribution.md); dark grey: in no cluster.")
            return
        scene, o = self.session.scene, self.view.options     # what is drawn now, and only that
        contacts = scene is not None and scene.n_contacts > 0
        parts = []
        if contacts and legend["max_force"] == 0:
            parts.append("no contact force.")
        elif contacts and o["forces"]:
            parts.append(f"{'lines' if legend.get('lines') else 'arrows'}: the contact force on each particle "
                         "(pointing into it when compressive; red compressive, blue tensile, orange at the Coulomb "
                         f"limit); length {legend['arrow']:.2g}·size = largest |f| = {legend['max_force']:.3g}.")
        if contacts and o["normals"]:
            parts.append("Blue lines: normals n^pq.")
        if contacts and o["osculating"] and scene.n_contacts <= MESH_MAX:
            parts.append("Purple arcs: osculating circles (radius ρ at each contact).")
        if scene is not None and scene.n_particles <= MESH_MAX:
            parts.append("Dark stripe: a body axis (turns with the particle).")
        if self._lines_default and not (o["forces"] or o["normals"]):
            parts.append(f"Force lines and normals are off above {LINES_MAX:,} contacts (seconds per frame in a "
                         "browser without a GPU): tick them under *Display*.")
        self.legend.content = "**Legend** — " + " ".join(parts) if parts else ""

    def _write_field(self) -> None:
        s = self.session
        field = s.field()
        if field is None:
            return
        lam, tol = s.rolling_eigenvalue(), s.zero_tolerance()
        now = ("" if lam is None else f" (λ⁽⁶⁾/k = 0 within the zero tolerance {tol:.0e})" if lam == 0
               else f" (λ⁽⁶⁾/k = {lam:.4g})")
        self.field_note.content = (f"Rolling eigenvalue λ⁽⁶⁾/k over (ρ/r, f/(kr)) at α = {field.alpha:g}; "
                                   f"★ = now{now}")
        if self._contour_of is not field:                 # the picture: once per field (α, rolling stiffness)
            self._contour_of = field
            self.contour.content = contour_html(field)
        self.star.content = contour_star(field, (s.params["rho_r"], s.params["f_kr"]))

    def _write_modes(self) -> None:
        s = self.session
        modes = s.modes()
        large = s.scene is not None and s.scene.n_particles > SPECTRUM_PARTICLES
        if large != self._spectrum_default:          # a new scene size class: the default for it (off when large)
            self._spectrum_default = large
            with self._quiet():
                self.show_spectrum.value = not large
        plot = bool(modes) and self.show_spectrum.value
        for h in (self.show_spectrum, self.mode_pick, self.play, self.amplitude, self.speed):
            h.visible = bool(modes)             # no analysis (a large packing, the scan map): nothing to pick or play
        if not modes:
            self._stop_play()
        if plot:            # mounted when first needed, then never unmounted: unmounting a plot with a plotly redraw
            self.spectrum.visible = True    # pending is the `_redrawFromAutoMarginCount` page error; a blank strip
        if self.spectrum.visible:           # when unused (no empty axes)
            self.spectrum.aspect = SPECTRUM_ASPECT if plot else BLANK_ASPECT
        keys: dict[str, tuple] = {}
        by_branch: dict[int, int] = {}
        for m in sorted((m for m in modes if m.label != "rigid"), key=lambda m: (m.branch, m.eigenvalue)):
            if by_branch.get(m.branch, 0) < MODES_PER_BRANCH or (m.consistent and m.eigenvalue <= 0):
                keys[m.key] = (m.branch, m.index)
                by_branch[m.branch] = by_branch.get(m.branch, 0) + 1
        self._mode_keys = keys
        listed = set(keys.values())
        shown = [m for m in modes if (m.branch, m.index) in listed or (m.label == "rigid" and len(modes) <= 60)]
        drawn = (tuple((m.branch, m.eigenvalue, m.code, m.label) for m in shown), len(modes) - len(shown)) if plot \
            else "empty" if self.spectrum.visible else None
        if drawn is not None and drawn != self._spectrum_shown:   # a redraw costs the browser (and plotly's build and
            self._spectrum_shown = drawn                          # JSON the server): only on a change of what it shows
            self.spectrum.figure = spectrum_figure(shown, hidden=drawn[1]) if plot else _empty_figure()
        if self._modes_of is not s.model:            # another scene: its own lowest mode, not the old index
            self._modes_of, self.selected = s.model, None
        if self.selected not in keys.values():
            pick = next((m for m in sorted(modes, key=lambda m: m.eigenvalue) if m.consistent), None)
            self.selected = (pick.branch, pick.index) if pick else next(iter(keys.values()), None)
        current = next((k for k, v in keys.items() if v == self.selected), "(none)")
        with self._quiet():
            self.mode_pick.options = list(keys) or ["(none)"]
            self.mode_pick.value = current
        self._describe_mode()

    def _colour_by_mode(self, m) -> None:
        s = self.session
        if s.scene is None:
            return
        on = m is not None and self.show["shares"].value and self.colours_by_mode
        names = [b.name for b in s.bodies()]
        index = {n: i for i, n in enumerate(s.scene.names)}
        shares = s.particle_shares(m)[[index[n] for n in names]] if on else None
        self.view.colour_particles(names, shares, s.map_colours)

    @property
    def colours_by_mode(self) -> bool:
        """Whether particles can be coloured by their share of a mode: an analysed scene of more than two."""
        s = self.session
        return s.analysis is not None and s.scene.n_particles > 2

    def _describe_mode(self) -> None:
        m = self._current_mode()
        self._colour_by_mode(m)
        if m is None:
            s = self.session              # say why this panel is empty, and how to fill it
            self.mode_info.content = (
                "No mode to show." if s.analysis is not None else
                "A map has no modes: open a particle's cluster (click it, or type its name under *Scene*) "
                "for its eigenmodes." if s.kind == "scan_map" else
                "Not analysed yet: *Analyse the whole packing* (under *Scene*) computes the modes." if s.deferred else
                f"No analysis: {s.error}")
            return
        shares = ", ".join(f"{k} {v:.0%}" for k, v in m.shares.items() if v >= 0.005)
        way = {1: "consistent in +v only", -1: "consistent in -v only", 0: "consistent both ways",
               2: "not consistent with its branch", 3: "rigid"}[m.code]
        mask = self.session.analysis.branches[m.branch].mask
        sliding, unloading = int(np.sum(mask == 1)), int(np.sum(mask == -1))
        where = f"{sliding} sliding, {unloading} unloading contact(s)" if sliding + unloading else "no contact at yield"
        self.mode_info.content = (f"**{m.label}** mode, λ = {m.eigenvalue:.5g} (branch {m.branch}: {where}), "
                                  f"{way}{' (hinges on the S tolerance)' if m.hinges else ''}. "
                                  f"Contact deformation: {shares or '—'}. Tick *Play* to animate it."
                                  + (" Particle colour: its share of this mode's motion, white 0 → dark red "
                                     "100 % of the largest." if self.view.colours_by_mode else ""))

    def _set_camera(self) -> None:
        pose = camera_pose(self.session, self.camera_view.value == OBLIQUE and self.session.scene_dim == 2,
                           self.view.options["surface"], lambda w, h: fit_distance(w, h, self.client.camera))
        for key, value in pose.items():
            setattr(self.client.camera, key, value)


def camera_pose(s, oblique: bool, surface: bool, fit) -> dict:
    """Where the camera looks at session `s` from: near, far, up_direction, position, look_at (in the order to set
    them). 2D from above (or `oblique`: from the front and above, heights readable; the λ⁽⁶⁾ surface included when
    `surface` is shown), `fit(half_w, half_h)` the distance that fits the scene; 3D from an oblique corner. The
    explorer's camera (ClientUI._set_camera) and the published page's (app/publish.py)."""
    bodies = s.bodies()
    x = np.array([b.x for b in bodies])
    reach = 1.2 * np.array([max(b.axes) for b in bodies])[:, None]   # each body by its own size (hand_in_glove's
                                                                      # q is larger than the mean)
    lo, hi = (x - reach).min(axis=0), (x + reach).max(axis=0)
    span = float(np.max(hi - lo))
    pose = {"near": 1e-3 * span, "far": 1e2 * span}                     # packings in px or in m
    c = 0.5 * (lo + hi)
    if s.scene_dim == 2:
        if s.field() is not None and surface:
            lo[1] = min(lo[1], -4.9 * s.field_scale)
            c = 0.5 * (lo + hi)
        distance = fit(0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]))
        if oblique:
            pose.update(up_direction=(0.0, 0.0, 1.0),
                        position=(float(c[0]), float(c[1]) - 0.8 * distance, 0.75 * distance))
        else:
            pose.update(up_direction=(0.0, 1.0, 0.0), position=(float(c[0]), float(c[1]), distance))
        pose["look_at"] = (float(c[0]), float(c[1]), 0.0)
        return pose
    extent = float(np.max(hi - lo))
    view = np.array([0.55, -0.65, 0.5])
    pose.update(up_direction=(0.0, 0.0, 1.0), position=tuple((c + 1.3 * extent * view / np.linalg.norm(view)).tolist()),
                look_at=tuple(c.tolist()))
    return pose


def fit_distance(half_w: float, half_h: float, camera, covered: float = COVERED_PX, fill: float = 0.9) -> float:
    """How far above a 2D scene of half-sizes (half_w, half_h) the camera must be for the scene to fill at most `fill`
    of the canvas that the side panels (`covered` px of its width) leave free, for the camera's vertical field of
    view and the canvas's size in px (an opened cluster was cut at the canvas edge by a fixed distance)."""
    t = np.tan(0.5 * float(camera.fov))
    width, height = float(camera.image_width), float(camera.image_height)
    free = max(width - covered, 0.3 * width)
    return max(half_h / (fill * t), half_w / (fill * t * free / height))


# ------------------------------------------------------------------------------------------ figures

def wrapped(text: str) -> str:
    """Preformatted lines that wrap at the panel's edge (a Markdown code block cuts them off), as Markdown's raw
    HTML."""
    return (f'<div class="granstab-report" style="white-space:pre-wrap;overflow-wrap:anywhere;font-family:monospace;'
            f'font-size:0.85em">{html.escape(text)}</div>')


def _empty_figure():
    """A blank figure: no axes, no grid (the spectrum plot while it is off)."""
    import plotly.graph_objects as go
    return go.Figure(layout={"template": PLOT_LOOK, "margin": {"l": 0, "r": 0, "t": 0, "b": 0}, "xaxis": {"visible": False},
                            "yaxis": {"visible": False}, "plot_bgcolor": "rgba(0,0,0,0)"})


def contour_html(field) -> str:
    """The λ⁽⁶⁾/k contour as a picture (field.field_picture, drawn once per field): sent once per field, the ★ beside it
    (contour_star) at each move (the picture is 49 kB, the ★ 0.4 kB)."""
    png, _ = field_picture(field)
    return (f'<div class="granstab-contour" style="margin:0 8px">'
            f'<img alt="λ⁽⁶⁾/k over ρ/r and f/(kr)" style="width:100%;display:block" '
            f'src="data:image/png;base64,{base64.b64encode(png).decode()}"></div>')


def contour_star(field, mark) -> str:
    """The current state ★ at `mark` = (ρ/r, f/(kr)) (within the field's grid: the sliders' ranges), drawn over the
    picture of contour_html, the element just above it: a box of the picture's width and aspect ratio moved up by its
    own height, in a strip of no height (viser's HTML elements follow one another without a gap)."""
    png, (x0, y0, x1, y1) = field_picture(field)
    width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")     # the PNG's IHDR
    u = (mark[0] - field.rho_r[0]) / (field.rho_r[-1] - field.rho_r[0])
    v = (mark[1] - field.f_kr[0]) / (field.f_kr[-1] - field.f_kr[0])
    left, top = 100 * (x0 + u * (x1 - x0)), 100 * (1 - y0 - v * (y1 - y0))
    return (f'<div style="height:0;margin:0 8px"><div style="position:relative;width:100%;'
            f'aspect-ratio:{width}/{height};transform:translateY(-100%);pointer-events:none">'
            f'<div class="granstab-star" style="position:absolute;left:{left:.2f}%;top:{top:.2f}%;'
            'transform:translate(-50%,-52%);font-size:26px;line-height:1;color:gold;-webkit-text-stroke:1px black">'
            '★</div></div></div>')


def spectrum_figure(modes, hidden: int = 0):
    """Eigenvalues of sym(𝓗^i) per branch on a signed log scale: ● consistent, ○ not consistent, × rigid
    (`hidden`: how many higher eigenvalues are left out, said in the title). Built in one call from plain data
    (plotly checks each object it is given: trace by trace and a layout update cost 7 ms of a pair's slider move)."""
    import plotly.graph_objects as go
    lam = np.array([m.eigenvalue for m in modes]) if modes else np.zeros(0)
    eps = 1e-4 * (float(np.abs(lam).max()) if lam.size and np.abs(lam).max() > 0 else 1.0)

    def slog(v):
        return np.sign(v) * np.log10(1.0 + np.abs(v) / eps)

    traces = []
    for kind, symbol, colour, pick in (
            ("consistent, negative", "circle", NEGATIVE, lambda m: m.consistent and m.eigenvalue < 0),
            ("consistent, ≥ 0", "circle", OTHER, lambda m: m.consistent and m.eigenvalue >= 0),
            ("not consistent", "circle-open", OTHER, lambda m: not m.consistent and m.label != "rigid"),
            ("rigid", "x-thin-open", OTHER, lambda m: m.label == "rigid")):
        sel = [m for m in modes if pick(m)]          # one colour per trace: its legend entry shows that colour
        if sel:
            traces.append({
                "type": "scatter", "x": [f"branch {m.branch}" for m in sel], "mode": "markers", "name": kind,
                "y": slog(np.array([m.eigenvalue for m in sel])),
                "marker": {"symbol": symbol, "size": 11, "color": colour, "line": {"width": 1.5, "color": colour}},
                "text": [f"λ = {m.eigenvalue:.5g}<br>{m.label}<br>{kind}" for m in sel],
                "hovertemplate": "%{text}<extra></extra>"})
    top = int(np.ceil(float(np.abs(slog(lam)).max()))) if lam.size else 1
    ticks = np.arange(-top, top + 1)
    note = [{"text": f"lowest {len(modes)} shown, {hidden} higher left out", "showarrow": False, "xref": "paper",
             "yref": "paper", "x": 1, "y": 1, "xanchor": "right", "font": {"size": 10}}] if hidden else []
    return go.Figure({"data": traces, "layout": {
        "template": PLOT_LOOK, "margin": {"l": 60, "r": 10, "t": 10, "b": 30}, "annotations": note,
        "legend": {"orientation": "h", "y": 1.08},
        "yaxis": {"title": {"text": "eigenvalue (signed log scale)"}, "tickvals": ticks.tolist(), "zeroline": True,
                  "ticktext": [f"{np.sign(t) * eps * (10 ** abs(t) - 1):.1g}" for t in ticks]}}})
