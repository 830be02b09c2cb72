"""What a path typed into *Path on server* may open (no viser).

A server bound to the loopback address serves its own user: any path opens. One bound beyond it (`--host 0.0.0.0`)
serves a room: typed paths are off unless `--data-root DIR` is given, and then a path is read relative to DIR and
must stay inside it (no `..`, no symbolic link leading out). A folder opens when it is a scan, or a snapshot that one
format reads whole; any other folder is named as a folder, with the scene files in it to choose from (it is never
tried file by file).
"""
from __future__ import annotations

import ipaddress
from pathlib import Path

SCENE_SUFFIXES = (".toml", ".json", ".npz")
LISTED = 8          # scene files named in the message of a folder that cannot be opened


class PathRefused(ValueError):
    """A typed path the server will not open, with the one-line reason."""


def is_loopback(host: str) -> bool:
    """Whether `host` is a loopback address (or localhost): the server is reachable from this machine only."""
    if host in ("localhost", ""):
        return host == "localhost"
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def typed_path(text: str, root: Path | None, allowed: bool = True) -> Path:
    """The path `text` names under the policy: `allowed` False (beyond loopback without a data root) refuses every
    path; with a `root`, a relative path is read from it, `..` is refused, and the resolved path (symbolic links
    followed) must lie inside the resolved root. Raises PathRefused."""
    if not allowed:
        raise PathRefused(f"{text}: typed paths are off on a server reachable from other machines; start it with "
                          "--data-root DIR to open files under DIR (or open a file from this page)")
    path = Path(text)
    if root is None:
        return path
    if ".." in path.parts:
        raise PathRefused(f"{text}: '..' is not allowed: paths are read inside the data root")
    full = path if path.is_absolute() else Path(root) / path
    base = Path(root).resolve()
    if not full.resolve().is_relative_to(base):
        raise PathRefused(f"{text}: outside the data root ({base}); type a path inside it")
    return full


def folder_choice(folder: Path) -> str:
    """The message for a folder that is neither a scan nor a snapshot: it is a folder; the scene files in it."""
    names = sorted(p.name for p in folder.iterdir() if p.is_file() and p.suffix.lower() in SCENE_SUFFIXES
                   and not p.name.startswith("."))
    if not names:
        return f"{folder}: is a folder with no scene file (.toml, .json, .npz) and no snapshot; choose a file"
    more = f" and {len(names) - LISTED} more" if len(names) > LISTED else ""
    return f"{folder}: is a folder; choose a file in it: {', '.join(names[:LISTED])}{more}"
