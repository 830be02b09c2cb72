"""The *Display* tab (what is drawn, arrow length, the 2D view) and the legend under the tabs."""
from __future__ import annotations

from ..camera import OBLIQUE, TOP, above_sheet, camera_pose, fit_distance
from ..text import MAP_LEGEND, legend_markdown
from ..views import MESH_MAX

LINES_MAX = 5_000         # contacts: above this force lines and normals are off until asked for (seconds per frame
                          # in a browser without a GPU: 10⁴ disks 0.38 s, 10⁵ disks 10 s)


class DisplayPanel:
    def __init__(self, ui):
        self.ui = ui
        self._lines_default = None                # the scene size class the force-line default was last set for
        self._view_picked = False                 # the user chose a 2D view: kept over each scene's default view

    def build(self, gui) -> None:
        ui = self.ui
        self.show = {key: gui.add_checkbox(label, initial_value=True) for key, label in (
            ("forces", "Force arrows"), ("normals", "Contact normals"), ("osculating", "Osculating circles"),
            ("surface", "λ⁽⁶⁾ height surface (pair)"), ("shares", "Colour particles by the selected mode"))}
        self.force_scale = gui.add_slider("Arrow length ×", min=0.2, max=3.0, step=0.1, initial_value=1.0)
        for h in (*self.show.values(), self.force_scale):
            h.on_update(lambda _: ui.run(self._display))
        self.camera_view = gui.add_dropdown("View", options=[TOP, OBLIQUE], initial_value=TOP)
        self.camera_view.on_update(self._pick_view)
        gui.add_button("Reset view").on_click(lambda _: ui.run(self.set_camera))

    def build_legend(self, gui) -> None:
        self.legend = gui.add_markdown("")

    def write(self, s) -> None:
        """The size class's defaults (lines off when many contacts) and which ticks apply (called in ui.quiet)."""
        many = s.scene is not None and s.scene.n_contacts > LINES_MAX
        if many != self._lines_default:           # a new size class: its default (lines off when many)
            self._lines_default = many
            for key in ("forces", "normals"):
                self.show[key].value = self.ui.view.options[key] = not many
        self.show["surface"].visible = s.kind == "two_particle"
        self.show["shares"].visible = self.ui.modes.colours_by_mode    # a pair's two particles share a mode evenly
        self.camera_view.visible = s.scene_dim == 2                # a 3D scene has one view: Reset view

    def write_legend(self, s, legend: dict) -> None:
        if s.on_map:
            self.legend.content = s.model.legend or MAP_LEGEND
            return
        self.legend.content = legend_markdown(s.scene, self.ui.view.options, legend, bool(self._lines_default),
                                              LINES_MAX, MESH_MAX)

    def camera(self, s) -> None:
        """The camera for a newly opened scene: its default 2D view unless the user picked one, fitted."""
        if not self._view_picked:       # the pair opens oblique: its λ⁽⁶⁾ height surface is flat seen from above
            with self.ui.quiet():
                self.camera_view.value = OBLIQUE if s.field() is not None else TOP
        self.set_camera()

    def _display(self) -> None:
        view = self.ui.view
        view.options.update({key: h.value for key, h in self.show.items()})
        view.options["force_scale"] = self.force_scale.value
        if not view.options["surface"]:
            view.clear_field()
        self.ui.refresh(particles=False)

    def _pick_view(self, _) -> None:
        """The View menu: the user's choice, noted as it arrives (a scene opening meanwhile keeps it), then shown."""
        if not self.ui.echo():
            self._view_picked = True
        self.ui.run(self.set_camera)

    def set_camera(self) -> None:
        ui, s = self.ui, self.ui.session
        pose = above_sheet(camera_pose(s, self.camera_view.value == OBLIQUE and s.scene_dim == 2,
                                       ui.view.options["surface"], lambda w, h: fit_distance(w, h, ui.client.camera)),
                           ui.client.camera)
        for key, value in pose.items():
            setattr(ui.client.camera, key, value)
