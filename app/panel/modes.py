"""The Eigenmodes panel (left): the mode menu, *Play* and its animation loop, the spectrum plot; particles coloured
by the selected mode's share."""
from __future__ import annotations

import threading
import time

import numpy as np

from ..figures import empty_figure, spectrum_figure
from ..text import lowest_mode, mode_text, no_mode_text

FRAME = 1 / 20            # s per animation frame
MODES_PER_BRANCH = 24     # the mode picker lists the lowest non-rigid modes of each branch
SPECTRUM_PARTICLES = 30   # above this the spectrum plot is off until asked for (seconds of browser work per update)
SPECTRUM_ASPECT, BLANK_ASPECT = 1.3, 0.1    # height/width of the spectrum plot, and of the blank strip while it is off


def unstable(m, analysis) -> bool:
    """A consistent mode whose eigenvalue is below minus its branch's zero tolerance (what makes a verdict
    unstable, eq:instab)."""
    return m.consistent and m.eigenvalue < -analysis.branches[m.branch].zero_tol


class ModesPanel:
    def __init__(self, ui):
        self.ui = ui
        self._player: threading.Thread | None = None
        self._mode_keys: dict[str, tuple] = {}
        self.selected: tuple | None = None
        self._modes_of = None                     # the revision whose lowest mode was selected
        self._spectrum_default = None             # the scene size the checkbox default was last set for
        self._spectrum_shown = None               # what the spectrum plot shows now (a redraw only on a change)
        ui.stoppers.append(self._join)

    def build(self, gui) -> None:
        ui = self.ui
        self.mode_pick = gui.add_dropdown("Mode", options=["(none)"], initial_value="(none)")
        self.mode_pick.on_update(lambda _: ui.run(self._pick_mode))
        self.play = gui.add_checkbox("Play", initial_value=False)
        self.play.on_update(lambda _: ui.run(self._toggle_play))
        self.amplitude = gui.add_slider("Amplitude (particle sizes)", min=0.0, max=0.6, step=0.01, initial_value=0.35)
        self.speed = gui.add_slider("Speed (cycles/s)", min=0.1, max=2.0, step=0.1, initial_value=0.5)
        self.mode_info = gui.add_markdown("")
        self.show_spectrum = gui.add_checkbox("Spectrum plot", initial_value=True)
        self.show_spectrum.on_update(lambda _: ui.run(self.write, ui.session))
        self.spectrum = gui.add_plotly(empty_figure(), aspect=SPECTRUM_ASPECT, visible=False)

    @property
    def colours_by_mode(self) -> bool:
        """Whether particles can be coloured by their share of a mode: an analysed scene of more than two."""
        s = self.ui.session
        return s.analysis is not None and s.scene.n_particles > 2

    def write(self, s) -> None:
        """The mode menu (the lowest MODES_PER_BRANCH of each branch and every consistent negative one), the plot
        (redrawn only when what it shows changed) and the selected mode."""
        ui, modes = self.ui, s.modes()
        large = s.scene is not None and s.scene.n_particles > SPECTRUM_PARTICLES
        if large != self._spectrum_default:          # a new scene size class: the default for it (off when large)
            self._spectrum_default = large
            with ui.quiet():
                self.show_spectrum.value = not large
        plot = bool(modes) and self.show_spectrum.value and not ui.folded   # a narrow page's drawer: no plotly
        # plot in it (one mounted there and unmounted with a redraw pending was the _redrawFromAutoMarginCount error)
        for h in (self.show_spectrum, self.mode_pick, self.play, self.amplitude, self.speed):
            h.visible = bool(modes)             # no analysis (a large packing, the scan map): nothing to pick or play
        if not modes:
            self.stop_play()
        keys = self._listed(modes)
        self._draw_spectrum(modes, set(keys.values()), plot)
        if self._modes_of != s.revision or self.selected not in keys.values():
            self._modes_of = s.revision               # every change: the lowest consistent mode, whatever was before
            pick = lowest_mode(modes)
            self.selected = (pick.branch, pick.index) if pick else next(iter(keys.values()), None)
        current = next((k for k, v in keys.items() if v == self.selected), "(none)")
        with ui.quiet():
            self.mode_pick.options = list(keys) or ["(none)"]
            self.mode_pick.value = current
        self._describe_mode()

    def _listed(self, modes) -> dict[str, tuple]:
        keys: dict[str, tuple] = {}
        by_branch: dict[int, int] = {}
        for m in sorted((m for m in modes if m.label != "rigid"), key=lambda m: (m.branch, m.eigenvalue)):
            if by_branch.get(m.branch, 0) < MODES_PER_BRANCH or (m.consistent and m.eigenvalue <= 0):
                keys[m.key] = (m.branch, m.index)
                by_branch[m.branch] = by_branch.get(m.branch, 0) + 1
        self._mode_keys = keys
        return keys

    def _draw_spectrum(self, modes, listed: set, plot: bool) -> None:
        if plot:            # mounted when first needed, then never unmounted: unmounting a plot with a plotly redraw
            self.spectrum.visible = True    # pending is the `_redrawFromAutoMarginCount` page error; a blank strip
        if self.spectrum.visible:           # when unused (no empty axes)
            self.spectrum.aspect = SPECTRUM_ASPECT if plot else BLANK_ASPECT
        shown = [m for m in modes if (m.branch, m.index) in listed or (m.label == "rigid" and len(modes) <= 60)]
        drawn = (tuple((m.branch, m.eigenvalue, m.code, m.label) for m in shown), len(modes) - len(shown)) if plot \
            else "empty" if self.spectrum.visible else None
        if drawn is not None and drawn != self._spectrum_shown:   # a redraw costs the browser (and plotly's build and
            self._spectrum_shown = drawn                          # JSON the server): only on a change of what it shows
            self.spectrum.figure = spectrum_figure(shown, hidden=drawn[1]) if plot else empty_figure()

    def _colour_by_mode(self, m) -> None:
        ui, s = self.ui, self.ui.session
        if s.scene is None:
            return
        on = m is not None and ui.display.show["shares"].value and self.colours_by_mode
        names = [b.name for b in s.bodies()]
        index = {n: i for i, n in enumerate(s.scene.names)}
        shares = s.particle_shares(m)[[index[n] for n in names]] if on else None
        ui.view.colour_particles(names, shares, s.map_colours, unstable=m is not None and unstable(m, s.analysis))

    def _describe_mode(self) -> None:
        s = self.ui.session
        m = self._current_mode()
        self._colour_by_mode(m)
        self.mode_info.content = (no_mode_text(s) if m is None else
                                  mode_text(m, s.analysis.branches[m.branch].mask, self.ui.view.colours_by_mode))

    def _current_mode(self):
        if self.selected is None:
            return None
        return next((m for m in self.ui.session.modes() if (m.branch, m.index) == self.selected), None)

    def _pick_mode(self) -> None:
        self.selected = self._mode_keys.get(self.mode_pick.value)
        self._describe_mode()

    # ------------------------------------------------------------------------------------------- animation
    def _toggle_play(self) -> None:
        if self.play.value and (self._player is None or not self._player.is_alive()):
            self._player = threading.Thread(target=self._play_loop, daemon=True)
            self._player.start()

    def stop_play(self) -> None:
        if self.play.value:
            with self.ui.quiet():
                self.play.value = False

    def _play_loop(self) -> None:
        """Animate the selected mode while Play is on (no work at all when paused)."""
        ui, start = self.ui, time.monotonic()
        shown = None                                  # the mode and amplitude whose rest ghost and arrows are drawn
        while not ui.closed and self.play.value:
            with ui.lock:
                try:
                    mode = self._current_mode()
                    if mode is not None and shown != (mode, self.amplitude.value, ui.session.revision):
                        shown = (mode, self.amplitude.value, ui.session.revision)
                        with ui.client.atomic():
                            ui.view.show_rest(ui.session.bodies(), ui.session.mode_bodies(
                                mode, self.amplitude.value, 0.5 * np.pi), ui.session.size)
                    if mode is not None:
                        phase = 2 * np.pi * self.speed.value * (time.monotonic() - start)
                        bodies = ui.session.mode_bodies(mode, self.amplitude.value, phase)
                        with ui.client.atomic():
                            ui.view.animate(bodies)
                except Exception as exc:  # noqa: BLE001
                    ui.show_message(f"animation: {' '.join(str(exc).split())}")
                    break
            time.sleep(FRAME)
        if not ui.closed:
            with ui.lock:
                ui.view.stop_animation()

    def _join(self) -> None:
        """The tab closed: the animation thread ends (joined)."""
        player = self._player
        if player is not None and player is not threading.current_thread():
            player.join(timeout=5.0)
        with self.ui.lock:
            self._player = None
