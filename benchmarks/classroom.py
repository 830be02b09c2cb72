"""A class on one server (issue 29): PAGES pages on one explorer, each moving a slider every PERIOD seconds, ANNULUS of
them on annulus_frame (μ), the rest on the pair (ρ/r), no value typed twice in the class.

This process runs the server alone (app.server.App, as `granstab-app` does); the pages run in another process
(benchmarks/classroom_pupils.py), as a class's pages run in the pupils' own browsers. Three runs, a server each:
- one Chromium page alone (QUIET_MOVES moves): the browser's own part of a move, stamped in the page against the
  server's time.time (one system clock): its input event → the server's callback starts, and the verdict queued →
  the first frame after the badge shows it;
- the class of protocol pages (viser's websocket protocol, each a real session sent and decoding everything a browser
  is sent): the server's part, message sent → the window with the new verdict received, on CLOCK_MONOTONIC in both
  processes (time.perf_counter, viser's `timestampSec`), split by the server's own stamps (callback start, verdict
  queued) into reaching the callback, the callback's work up to the verdict, and the verdict's way out;
- the class again with BROWSERS of its pair pages in headless Chromium (software WebGL on this machine's cores beside
  the server): no page error, the state its own, the canvas drawn, and the latency in those pages.
A pupil's latency is composed: the server's part under the class + the browser's own.

Also: the server's memory (RSS of this process) before, with all pages open, after the moves and after every page has
closed; its garbage collections while moving; the CPU of the server, of its analysis workers (app/state.py
`analysis_pool`), of the pages' process and of Chromium while the class moved; each move's own CPU in the server (its
callback's thread time)."""
from __future__ import annotations

import contextlib
import gc
import json
import os
import queue
import statistics
import subprocess
import sys
import threading
import time

PAGES = {True: 6, False: 30}
ANNULUS = {True: 2, False: 5}
BROWSERS = {True: 1, False: 2}     # Chromium pages in the class, all on the pair
QUIET_MOVES = {True: 4, False: 20}  # the Chromium page alone
MOVES = {True: 3, False: 10}
PROBES = {True: (), False: (60, 90)}    # larger classes of protocol pages, same mix: where the ceiling is
PROBE_MOVES = 5
VIEWPORT = {"width": 1200, "height": 800}   # px of each Chromium page
PERIOD = 2.0                       # s between one page's slider moves
LOST_S = 30.0                      # s after which a move that never showed is counted lost (as infinitely slow)
OPEN_S = 300.0                     # s a page may take to open
GOAL_P95_S = 0.3                   # the pair's slider → verdict, 95th percentile
PAIR, RING = ("two_particle", "rho_r"), ("annulus_frame", "mu")
CORES = os.cpu_count() or 1        # this machine's cores (the ceiling)


def values_of(j: int, same: int, key: str, moves: int, step: float = 0.01) -> list[float]:
    """The values the j-th of `same` pages on slider `key` types, one per move: no value twice in the class (no page
    is served an analysis another page or an earlier move made, app/state.py `shared`), `step` apart (the slider's
    0.01, or half of it, a quarter step off the slider's, for a class too large for its steps), none the preset's
    (ρ/r 0.5 and μ 0.3 would change nothing at the first move: the move would never show)."""
    low = (0.25 if key == "rho_r" else 0.31) + (0.01 - step) / 2
    return [round(low + step * (j + same * k), 4) for k in range(moves)]


def _spec(i: int, j: int, same: int, preset_key: tuple, browser: bool, moves: int, step: float = 0.01) -> dict:
    from granstab_app.params import PARAMS
    preset, key = preset_key
    return {"i": i, "preset": preset, "default_preset": PAIR[0], "key": key, "label": PARAMS[key].label,
            "values": values_of(j, same, key, moves, step), "browser": browser}


def _rss() -> float:
    import psutil
    return psutil.Process().memory_info().rss / 1e6


class Pupils:
    """The pages' process (benchmarks/classroom_pupils.py): given its plan, then told `go` and `leave`; its events
    are read line by line on a thread (`expect`)."""

    def __init__(self, plan: dict):
        import tempfile
        self.stderr = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen([sys.executable, "-m", "granstab_bench.classroom_pupils"], text=True, bufsize=1,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.stderr)
        self.events: queue.Queue = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        self.say(json.dumps(plan))

    def _read(self) -> None:
        from .classroom_pupils import MARK
        for line in self.proc.stdout:
            if line.startswith(MARK):
                self.events.put(json.loads(line[len(MARK):]))
        self.events.put(None)

    def say(self, line: str) -> None:
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def expect(self, event: str, timeout: float) -> dict:
        got = self.events.get(timeout=timeout)
        if got is None or got["event"] != event:
            self.stderr.seek(0)
            raise RuntimeError(f"the pages' process: expected {event!r}, got {got!r}: {self.stderr.read()[-2000:]}")
        return got

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        self.stderr.close()


def _timed(ui, log: list) -> None:
    """Stamp the server's part of each slider move of the tab into `log`: its callback's start, the moment its verdict
    is queued (refresh's `_send_now`, before the scene is drawn), its end, each on time.perf_counter (and time.time
    for a browser's clock), and its thread's CPU (scene, an analysis run in this process, drawing: an offloaded
    analysis's worker time is not in it)."""
    apply, send = ui._apply_sliders, ui._send_now

    def timed_apply():
        entry = ui.move_stamps = {"start": time.perf_counter(), "start_epoch": time.time(), "cpu": time.thread_time()}
        apply()
        entry.update(end=time.perf_counter(), cpu=time.thread_time() - entry["cpu"], revision=ui.session.revision)
        log.append(entry)

    def timed_send():
        entry = getattr(ui, "move_stamps", None)
        if entry is not None and "queued" not in entry:
            entry.update(queued=time.perf_counter(), queued_epoch=time.time())
        send()
    ui._apply_sliders, ui._send_now = timed_apply, timed_send    # looked up at each call (app/panels.py)


def _cpu(processes, since: dict | None = None) -> dict:
    """CPU seconds (user + system) by process id of the processes still alive, less `since` (theirs before)."""
    import psutil
    out = {}
    for proc in processes:
        try:
            out[proc.pid] = sum(proc.cpu_times()[:2]) - (since or {}).get(proc.pid, 0.0)
        except psutil.Error:
            continue
    return out


def _kinds(me, pupils) -> dict:
    """The processes by kind: the server (this one), its analysis workers (spawned by multiprocessing), the pages'
    process and Chromium (with Playwright's driver, the pages' process's children)."""
    import psutil
    workers = [c for c in me.children(recursive=True) if c.pid != pupils.pid and _is_worker(c)]
    try:
        chromium = pupils.children(recursive=True)
    except psutil.Error:
        chromium = []
    return {"server": [me], "workers": workers, "pages_process": [pupils], "chromium": chromium}


def _is_worker(proc) -> bool:
    import psutil
    try:
        return "multiprocessing" in " ".join(proc.cmdline())
    except psutil.Error:
        return False


def _class(pages: list[dict], moves: int) -> dict:
    """Run `pages` (specs) on a new server, `moves` each; what the pages and the server measured, matched."""
    import psutil

    from granstab_app.server import App
    app, me = App(host="127.0.0.1", port=0, preset=PAIR[0]), psutil.Process()
    out = {"pages": len(pages), "moves": moves, "rss_start_mb": _rss()}
    pupils = Pupils({"url": app.url, "pages": pages, "moves": moves, "period": PERIOD, "lost_s": LOST_S,
                     "open_s": OPEN_S, "viewport": VIEWPORT})
    try:
        out.update({k: v for k, v in pupils.expect("ready", OPEN_S * 2).items() if k != "event"})
        uis = dict(app.uis)
        logs = {cid: [] for cid in uis}
        for cid, ui in uis.items():
            _timed(ui, logs[cid])
        time.sleep(2.0)                                      # the last pages' scenes drawn and sent
        out["rss_open_mb"], out["sessions_open"] = _rss(), len(uis)
        before = {kind: _cpu(procs) for kind, procs in _kinds(me, psutil.Process(pupils.proc.pid)).items()}
        wall0, load0 = time.perf_counter(), os.getloadavg()[0]
        pupils.say(f"go {time.monotonic() + 1.0}")
        with _collections() as pauses:
            reports = pupils.expect("moved", moves * PERIOD + 2 * LOST_S + 60)["pages"]
        out["gc"] = {"count": len(pauses), "full": sum(g == 2 for g, _, _ in pauses),
                     "longest_s": max((d for _, _, d in pauses), default=0.0)}
        out["moving_s"] = time.perf_counter() - wall0
        now = _kinds(me, psutil.Process(pupils.proc.pid))
        out["cores"] = {kind: sum(_cpu(procs, before[kind]).values()) / out["moving_s"] for kind, procs in now.items()}
        out["load_moving"] = (load0, os.getloadavg()[0])
        out["rss_moved_mb"] = _rss()
        out["matched"] = [_match(r, pages, uis, logs, moves) for r in reports]
        pupils.say("leave")
        pupils.expect("closed", 120)
        out["released"] = sum(ui.released.wait(120) for ui in uis.values())
        out["sessions_left"], out["rss_closed_mb"] = len(app.uis), _rss()
    finally:
        pupils.stop()
        app.stop()
    return out


@contextlib.contextmanager
def _collections():
    """The server's garbage collections meanwhile: [(generation, start on perf_counter, seconds)] (a collection holds
    the GIL: every page of the server waits)."""
    pauses, started = [], {}

    def note(phase, info):
        if phase == "start":
            started["t"] = time.perf_counter()
        elif "t" in started:
            pauses.append((info["generation"], started["t"], time.perf_counter() - started.pop("t")))
    gc.callbacks.append(note)
    try:
        yield pauses
    finally:
        gc.callbacks.remove(note)


def _match(report: dict, pages: list[dict], uis: dict, logs: dict, moves: int) -> dict:
    """A page's report joined with its session: the session holding the page's last value (each page types values
    of its own), whether it holds the page's last verdict too (own state), and each move split by the stamps."""
    from granstab_app.params import PARAMS
    spec = pages[report["i"]]
    last = PARAMS[spec["key"]].clean(spec["values"][moves - 1])
    mine = [cid for cid, ui in uis.items()
            if ui.session.preset == spec["preset"] and ui.session.params.get(spec["key"]) == last]
    ui = uis[mine[0]] if len(mine) == 1 else None
    why = ("no session of its own" if ui is None else "another revision" if report["revision"] != ui.session.revision
           else "another verdict" if report["verdict"] != (ui.session.verdict or "none")
           else "another value shown" if PARAMS[spec["key"]].clean(float(report["shown"])) != last else None)
    log = {e["revision"]: e for e in logs[mine[0]]} if ui is not None else {}
    moves_out = _browser_moves(report, log) if spec["browser"] else _protocol_moves(report, log)
    return {"i": spec["i"], "preset": spec["preset"], "browser": spec["browser"], "own": why is None, "why": why,
            "sessions": len(mine),
            "moves": moves_out, "errors": report.get("errors", []), "canvas": report.get("canvas"),
            "cpu": [e["cpu"] for e in log.values()]}


def _protocol_moves(report: dict, log: dict) -> list[dict]:
    """Per move of a protocol page (perf_counter, one clock): total = sent → verdict received; reach = sent → the
    callback starts (websocket, viser's dispatch, its thread pool, the tab's lock); work = callback start → verdict
    queued (scene, analysis, verdict); out = queued → received (the event loop packing the window, the send, the
    pages' own loop)."""
    out = []
    for m in report["moves"]:
        if m.get("lost") or "received" not in m:
            out.append({"total": float("inf")})
            continue
        e = log.get(m["revision"], {})
        row = {"total": m["received"] - m["sent"], "at": m["sent"]}
        if "queued" in e:
            row.update(reach=e["start"] - m["sent"], work=e["queued"] - e["start"], out=m["received"] - e["queued"],
                       callback=e["end"] - e["start"])
        out.append(row)
    return out


def _browser_moves(report: dict, log: dict) -> list[dict]:
    """Per move of a Chromium page (the page's clock, ms since the epoch): total = the value's input event → the
    frame after the badge shows a new revision; send = input → the server's callback starts (its time.time: the
    page's handler, its websocket worker, the way there, viser's dispatch); show = the verdict queued → that frame (the
    way back, the page's worker decoding it, React, the frame); own = send + show, the browser's part of a move."""
    inputs, badges, out, at = report["stamps"]["input"], report["stamps"]["badge"], [], 0
    for typed in report["typed"]:
        text = f"{typed['value']:g}"
        at = next((j for j in range(at, len(inputs)) if inputs[j][0] == text), None)
        if at is None or typed.get("lost"):
            out.append({"total": float("inf")})
            at = at or 0
            continue
        t_in = inputs[at][1]
        shown = next((b for b in badges if b[0] != typed["before"] and b[1] >= t_in), None)
        if shown is None:
            out.append({"total": float("inf")})
            continue
        row = {"total": (shown[2] - t_in) / 1e3}
        e = log.get(int(shown[0]), {})
        if "queued_epoch" in e:
            send, show = e["start_epoch"] - t_in / 1e3, shown[2] / 1e3 - e["queued_epoch"]
            row.update(send=send, show=show, own=send + show)
        out.append(row)
        at += 1
    return out


def run(quick: bool = False) -> dict:
    """Three servers one after the other: a Chromium page alone; the class of protocol pages (the server's latency,
    nothing of the pages' drawing on its cores); the class again with BROWSERS of its pair pages in Chromium."""
    from granstab.solve.threads import cap_process
    cap_process(1)                     # as granstab-app does: one BLAS thread per call
    alone = _class([_spec(0, 0, 1, PAIR, True, QUIET_MOVES[quick])], QUIET_MOVES[quick])
    n, ring, browsers, moves = PAGES[quick], ANNULUS[quick], BROWSERS[quick], MOVES[quick]

    def pages(in_chromium: int) -> list[dict]:
        return [_spec(i, i, ring, RING, False, moves) if i < ring else
                _spec(i, i - ring, n - ring, PAIR, i < ring + in_chromium, moves) for i in range(n)]
    r = _class(pages(browsers if quick else 0), moves)
    beside = r if quick else _class(pages(browsers), moves)      # --quick: one class, with its Chromium page
    r.update(annulus_pages=ring, browsers=browsers, period_s=PERIOD, alone=_summary_alone(alone))
    for run_ in {id(r): r, id(beside): beside}.values():
        run_.update(_summary(run_))
    r["beside"] = {k: beside[k] for k in ("errors", "own_state", "not_own", "canvas", "browser_in_class",
                                          f"{PAIR[0]}_protocol", "cores", "load_moving", "gc", "released", "lost",
                                          "sessions_left")}
    r.update(_ceiling_numbers(r))
    r["composed"] = _composed(r)
    del r["matched"]                   # every move of every page: summarised above
    r["probes"] = [_probe(size, size * ring // n) for size in PROBES[quick]]
    return r


def _probe(size: int, ring: int) -> dict:
    """A class of `size` protocol pages, `ring` of them on annulus_frame, PROBE_MOVES moves each (ρ/r half a slider
    step apart: 0.005, which a protocol page can send): the server's latency, CPU and memory there."""
    pages = [_spec(i, i, ring, RING, False, PROBE_MOVES) if i < ring else
             _spec(i, i - ring, size - ring, PAIR, False, PROBE_MOVES, step=0.005) for i in range(size)]
    p = _class(pages, PROBE_MOVES)
    p.update(_summary(p))
    return {"pages": size, "annulus_pages": ring, "pair": p[f"{PAIR[0]}_protocol"]["total"],
            "annulus": p[f"{RING[0]}_protocol"]["total"], "cores": p["cores"], "load": p["load_moving"],
            "per_page_mb": p["per_page_mb"], "own_state": p["own_state"], "gc": p["gc"], "lost": p["lost"]}


def _parts(matched: list, preset: str, browser: bool) -> dict:
    """Every move's parts of the pages of `preset` (Chromium pages or protocol pages), as sorted lists."""
    rows = [m for p in matched if p["preset"] == preset and p["browser"] == browser for m in p["moves"]]
    names = {k for row in rows for k in row} - {"at"}
    return {k: sorted(row[k] for row in rows if k in row) for k in names}


def _stats(values: list) -> dict:
    return {"n": len(values), "p50": statistics.median(values), "p95": _p95(values)} if values else {"n": 0}


def _summary_alone(r: dict) -> dict:
    parts = _parts(r["matched"], PAIR[0], True)
    return {"parts": {k: _stats(v) for k, v in parts.items()}, "errors": [e for p in r["matched"] for e in p["errors"]],
            "own": all(p["own"] for p in r["matched"]), "load": r["load_moving"], "moves": r["moves"],
            "own_s": parts.get("own", [])}


def _summary(r: dict) -> dict:
    """Medians and p95s of each part, per preset; the composed latency of a pupil on the pair."""
    out = {"errors": [e for p in r["matched"] for e in p["errors"]], "own_state": sum(p["own"] for p in r["matched"]),
           "not_own": [(p["i"], p["preset"], p["why"]) for p in r["matched"] if not p["own"]],
           "canvas": [p["canvas"] for p in r["matched"] if p["browser"]],
           "per_page_mb": (r["rss_open_mb"] - r["rss_start_mb"]) / r["pages"],
           "lost": sum(m["total"] == float("inf") for p in r["matched"] for m in p["moves"])}
    for name in (PAIR[0], RING[0]):
        out[f"{name}_protocol"] = {k: _stats(v) for k, v in _parts(r["matched"], name, False).items()}
        out[f"{name}_cpu_p50_s"] = statistics.median([c for p in r["matched"] if p["preset"] == name
                                                      for c in p["cpu"]] or [float("nan")])
    out["browser_in_class"] = {k: _stats(v) for k, v in _parts(r["matched"], PAIR[0], True).items()}
    return out


def _composed(r: dict) -> dict:
    """A pupil's pair move: the server's part under the class (each protocol page's move) + a browser's own part
    (each move of the page alone), every pair of the two taken (the parts drawn independently): median and p95."""
    server, own = _parts(r["matched"], PAIR[0], False).get("total", []), r["alone"]["own_s"]
    return _stats(sorted(a + b for a in server for b in own))


def _ceiling_numbers(r: dict) -> dict:
    """The class this machine could serve at the measured mix of pages moving every PERIOD s, from the CPU per move:
    the server's one process (one core of Python, its GIL) against its CPU per move, and the cores against the
    server's and the analysis workers' CPU per page (the pages are the pupils' browsers, on machines of their own)."""
    total = r["pages"] * r["moves"]
    per_move = r["cores"]["server"] * r["moving_s"] / total                                 # s of the server per move
    per_ring_move = r["cores"]["workers"] * r["moving_s"] / (r["annulus_pages"] * r["moves"])   # s of a worker
    per_page = (per_move + r["annulus_pages"] / r["pages"] * per_ring_move) / r["period_s"]     # cores per page
    return {"server_cpu_per_move_s": per_move, "worker_cpu_per_ring_move_s": per_ring_move, "cores_per_page": per_page,
            "ceiling_process_pages": r["period_s"] / per_move, "ceiling_machine_pages": CORES / per_page,
            "class_cores": per_page * r["pages"]}


def _p95(sorted_values: list) -> float:
    """The 95th percentile (nearest rank) of sorted values."""
    return sorted_values[min(len(sorted_values) - 1, int(round(0.95 * (len(sorted_values) - 1))))]


def _ms(s: dict, scale: str = "ms") -> str:
    """median · p95 of a part (ms or s)."""
    if not s.get("n"):
        return "—"
    f = (lambda x: f"{x * 1e3:.0f} ms") if scale == "ms" else (lambda x: f"{x:.1f} s")
    return f"{f(s['p50'])} · {f(s['p95'])}"


def markdown(r: dict) -> str:
    pair, ring, a, b = r[f"{PAIR[0]}_protocol"], r[f"{RING[0]}_protocol"], r["alone"], r["beside"]
    own, comp, c, n_pair = a["parts"], r["composed"], r["cores"], r["pages"] - r["annulus_pages"]
    return "\n".join([
        "## A class on one server", "",
        f"{r['pages']} pages on one `granstab-app` server (benchmarks/classroom.py): {n_pair} on the pair moving ρ/r, "
        f"{r['annulus_pages']} on annulus_frame (143 disks) moving μ, one move every {r['period_s']:g} s each, "
        f"{r['moves']} moves, no value typed twice in the class. The server runs alone in its process; the pages run "
        "in another (benchmarks/classroom_pupils.py), as a class's pages run in the pupils' browsers. Protocol pages "
        "speak viser's websocket protocol (real sessions, sent and decoding everything a browser is sent, moving "
        "their slider with a browser's message) and time a move from the message sent to the window with the new "
        "verdict received, on CLOCK_MONOTONIC in both processes, split by the server's own stamps. Three runs, one "
        f"server each: a Chromium page alone ({a['moves']} moves, load {a['load'][0]:.1f}: the browser's own time, its "
        "value's input event → the server's callback starts, and the verdict queued → the first frame after the badge "
        "shows it, the page's clock against the server's time.time, one system clock); the "
        f"class of {r['pages']} protocol pages; the class again with {r['browsers']} of its pair pages in headless "
        "Chromium (software WebGL on the same cores: the in-page check), timed in the page from the value's input "
        "event to that frame.", "",
        "| | median · p95 | goal |", "|---|---|---|",
        f"| **pair, slider → verdict as a pupil sees it**: the server's part under the class + the browser's own "
        f"(every pair of the two) | {_ms(comp)} | p95 ≤ {GOAL_P95_S * 1e3:.0f} ms |",
        f"| pair, the server's part: {n_pair} protocol pages, message sent → verdict received | {_ms(pair['total'])} | |",
        f"| · reaching the callback (websocket, viser's threads, the tab's lock) | {_ms(pair.get('reach', {}))} | |",
        f"| · the callback up to the verdict (scene, analysis, verdict) | {_ms(pair.get('work', {}))} | |",
        f"| · the verdict's way out (event loop, send, the pages' process) | {_ms(pair.get('out', {}))} | |",
        f"| pair, the browser's own (a Chromium page alone): input → the server's callback + verdict queued → the "
        f"frame showing it | {_ms(own.get('own', {}))} | |",
        f"| · input → the server's callback starts · verdict queued → the frame | {_ms(own.get('send', {}))} · "
        f"{_ms(own.get('show', {}))} | |",
        f"| that page alone, typed → shown | {_ms(own.get('total', {}))} | |",
        f"| the class with {r['browsers']} Chromium page(s): in those, typed → shown | "
        f"{_ms(b['browser_in_class'].get('total', {}))} | |",
        f"| · in those, the browser's own part (as alone, above) | {_ms(b['browser_in_class'].get('own', {}))} | |",
        f"| · the protocol pages of that run, sent → received | {_ms(b[f'{PAIR[0]}_protocol']['total'])} | |",
        f"| annulus_frame, sent → received (its analysis in a worker) | {_ms(ring['total'], 's')} | |",
        f"| Chromium: page errors · canvas drawn (colours in a screenshot of it) | {len(b['errors']) + len(a['errors'])}"
        f" · {', '.join(str(x) for x in b['canvas'])} | 0 · drawn |",
        f"| pages keeping their own state (last value, last verdict, nothing written over): the class · with "
        f"Chromium | {r['own_state']} · {b['own_state']} of {r['pages']} | all |",
        f"| moves lost (no verdict within {LOST_S:.0f} s): the class · with Chromium | {r['lost']} · {b['lost']} | 0 |",
        f"| server RSS: start · {r['pages']} pages open · after the moves · all closed | {r['rss_start_mb']:.0f} · "
        f"{r['rss_open_mb']:.0f} · {r['rss_moved_mb']:.0f} · {r['rss_closed_mb']:.0f} MB | bounded |",
        f"| per page (open − start, / pages) | {r['per_page_mb']:.1f} MB | |",
        f"| closed pages: sessions released · left | {r['released']} · {r['sessions_left']} | all · 0 |",
        f"| the server's garbage collections while moving: longest · full ones · all | "
        f"{r['gc']['longest_s'] * 1e3:.0f} ms · {r['gc']['full']} · {r['gc']['count']} | |",
        f"| CPU while moving (cores): server · analysis workers · pages' process; with Chromium: Chromium | "
        f"{c['server']:.2f} · {c['workers']:.2f} · {c['pages_process']:.2f}; {b['cores']['chromium']:.2f} | |",
        f"| 1-min load at the start and end of the moves ({CORES} cores): the class · with Chromium | "
        f"{r['load_moving'][0]:.1f} → {r['load_moving'][1]:.1f} · {b['load_moving'][0]:.1f} → "
        f"{b['load_moving'][1]:.1f} | |",
        f"| ceiling at this mix: pages one server process serves · pages {CORES} cores serve (server + workers) | "
        f"{r['ceiling_process_pages']:.0f} · {r['ceiling_machine_pages']:.0f} | ≥ {r['pages']} |",
        "", _verdict(r), "", *_probe_table(r),
    ]) + "\n"


def _probe_table(r: dict) -> list[str]:
    """The class and the larger classes of protocol pages, side by side."""
    if not r.get("probes"):
        return []
    rows = [{"pages": r["pages"], "annulus_pages": r["annulus_pages"], "pair": r[f"{PAIR[0]}_protocol"]["total"],
             "annulus": r[f"{RING[0]}_protocol"]["total"], "cores": r["cores"], "load": r["load_moving"],
             "per_page_mb": r["per_page_mb"], "own_state": r["own_state"], "lost": r["lost"]}, *r["probes"]]
    return [f"Larger classes of protocol pages, the same mix ({PROBE_MOVES} moves each, one server each):", "",
            "| pages (annulus_frame) | pair, server's part: median · p95 | annulus_frame: median · p95 | CPU: "
            "server · workers | RSS per page | own state · moves lost | load |", "|---|---|---|---|---|---|---|",
            *(f"| {x['pages']} ({x['annulus_pages']}) | {_ms(x['pair'])} | {_ms(x['annulus'], 's')} | "
              f"{x['cores']['server']:.2f} · {x['cores']['workers']:.2f} | {x['per_page_mb']:.1f} MB | "
              f"{x['own_state']} of {x['pages']} · {x['lost']} | {x['load'][0]:.1f} → {x['load'][1]:.1f} |" for x in rows),
            ""]


def _verdict(r: dict) -> str:
    """What the numbers say: the goal, where a pupil's time goes, the ceiling."""
    comp, met = r["composed"], r["composed"].get("p95", float("inf")) <= GOAL_P95_S
    server, own = r[f"{PAIR[0]}_protocol"]["total"], r["alone"]["parts"].get("own", {})
    inpage = r["beside"]["browser_in_class"].get("total", {})
    ring = r[f"{RING[0]}_protocol"]["total"]
    return (f"**The goal is {'met' if met else 'not met'} on this machine**: a pupil's p95 is "
            f"{comp.get('p95', float('nan')) * 1e3:.0f} ms, composed of the server's part under the class (p95 "
            f"{server.get('p95', float('nan')) * 1e3:.0f} ms) and the browser's own (p95 "
            f"{own.get('p95', float('nan')) * 1e3:.0f} ms, on a page alone). The Chromium pages drawing beside the "
            f"class on its {CORES} cores saw p95 {inpage.get('p95', float('nan')) * 1e3:.0f} ms: a pupil's browser "
            "draws on the pupil's machine, these on the server's. The server process took "
            f"{r['cores']['server']:.2f} of a core, {r['server_cpu_per_move_s'] * 1e3:.0f} ms per move at this mix "
            f"(a pair move's callback {r[f'{PAIR[0]}_cpu_p50_s'] * 1e3:.0f} ms; an annulus_frame move's "
            f"{r[f'{RING[0]}_cpu_p50_s'] * 1e3:.0f} ms, and {r['worker_cpu_per_ring_move_s']:.2f} s of analysis in a "
            f"worker at a lower priority: the rest of an annulus_frame move's median {ring.get('p50', 0):.1f} s is "
            "waiting, for a free worker and for a core of this shared machine); its longest garbage collection "
            f"{r['gc']['longest_s'] * 1e3:.0f} ms (the open tabs' objects are kept out of the collector's full passes, "
            "app/server.py settle_heap: with 30 tabs those passes held the GIL 210-225 ms, twice in 20 s). "
            + _ceiling(r) + " Beyond it moves queue behind each tab's lock, where only the latest value is analysed "
            "(app/panels.py): a busy server delays pages, it never mixes their states.")


def _ceiling(r: dict) -> str:
    """The ceiling: computed from the CPU per move, and bracketed by the larger classes measured (the goal with the
    browser's own p95 added to the server's)."""
    own = r["alone"]["parts"].get("own", {}).get("p95", 0.0)
    sizes = [(r["pages"], r[f"{PAIR[0]}_protocol"]["total"].get("p95", float("inf")))] + [
        (x["pages"], x["pair"].get("p95", float("inf"))) for x in r.get("probes", ())]
    held = [n for n, p95 in sizes if p95 + own <= GOAL_P95_S]
    lost = [n for n, p95 in sizes if p95 + own > GOAL_P95_S]
    measured = ("" if not r.get("probes") else
                f" Measured (below): the goal holds up to {max(held)} pages." if held and not lost else
                f" Measured (below): the goal holds with {max(held)} pages and is lost with {min(lost)}: "
                "the ceiling for the goal is between the two." if held else
                " Measured (below): the goal is lost already.")
    return (f"Ceiling from the CPU per move: one server process (one core of Python) saturates at about "
            f"{r['ceiling_process_pages']:.0f} pages moving every {r['period_s']:g} s, the {CORES} cores with the "
            f"workers' analyses at about {r['ceiling_machine_pages']:.0f} pages of this mix." + measured)
