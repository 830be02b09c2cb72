"""Figures of the benchmarks: matplotlib's object-oriented API (no pyplot, no global backend), PNG at 110 dpi."""
from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure


def save(fig: Figure, path: Path, **options):
    """Lay out and write the figure as PNG."""
    fig.tight_layout()
    fig.savefig(path, dpi=110, **options)
