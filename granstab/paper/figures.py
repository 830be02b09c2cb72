"""Helpers shared by the report writers: number formats, CSV and figure output, the claim record."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

LABEL = {"mu": "μ", "alpha": "α", "beta_deg": "β (deg)", "f_over_k": "f/k", "rho_over_r": "ρ/r"}
STYLE = {"svg.hashsalt": "granstab", "svg.fonttype": "none", "font.size": 10, "axes.titlesize": 11,
         "axes.labelsize": 10, "legend.fontsize": 8.5, "figure.dpi": 100}



def g(x, digits: int = 6) -> str:
    """A number for the report."""
    return f"{x:.{digits}g}"


def bound(x: float) -> str:
    """A round-off level error as an upper bound (stable across machines): '< 1e-14'."""
    if x == 0:
        return "= 0"
    exponent = int(np.ceil(np.log10(x)))
    return f"< 1e{exponent}" if x > 0 else "0"


def save(fig: Figure, out: Path, stem: str) -> list[Path]:
    FigureCanvasAgg(fig)
    paths = [out / f"{stem}.png", out / f"{stem}.svg"]
    fig.savefig(paths[0], dpi=150, metadata={"Software": None})
    fig.savefig(paths[1], metadata={"Date": None, "Creator": None})
    return paths


def write_csv(path: Path, header: list[str], rows) -> Path:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for row in rows:
            w.writerow([f"{v:.12g}" if isinstance(v, (float, np.floating)) else v for v in row])
    return path


def span(lo, hi) -> str:
    return f"{lo}" if lo == hi else f"{lo}–{hi}"


def cell(text) -> str:
    """Markdown table cell: pipes escaped."""
    return str(text).replace("|", "\\|")


def mask_text(mask) -> str:
    return "".join("+" if v > 0 else "-" if v < 0 else "0" for v in mask)


def section() -> tuple[list, object]:
    """The lines of a REPRODUCTION.md section and the function that appends one."""
    lines = []
    return lines, lines.append


def claim(cid, section, statement, paper, ours, verdict="reproduced", note="") -> dict:
    return {"id": cid, "section": section, "claim": statement, "paper": paper, "ours": ours, "verdict": verdict,
            "note": note}

