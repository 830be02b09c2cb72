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
from dataclasses import dataclass

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

    def __init__(self, app, timeout: float = 120.0, record: bool = False):
        self.app, self.timeout, self.record = app, timeout, record
        self.ui = None
        self.received = 0                    # bytes the server sent this page
        self.messages: list[Sent] = []       # with `record`: every message received, in order (read_window)
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
                if self.record:
                    self.messages += read_window(message)
        except Exception:  # noqa: BLE001 — the connection closed: the page is gone
            return

    def __exit__(self, *exc) -> None:
        self._ws.close()
        self._reader.join(self.timeout)
        released = self.ui.released
        _wait(lambda: released.is_set() or None, self.timeout, "the session to be released")


@dataclass(frozen=True)
class Sent:
    """One message the server sent: its type, the scene node's name or the GUI element's id, the properties it writes
    (an update) and its size: msgpack bytes plus the binary arrays it carries (vertices, points)."""

    type: str
    name: str
    props: tuple
    size: int


def read_window(raw: bytes) -> list[Sent]:
    """The messages of one websocket window of viser's wire format (viser/infra/_infra.py `_message_producer`): the
    decompressed and compressed sizes of a zstd-compressed msgpack {"messages", "binaryBufferLengths"}, then the
    binary buffers (each 8-byte aligned), which messages name by index."""
    window = decode_window(raw)
    lengths = window.get("binaryBufferLengths", ())
    out = []
    for m in window["messages"]:
        props = m.get("updates") or m.get("props") or {}
        out.append(Sent(m["type"], str(m.get("name") or m.get("uuid") or ""), tuple(props),
                        len(msgspec.msgpack.encode(m)) + sum(lengths[i] for i in _buffers(m))))
    return out


def decode_window(raw: bytes, zstd=None) -> dict:
    """One window of viser's wire format decoded: {"messages", "timestampSec" (the server's time.perf_counter when it
    packed the window), "binaryBufferLengths"}; the binary buffers after it are left undecoded. `zstd`: a
    zstandard.ZstdDecompressor to reuse."""
    if zstd is None:
        import zstandard
        zstd = zstandard.ZstdDecompressor()
    size, packed = int.from_bytes(raw[:8], "little"), int.from_bytes(raw[8:16], "little")
    return msgspec.msgpack.decode(zstd.decompress(raw[16:16 + packed], max_output_size=size))


def _buffers(value) -> list[int]:
    """The indices of the binary buffers a decoded message refers to (placeholders {"__binary_index": i, "dtype": …})."""
    if isinstance(value, dict):
        own = [value["__binary_index"]] if isinstance(value.get("__binary_index"), int) else []
        return own + [i for v in value.values() for i in _buffers(v)]
    if isinstance(value, (list, tuple)):
        return [i for v in value for i in _buffers(v)]
    return []


def _wait(fn, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = fn()
        if got is not None:
            return got
        time.sleep(0.02)
    raise TimeoutError(f"waited {timeout:.0f} s for {what}")
