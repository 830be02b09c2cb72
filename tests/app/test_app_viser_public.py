"""The explorer (app/) uses viser's public API only: no module imports a private viser module or name, reads a
private attribute of anything but its own object (`self._x`), or names one of another object through
getattr/setattr/hasattr/delattr.
Where viser's public API falls short, docs/viser-gaps.md says what the explorer does instead."""
from __future__ import annotations

import ast

import pytest
from helpers import ROOT  # noqa: E402

APP = ROOT / "app"
ATTRIBUTE_CALLS = {"getattr", "setattr", "hasattr", "delattr"}


def private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def violations(source: str) -> list[str]:
    """Private viser imports and private attributes of other objects than self/cls, in one module's source."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [f"import {a.name}" for a in node.names
                      if a.name.split(".")[0] == "viser" and any(map(private, a.name.split(".")))]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "viser":
            if any(map(private, node.module.split("."))) or any(private(a.name) for a in node.names):
                found.append(f"from {node.module} import {', '.join(a.name for a in node.names)}")
        elif isinstance(node, ast.Attribute) and private(node.attr):
            if not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                found.append(ast.unparse(node))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ATTRIBUTE_CALLS
              and len(node.args) > 1 and not (isinstance(node.args[0], ast.Name) and node.args[0].id in ("self", "cls"))
              and isinstance(node.args[1], ast.Constant)
              and isinstance(node.args[1].value, str) and private(node.args[1].value)):
            found.append(ast.unparse(node))
    return found


@pytest.mark.parametrize("path", sorted(APP.rglob("*.py")), ids=lambda p: p.name)
def test_app_uses_viser_public_api_only(path):
    assert violations(path.read_text(encoding="utf-8")) == []


def test_the_check_finds_what_the_app_used_to_do():
    """What app/panels.py and app/browser.py did before (viser 1.1 internals) is found; own private state is not."""
    before = '''
from viser._messages import FileTransferPartAck, NotificationProps
import viser._gui_api
from viser import _messages
class UI:
    def f(self, handle):
        connection = self.client._websock_connection
        start = self.client.gui._handle_file_transfer_start
        uuid = handle._impl.uuid
        states = getattr(self.client.gui, "_current_file_upload_states")
        self._transfers = {}
        return self._quiet_thread, handle.__class__, getattr(handle, "label"), getattr(self, "_key", None)
'''
    assert sorted(violations(before)) == sorted([
        "from viser._messages import FileTransferPartAck, NotificationProps", "import viser._gui_api",
        "from viser import _messages", "self.client._websock_connection", "self.client.gui._handle_file_transfer_start",
        "handle._impl", "getattr(self.client.gui, '_current_file_upload_states')"])
