"""A page without a browser: a websocket client that speaks enough of viser's protocol to be a session of the explorer
(the memory test and the `sessions` benchmark open and close a hundred of them in a minute or two, where a headless
Chromium page costs 10-20 s).

viser 1.1 counts a connection as a client once it has sent its first camera (ViewerCameraMessage, msgpack over a
websocket whose subprotocol names the viser version); from then on the server builds the tab's session as for a
browser. The page reads (and drops) everything the server sends, as a browser would take it, until it is closed.
"""
from __future__ import annotations

import threading
import time

import msgspec
import viser
from websockets.sync.client import connect

CAMERA = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [0.0, 0.0, 5.0], "fov": 1.0,
          "near": 0.01, "far": 100.0, "image_height": 800, "image_width": 1600, "look_at": [0.0, 0.0, 0.0],
          "up_direction": [0.0, 1.0, 0.0]}
_LOCK = threading.Lock()
_OPENED = 0


class HeadlessPage:
    """`with HeadlessPage(app) as page:` one connected tab; `page.ui` is its ClientUI (app.server.App.uis)."""

    def __init__(self, app, timeout: float = 120.0):
        self.app, self.timeout = app, timeout
        self.ui = None
        self.received = 0                    # bytes the server sent this page
        self._ws = None
        self._reader = None

    def __enter__(self) -> HeadlessPage:
        with _LOCK:                              # the page is told apart by its canvas height (pages open at once)
            global _OPENED
            _OPENED += 1
            height = 800 + _OPENED % 200
        self._ws = connect(f"ws://127.0.0.1:{self.app.port}", subprotocols=[f"viser-v{viser.__version__}"],
                           max_size=None)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self._ws.send(msgspec.msgpack.encode({**CAMERA, "image_height": height}))
        self.ui = _wait(lambda: next((u for u in list(self.app.uis.values())
                                      if u.client.camera.image_height == height), None),
                        self.timeout, "the page's session")
        return self

    def send(self, message: dict) -> None:
        """Send one message of viser's protocol as a browser would (msgpack): a GuiUpdateMessage moves a slider."""
        self._ws.send(msgspec.msgpack.encode(message))

    def _read(self) -> None:
        try:
            for message in self._ws:
                self.received += len(message)
        except Exception:  # noqa: BLE001 — the connection closed: the page is gone
            return

    def __exit__(self, *exc) -> None:
        self._ws.close()
        self._reader.join(self.timeout)
        released = self.ui.released
        _wait(lambda: released.is_set() or None, self.timeout, "the session to be released")


def _wait(fn, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = fn()
        if got is not None:
            return got
        time.sleep(0.02)
    raise TimeoutError(f"waited {timeout:.0f} s for {what}")
