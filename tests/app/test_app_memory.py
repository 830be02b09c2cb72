"""A closed tab gives its memory and threads back (issue 26: a 30-page class left 868 MB and 33 threads with no page
open). Pages are headless websocket clients of the real server (granstab_app.headless): each builds the tab's session
exactly as a browser's first camera message does.

Tolerances: over sequential sessions, RSS within 10 % of the warm figure (the issue's criterion; a page's session is
10-25 MB, so a few pages kept exceed it) and threads exactly as many as after the warm-up. After a class of pages
open at once has left, at most a quarter of the memory it used is still held (measured: 95 % before the fix, 4-10 %
after): Python's small-object arenas go back only when wholly empty, and the new pool threads keep their stacks."""
from __future__ import annotations

import threading
import time

import psutil
import pytest

from granstab_app.headless import HeadlessPage
from granstab_app.server import App

pytestmark = pytest.mark.slow
SESSIONS = 50            # the `sessions` benchmark runs 100 (BENCHMARKS.md); 50 keep this test under a minute
CLASS = 8


@pytest.fixture
def app():
    running = App(host="127.0.0.1", port=0, preset="gear_packing")
    yield running
    running.stop()


def rss() -> float:
    return psutil.Process().memory_info().rss


def settled_threads(expected: int | None = None, quiet: float = 0.5, limit: float = 30.0) -> int:
    """The process's thread count once it is `expected` (or, without one, once it has not changed for `quiet` s), at
    most `limit` s: a thread of the closed connection may still be ending when the session's release is signalled
    (one thread too many was counted once at load 8); a thread kept for good never leaves, so a leak still shows."""
    start = time.monotonic()
    count, since = threading.active_count(), start
    while count != expected and time.monotonic() - start < limit:
        if expected is None and time.monotonic() - since >= quiet:
            break
        time.sleep(0.02)
        if threading.active_count() != count:
            count, since = threading.active_count(), time.monotonic()
    return count


def test_sequential_sessions_leave_memory_and_threads_flat(app):
    for _ in range(10):                                 # warm-up: imports, caches, viser's first pool threads
        with HeadlessPage(app):
            pass
    warm, threads = rss(), settled_threads()
    worst = warm
    for _ in range(SESSIONS):
        with HeadlessPage(app) as page:
            assert page.ui.session.analysis is not None
        worst = max(worst, rss())
        assert settled_threads(threads) == threads
    assert not app.uis
    assert worst <= 1.10 * warm, f"RSS grew from {warm / 1e6:.0f} MB to {worst / 1e6:.0f} MB over {SESSIONS} sessions"


def test_a_class_that_has_left_gives_its_memory_back(app):
    """CLASS pages open at once, then all closed: the heap they used goes back (before: 208 of 220 MB kept for 10
    gear_packing pages, in the malloc arenas of viser's pool threads)."""
    with HeadlessPage(app):
        pass
    warm = rss()
    opened, leave = threading.Barrier(CLASS + 1), threading.Event()
    errors = []

    def pupil():
        try:
            with HeadlessPage(app):
                opened.wait(timeout=300)
                leave.wait(timeout=300)
        except Exception as exc:  # noqa: BLE001 — reported by the assertion below
            errors.append(exc)
            opened.abort()

    pupils = [threading.Thread(target=pupil) for _ in range(CLASS)]
    for t in pupils:
        t.start()
    opened.wait(timeout=300)
    assert len(app.uis) == CLASS
    during = rss()
    leave.set()
    for t in pupils:
        t.join(timeout=300)
    assert errors == [] and not app.uis
    after = rss()
    # a page's session is 10-25 MB: the class's use, not the process's (whose size is what ran in it before: 672 MB
    # on a pytest-xdist worker, where 8 pages' 123 MB failed the old premise, a quarter of that size)
    assert during - warm > CLASS * 10e6, "the class used too little memory to tell anything"
    kept = (after - warm) / (during - warm)
    assert kept <= 0.25, (f"{after / 1e6:.0f} MB after the class left, {warm / 1e6:.0f} MB before, "
                          f"{during / 1e6:.0f} MB with it: {kept:.0%} of what it used is still held")
