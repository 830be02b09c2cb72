"""What the explorer asks of a scene model: two small base classes instead of probes of `kind` and attributes.

`SceneModel`: something the explorer draws and analyses (the slider-driven pair, shapes, contact-level scenes):
`params_used`, `initial_params()`, `build(params) -> Scene`, `bodies(params)`, whether it can be dragged, the
frames it holds (None: one) and its import report. `MapModel`: a packing shown as a map (a scan, a track's frame,
a rigidity folder): not analysed as a whole; particles coloured by `colours`, opened by `cluster(name)`, picked by
`pick(origin, direction)`; its own `headline`, `details`, `legend` and `contact_colours` where it has them (None:
the explorer's default text). Every model in app/scenes.py, app/scanmap.py, app/trackmap.py and
app/rigiditymap.py derives from one of them.
"""
from __future__ import annotations


class SceneModel:
    """A scene the explorer analyses. Subclasses set `kind`, `params_used`, `draggable` and the methods."""

    kind = "scene"
    params_used: tuple = ()
    draggable = False
    frames: list | None = None      # the frames its input holds (None: one); `frame` is the one shown
    frame = None
    report = ""                     # an import or scan report, shown under *Scene* ("" none)

    def initial_params(self) -> dict:
        raise NotImplementedError

    def build(self, P: dict):
        raise NotImplementedError

    def bodies(self, P: dict) -> list:
        raise NotImplementedError

    def dimension(self) -> int:
        """Its dimension before a scene is built (a scene that failed to build)."""
        return 2

    def field_scale(self) -> float:
        """The length the pair's λ⁽⁶⁾ surface is laid out in (the pair's r; 1 for every other scene)."""
        return 1.0

    def adjustments(self, P: dict) -> str:
        """What `build(P)` changed beyond the sliders' values, in one line ("" nothing)."""
        return ""

    def at_frame(self, frame):
        """The model at another of its `frames` (None: the explorer re-reads the file at that frame)."""
        return None


class MapModel(SceneModel):
    """A packing shown as a map: no verdict of its own, a cluster per particle."""

    kind = "scan_map"
    headline: tuple[str, str] | None = None     # (title, badge); None: "click one for its cluster", "scan map"
    details: str | None = None                  # the Verdict tab's text; None: the scan map's
    legend: str | None = None                   # the legend; None: the scan map's
    contact_colours = None                      # (M, 3) uint8 per contact, or None: contacts not drawn

    @property
    def colours(self):
        raise NotImplementedError

    def cluster(self, name: str):
        raise NotImplementedError

    def pick(self, origin, direction) -> str | None:
        raise NotImplementedError
