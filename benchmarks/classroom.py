"""A class on one server (issue 29): PAGES pages on one explorer, each moving a slider every PERIOD seconds, ANNULUS
of them on annulus_frame (μ) and the rest on the pair (ρ/r). BROWSERS of the pages are headless Chromium pages (one on
annulus_frame, the rest on the pair), whose latency is measured as browser_latency measures it (the value typed into
the slider's number box → the page's verdict badge showing a new analysis, its data-revision); the others are
protocol pages (granstab_app.headless: viser's websocket protocol, each a real session of the server that receives
everything a browser would), moving their slider by viser's GuiUpdateMessage, whose latency is the server's (message
sent → the new verdict written). Each Chromium page draws its canvas in software (no GPU): the CPU the Chromium
processes took while the class moved is measured and reported per page, and it is what bounds BROWSERS on this 2-core
machine (each run says how many fit by its own numbers: `_fit`). The Chromium pages are all on the pair, whose latency
is the goal. Runs here (2026-11-26, a loaded machine) with one annulus_frame page among them took 0.76 core for 2
pages and 1.01 for 8 (1 + 7 on the pair), with 2 pair pages alone 0.35: the annulus_frame page (143 particles and 240
contact lines drawn in software) takes Chromium most of a core, and beside the 1.0 core the server and its workers ask
of the full class it filled the machine, so the browsers' contention, not the server, set the pages' latency. Each page types values of its own; at the end every
session holds its page's last value and its verdict. The server's memory (RSS of this process; Chromium, Playwright's
driver and the analysis workers are processes of their own) before, with all pages open, after the moves and after
every page has closed; the CPU of the server's process, of its analysis workers (app/state.py `analysis_pool`) and of
Chromium while the class moved, and each move's own CPU in the server (its callback's thread time)."""
from __future__ import annotations

import asyncio
import os
import statistics
import tempfile
import threading
import time

PAGES = {True: 6, False: 30}
ANNULUS = {True: 2, False: 5}
BROWSERS = {True: 2, False: 8}     # all on the pair (how many fit: `_fit`)
BUSY = 0.8                         # share of the cores the class and its Chromium pages may keep busy (`_fit`)
MOVES = {True: 3, False: 10}
VIEWPORT = {"width": 1200, "height": 800}   # px of each Chromium page (less software-rendered canvas than 1600 × 1000)
PERIOD = 2.0                       # s between one page's slider moves
LOST_S = 120.0                     # s after which a move that never showed is counted lost (as infinitely slow)
GOAL_P95_S = 0.3                   # the pair's slider → verdict, 95th percentile
PAIR, RING = ("two_particle", "rho_r"), ("annulus_frame", "mu")
CORES = os.cpu_count() or 1        # this machine's cores (the ceiling)


def values_of(i: int, key: str) -> tuple[float, float]:
    """Page i's two values (its own: no two pages type the same one; neither is the preset's, ρ/r 0.5 and μ 0.3)."""
    return (0.6 + 0.01 * i, 1.4 + 0.01 * i) if key == "rho_r" else (0.35 + 0.01 * i, 0.60 + 0.01 * i)


def _rss() -> float:
    import psutil
    return psutil.Process().memory_info().rss / 1e6


def _revision(ui) -> str:
    """The revision of the verdict the server last wrote into the tab's badge."""
    import re
    return re.search(r'data-revision="(\d+)"', ui.headline.content).group(1)


def _prepare(ui, preset: str) -> None:
    """Switch the tab to `preset` (from the server side, as the page's menu does) and time the server's part of each
    slider move from then on (`ui.update_s`: the callback, lock wait to scene sent; `ui.update_cpu_s`: its thread's
    CPU: scene, an analysis run in this process, drawing — an offloaded analysis's worker time is not in it)."""
    if preset != PAIR[0]:
        ui.preset.value = preset
    ui.update_s, ui.update_cpu_s = [], []
    apply = ui._apply_sliders

    def timed():
        t, c = time.perf_counter(), time.thread_time()
        apply()
        ui.update_s.append(time.perf_counter() - t)
        ui.update_cpu_s.append(time.thread_time() - c)
    ui._apply_sliders = timed         # looked up at each call by the slider's callback (app/panels.py)


async def _open(ctx, app, errors: list, preset: str):
    """One Chromium page, its session found (the one new to app.uis), switched to `preset`."""
    known = set(app.uis)
    page = await ctx.new_page()
    page.on("pageerror", lambda exc: errors.append(f"pageerror: {exc}"))
    page.on("console", lambda m: errors.append(f"console: {m.text}") if m.type == "error" else None)
    await page.goto(app.url)
    await page.wait_for_selector(".granstab-verdict:not([data-verdict=none])", timeout=300_000)
    end = time.monotonic() + 120
    while not set(app.uis) - known and time.monotonic() < end:
        await asyncio.sleep(0.1)
    ui = app.uis[next(iter(set(app.uis) - known))]
    await asyncio.get_running_loop().run_in_executor(None, _prepare, ui, preset)
    await page.wait_for_selector(f'.granstab-verdict[data-revision="{ui.session.revision}"]', timeout=300_000)
    return page, ui


async def _browser_pupil(page, ui, key: str, values, moves: int, start: float) -> list[float]:
    """MOVES slider moves typed into the page at start + k·PERIOD (later when the previous one took longer)."""
    from playwright.async_api import TimeoutError as PlaywrightTimeout

    from granstab_app.browser import number_box
    box = number_box(page, ui.sliders[key])
    out = []
    for k in range(moves):
        await asyncio.sleep(max(0.0, start + k * PERIOD - time.monotonic()))
        rev = await page.locator(".granstab-verdict").get_attribute("data-revision")
        t = time.perf_counter()
        await box.fill(f"{values[k % 2]:g}")
        await box.press("Enter")
        try:
            await page.wait_for_function("r => document.querySelector('.granstab-verdict').dataset.revision !== r",
                                         arg=rev, timeout=LOST_S * 1e3)
            out.append(time.perf_counter() - t)
        except PlaywrightTimeout:
            out.append(float("inf"))            # a move that never showed: counted, as the slowest
    return out


class ProtocolPupil(threading.Thread):
    """A protocol page: opens, switches to its preset, waits for `go`, moves its slider MOVES times (GuiUpdateMessage,
    as the browser sends it), then stays until `leave` and closes (HeadlessPage waits for its session's release)."""

    def __init__(self, app, preset, key, values, moves, go, leave, clock):
        super().__init__(daemon=True)
        self.app, self.preset, self.key, self.values, self.moves = app, preset, key, values, moves
        self.go, self.leave, self.clock = go, leave, clock
        self.ready, self.ui, self.latency, self.released = threading.Event(), None, [], False

    def run(self) -> None:
        from granstab_app.headless import HeadlessPage
        with HeadlessPage(self.app, timeout=300) as page:
            self.ui = page.ui
            _prepare(self.ui, self.preset)
            self.ready.set()
            self.go.wait()
            uuid = self.ui.sliders[self.key]._impl.uuid      # the slider's id in viser's protocol
            for k in range(self.moves):
                time.sleep(max(0.0, self.clock["start"] + k * PERIOD - time.monotonic()))
                rev, t = _revision(self.ui), time.perf_counter()
                page.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": self.values[k % 2]}})
                while _revision(self.ui) == rev and time.perf_counter() - t < LOST_S:
                    time.sleep(0.005)
                self.latency.append(time.perf_counter() - t if _revision(self.ui) != rev else float("inf"))
            self.leave.wait()
        self.released = self.ui.released.is_set()


def _helpers(me) -> dict:
    """This process's helper processes by kind: the analysis workers (spawned by multiprocessing) and Chromium's."""
    import psutil
    out = {"workers": [], "chromium": []}
    for child in me.children(recursive=True):
        try:
            if "multiprocessing" in " ".join(child.cmdline()):
                out["workers"].append(child)
            elif "chrom" in child.name():
                out["chromium"].append(child)
        except psutil.Error:
            continue
    return out


def _cpu(processes) -> float:
    """CPU seconds (user + system) of the processes still alive."""
    import psutil
    total = 0.0
    for proc in processes:
        try:
            total += sum(proc.cpu_times()[:2])
        except psutil.Error:
            continue
    return total


def _own_state(ui, key: str, value: float) -> bool:
    """The tab's session holds its page's last value, and its badge the verdict of that state."""
    with ui.lock:
        return ui.session.params[key] == value and _revision(ui) == str(ui.session.revision)


async def _chromium_class(app, plan, moves: int, clock: dict, go, errors: list, out: dict) -> list:
    """Open the Chromium pages (`plan`: [(page index, (preset, slider))]), then (once the protocol pages are ready: `clock["ready"]`) start every page's moves;
    returns [(page's last shown revision, ui, latencies)] after closing them."""
    from playwright.async_api import async_playwright

    from granstab_app.browser import FLAGS
    async with async_playwright() as pw:
        with tempfile.TemporaryDirectory() as profile:
            ctx = await pw.chromium.launch_persistent_context(profile, executable_path="/usr/bin/chromium",
                                                              headless=True, viewport=VIEWPORT, args=FLAGS)
            t = time.perf_counter()
            opened = [await _open(ctx, app, errors, preset) for _, (preset, _) in plan]
            out["open_browsers_s"] = time.perf_counter() - t
            await asyncio.get_running_loop().run_in_executor(None, clock["ready"])
            clock["start"] = time.monotonic() + 1.0
            go.set()
            lat = await asyncio.gather(*(
                _browser_pupil(page, ui, key, values_of(i, key), moves, clock["start"] + PERIOD * i / clock["n"])
                for (page, ui), (i, (_, key)) in zip(opened, plan)))
            await asyncio.get_running_loop().run_in_executor(None, clock["moved"])   # Chromium still open
            shown = [await p.locator(".granstab-verdict").get_attribute("data-revision") for p, _ in opened]
            for page, _ in opened:
                await page.close()
            await ctx.close()
    return [(rev, ui, row) for rev, (_, ui), row in zip(shown, opened, lat)]


def _class(quick: bool) -> dict:
    import psutil

    from granstab_app.server import App
    n, ring, browsers, moves = PAGES[quick], ANNULUS[quick], BROWSERS[quick], MOVES[quick]
    plan = [RING if i < ring else PAIR for i in range(n)]          # page i: the first `ring` on annulus_frame
    in_browser = list(range(ring, ring + browsers))               # Chromium pages: on the pair (the goal's)
    app = App(host="127.0.0.1", port=0, preset=PAIR[0])
    go, leave, errors, me = threading.Event(), threading.Event(), [], psutil.Process()
    out = {"pages": n, "annulus_pages": ring, "browsers": browsers, "moves": moves, "period_s": PERIOD,
           "rss_start_mb": _rss()}
    clock = {"n": n, "start": 0.0}
    pupils = {i: ProtocolPupil(app, plan[i][0], plan[i][1], values_of(i, plan[i][1]), moves, go, leave, clock)
              for i in range(n) if i not in in_browser}

    def ready():
        """The protocol pages open once the browsers are open; then the moves start for every page."""
        t = time.perf_counter()
        for pupil in pupils.values():
            pupil.start()
        for pupil in pupils.values():
            pupil.ready.wait(600)
        out["open_protocol_s"] = time.perf_counter() - t
        out["rss_open_mb"] = _rss()
        clock["helpers"] = _helpers(me)
        clock["cpu0"], clock["wall0"], clock["load0"] = sum(me.cpu_times()[:2]), time.perf_counter(), os.getloadavg()[0]
        clock["helpers0"] = {kind: _cpu(procs) for kind, procs in clock["helpers"].items()}
    clock["ready"] = ready

    def moved():
        """Every page has made its moves: the CPU the server, its workers and Chromium took meanwhile."""
        for pupil in pupils.values():
            while len(pupil.latency) < moves and pupil.is_alive():
                time.sleep(0.1)
        out["moving_s"] = time.perf_counter() - clock["wall0"]
        out["server_cpu_share"] = (sum(me.cpu_times()[:2]) - clock["cpu0"]) / out["moving_s"]
        for kind, procs in clock["helpers"].items():        # cores the analysis workers and Chromium took
            out[f"{kind}_cores"] = (_cpu(procs) - clock["helpers0"][kind]) / out["moving_s"]
        out["load_moving"] = (clock["load0"], os.getloadavg()[0])
    clock["moved"] = moved
    try:
        shown = asyncio.run(_chromium_class(app, [(i, plan[i]) for i in in_browser], moves, clock, go, errors, out))
        out["rss_moved_mb"] = _rss()
        last = {i: round(values_of(i, plan[i][1])[(moves - 1) % 2], 6) for i in range(n)}
        uis = [ui for _, ui, _ in shown] + [p.ui for p in pupils.values()]
        page_revs = [rev for rev, _, _ in shown] + [None] * len(pupils)
        own = [(rev is None or rev == str(ui.session.revision)) and _own_state(ui, plan[i][1], last[i])
               for i, ui, rev in zip([*in_browser, *pupils], uis, page_revs)]
        out["own_state"] = sum(own)
        out["not_own"] = [(i, plan[i][0], ui.session.params[plan[i][1]], last[i], rev, _revision(ui),
                           ui.session.revision) for i, ui, rev, ok in zip([*in_browser, *pupils], uis, page_revs, own)
                          if not ok]
        leave.set()
        for pupil in pupils.values():
            pupil.join(600)
        for ui in uis:
            ui.released.wait(120)
        out["released"] = sum(ui.released.is_set() for ui in uis)
        out["sessions_left"] = len(app.uis)
        out["rss_closed_mb"] = _rss()
    finally:
        leave.set()
        app.stop()
    names = (PAIR[0], RING[0])
    out["latency_s"] = {nm: [x for i, (_, _, row) in zip(in_browser, shown) if plan[i][0] == nm for x in row]
                        for nm in names}
    out["protocol_latency_s"] = {nm: [x for i, p in pupils.items() if plan[i][0] == nm for x in p.latency]
                                 for nm in names}
    out["server_s"] = {nm: [x for ui, i in zip(uis, [*in_browser, *pupils]) if plan[i][0] == nm for x in ui.update_s]
                       for nm in names}
    out["callback_cpu_s"] = {nm: [x for ui, i in zip(uis, [*in_browser, *pupils]) if plan[i][0] == nm
                                  for x in ui.update_cpu_s] for nm in names}
    out["errors"] = errors
    return out


def run(quick: bool = False) -> dict:
    from granstab.solve.threads import cap_process
    cap_process(1)                     # as granstab-app does: one BLAS thread per call
    r = _class(quick)
    for name in (PAIR[0], RING[0]):
        server = sorted(r["server_s"][name]) or [float("nan")]
        r[f"{name}_server_p50_s"], r[f"{name}_server_p95_s"] = statistics.median(server), _p95(server)
        proto = sorted(r["protocol_latency_s"][name]) or [float("nan")]
        r[f"{name}_protocol_p50_s"], r[f"{name}_protocol_p95_s"] = statistics.median(proto), _p95(proto)
    pair = sorted(r["latency_s"][PAIR[0]])
    r["pair_p50_s"], r["pair_p95_s"] = statistics.median(pair), _p95(pair)
    r["per_page_mb"] = (r["rss_open_mb"] - r["rss_start_mb"]) / r["pages"]
    for name in (PAIR[0], RING[0]):
        r[f"{name}_cpu_p50_s"] = statistics.median(r["callback_cpu_s"][name] or [float("nan")])
    r.update(_ceiling_numbers(r))
    return r


def _ceiling_numbers(r: dict) -> dict:
    """The class this machine could serve at the measured mix of pages moving every PERIOD s, from the CPU per move
    (every page made all its moves, late or not): the server's one process (one core of Python, its GIL) against its
    CPU per move, and the cores against the server's and the analysis workers' CPU per page (Chromium is the
    benchmark's own client: a class's browsers run on the pupils' machines)."""
    per_move = r["server_cpu_share"] * r["moving_s"] / (r["pages"] * r["moves"])       # s of the server per move
    per_ring_move = r["workers_cores"] * r["moving_s"] / (r["annulus_pages"] * r["moves"])   # s of a worker
    per_page = (per_move + r["annulus_pages"] / r["pages"] * per_ring_move) / r["period_s"]   # cores per page
    return {"server_cpu_per_move_s": per_move, "worker_cpu_per_ring_move_s": per_ring_move, "cores_per_page": per_page,
            "ceiling_process_pages": r["period_s"] / per_move, "ceiling_machine_pages": CORES / per_page,
            "chromium_cores_per_page": r["chromium_cores"] / r["browsers"], "class_cores": per_page * r["pages"]}


def _fit(r: dict) -> str:
    """How many Chromium pages fit beside the class: those that keep the server, its workers (the cores the class
    asks at its schedule) and Chromium (its measured cores a page) under BUSY of the cores."""
    fit = int((BUSY * CORES - r["class_cores"]) / r["chromium_cores_per_page"])
    return (f"Chromium pages that fit beside this class: about {max(fit, 0)} (the class asks {r['class_cores']:.2f} "
            f"of the {CORES} cores at its schedule, a Chromium page took {r['chromium_cores_per_page']:.2f} while "
            f"moving; {BUSY:.0%} busy at most, above which every process queues for a core).")


def _p95(sorted_values: list) -> float:
    """The 95th percentile (nearest rank) of sorted values."""
    return sorted_values[min(len(sorted_values) - 1, int(round(0.95 * (len(sorted_values) - 1))))]


def markdown(r: dict) -> str:
    pair_n, ring_n = r["pages"] - r["annulus_pages"], r["annulus_pages"]
    return "\n".join([
        "## A class on one server", "",
        f"{r['pages']} pages on one `granstab-app` server (benchmarks/classroom.py): {pair_n} on the pair moving ρ/r, "
        f"{ring_n} on annulus_frame (143 disks) moving μ, each page one move every {r['period_s']:g} s, {r['moves']} "
        f"moves, every page typing values of its own. {r['browsers']} of them are headless Chromium pages (software "
        "WebGL, in one Chromium on this machine beside the server; all on the pair: an annulus_frame page "
        "takes Chromium most of a core, benchmarks/classroom.py), their latency measured as "
        "browser_latency does (value typed → the badge shows the new analysis); the other "
        f"{r['pages'] - r['browsers']} are protocol pages (viser's websocket protocol: real sessions of the server, "
        "sent everything a browser is sent, moving their slider with the message a browser sends), their latency "
        f"the server's (message sent → new verdict written). Opening: the Chromium pages one after the other in "
        f"{r['open_browsers_s']:.0f} s, then the protocol pages at once in {r['open_protocol_s']:.0f} s.", "",
        "| | result | goal |", "|---|---|---|",
        f"| page errors | {len(r['errors'])} | 0 |",
        f"| pages keeping their own state (own last value, last verdict sent) | {r['own_state']} of {r['pages']} | all |",
        f"| pair: slider → verdict in the page, median · p95 | {r['pair_p50_s'] * 1e3:.0f} ms · "
        f"**{r['pair_p95_s'] * 1e3:.0f} ms** | p95 ≤ {GOAL_P95_S * 1e3:.0f} ms |",
        f"| pair: slider → verdict at the server, protocol pages, median · p95 | "
        f"{r['two_particle_protocol_p50_s'] * 1e3:.0f} ms · **{r['two_particle_protocol_p95_s'] * 1e3:.0f} ms** | |",
        f"| pair: the server's part (callback start → scene sent), median · p95 · its own CPU, median | "
        f"{r['two_particle_server_p50_s'] * 1e3:.0f} ms · {r['two_particle_server_p95_s'] * 1e3:.0f} ms · "
        f"{r['two_particle_cpu_p50_s'] * 1e3:.0f} ms | |",
        f"| annulus_frame: slider → verdict at the server, protocol pages, median · p95 | "
        f"{r['annulus_frame_protocol_p50_s']:.1f} s · {r['annulus_frame_protocol_p95_s']:.1f} s | |",
        f"| annulus_frame: the server's part, median · p95 · its own CPU (analysis in a worker), median | "
        f"{r['annulus_frame_server_p50_s']:.1f} s · {r['annulus_frame_server_p95_s']:.1f} s · "
        f"{r['annulus_frame_cpu_p50_s'] * 1e3:.0f} ms | |",
        f"| server RSS: start · {r['pages']} pages open · after the moves · all closed | {r['rss_start_mb']:.0f} · "
        f"{r['rss_open_mb']:.0f} · {r['rss_moved_mb']:.0f} · {r['rss_closed_mb']:.0f} MB | bounded |",
        f"| per page (open − start, / pages) | {r['per_page_mb']:.1f} MB | |",
        f"| closed pages: sessions released · left | {r['released']} · {r['sessions_left']} | all · 0 |",
        f"| CPU while moving (cores): server process · analysis workers · Chromium ({r['chromium_cores_per_page']:.2f} "
        f"per page) | {r['server_cpu_share']:.2f} · {r['workers_cores']:.2f} · {r['chromium_cores']:.2f} | |",
        f"| 1-min load at the start and end of the moves ({CORES} cores) | {r['load_moving'][0]:.1f} → "
        f"{r['load_moving'][1]:.1f} | |",
        f"| ceiling at this mix: pages one server process serves · pages {CORES} cores serve (server + workers) | "
        f"{r['ceiling_process_pages']:.0f} · {r['ceiling_machine_pages']:.0f} | ≥ {r['pages']} |",
        "", _ceiling(r) + " " + _fit(r), "",
    ]) + "\n"


def _ceiling(r: dict) -> str:
    """Where the time goes and what limits the class here, from the measured parts: the CPU the server process got
    against what the schedule asks of it (pages / PERIOD moves a second at its CPU per move)."""
    asked = r["server_cpu_per_move_s"] * r["pages"] / r["period_s"]      # cores the schedule asks of the server
    starved = r["server_cpu_share"] < 0.8 * asked
    where = "" if r["pair_p95_s"] <= GOAL_P95_S else " The goal is not met here. " + (
        f"The server process got {r['server_cpu_share']:.2f} of a core where the schedule asks {asked:.2f}: its "
        f"moves waited for a core of the machine (1-minute load {r['load_moving'][1]:.1f} on {CORES} cores: the "
        "Chromium pages, the workers and other work on this shared machine), not for its own Python, which a busy "
        "process would show near 1 core." if starved else
        f"The server process got {r['server_cpu_share']:.2f} of a core, what the schedule asks ({asked:.2f}): "
        + ("its moves queue for its one core of Python (the GIL)." if r["server_cpu_share"] > 0.7 else
           "the time beyond its own is the page's (Chromium drawing in software beside it).")) + (
        f" In the page the pair's p95 is {r['pair_p95_s'] / max(r['two_particle_protocol_p95_s'], 1e-9):.1f}× the "
        "server's: the rest is Chromium's own time on the shared cores.")
    return (f"Where the time goes: while the class moved the server process took {r['server_cpu_share']:.2f} of a "
            f"core, its analysis workers {r['workers_cores']:.2f} (at a lower priority, app/state.py WORKER_NICE: a "
            f"core goes to the server first) and the {r['browsers']} Chromium pages {r['chromium_cores']:.2f} "
            f"({r['chromium_cores_per_page']:.2f} each: a page redraws its canvas in software; more Chromium pages "
            f"would measure the browsers' contention for the {CORES} cores rather than the server). A pair move cost "
            f"the server {r['two_particle_cpu_p50_s'] * 1e3:.0f} ms of its callback's CPU (median: scene, analysis, "
            f"drawing the changes), an annulus_frame move {r['annulus_frame_cpu_p50_s'] * 1e3:.0f} ms (its analysis "
            f"runs in a worker: {r['worker_cpu_per_ring_move_s']:.2f} s of it per move); with viser's sending, the server "
            f"process spent {r['server_cpu_per_move_s'] * 1e3:.0f} ms per move at this mix. Ceiling: one server process (one core of Python) serves about "
            f"{r['ceiling_process_pages']:.0f} pages of this mix moving every {r['period_s']:g} s, and the {CORES} "
            f"cores, with the workers' annulus_frame analyses, about {r['ceiling_machine_pages']:.0f}; moves beyond "
            "that queue behind each tab's lock, where only the latest value is analysed (app/panels.py): a busy "
            "server delays pages, it never mixes their states." + where)
