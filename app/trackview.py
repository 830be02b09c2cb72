"""A tracked folder's controls: the D²min overlay toggle and its legend (under the Frame slider, which is the Scene
tab's own, app/panels.py) and the λ_min(t)/stress(t) plot with the frame now and the events marked (in the left
panel, under the spectrum: no mode is shown on a map).

Callbacks only call the model (app/trackmap.py) and redraw through `refresh`. The plot is a plotly figure like the
spectrum's: shown when a track first opens, then never hidden (a blank strip off a track: unmounting a plot with a
redraw pending is a page error, app/panels.py); it is re-sent only when it changes. The overlay is a point
cloud of dots above the particles, sent only while ticked.
"""
from __future__ import annotations

import numpy as np

from .meshes import digest, to3
from .trackmap import TrackModel

PLOT_ASPECT, BLANK_ASPECT = 1.0, 0.1
EVENT, NOW = "rgba(192, 57, 43, 0.18)", "#2c3e50"
LEGEND = ("**D²min overlay** — dot in each particle: its D²min over the window from this frame to the next "
          "(Falk & Langer, docs/track.md), white 0 → dark blue at the window's 90th percentile and above (the "
          "prediction test's top 10 %); no dot: no window (the last frames) or the particle is gone.")


class TrackPanel:
    """The track's handles in the tab being built (`gui`), its overlay in `scene_api`; `run` is the tab's
    serialising runner (ClientUI.run), `redraw` what a toggle calls after the model changed."""

    def __init__(self, gui, scene_api, run, redraw):
        self.api, self.run, self.redraw = scene_api, run, redraw
        self.toggle = gui.add_checkbox("D²min of the next window", initial_value=False, visible=False)
        self.toggle.on_update(lambda _: self.run(self._toggled))
        self.note = gui.add_markdown("", visible=False)
        self.plot = None                     # add_plot: in the side panel, beside the spectrum
        self._plot_json = None
        self._dots = None                    # digest of the overlay shown (None: none)
        self.model: TrackModel | None = None

    def add_plot(self, gui) -> None:
        """The λ_min(t)/stress(t) plot, hidden until a track opens, in the tab being built: the left panel's, as the
        spectrum plot. In the main panel it threw `_redrawFromAutoMarginCount` on most loads (that panel remounts its
        contents once the page has measured itself, purging a plot whose first redraw is pending)."""
        self.plot = gui.add_plotly(_blank(), aspect=BLANK_ASPECT, visible=False)

    def _toggled(self) -> None:
        if self.model is not None and self.model.show_d2min(self.toggle.value):
            self.redraw()

    def refresh(self, session) -> None:
        """Show the track's handles while one of its frames is the map (a cluster opened from it: hidden)."""
        model = session.model if isinstance(session.model, TrackModel) else None
        self.model = model
        self.toggle.visible = self.note.visible = model is not None
        if model is not None:
            if self.toggle.value != model.overlay:
                self.toggle.value = model.overlay
            self.note.content = LEGEND if model.overlay else "Tick it to see where the packing moved non-affinely next."
        if model is not None or self.plot.visible:
            self._write_plot(model)
        self._draw_dots(model, session)

    def _write_plot(self, model) -> None:
        """The figure, re-sent only when it changed; shown from the first track on, then never hidden."""
        figure = track_figure(model.series()) if model is not None else _blank()
        text = figure.to_json()
        if text != self._plot_json:
            self._plot_json = text
            self.plot.figure = figure
        self.plot.aspect = PLOT_ASPECT if model is not None else BLANK_ASPECT
        self.plot.visible = True

    def _draw_dots(self, model, session) -> None:
        got = None if model is None else model.overlay_points()
        key = None if got is None else digest((session.size,), *got)
        if key == self._dots:
            return
        self._dots = key
        self.api.remove_by_name("/track")
        if got is None or not len(got[0]):
            return
        x, colours = got
        z = 0.12 * session.size if x.shape[1] == 2 else 0.0       # above a 2D particle's top face (0.075 size)
        self.api.add_point_cloud("/track/d2min", points=to3(x, z), colors=colours, point_size=0.5 * session.size,
                                 point_shape="circle", precision="float32")


def _blank():
    import plotly.graph_objects as go
    return go.Figure(layout={"margin": {"l": 0, "r": 0, "t": 0, "b": 0}, "xaxis": {"visible": False},
                            "yaxis": {"visible": False}, "plot_bgcolor": "rgba(0,0,0,0)"})


def track_figure(series: dict):
    """λ_min(t) of the all-unloading and all-loading branches (--whole; else a note) above the event quantity (t),
    frames on x; each event a shaded band from its frame to the next, the frame now a dotted vertical line. Fixed
    margins and no legend (a key above the plot instead): plotly's automatic margins (a legend asks for them even
    inside the plot) redraw the plot once more after it is drawn, and that redraw threw `_redrawFromAutoMarginCount`
    in the page."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots
    t = series["frame"]
    whole = [(name, colour) for name, colour in (("unloading", "#1f77b4"), ("loading", "#c0392b"))
             if np.isfinite(series[name]).any()]
    rows = 2 if whole else 1
    fig = make_subplots(rows=rows, cols=1, shared_xaxes=True, vertical_spacing=0.08)
    hover = [f"frame {f}" + ("" if np.isnan(s) else f" (step {s:g})") for f, s in zip(t, series["step"])]
    for name, colour in whole:
        fig.add_trace(go.Scatter(x=t, y=series[name], mode="lines+markers", name=f"λ_min {name}", text=hover,
                                 line={"color": colour}, hovertemplate="%{text}: %{y:.4g}<extra></extra>"),
                      row=1, col=1)
    fig.add_trace(go.Scatter(x=t, y=series["stress"], mode="lines+markers", name=series["quantity"], text=hover,
                             line={"color": "#2c3e50"}, hovertemplate="%{text}: %{y:.4g}<extra></extra>"),
                  row=rows, col=1)
    for start, end in series["events"]:
        fig.add_vrect(x0=start, x1=end, fillcolor=EVENT, line_width=0, row="all", col=1)
    fig.add_vline(x=series["now"], line={"color": NOW, "width": 2, "dash": "dot"}, row="all", col=1)
    fig.update_layout(margin={"l": 60, "r": 10, "t": 30, "b": 45}, showlegend=False)
    key = "   ".join(f'<span style="color:{colour}">● λ_min all-{name}</span>' for name, colour in whole)
    fig.add_annotation(text=key or "λ_min(t): not tracked (granstab track --whole)", showarrow=False,
                       xref="paper", yref="paper", x=0.5, y=1.0, yanchor="bottom", font={"size": 11})
    fig.update_xaxes(automargin=False, **({"tickvals": list(t)} if len(t) <= 12 else {}))
    fig.update_yaxes(automargin=False)
    fig.update_xaxes(title_text="frame (shaded: a stress drop event)", title_standoff=4, row=rows, col=1)
    if whole:
        fig.update_yaxes(title_text="λ_min", row=1, col=1)
    fig.update_yaxes(title_text=series["quantity"].replace("_", " "), row=rows, col=1)
    return fig
