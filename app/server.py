"""`granstab-app`: the viser server, one session (state + GUI + scene) per browser tab.

    granstab-app [--preset NAME_OR_FILE] [--host 127.0.0.1] [--port 8080] [--data-root DIR]

Each connection gets its own `Session` (app/state.py) and `ClientUI` (app/panels.py) built on client.gui /
client.scene, so several tabs each have their own state. The server binds 127.0.0.1 unless told otherwise.
"""
from __future__ import annotations

import argparse
import ctypes
import functools
import gc
import sys
import threading
import time
from pathlib import Path

import viser

from granstab.solve.threads import cap_process

from .panels import ClientUI
from .paths import is_loopback
from .state import DEFAULT_PRESET, Session


class App:
    """The running explorer: the viser server and the per-client UIs (`uis`, keyed by client id)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, preset: str = DEFAULT_PRESET, presets_dir=None,
                 verbose: bool = False, data_root=None):
        self.preset = preset
        self.presets_dir = presets_dir
        self.data_root = data_root                  # typed paths: confined to it (app/paths.py)
        self.typed_paths = is_loopback(host) or data_root is not None
        self.uis: dict[int, ClientUI] = {}
        self._lock = threading.Lock()
        self.server = viser.ViserServer(host=host, port=port, verbose=verbose)
        self.server.gui.configure_theme(show_share_button=False, control_width="large")
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        host = self.server.get_host()
        return f"http://{'127.0.0.1' if host in ('0.0.0.0', '') else host}:{self.port}"

    def _connect(self, client) -> None:
        try:
            ui = ClientUI(client, Session(self.preset, self.presets_dir, self.data_root, self.typed_paths))
        except Exception as exc:  # a broken page, not a broken server
            client.gui.add_markdown(f"⚠️ the explorer failed to start for this tab: {type(exc).__name__}: {exc}")
            raise
        with self._lock:
            self.uis[client.client_id] = ui

    def _disconnect(self, client) -> None:
        """A closed tab: its UI stops (timers, animation) and is dropped, and the memory it held goes back to the
        system (release_memory); `ui.released` is set then."""
        with self._lock:
            ui = self.uis.pop(client.client_id, None)
        if ui is not None:
            ui.close()
            release_memory()
            ui.released.set()

    def sessions(self) -> list[Session]:
        with self._lock:
            return [ui.session for ui in self.uis.values()]

    def stop(self) -> None:
        for ui in list(self.uis.values()):
            ui.close()
        self.server.stop()


def release_memory() -> None:
    """Collect the closed tab's objects and hand the freed heap back to the system. glibc keeps freed memory in the
    arena of the thread that freed it, and viser runs callbacks on a pool of up to 32 threads: a class of 10 tabs left
    +208 MB after every tab had closed (gear_packing, measured here), 0 after malloc_trim. Elsewhere (no glibc): the
    collection only."""
    gc.collect()
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.cache
def _malloc_trim():
    """glibc's malloc_trim, or None where there is no glibc."""
    try:
        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="granstab-app", description="granstab explorer: a browser app to play with "
                                 "the stability of granular clusters (Kuhn & Chang).")
    ap.add_argument("--preset", default=DEFAULT_PRESET,
                    help="preset name (file stem in presets/) or path to a scene file (default: %(default)s)")
    ap.add_argument("--host", default="127.0.0.1", help="address to bind (default: %(default)s)")
    ap.add_argument("--port", type=int, default=8080, help="port; a busy port is replaced by the next free one")
    ap.add_argument("--data-root", metavar="DIR", default=None,
                    help="paths typed into the page are read inside DIR only (no '..', no link out); without it a "
                         "server bound beyond 127.0.0.1 turns typed paths off")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    probe = Session(args.preset)
    if probe.error:
        print(f"granstab-app: {probe.error}", file=sys.stderr)
        if probe.preset != args.preset and str(args.preset) != DEFAULT_PRESET:
            return 2
    cap_process(1)     # many small sessions at once: a BLAS pool per call only waits for a core on a busy machine
    if args.data_root is not None and not Path(args.data_root).is_dir():
        print(f"granstab-app: --data-root: {args.data_root}: not a folder", file=sys.stderr)
        return 2
    app = App(args.host, args.port, args.preset, data_root=args.data_root)
    print(f"granstab explorer running at {app.url}  (Ctrl+C to stop)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        app.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
