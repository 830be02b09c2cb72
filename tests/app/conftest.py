"""The explorer's tests: an explorer serving copies of chosen presets, as several of them start one."""
import shutil

import pytest
from helpers import ROOT


@pytest.fixture(scope="module")
def explorer(tmp_path_factory):
    """`explorer(*preset_names, files={name: text})`: an explorer (granstab_app.server.App on 127.0.0.1, a free
    port) serving copies of those presets and those extra files; every one started is stopped with the module."""
    from granstab_app.server import App
    running = []

    def start(*names: str, files: dict | None = None):
        folder = tmp_path_factory.mktemp("presets")
        for name in names:
            shutil.copy(ROOT / "presets" / name, folder)
        for name, text in (files or {}).items():
            (folder / name).write_text(text, encoding="utf-8")
        running.append(App(host="127.0.0.1", port=0, presets_dir=folder))
        return running[-1]

    yield start
    for app in running:
        app.stop()
