"""The headline (the coloured verdict, the scene's title, the reason) and the *Verdict* tab (metric menu, the table
of the verdict and its bounds, *Check other metrics*)."""
from __future__ import annotations

import threading
from pathlib import Path

from ..text import badge, details_markdown, headline_html, metric_row, notation_html
from .uncertainty import BandControl

DOCS = Path(__file__).resolve().parents[2] / "docs"


class VerdictPanel:
    def __init__(self, ui):
        self.ui = ui
        self._checking: int | None = None         # the revision whose metric family is being checked

    def build_headline(self, gui) -> None:
        self.headline = gui.add_html("")
        gui.add_html(notation_html(notation()))       # static: sent once, folded until asked for

    def build(self, gui) -> None:
        ui = self.ui
        self.metric = gui.add_dropdown("Metric", options=["L", "inertia"], initial_value="L", visible=False,
                                       hint="L: rotations scaled by the mean contact radius; inertia: the "
                                            "kinetic-energy metric (λ = ω², frequencies), for scenes with masses")
        self.metric.on_update(lambda _: ui.run(self._set_metric))
        self.details = gui.add_markdown("")
        check = gui.add_button("Check other metrics")
        check.on_click(lambda _: ui.run(self._check_metrics))
        self.band = BandControl(ui, gui)                  # issue 42: the force uncertainty (panel/uncertainty.py)

    def write_controls(self, s) -> None:
        self.metric.visible = len(s.metric_choices) > 1
        self.ui.show_value("metric", self.metric, s.metric)

    def write(self, s) -> str | None:
        """The headline and the table; returns the badge (the Scene tab's text names a map by it)."""
        verdict, title, reason = badge(s)
        self.headline.content = headline_html(verdict, title, reason, s.revision)
        self.ui.show_message(s.error)
        row = metric_row(s.metric, s.metrics, s.revision, self._checking == s.revision,
                         s.scene is not None and s.scene.mass is not None, s.family_estimate())
        self.details.content = details_markdown(s, row)
        self.band.write(s)
        return verdict

    def _set_metric(self) -> None:
        ui = self.ui
        ui.shown["metric"] = self.metric.value
        if ui.session.set_metric(self.metric.value):
            ui.refresh()

    def _check_metrics(self) -> None:
        """*Check other metrics*: says at once that it runs and about how long, then runs off the lock (a slider
        stays live); the result is kept only if nothing moved meanwhile (Session.keep_metrics), else the row says
        the check was superseded."""
        ui, s = self.ui, self.ui.session
        if s.scene is None or s.analysis is None or self._checking == s.revision:
            return
        self._checking = s.revision
        ui.write_verdict()
        ui.client.flush()
        threading.Thread(target=self._family, args=(s.scene, s.revision), daemon=True).start()

    def _family(self, scene, revision: int) -> None:
        from .. import pools  # looked up at each call (a test replaces it)
        try:
            metrics = pools.metric_family(scene)
        except Exception as exc:  # noqa: BLE001 — shown in the page
            self.ui.run(self.ui.show_message, f"Check other metrics: {' '.join(str(exc).split())}")
            metrics = None
        self.ui.run(self._family_done, metrics, revision)

    def _family_done(self, metrics, revision: int) -> None:
        if self._checking == revision:
            self._checking = None
        if metrics is not None and self.ui.session.keep_metrics(metrics, revision) is not None:
            self.ui.write_verdict()


def notation() -> str:
    """The Notation section of docs/equations.md (where the checkout has it), else where to find it."""
    path = DOCS / "equations.md"
    text = path.read_text(encoding="utf-8") if path.is_file() else ""
    start = text.find("## Notation")
    if start < 0:
        return "See docs/equations.md#notation in granstab's source."
    end = text.find("\n## ", start + 3)
    return text[start + len("## Notation"):end if end > 0 else None].strip()
