"""The *Scene* tab: what is open (preset, file, path, frame, a map's cluster) and its parameter sliders."""
from __future__ import annotations

from pathlib import Path

from ..params import PARAMS
from ..text import info_markdown, preset_label
from ..trackview import TrackPanel


def frame_axis(frames: list) -> tuple:
    """(min, max, step) of the Frame slider: the frames' own numbers where they are integers evenly spaced (a
    track's 0 … 30: its slider ran 1 … 31 over them), else their positions 1 … N."""
    steps = {b - a for a, b in zip(frames, frames[1:])}
    if all(isinstance(f, int) for f in frames) and len(steps) == 1 and min(steps) > 0:
        return frames[0], frames[-1], steps.pop()
    return 1, len(frames), 1


class ScenePanel:
    """Preset menu, upload, typed path, frame slider, track panel, *Analyse*, cluster box, sliders, *Reset*."""

    def __init__(self, ui):
        self.ui = ui
        self._listening = False                   # a scene click callback is registered (maps only)

    def build(self, gui) -> None:
        ui, s = self.ui, self.ui.session
        self.preset = gui.add_dropdown("Preset", options=self._options(s) or ["(none)"],
                                       initial_value=preset_label(self._option()))
        self.preset.on_update(ui.picking(self._load_preset))
        self.upload = gui.add_upload_button("Open scene file", mime_type="*/*")
        self.upload.on_upload(ui.picking(self._upload))
        self.path = gui.add_text("Path on server", initial_value="", disabled=not s.typed_paths)
        self.path.on_update(ui.after_typing(self._open_path))
        self.frame = gui.add_slider("Frame", min=1, max=2, step=1, initial_value=1, visible=False)
        self.frame.on_update(lambda _: ui.run(self._pick_frame))
        self.track = TrackPanel(gui, ui.client.scene, ui.run, ui.refresh)     # a tracked folder's frame
        self.analyse = gui.add_button("Analyse the whole packing", visible=False)
        self.analyse.on_click(lambda _: ui.run(self._analyse))
        self.cluster_name = gui.add_text("Open cluster of", initial_value="", visible=False)
        self.cluster_name.on_update(ui.after_typing(lambda: self._open_cluster(self.cluster_name.value.strip())))
        self.back = gui.add_button("Back to the map", visible=False)
        self.back.on_click(lambda _: ui.run(self._back_to_map))
        self._typing = ui.after_typing(self._clamp_typed)     # a typed value out of range: clamped after a pause
        self.sliders = {}
        for key, p in PARAMS.items():
            # what each slider is stands in the scene line below them
            h = gui.add_slider(p.label, min=p.lo, max=p.hi, step=p.step, initial_value=p.default)
            h.on_update(lambda _: ui.slider_moved())
            self.sliders[key] = h
        self.reset = gui.add_button("Reset", visible=False)
        self.reset.on_click(lambda _: ui.run(self._reset_poses))
        self.info = gui.add_markdown("")

    def _option(self) -> str:
        s = self.ui.session
        options = s.presets()
        return s.preset if s.preset in options else (options[0] if options else "(none)")

    def _options(self, s) -> list[str]:
        """The menu's entries: each preset by its title (text.PRESETS), the open scene's own name last if it is no
        preset; `self.stems` maps an entry back to the name the session knows."""
        names = s.presets()
        if s.preset is not None and s.preset not in names:
            names = [*names, s.preset]
        self.stems = {preset_label(n): n for n in names}
        return list(self.stems)

    def write(self, s) -> None:
        """Slider visibility/values, the preset list, the frame and the map's controls follow the session, without
        firing callbacks (called in ui.quiet)."""
        ui = self.ui
        options = self._options(s)
        if tuple(self.preset.options) != tuple(options):
            self.preset.options = options
        ui.show_value("preset", self.preset, preset_label(s.preset))
        used = set(s.used_params)
        for key, h in self.sliders.items():
            h.visible = key in used
            if key in used:
                p = s.param(key)                     # k follows the scene's scale (params.Param.around)
                if (h.min, h.max, h.step) != (p.lo, p.hi, p.step):
                    h.min, h.max, h.step = p.lo, p.hi, p.step
                ui.show_value(key, h, s.params[key])
        self.reset.visible = s.resettable
        frames = s.model.frames
        self.frame.visible = bool(frames) and len(frames) > 1
        if self.frame.visible:
            lo, hi, step = frame_axis(frames)
            if (self.frame.min, self.frame.max, self.frame.step) != (lo, hi, step):
                self.frame.min, self.frame.max, self.frame.step = lo, hi, step
            at = s.model.frame if s.model.frame in frames else frames[0]
            ui.show_value("frame", self.frame, at if lo == frames[0] else frames.index(at) + 1)
        self.analyse.visible = s.deferred
        self.cluster_name.visible, self.back.visible = s.on_map, s.map is not None
        if s.on_map != self._listening:             # scene clicks are only listened to on a map
            self._listening = s.on_map
            if s.on_map:
                ui.client.scene.on_click()(lambda event: ui.run(self._map_click, event))
            else:
                ui.client.scene.remove_click_callback()

    def write_info(self, s, verdict) -> None:
        self.info.content = info_markdown(s, verdict)

    # ------------------------------------------------------------------------------------------- callbacks
    def _apply_sliders(self) -> None:
        """The sliders' values, taken as typed. A value outside its slider's range is a number still being typed
        (the box sends "0" on the way to "0.5": clamped to ρ/r's 0.2 and written back, it became 0.52): it waits
        TYPING_PAUSE, and is clamped only if it still stands then (`_clamp_typed`)."""
        ui, s = self.ui, self.ui.session
        values = {key: self.sliders[key].value for key in s.used_params}
        ui.shown.update(values)              # what the page shows: not written back (see Dispatch.show_value)
        typing = {key for key, v in values.items() if not s.param(key).lo <= v <= s.param(key).hi}
        if typing:
            self._typing(None)
        if s.set_params(**{key: v for key, v in values.items() if key not in typing}):
            ui.refresh()

    def _clamp_typed(self) -> None:
        """A typed value out of range that still stands after the pause: clamped, and the box shows the clamp."""
        ui, s = self.ui, self.ui.session
        for key in s.used_params:
            p, h = s.param(key), self.sliders[key]
            if not p.lo <= h.value <= p.hi:
                ui.shown[key] = None                 # written back by the refresh: the clamp is the session's
                s.set_params(**{key: h.value})
        ui.refresh()

    def _load_preset(self) -> None:
        ui = self.ui
        ui.shown["preset"] = self.preset.value
        name = self.stems.get(self.preset.value, self.preset.value)
        if name == ui.session.preset:
            return
        if name not in ui.session.presets():          # the menu's options only (a forged value is no path)
            ui.show_message(f"{name}: not a preset of this server")
            return
        self._open(name, lambda: ui.session.load_preset(name))

    def _upload(self) -> None:
        """Open the file sent from the page; one that cannot be opened (over MAX_UPLOAD: refused unread) gets a red
        notice with the reason beside viser's own notice of the transfer (docs/viser-gaps.md: uploads)."""
        ui, up = self.ui, self.upload.value
        if not self._open(Path(up.name).name, lambda: ui.session.load_upload(up.name, up.content)):
            ui.client.add_notification(f"Not opened: {Path(up.name).name}", ui.session.error, color="red",
                                       with_close_button=True, auto_close_seconds=None)

    def _open_path(self) -> None:
        ui, path = self.ui, self.path.value.strip()
        if not path or path == ui.session.preset:
            return
        self._open(path, lambda: ui.session.open_typed(path))

    def _open(self, name: str, opener) -> bool:
        """Open a scene (`opener()`: whether it opened), saying so meanwhile; the page drawn anew, the camera
        fitted to it."""
        ui = self.ui
        ui.loading(name)
        ok = opener()
        ui.view.key = None
        ui.refresh(camera=ok)
        return ok

    def _pick_frame(self) -> None:
        ui = self.ui
        frames = ui.session.model.frames
        ui.shown["frame"] = value = int(round(self.frame.value))
        numbered = frame_axis(frames)[0] == frames[0]
        if not numbered and not 1 <= value <= len(frames) or numbered and value not in frames:
            return                                   # a number still being typed (Frame 1… of 0…30: "1" of "12")
        if ui.session.set_frame(value if numbered else frames[value - 1]):
            ui.refresh()

    def _open_cluster(self, name: str) -> None:
        ui = self.ui
        if name and ui.session.open_cluster(name):
            ui.view.key = None
            ui.refresh(camera=True)
        elif name:
            ui.show_message(ui.session.error)

    def _back_to_map(self) -> None:
        ui = self.ui
        if ui.session.back_to_map():
            ui.view.key = None
            ui.refresh(camera=True)

    def _map_click(self, event) -> None:
        """A click in the scene while a map is shown: open the cluster of the particle under it."""
        name = self.ui.session.pick(event.ray_origin, event.ray_direction)
        if name is not None:
            self._open_cluster(name)

    def _analyse(self) -> None:
        self.ui.session.analyse()
        self.ui.refresh()

    def _reset_poses(self) -> None:
        self.ui.session.reset_poses()
        self.ui.refresh()
