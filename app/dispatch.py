"""How one browser tab's callbacks run: the concurrency rules of the explorer, in one place.

Callbacks only read handles, call the session (app/state.py) and write handles and views. They run on viser's
thread pool, concurrently and possibly out of order, so each takes `lock` and RE-READS the current handle values
inside it: when several slider events queue up, whichever runs last computes the latest values and the others
find nothing changed (last value wins). Every callback goes through `run`, which turns any exception into a
message in the page; nothing a user does reaches the server as an exception. Handles written from Python echo
their callbacks synchronously in the writing thread: `quiet()` marks that thread, and `run` ignores its echoes.
"""
from __future__ import annotations

import threading
import time
from contextlib import contextmanager

from .text import error_html, loading_html

TYPING_PAUSE = 1.0        # s a text box rests before what it names is opened (0.6 opened a prefix on a loaded machine)
SEND_PAUSE = 0.02         # s the scene waits after the verdict was flushed, for it to leave in a window of its own


class Dispatch:
    """The lock, the echo guard, the slider coalescing, typing pauses and the message line of one client.
    Subclasses provide `_apply_sliders` (the slider callback, looked up at each call) and `_build_message`'s handle
    `message`."""

    def __init__(self, client):
        self.client = client
        self.lock = threading.RLock()
        self._quiet_thread: int | None = None   # the thread writing handles: its own echo callbacks are ignored
        self.closed = False
        self._sliding = threading.Lock()          # guards the two flags below (_slider_moved)
        self._slider_busy = self._slider_again = False
        self.released = threading.Event()         # set by the server once a closed tab's memory is handed back
        self._timers: set[threading.Timer] = set()    # typing pauses pending (cancelled on close)
        self._picks = 0                           # presets picked and files uploaded (a typed path waits: _after_typing)
        self.shown: dict[str, object] = {}       # what the page shows, by slider key, "preset", "frame", "metric":
                                                  # a user's entry or a value written here (see show_value)
        self.errors_shown = 0
        self.message = None                       # the red/grey line under the headline (built by the subclass)
        self.stoppers: list = []                 # called on close, before the lock is taken (the animation)

    @contextmanager
    def quiet(self):
        """Write handles without reacting to them: setting a value from Python runs its callbacks synchronously in
        this thread, and those echoes must not recompute. Other threads' (users') events wait for the lock."""
        self._quiet_thread = threading.get_ident()
        try:
            yield
        finally:
            self._quiet_thread = None

    def echo(self) -> bool:
        return self._quiet_thread == threading.get_ident()

    def run(self, fn, *args, **kwargs):
        """Call fn under the lock; an exception becomes a message in the page (and never reaches viser)."""
        if self.closed or self.echo():
            return None
        with self.lock:
            try:
                return fn(*args, **kwargs)
            except Exception as exc:  # noqa: BLE001
                self.errors_shown += 1
                self.show_message(f"{type(exc).__name__}: {' '.join(str(exc).split())}")
                return None

    def slider_moved(self) -> None:
        """A slider's event. A tab's slider events are coalesced: while its slider callback runs, a new event only
        marks it to run once more (reading the latest values), so that a dragged slider holds one of viser's pool
        threads (32 for every tab of the server), not one per event waiting for the tab's lock while a large scene
        is analysed."""
        if self.closed or self.echo():
            return
        with self._sliding:
            self._slider_again = True
            if self._slider_busy:
                return
            self._slider_busy = True
        try:
            while True:
                with self._sliding:
                    if not self._slider_again:
                        self._slider_busy = False        # under the lock: a later event starts its own run
                        return
                    self._slider_again = False
                self.run(self._apply_sliders)          # `run` turns any Exception into a message in the page
        except BaseException:
            with self._sliding:
                self._slider_busy = False
            raise

    def picking(self, fn):
        """The callback of a control that picks a scene (preset, upload): counted as it arrives, before it waits
        for the lock (a path typed before it then stays unopened: _after_typing), then run."""
        def update(_):
            if not self.echo():
                self._picks += 1
            self.run(fn)
        return update

    def after_typing(self, fn):
        """An on_update for a text box (it reports every letter): `fn` runs, through `run`, once the text has rested
        TYPING_PAUSE s, so a path typed letter by letter is opened once, not at every prefix (each one a red error,
        some a folder to search or another file); not at all if a preset was picked or a file uploaded meanwhile
        (the last thing the user chose wins)."""
        timer = None

        def update(_):
            nonlocal timer
            if timer is not None:
                timer.cancel()
                self._timers.discard(timer)
            if self.closed:
                return
            picks = self._picks

            def fire():
                self._timers.discard(mine)
                if self._picks == picks:
                    self.run(fn)
            timer = mine = threading.Timer(TYPING_PAUSE, fire)
            timer.daemon = True
            self._timers.add(timer)
            timer.start()
        return update

    def show_value(self, key: str, handle, value) -> None:
        """Write `value` into `handle` only when the session changed it (a preset, a reset, a cleaned entry, a file
        opened), never because the handle differs: the handle may already hold a newer entry whose callback is queued,
        and writing the older value back drops that entry (seen: the last of quick slider entries lost; a preset
        picked right after another one reverted to the first)."""
        if self.shown.get(key) != value:
            handle.value = self.shown[key] = value

    def loading(self, name: str) -> None:
        """While a scene opens: the last error goes, and the page says what is opening (sent at once)."""
        self.message.content = loading_html(name)
        self.message.visible = True
        self.client.flush()

    def show_message(self, text: str | None) -> None:
        self.message.content = error_html(text)
        self.message.visible = bool(text)

    def _send_now(self) -> None:
        """Send what is queued (the verdict and the other panels' text) in a websocket window of its own: flush, then
        give viser's event loop SEND_PAUSE to take it before the scene's messages queue up. The browser applies a
        window of GUI messages at once, but one that also holds scene messages only at its next 3D frame: on a large
        scene in a software-rendered browser that kept the new verdict ≈ 0.5–1 s behind the particle colours of the
        same window. viser has no public signal that a window left, so the pause is fixed (docs/viser-gaps.md)."""
        self.client.flush()
        time.sleep(SEND_PAUSE)

    def close(self) -> None:
        """The tab is gone: nothing runs for it any more. Pending typing pauses are cancelled, the stoppers run (the
        animation thread ends, joined), a callback running now finishes first (the lock)."""
        self.closed = True
        for timer in list(self._timers):
            timer.cancel()
        self._timers.clear()
        for stop in self.stoppers:
            stop()
