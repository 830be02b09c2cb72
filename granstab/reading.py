"""Structural reading of scene files: one-line `SceneError`s naming file, entry and field.

Shared by the contact-level reader (scene.py) and the shape-based reader (shapes.py); imports neither.
"""
from __future__ import annotations

import json

import numpy as np

from .vec import rot_dim


class SceneError(ValueError):
    """Invalid scene input; the message is the one line the CLI prints."""


def one_line(text: str) -> str:
    """Collapse whitespace and newlines (a parser's multi-line message) into one line."""
    return " ".join(text.split())


class Reader:
    """Structural checks of one entry, raising one-line errors that name file, entry and field."""

    def __init__(self, source: str, entry: str, data, allowed: set):
        self.source, self.entry, self.data = source, entry, data
        if not isinstance(data, dict):
            self.fail("", f"must be a table, got {type(data).__name__}")
        unknown = sorted(set(data) - allowed)
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
            self.fail(key, f"must be a non-empty string, got {value!r}")
        return value

    def number(self, key: str, default=None) -> float:
        if key not in self.data:
            if default is None:
                self.fail(key, "missing")
            return float(default)
        return self._finite(key, self.data[key], ())

    def array(self, key: str, shape: tuple, default=None) -> np.ndarray:
        """A finite array of the given shape; shape () is a scalar."""
        if key not in self.data:
            if default is None:
                self.fail(key, "missing")
            return np.broadcast_to(np.asarray(default, dtype=float), shape).copy()
        return self._finite(key, self.data[key], shape)

    def _finite(self, key, value, shape):
        def bad():
            want = "a number" if shape == () else f"{'x'.join(map(str, shape))} numbers"
            self.fail(key, f"must be {want}, got {json.dumps(value) if _jsonable(value) else value!r}")

        try:
            arr = np.array(value, dtype=float)
        except (TypeError, ValueError):
            bad()
        if arr.shape != shape or not _all_numbers(value):
            bad()
        if not np.all(np.isfinite(arr)):
            self.fail(key, "must be finite (no nan or inf)")
        return arr


def _jsonable(value) -> bool:
    try:
        json.dumps(value)
        return True
    except (TypeError, ValueError):
        return False


def _all_numbers(value) -> bool:
    """True if every leaf is an int or float (not a bool, not a string that numpy would convert)."""
    if isinstance(value, (list, tuple)):
        return all(_all_numbers(v) for v in value)
    return isinstance(value, (int, float)) and not isinstance(value, bool)


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
        if dim == 2 or np.ndim(rd.data["rolling_stiffness"]) == 0:
            value = rd.array("rolling_stiffness", ())
            if value < 0:
                rd.fail("rolling_stiffness", f"must be >= 0, got {value}")
            rolling = value * np.eye(r)
        else:
            rolling = rd.array("rolling_stiffness", (3, 3))
    return {"k": k, "alpha": alpha, "mu": mu, "rolling_stiffness": rolling}
