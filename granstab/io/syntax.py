"""Scene files as data: TOML, JSON (with a nesting limit and no duplicate keys) and NPZ (binary), read and written.

Only the syntax lives here; schema.py and shapefile.py check the schema, model/scene.py the physics. Every failure
raises `SceneError` with ONE line naming the file (and the line where the syntax says it).

JSON is parsed by the standard library's C parser after one vectorised pass over the bytes (numpy), which
finds the nesting depth (rejected beyond MAX_DEPTH instead of recursing into a RecursionError) and counts the
keys (a duplicate key, which json keeps silently as last-one-wins, makes the parsed count smaller; only then is
the file parsed again with an `object_pairs_hook` to name it). TOML (tomllib) already rejects duplicate keys.
"""
from __future__ import annotations

import gc
import json
import re
import tomllib
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..model.errors import DuplicateKeys, SceneError, one_line

MAX_DEPTH = 10          # the schema nests at most 5 deep (scene → contacts → entry → 3x3 curvature rows)
CHUNK = 1 << 23         # bytes per step of the structural scan (memory: a few times this, not the file)


# ------------------------------------------------------------------------------------------------- reading

@contextmanager
def paused_gc():
    """Pause Python's cyclic garbage collector while millions of acyclic objects (parsed JSON, dicts for writing) are
    made: each collection would walk all of them again (measured: to_dict of 3·10⁵ contacts 7.4 s → 1.4 s)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def read_bytes(path: Path, progress=None) -> bytes:
    """The file's bytes, in chunks so that `progress(n_bytes)` can report; OSError → one line."""
    try:
        with open(path, "rb") as fh:
            parts = []
            while chunk := fh.read(CHUNK):
                parts.append(chunk)
                if progress is not None:
                    progress(len(chunk))
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    return b"".join(parts)


def decode(raw: bytes, source: str) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        raise SceneError(f"{source}: not a UTF-8 text file") from None


def parse_toml(text: str, source: str) -> dict:
    """tomllib (which already refuses duplicate keys); its recursion on arrays nested hundreds deep is caught
    here (tomllib is pure Python: nothing is left half-done) and reported as the nesting it is."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: malformed TOML: {one_line(exc)}") from None
    except RecursionError:
        raise SceneError(f"{source}: nesting too deep for the TOML parser (the scene schema needs at most 5 "
                         "levels)") from None


def _pairs_hook(pairs):
    out = dict(pairs)
    if len(out) == len(pairs):
        return out
    seen = set()
    dup = next(key for key, _ in pairs if key in seen or seen.add(key))
    marked = DuplicateKeys(out)
    marked.duplicate = dup
    return marked


def parse_json(raw: bytes, source: str):
    """Parse JSON bytes. Depth beyond MAX_DEPTH and malformed text are one-line errors; objects with a duplicate
    key come back as `DuplicateKeys` (only then is the slower hook used)."""
    text = decode(raw, source)
    depth, pos, n_keys = structure(raw)
    if depth > MAX_DEPTH:
        line = raw.count(b"\n", 0, pos) + 1
        raise SceneError(f"{source}: nesting deeper than {MAX_DEPTH} levels at line {line} (the scene schema "
                         "needs at most 5)")
    try:
        with paused_gc():
            data = json.loads(text)
            if count_keys(data) != n_keys:
                data = json.loads(text, object_pairs_hook=_pairs_hook)
    except json.JSONDecodeError as exc:
        raise SceneError(f"{source}: malformed JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    except RecursionError:   # unreachable after the depth scan; kept so that no traceback can escape
        raise SceneError(f"{source}: nesting too deep for the JSON parser") from None
    return data


# byte classes of the structural scan: 1 quote, 2 opening bracket, 3 closing bracket, 4 colon
_CLASS = np.zeros(256, np.uint8)
_CLASS[ord('"')] = 1
_CLASS[[ord("["), ord("{")]] = 2
_CLASS[[ord("]"), ord("}")]] = 3
_CLASS[ord(":")] = 4


def structure(raw: bytes) -> tuple[int, int, int]:
    """One vectorised pass over JSON bytes: (max depth, byte offset where it is first reached, number of keys
    (colons outside strings)). Only the structural bytes are kept (a few
    per cent of the file); strings are tracked by quote parity after escaped characters are blanked (regex,
    C speed, only in files that have a backslash)."""
    if b"\\" in raw:
        raw = re.sub(rb"\\.", b"__", raw, flags=re.DOTALL)
    depth = inside = keys = 0
    best, best_pos = 0, 0
    for start in range(0, len(raw), CHUNK):
        b = np.frombuffer(raw, np.uint8, count=min(CHUNK, len(raw) - start), offset=start)
        pos = np.flatnonzero(_CLASS[b])
        cls = _CLASS[b[pos]]
        q = cls == 1
        parity = (np.cumsum(q, dtype=np.int64) + inside) & 1        # 1 inside a string (and on its opening quote)
        outside = (parity == 0) & ~q
        step = np.where(outside & (cls == 2), 1, np.where(outside & (cls == 3), -1, 0))
        level = np.cumsum(step) + depth
        if level.size and level.max() > best:
            at = int(np.argmax(level))
            best, best_pos = int(level[at]), start + int(pos[at])
        keys += int(np.count_nonzero(outside & (cls == 4)))
        if level.size:
            depth, inside = int(level[-1]), int(parity[-1])
    return best, best_pos, keys


def count_keys(data) -> int:
    """Keys of the objects where the schema has objects: the top level, `defaults`, every particle (and its
    `shape`) and every contact. Any other object makes the count differ from the text's, which only costs the
    second parse (schema.py then rejects it by type)."""
    if not isinstance(data, dict):
        return -1
    n = len(data)
    if isinstance(data.get("defaults"), dict):
        n += len(data["defaults"])
    for key in ("particles", "contacts"):
        items = data.get(key)
        if isinstance(items, list):
            dicts = [item for item in items if type(item) is dict]
            n += sum(map(len, dicts))
            if key == "particles":
                n += sum(len(s) for s in (item.get("shape") for item in dicts) if type(s) is dict)
    return n


def load_npz(path: Path, source: str) -> dict:
    """The arrays of an .npz scene (no pickles: object arrays are refused)."""
    try:
        with np.load(path, allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except OSError as exc:
        raise SceneError(f"{source}: cannot read file ({exc.strerror or one_line(exc)})") from None
    except ValueError as exc:
        raise SceneError(f"{source}: not a scene .npz ({one_line(exc)})") from None
    except Exception as exc:   # zipfile.BadZipFile and friends: a garbled archive
        raise SceneError(f"{source}: not a readable .npz archive ({type(exc).__name__}: {one_line(exc)})") from None


# ------------------------------------------------------------------------------------------------- writing

def write_json(data: dict, path: Path) -> None:
    """Strict JSON (no NaN/Infinity); a non-finite number is a one-line error, never written."""
    try:
        with paused_gc():
            text = json.dumps(data, allow_nan=False)
    except ValueError:
        raise SceneError(f"{path}: refusing to write a non-finite number (strict JSON)") from None
    Path(path).write_text(text, encoding="utf-8")


def write_npz(arrays: dict, path: Path) -> None:
    with open(path, "wb") as fh:          # np.savez would append .npz to a path without it
        np.savez(fh, **arrays)
