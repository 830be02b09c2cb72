"""Numbers and tables for BENCHMARKS.md, and a progress bar on stderr."""
from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm


def fmt_t(seconds: float) -> str:
    """A duration: µs, ms or s."""
    if seconds is None or not np.isfinite(seconds):
        return "—"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.0f} µs"
    if seconds < 1:
        return f"{seconds * 1e3:.1f} ms"
    return f"{seconds:.2f} s"


def fmt_long(seconds) -> str:
    """A possibly very long duration (extrapolations): s, min, h or days."""
    if seconds is None:
        return "—"
    if seconds < 120:
        return fmt_t(seconds)
    if seconds < 3600:
        return f"{seconds / 60:.0f} min"
    if seconds < 86400 * 3:
        return f"{seconds / 3600:.0f} h"
    return f"{seconds / 86400:,.0f} days"


def fmt_e(x) -> str:
    """An error: one significant digit and the exponent."""
    return "—" if x is None or not np.isfinite(x) else f"{x:.1e}"


def table(header: list, rows: list) -> str:
    """A Markdown table."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def progress(total: int, desc: str):
    """A tqdm bar on stderr that disappears when done."""
    return tqdm(total=total, desc=desc, leave=False, mininterval=0.5)
