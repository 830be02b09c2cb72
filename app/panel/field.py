"""The λ⁽⁶⁾ field panel (the pair only): the contour picture, drawn once per field, and the ★ of the state now."""
from __future__ import annotations

from ..figures import contour_html, contour_star
from ..text import field_note, lowest_mode


class FieldPanel:
    def __init__(self, ui):
        self.ui = ui
        self._contour_of = None                # the field the picture shows

    def build(self, gui, side) -> None:
        """Docked above the Eigenmodes panel `side` (docking remounts a panel's contents: docked first)."""
        self.field_panel = gui.add_panel()
        self.field_panel.dock_above(side)
        with self.field_panel.add_tab("λ⁽⁶⁾ field"):
            self.field_note = gui.add_markdown("")
            self.contour = gui.add_html("")        # a picture, not a plotly plot: this panel comes and goes
            self.star = gui.add_html("")           # the current state over it (contour_star)

    def write_visibility(self, s) -> None:
        self.field_panel.visible = s.kind == "two_particle"

    def write(self, s) -> None:
        field = s.field()
        if field is None:
            return
        lam = s.rolling_eigenvalue()
        worst = lowest_mode(s.modes())
        other = (worst.key.split(",")[0] if s.verdict == "unstable" and worst is not None and (lam is None or lam >= 0)
                 else None)
        self.field_note.content = field_note(field.alpha, lam, s.zero_tolerance(), other)
        if self._contour_of is not field:                 # the picture: once per field (α, rolling stiffness)
            self._contour_of = field
            self.contour.content = contour_html(field)
        self.star.content = contour_star(field, (s.params["rho_r"], s.params["f_kr"]), "red" if other else "gold")
