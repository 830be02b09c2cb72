"""A resumable folder (scan, track) knows what it was made from (issue 38): options.json holds the options, and
inputs.json each input file's size, modification time and content hash, so that a resume never mixes two inputs or
two sets of options. The hash is of what the run reads (BLAKE2b): where the frames are read lazily from known byte
offsets (a LAMMPS dump's timesteps: io.source.Source.spans) one hash a frame read, so that a refusal names the
frame whose contents changed; any other file is hashed whole. A changed file, frame or option is a one-line refusal
naming it (an option with both values, only what differs) and saying how to start afresh (--overwrite: the
folder's parts and records are removed first).
"""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

from ..model.scene import SceneError

CHUNK = 1 << 20
INPUTS = "inputs.json"
OPTIONS = "options.json"


def files_of(paths) -> list[Path]:
    """The files of `paths`: a file as given, a folder's files (recursively, sorted)."""
    out = []
    for p in map(Path, paths):
        out += sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
    return out


def content_hash(path: Path, lo: int = 0, hi: int | None = None) -> str:
    """BLAKE2b (hex) of the file's bytes [lo, hi) (default all)."""
    h = hashlib.blake2b(digest_size=20)
    with open(path, "rb") as f:
        f.seek(lo)
        left = float("inf") if hi is None else hi - lo
        while left > 0 and (block := f.read(int(min(CHUNK, left)))):
            h.update(block)
            left -= len(block)
    return h.hexdigest()


def fingerprint(paths, spans: dict | None = None) -> dict:
    """{file: {"size", "mtime", and "blake2b" or "frames" {frame: blake2b}}} of every file of `paths` (files_of);
    a file in `spans` ({path: [(frame, first byte, end)]}: the frames read) is hashed frame by frame."""
    framed = {str(Path(f).resolve()): parts for f, parts in (spans or {}).items()}
    out = {}
    for f in files_of(paths):
        st, key = f.stat(), str(f.resolve())
        got = ({"frames": {str(t): content_hash(f, lo, hi) for t, lo, hi in framed[key]}} if key in framed
               else {"blake2b": content_hash(f)})
        out[key] = {"size": st.st_size, "mtime": st.st_mtime, **got}
    return out


def changed_input(before: dict, now: dict) -> str | None:
    """What differs between two fingerprints, in words: the file, and the first frame whose contents changed where
    frames are hashed (None: the same contents; a new modification time alone with the same bytes is the same
    input)."""
    for name in sorted(set(before) | set(now)):
        old, new = before.get(name), now.get(name)
        if old is None or new is None:
            return f"{name} {'is new' if old is None else 'is gone'} since"
        frame = _changed_frame(old.get("frames"), new.get("frames"))
        if frame:
            return f"{name}: {frame} since"
        if old["size"] != new["size"]:
            return f"{name} changed (size {old['size']} → {new['size']} bytes) since"
        if old.get("blake2b") != new.get("blake2b"):
            return f"{name} changed (same size, other contents; modified {_when(new['mtime'])}) since"
    return None


def _changed_frame(old: dict | None, new: dict | None) -> str | None:
    """The first frame (timestep) whose hash differs, is gone or is new, in words."""
    if old is None or new is None:
        return None
    for frame in sorted(set(old) | set(new), key=lambda t: (len(t), t)):
        if old.get(frame) != new.get(frame):
            what = "is gone" if frame not in new else "is new" if frame not in old else "changed (other contents)"
            return f"the frame at timestep {frame} {what}"
    return None


def _when(mtime: float) -> str:
    import time
    return time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(mtime))


def changed_options(before: dict, now: dict, prefix: str = "") -> list[str]:
    """'name: before → now' for each option that differs (nested dicts by dotted names)."""
    out = []
    for key in sorted(set(before) | set(now), key=str):
        old, new = before.get(key, "unset"), now.get(key, "unset")
        if isinstance(old, dict) and isinstance(new, dict):
            out += changed_options(old, new, f"{prefix}{key}.")
        elif old != new:
            out.append(f"{prefix}{key}: {json.dumps(old)} → {json.dumps(new)}")
    return out


def start_afresh(folder: Path) -> None:
    """--overwrite: remove what a resume would keep (options, inputs, the parts) before a new run."""
    for name in (OPTIONS, INPUTS):
        (folder / name).unlink(missing_ok=True)
    if (folder / "parts").is_dir():
        shutil.rmtree(folder / "parts")
    (folder / "parts").mkdir(parents=True, exist_ok=True)


def check(folder: Path, stated: dict, inputs, what: str, spans: dict | None = None) -> bool:
    """Whether `folder` holds a `what` (False: a new folder); a one-line SceneError when its options or inputs
    (their frames `spans`: `fingerprint`) differ from these."""
    saved = folder / OPTIONS
    if not saved.exists():
        return False
    afresh = "start afresh with --overwrite (its results are replaced) or choose another --out"
    diff = changed_options(json.loads(saved.read_text(encoding="utf-8")), stated)
    if diff:
        raise SceneError(f"{folder}: holds a {what} made with other options ({'; '.join(diff)}); resume with the "
                         f"same options, or {afresh}")
    recorded = folder / INPUTS
    if inputs is not None and recorded.exists():
        why = changed_input(json.loads(recorded.read_text(encoding="utf-8")), fingerprint(inputs, spans))
        if why:
            raise SceneError(f"{folder}: {why} this {what} began: a resume would mix two inputs; {afresh}")
    return True


def record(folder: Path, stated: dict, inputs, spans: dict | None = None) -> None:
    """Write options.json and (inputs given) inputs.json (`fingerprint`)."""
    if inputs is not None:
        (folder / INPUTS).write_text(json.dumps(fingerprint(inputs, spans), indent=1), encoding="utf-8")
    (folder / OPTIONS).write_text(json.dumps(stated), encoding="utf-8")
