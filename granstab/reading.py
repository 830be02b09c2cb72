"""Structural reading of scene files: one-line `SceneError`s naming file, entry and field, and the value checks
(types, shapes, finite, within MAX_MAGNITUDE) shared by the table-at-a-time `Reader` (top level, defaults, shape
entries) and the column-wise readers of tables.py. Imports neither scene.py nor shapes.py.
"""
from __future__ import annotations

import json
import math

import numpy as np

from .tolerances import MAX_MAGNITUDE
from .vec import rot_dim


class SceneError(ValueError):
    """Invalid scene input; the message is the one line the CLI prints."""


def one_line(text) -> str:
    """Collapse whitespace and newlines (a parser's multi-line message) into one line."""
    return " ".join(str(text).split())


class DuplicateKeys(dict):
    """A JSON object that had a key twice (`duplicate`); fileformat.parse_json makes one only when the key count
    says there is one, and every reader rejects it naming the entry and the key."""

    duplicate: str = ""


def describe(value) -> str:
    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def all_numbers(value) -> bool:
    """True if every leaf is an int or float (not a bool, not a string that numpy would convert)."""
    if isinstance(value, (list, tuple)):
        return all(all_numbers(v) for v in value)
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def value_problem(value, shape: tuple) -> str | None:
    """Why `value` is not a finite float array of `shape` (shape () is a scalar), or None."""
    want = "a number" if shape == () else f"{'x'.join(map(str, shape))} numbers"
    try:
        arr = np.array(value, dtype=float)
    except OverflowError:
        return f"a number beyond float64's range ({magnitude_message(math.inf)})"
    except (TypeError, ValueError):
        return f"must be {want}, got {describe(value)}"
    if arr.shape != shape or not all_numbers(value):
        return f"must be {want}, got {describe(value)}"
    if not np.all(np.isfinite(arr)):
        return "must be finite (no nan or inf)"
    return None


def magnitude_message(value: float) -> str:
    return (f"|value| = {value:.3g} exceeds {MAX_MAGNITUDE:.0e}: H and its checks multiply up to six input "
            "numbers, which must stay below float64's 1.8e308 (change units)")


def row_problem(arr: np.ndarray):
    """(first row, message) of an (n, k) array with a non-finite entry or one above MAX_MAGNITUDE, or None."""
    if arr.size == 0 or (arr.max() <= MAX_MAGNITUDE and arr.min() >= -MAX_MAGNITUDE):   # NaN fails both: looked at
        return None                                                                     # below, as every offender
    ok = np.abs(arr) <= MAX_MAGNITUDE
    i = first(~ok.all(axis=1))
    worst = np.abs(arr[i]).max()
    return i, "must be finite (no nan or inf)" if not np.isfinite(worst) else magnitude_message(worst)


def first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


class Reader:
    """Structural checks of one small table (the top level, `defaults`, a shape entry), one-line errors naming
    file, entry and field. Arrays of entries (particles, contacts) are read column-wise by tables.py instead."""

    def __init__(self, source: str, entry: str, data, allowed: set):
        self.source, self.entry, self.data = source, entry, data
        if not isinstance(data, dict):
            self.fail("", f"must be a table, got {type(data).__name__}")
        if isinstance(data, DuplicateKeys):
            self.fail(data.duplicate, "duplicate key (JSON would keep only the last value)")
        unknown = sorted(set(data) - allowed, key=str)
        if unknown:
            self.fail(unknown[0], f"unknown key (allowed: {', '.join(sorted(allowed))})")

    def fail(self, key: str, msg: str):
        where = f"{self.entry}: {key}" if key else self.entry
        raise SceneError(one_line(f"{self.source}: {where}: {msg}"))

    def has(self, key: str) -> bool:
        return key in self.data

    def text(self, key: str, default=None) -> str:
        if key not in self.data:
            if default is None:
                self.fail(key, "missing")
            return default
        value = self.data[key]
        if not isinstance(value, str) or not value:
            self.fail(key, f"must be a non-empty string, got {describe(value)}")
        return value

    def number(self, key: str, default=None) -> float:
        return float(self.array(key, (), default))

    def array(self, key: str, shape: tuple, default=None) -> np.ndarray:
        """A finite array of the given shape (shape () is a scalar) within the accepted magnitude."""
        if key not in self.data:
            if default is None:
                self.fail(key, "missing")
            return np.broadcast_to(np.asarray(default, dtype=float), shape).copy()
        problem = value_problem(self.data[key], shape)
        if problem:
            self.fail(key, problem)
        arr = np.array(self.data[key], dtype=float)
        if np.abs(arr).max(initial=0.0) > MAX_MAGNITUDE:
            self.fail(key, magnitude_message(float(np.abs(arr).max())))
        return arr


def read_law(rd: Reader, dim: int, base: dict) -> dict:
    """k, alpha, mu (k, alpha > 0, mu >= 0) and rolling_stiffness (scalar × I or 3x3) of an entry, defaults `base`."""
    r = rot_dim(dim)
    k = rd.number("k", base["k"])
    alpha = rd.number("alpha", base["alpha"])
    mu = rd.number("mu", base["mu"])
    if k <= 0:
        rd.fail("k", f"must be > 0, got {k}")
    if alpha <= 0:
        rd.fail("alpha", f"must be > 0, got {alpha}")
    if mu < 0:
        rd.fail("mu", f"must be >= 0, got {mu}")
    rolling = base["rolling_stiffness"]
    if "rolling_stiffness" in rd.data:
        if dim == 2 or not isinstance(rd.data["rolling_stiffness"], list):
            value = rd.array("rolling_stiffness", ())
            if value < 0:
                rd.fail("rolling_stiffness", f"must be >= 0, got {value}")
            rolling = value * np.eye(r)
        else:
            rolling = rd.array("rolling_stiffness", (3, 3))
    return {"k": k, "alpha": alpha, "mu": mu, "rolling_stiffness": rolling}
