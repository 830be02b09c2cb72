"""Structural reading of scene files: one-line `SceneError`s naming file, entry and field, and the value checks
(types, shapes, finite, within MAX_MAGNITUDE) shared by the table-at-a-time `Reader` (top level, defaults, shape
entries) and the column-wise readers of io/entries.py; and the other one-line conditions every room may raise (a
missing optional dependency, an interruption). Imports no other room but model.
"""
from __future__ import annotations

import importlib
import json
import math

import numpy as np

from .tolerances import MAX_MAGNITUDE


class SceneError(ValueError):
    """Invalid scene input; the message is the one line the CLI prints."""


class MissingExtra(ImportError):
    """An optional dependency that is not installed; the message names the extra to install (one line)."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C; the message says what was kept and how to resume (the one line the CLI prints)."""


def require(module: str, extra: str, purpose: str):
    """`module` imported, or MissingExtra naming the extra that brings it (before any work or output starts)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtra(f"granstab: {module.split('.')[0]} is needed for {purpose} and is not installed: "
                           f"pip install \"granstab[{extra}]\" (in a checkout: pip install -e \".[{extra}]\")") \
            from None


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
