"""Issue 26, the explorer under a class and a new user's first hour, checked on the session and the pure functions
(no browser): typed paths under the server's policy, one verdict word, what is analysed is what is shown, modes
counted once, the slider boxes' numbers."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from granstab_app.paths import PathRefused, is_loopback, typed_path
from granstab_app.state import Session

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture()
def tree(tmp_path):
    """A data root holding a scene file and a folder of junk, and a secret beside the root (outside it)."""
    root = tmp_path / "root"
    (root / "runs").mkdir(parents=True)
    (root / "pair.toml").write_text((REPO / "presets" / "two_particle.toml").read_text())
    (root / "runs" / "four.toml").write_text((REPO / "presets" / "four_disk.toml").read_text())
    (root / "junk").mkdir()
    for name in ("a.conf", "b.conf", "c.txt"):
        (root / "junk" / name).write_text("not a scene\n")
    (tmp_path / "secret.toml").write_text((REPO / "presets" / "four_disk.toml").read_text())
    return root


def test_loopback_hosts():
    assert [is_loopback(h) for h in ("127.0.0.1", "::1", "localhost", "127.0.1.1")] == [True] * 4
    assert [is_loopback(h) for h in ("0.0.0.0", "192.168.1.4", "::", "example.org", "")] == [False] * 5


def test_typed_paths_are_confined_to_the_data_root(tree):
    assert typed_path("pair.toml", tree) == tree / "pair.toml"
    assert typed_path(str(tree / "runs" / "four.toml"), tree) == tree / "runs" / "four.toml"
    for text in ("../secret.toml", "runs/../../secret.toml", str(tree.parent / "secret.toml"), "/etc/passwd"):
        with pytest.raises(PathRefused):
            typed_path(text, tree)
    os.symlink(tree.parent / "secret.toml", tree / "link.toml")        # a link inside leading out
    with pytest.raises(PathRefused, match="outside the data root"):
        typed_path("link.toml", tree)
    with pytest.raises(PathRefused, match="--data-root"):
        typed_path("pair.toml", None, allowed=False)


def test_the_session_opens_typed_paths_under_the_policy(tree):
    s = Session(data_root=tree)
    assert s.open_typed("runs/four.toml") and s.scene.n_particles == 4 and s.error is None
    assert not s.open_typed("../secret.toml") and "data root" in s.error
    assert s.scene.n_particles == 4                                     # the scene shown stays
    assert s.open_typed("two_particle") and s.kind == "two_particle"   # a preset name is no path
    off = Session(typed_paths=False)
    assert not off.open_typed(str(tree / "pair.toml")) and "--data-root" in off.error


def test_a_folder_is_named_as_a_folder_not_tried_file_by_file(tree):
    s = Session()
    assert not s.open_typed(str(tree / "junk"))
    assert "is a folder" in s.error and "a.conf" not in s.error and "not recognised" not in s.error
    assert not s.open_typed(str(tree))
    assert s.error.endswith("choose a file in it: pair.toml")
    assert s.kind == "two_particle"
