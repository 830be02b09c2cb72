"""`granstab-app`: the viser server, one session (state + GUI + scene) per browser tab.

    granstab-app [--preset NAME_OR_FILE] [--host 127.0.0.1] [--port 8080] [--data-root DIR] [--password WORD]

Each connection gets its own `Session` (app/state.py) and `ClientUI` (app/panels.py) built on client.gui /
client.scene, so several tabs each have their own state. The server binds 127.0.0.1 unless told otherwise; bound
beyond it, it says that every machine that reaches this one can open the page. viser has no log-in of its own: with a
`password` a tab is first asked for it (PasswordGate) and gets its session only once it is given.
"""
from __future__ import annotations

import argparse
import ctypes
import functools
import gc
import hmac
import sys
import threading
import time
from pathlib import Path

import viser

from granstab.solve.threads import cap_process

from .panels import ClientUI
from .paths import is_loopback
from .pools import close_pool
from .state import DEFAULT_PRESET, Session


class App:
    """The running explorer: the viser server and the per-client UIs (`uis`, keyed by client id)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, preset: str = DEFAULT_PRESET, presets_dir=None,
                 verbose: bool = False, data_root=None, password: str | None = None):
        self.preset = preset
        self.password = password or None            # None: every tab opens at once
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
        if self.password is not None:
            PasswordGate(client, self.password, lambda: self._open(client))
            return
        self._open(client)

    def _open(self, client) -> None:
        try:
            ui = ClientUI(client, Session(self.preset, self.presets_dir, self.data_root, self.typed_paths, offload=True))
        except Exception as exc:  # a broken page, not a broken server
            client.gui.add_markdown(f"⚠️ the explorer failed to start for this tab: {type(exc).__name__}: {exc}")
            raise
        with self._lock:
            self.uis[client.client_id] = ui
        settle_heap()

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
        close_pool()
        with _HEAP:                  # nothing of this server stays out of the collector's reach (settle_heap)
            gc.unfreeze()


class PasswordGate:
    """The page asks for the server's password before the tab gets a session: nothing of the explorer (scene, panels,
    files) is sent until it is given. MAX_TRIES wrong answers end the tab's tries (a reload starts again)."""

    MAX_TRIES = 5

    def __init__(self, client, password: str, open_tab):
        gui = client.gui
        self.password, self.open_tab, self.tries, self.lock = password, open_tab, 0, threading.Lock()
        self.note = gui.add_markdown("**This explorer asks for a password** (the one its teacher started it with).")
        self.box = gui.add_text("Password", initial_value="")
        self.button = gui.add_button("Open the explorer")
        self.button.on_click(lambda _: self.check())

    def check(self) -> None:
        with self.lock:
            if self.tries >= self.MAX_TRIES or self.box is None:
                return
            if hmac.compare_digest(self.box.value.encode(), self.password.encode()):
                for handle in (self.note, self.box, self.button):
                    handle.remove()
                self.box = None
                self.open_tab()
                return
            self.tries += 1
            last = self.tries >= self.MAX_TRIES
            self.note.content = ("**Wrong password** — " + ("too many tries: reload the page to try again." if last
                                                             else f"try again ({self.MAX_TRIES - self.tries} left)."))
            self.box.disabled = self.button.disabled = last


def host_warning(host: str, password: str | None) -> str | None:
    """What `granstab-app` says when bound beyond this machine (None on a loopback address)."""
    if is_loopback(host):
        return None
    return (f"granstab-app: warning: bound to {host}: every machine on the network that reaches this one can open the "
            "explorer" + (" (each page asks for the --password first)." if password else
                          "; --password WORD makes each page ask for a password first."))


_HEAP = threading.Lock()     # settle_heap and release_memory: one at a time


def settle_heap() -> None:
    """A new tab's objects live as long as the tab: the young generations are collected and everything alive is moved
    out of the collector's reach (gc.freeze), so that its full passes no longer scan every open tab. With 30 tabs
    open a full pass held the GIL 210-225 ms, twice in 20 s of slider moves, and every tab's move waited behind it
    (benchmarks/classroom.py); the objects are still freed by reference counting, and release_memory unfreezes them to
    collect a closed tab's cycles."""
    with _HEAP:
        gc.collect(1)
        gc.freeze()


def release_memory() -> None:
    """Collect the closed tab's objects and hand the freed heap back to the system. glibc keeps freed memory in the
    arena of the thread that freed it, and viser runs callbacks on a pool of up to 32 threads: a class of 10 tabs left
    +208 MB after every tab had closed (gear_packing, measured here), 0 after malloc_trim. Elsewhere (no glibc): the
    collection only. The open tabs' objects go back out of the collector's reach after (settle_heap)."""
    with _HEAP:
        gc.unfreeze()
        gc.collect()
        trim = _malloc_trim()
        if trim is not None:
            trim(0)
        gc.freeze()


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
    ap.add_argument("--password", metavar="WORD", default=None,
                    help="each page asks for WORD before it opens (viser has no log-in; WORD is visible to other users "
                         "of this machine in its process list, and travels unencrypted over plain http)")
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
    app = App(args.host, args.port, args.preset, data_root=args.data_root, password=args.password)
    warning = host_warning(args.host, args.password)
    if warning:
        print(warning, file=sys.stderr, flush=True)
    print(f"granstab explorer running at {app.url}  (Ctrl+C to stop)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        app.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
