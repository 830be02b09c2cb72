"""The explorer under a class (issue 26): memory and threads of the server over many page sessions, opened and closed
one after the other, and after a class of pages open at once has left. Pages are headless websocket clients of the
real server (granstab_app.headless: each builds a tab's session as a browser's first camera does), on gear_packing."""
from __future__ import annotations

import statistics
import threading
import time

PRESET = "gear_packing"
SESSIONS = {True: 20, False: 100}
WARM = 10
MARKS = (10, 25, 50, 100)     # sessions after which RSS is listed (the shape of any growth)
CLASS = 10


def _rss() -> float:
    import psutil
    return psutil.Process().memory_info().rss / 1e6


def _class(app, size: int) -> float:
    """RSS (MB) while `size` pages are open at once; they close before this returns."""
    from granstab_app.headless import HeadlessPage
    opened, leave, during = threading.Barrier(size + 1), threading.Event(), []

    def pupil():
        with HeadlessPage(app):
            opened.wait(timeout=600)
            leave.wait(timeout=600)

    pupils = [threading.Thread(target=pupil) for _ in range(size)]
    for t in pupils:
        t.start()
    opened.wait(timeout=600)
    during.append(_rss())
    leave.set()
    for t in pupils:
        t.join(timeout=600)
    return during[0]


def run(quick: bool = False) -> dict:
    from granstab_app.headless import HeadlessPage
    from granstab_app.server import App
    app = App(host="127.0.0.1", port=0, preset=PRESET)
    try:
        for _ in range(WARM):
            with HeadlessPage(app):
                pass
        warm, threads = _rss(), threading.active_count()
        series, seconds = [], []
        for _ in range(SESSIONS[quick]):
            t = time.perf_counter()
            with HeadlessPage(app):
                pass
            seconds.append(time.perf_counter() - t)
            series.append(_rss())
        after_threads = threading.active_count()
        before_class = _rss()
        during = _class(app, CLASS)
        after_class = _rss()
    finally:
        app.stop()
    return {"preset": PRESET, "sessions": len(series), "warm_mb": warm, "last_mb": series[-1], "max_mb": max(series),
            "growth_per_session_mb": (series[-1] - series[0]) / max(len(series) - 1, 1),
            "marks": {n: series[n - 1] for n in MARKS if n <= len(series)},
            "threads_warm": threads, "threads_after": after_threads,
            "session_median_s": statistics.median(seconds), "class": CLASS, "class_before_mb": before_class,
            "class_during_mb": during, "class_after_mb": after_class}


def markdown(r: dict) -> str:
    kept = (r["class_after_mb"] - r["class_before_mb"]) / max(r["class_during_mb"] - r["class_before_mb"], 1e-9)
    return "\n".join([
        "## The explorer under a class (memory)", "",
        f"{r['sessions']} page sessions of `{r['preset']}` opened and closed one after the other (headless websocket "
        "pages of the real server, benchmarks/sessions.py; each builds and analyses the tab's session, "
        f"{r['session_median_s']:.2f} s median), after {WARM} warm-up sessions; then a class of {r['class']} pages "
        "open at once, all closed. Issue 26 measured 6.8 MB kept per session and 868 MB with 33 threads after a "
        "30-page class.", "",
        "| | RSS | threads |", "|---|---|---|",
        f"| after the warm-up | {r['warm_mb']:.0f} MB | {r['threads_warm']} |",
        *(f"| after {n} sessions | {mb:.0f} MB | |" for n, mb in r["marks"].items() if int(n) < r["sessions"]),
        f"| after {r['sessions']} sessions | {r['last_mb']:.0f} MB (largest {r['max_mb']:.0f} MB, "
        f"{r['growth_per_session_mb']:+.2f} MB per session) | {r['threads_after']} |",
        f"| {r['class']} pages open at once | {r['class_during_mb']:.0f} MB | |",
        f"| after they left | {r['class_after_mb']:.0f} MB ({max(kept, 0):.0%} of what the class used still held) | |",
        "", "A closed tab's UI stops its timers and animation thread and is dropped, and the server hands the freed "
        "heap back to the system (malloc_trim after each disconnect: glibc keeps it in the arenas of viser's 32 pool "
        "threads, which is where the class's memory stayed). viser's pool threads stay once started (up to 32; its "
        "public API cannot shrink the pool); sequential sessions start none.",
    ]) + "\n"
