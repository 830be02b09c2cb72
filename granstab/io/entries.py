"""Arrays of tables (a scene's `particles`, `contacts`) read column by column, with one-line errors.

A column is one field of every entry, converted to a float array by numpy in C (`map(itemgetter)` then
`np.array`): no per-entry Python loop on the way in. Only a column that does not convert cleanly (a missing
field, a string, a wrong length, a boolean) is walked entry by entry, to name the first bad entry in the
error: "<file>: <entry>: <field>: <what is wrong>". `TextTable` reads parsed TOML/JSON (lists of dicts);
`ArrayTable` the same schema stored as whole arrays (NPZ), where a field is present for every entry or none.
"""
from __future__ import annotations

from itertools import chain, compress, repeat
from operator import itemgetter, methodcaller

import numpy as np

from ..model.errors import (
    DuplicateKeys,
    SceneError,
    describe,
    first,
    magnitude_message,
    one_line,
    row_problem,
    value_problem,
)
from ..model.tolerances import MAX_MAGNITUDE
from ..model.vec import rot_dim


def numeric(values, n: int, shape: tuple) -> np.ndarray | None:
    """The fast path: `values` (a list) as an (n, *shape) float array, or None where numpy cannot do it cleanly
    (strings, ragged rows, objects, booleans — numpy would turn a boolean among numbers into 0 or 1, so the
    leaves' types are looked at too, in C: chain and map)."""
    try:
        arr = np.array(values)
    except (TypeError, ValueError, OverflowError):
        return None
    if arr.dtype.kind not in "fiu" or arr.shape != (n, *shape):
        return None
    leaves = values
    for _ in shape:
        leaves = chain.from_iterable(leaves)
    if bool in set(map(type, leaves)):
        return None
    return arr.astype(float, copy=False)


class TextTable:
    """The entries `items` (a list of dicts) of the array `name` of a parsed scene file.

    label(i) names entry i in errors (default "name[i]")."""

    def __init__(self, source: str, name: str, items, allowed: set):
        self.source, self.name, self.items = source, name, items
        self.label = lambda i: f"{name}[{i}]"
        if not isinstance(items, list):
            raise SceneError(f"{source}: scene: {name}: must be an array of tables")
        if set(map(type, items)) - {dict}:
            i = next(i for i, item in enumerate(items) if type(item) is not dict)
            if isinstance(items[i], DuplicateKeys):
                self.fail(i, items[i].duplicate, "duplicate key (JSON would keep only the last value)")
            self.fail(i, "", f"must be a table, got {type(items[i]).__name__}")
        kinds = set(map(frozenset, items))                 # usually one: every entry has the same fields
        self.everywhere = frozenset.intersection(*kinds) if kinds else frozenset()
        keys = frozenset.union(*kinds) if kinds else frozenset()
        unknown = sorted(keys - allowed, key=str)
        if unknown:
            i = next(i for i, item in enumerate(items) if unknown[0] in item)
            self.fail(i, unknown[0], f"unknown key (allowed: {', '.join(sorted(allowed))})")

    def __len__(self) -> int:
        return len(self.items)

    def fail(self, i: int, key: str, msg: str):
        where = f"{self.label(i)}: {key}" if key else self.label(i)
        raise SceneError(one_line(f"{self.source}: {where}: {msg}"))

    def present(self, key: str) -> np.ndarray:
        if key in self.everywhere:
            return np.ones(len(self.items), bool)
        return np.fromiter(map(methodcaller("__contains__", key), self.items), bool, len(self.items))

    def _values(self, key: str, required: bool, where=None):
        have = self.present(key)
        if required and not have.all():
            self.fail(first(~have), key, "missing")
        if where is not None:
            have &= where
        if have.all():
            return list(map(itemgetter(key), self.items)), have
        return list(map(itemgetter(key), compress(self.items, have))), have

    def matrix_form(self, key: str) -> np.ndarray:
        """Entries whose `key` is given as a list (a matrix) rather than a number, (n,) bool."""
        return np.fromiter(map(isinstance, map(methodcaller("get", key), self.items), repeat(list)), bool,
                           len(self.items))

    def numbers(self, key: str, shape: tuple = (), default=None, where=None) -> np.ndarray:
        """Field `key` of every entry (of the entries `where` selects) as an (n, *shape) finite float array;
        entries without it take `default` (None: the field is required)."""
        values, have = self._values(key, default is None, where)
        arr = numeric(values, len(values), shape)
        if arr is None:
            rows = np.flatnonzero(have)
            for j, value in enumerate(values):
                problem = value_problem(value, shape)
                if problem:
                    self.fail(int(rows[j]), key, problem)
            arr = np.array(values, dtype=float).reshape(len(values), *shape)
        bad = row_problem(arr.reshape(len(values), int(np.prod(shape))))
        if bad is not None:
            self.fail(int(np.flatnonzero(have)[bad[0]]), key, bad[1])
        if have.all():
            return arr
        out = np.empty((len(self.items), *shape))
        out[...] = np.asarray(default, dtype=float)
        out[have] = arr
        return out

    def raw(self, key: str):
        """The values of `key` as given (list) and where they are given (bool mask): fields of several shapes."""
        return self._values(key, False)

    def strings(self, key: str, default: str | None = None) -> list:
        """Field `key` of every entry: non-empty strings (`default` where absent; None: required)."""
        values, have = self._values(key, default is None)
        if set(map(type, values)) - {str} or (values and not min(map(len, values))):
            j = next(j for j, v in enumerate(values) if not (isinstance(v, str) and v))
            self.fail(int(np.flatnonzero(have)[j]), key, f"must be a non-empty string, got {describe(values[j])}")
        if have.all():
            return values
        out = [default] * len(self.items)
        for i, value in zip(np.flatnonzero(have).tolist(), values):
            out[i] = value
        return out


class ArrayTable:
    """The same schema as whole arrays (NPZ): `arrays` maps field → array over the n entries."""

    def __init__(self, source: str, name: str, arrays: dict, n: int):
        self.source, self.name, self.arrays, self.n = source, name, arrays, n
        self.label = lambda i: f"{name}[{i}]"

    def __len__(self) -> int:
        return self.n

    def fail(self, i, key: str, msg: str):
        where = self.label(i) if i is not None else self.name
        raise SceneError(one_line(f"{self.source}: {where}: {key}: {msg}"))

    def present(self, key: str) -> np.ndarray:
        return np.full(self.n, key in self.arrays)

    def matrix_form(self, key: str) -> np.ndarray:
        return np.full(self.n, key in self.arrays and self.arrays[key].ndim > 1)

    def numbers(self, key: str, shape: tuple = (), default=None, where=None) -> np.ndarray:
        if key not in self.arrays or (where is not None and not where.any()):
            if default is None:
                self.fail(None, key, "missing array")
            out = np.empty((self.n, *shape))
            out[...] = np.asarray(default, dtype=float)
            return out
        arr = self.arrays[key]
        if arr.dtype.kind not in "fiu" or arr.shape != (self.n, *shape):
            self.fail(None, key, f"must be a numeric array of shape {(self.n, *shape)}, got {arr.dtype} "
                                 f"{arr.shape}")
        arr = arr.astype(float, copy=False)
        bad = row_problem(arr.reshape(self.n, int(np.prod(shape))))
        if bad is not None:
            self.fail(bad[0], key, bad[1])
        return arr

    def raw(self, key: str):
        if key not in self.arrays:
            return [], np.zeros(self.n, bool)
        return self.arrays[key], np.ones(self.n, bool)

    def strings(self, key: str, default: str | None = None) -> list:
        if key not in self.arrays:
            if default is None:
                self.fail(None, key, "missing array")
            return [default] * self.n
        arr = self.arrays[key]
        if arr.dtype.kind != "U" or arr.shape != (self.n,):
            self.fail(None, key, f"must be a string array of shape ({self.n},), got {arr.dtype} {arr.shape}")
        if self.n and not np.char.str_len(arr).min():
            self.fail(first(np.char.str_len(arr) == 0), key, "must be a non-empty string")
        return arr.tolist()


class Reader:
    """Structural checks of one small table (the top level, `defaults`, a shape entry), one-line errors naming
    file, entry and field. Arrays of entries (particles, contacts) are read column-wise by TextTable and ArrayTable
    instead."""

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
    """k, alpha, mu (k > 0; alpha, mu >= 0: alpha = 0 or mu = 0 is frictionless) and rolling_stiffness (scalar × I or 3x3) of an entry, defaults `base`."""
    r = rot_dim(dim)
    k = rd.number("k", base["k"])
    alpha = rd.number("alpha", base["alpha"])
    mu = rd.number("mu", base["mu"])
    if k <= 0:
        rd.fail("k", f"must be > 0, got {k}")
    if alpha < 0:
        rd.fail("alpha", f"must be >= 0, got {alpha}")
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
