"""The explorer's pictures: the λ⁽⁶⁾ contour with its ★ (HTML around field.field_picture) and the spectrum plot
(plotly, built from plain data).
"""
from __future__ import annotations

import base64

import numpy as np

from .field import field_picture

NEGATIVE, OTHER = "#c0392b", "#2c3e50"      # spectrum markers: consistent negative eigenvalues, the rest
PLOT_LOOK = {"layout": {"plot_bgcolor": "#E5ECF6", "font": {"color": "#2a3f5f"}, "xaxis": {"gridcolor": "white"},
                        "yaxis": {"gridcolor": "white", "zerolinecolor": "white"}}}
                          # plotly's default look in 0.2 kB: its default template is 7.1 kB of the spectrum's 8.1 kB,
                          # sent again with every slider move that changes an eigenvalue


def empty_figure():
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


def contour_star(field, mark, colour: str = "gold") -> str:
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
            f'transform:translate(-50%,-52%);font-size:26px;line-height:1;color:{colour};-webkit-text-stroke:1px black">'
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
