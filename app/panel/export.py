"""The *Export* tab: the scene, the analysis and the λ⁽⁶⁾ contour as downloads."""
from __future__ import annotations


class ExportPanel:
    def __init__(self, ui):
        self.ui = ui

    def build(self, gui) -> None:
        s = self.ui.session
        gui.add_markdown("Download the current scene (reloads to the same analysis), the analysis, the contour.")
        self.exports = {}
        for key, label, fn in (("scene", "Scene file (.json)", s.export_scene),
                               ("analysis", "Analysis (.json)", s.export_analysis),
                               ("contour", "λ⁽⁶⁾ contour (.png)", s.export_contour)):
            self.exports[key] = gui.add_button(label)
            self.exports[key].on_click(self._download(fn))

    def write(self, s) -> None:
        self.exports["contour"].visible = s.kind == "two_particle"

    def _download(self, fn):
        ui = self.ui

        def _(event):
            def send():
                filename, content = fn()
                (event.client or ui.client).send_file_download(filename, content, save_immediately=True)
            ui.run(send)
        return _
