"""The class's pages, in a process of their own (`python -m granstab_bench.classroom_pupils`, driven by
benchmarks/classroom.py): the server's process then runs the server alone, as it does in a class, where every page is
a browser on a pupil's own machine.

One asyncio loop holds every page:
- protocol pages: websocket clients speaking viser's protocol as a browser does (the first camera opens the session;
  every window the server sends is received and its messages decoded; a slider moves by the GuiUpdateMessage a browser
  sends; the preset by the dropdown's);
- Chromium pages (Playwright, Debian chromium), whose latency is stamped inside the page (see STAMPS).

Clocks: a protocol page stamps with time.perf_counter (CLOCK_MONOTONIC on Linux, one clock for every process of this
machine), the clock of the server's stamps and of the `timestampSec` viser writes into each window it sends. A
Chromium page stamps with performance.timeOrigin + performance.now() (ms since the epoch), compared with the server's
time.time().

Talk with the parent: a JSON plan on the first line of stdin; then lines on stdout starting with MARK (`ready`,
`moved`, `closed` events, JSON) and, on stdin, `go START` (a time.monotonic at which the moves begin) and `leave`.
"""
from __future__ import annotations

import asyncio
import json
import re
import sys
import tempfile
import time
from types import SimpleNamespace

MARK = "@@pupils "
REVISION = re.compile(r'class="granstab-verdict" data-verdict="([^"]*)" data-revision="(\d+)"')
# In a Chromium page: the time each value typed into a slider's number box arrives (the input event, captured before
# the page's own handler sends it) and the time the verdict badge shows a new revision (the first animation frame
# after the DOM changed: the frame that paints it).
STAMPS = """(() => {
  const now = () => performance.timeOrigin + performance.now();
  window.granstabStamps = {input: [], badge: []};
  document.addEventListener('input', e => {
    const t = e.target;
    if (t && t.classList && t.classList.contains('mantine-NumberInput-input')) granstabStamps.input.push([t.value, now()]);
  }, true);
  let last = null;
  const look = () => {
    const b = document.querySelector('.granstab-verdict');
    const r = b ? b.dataset.revision : null;
    if (r !== null && r !== last) {
      last = r;
      const seen = now();
      requestAnimationFrame(() => granstabStamps.badge.push([r, seen, now()]));
    }
  };
  new MutationObserver(look).observe(document, {subtree: true, childList: true, attributes: true, characterData: true});
})()"""


class ProtocolPage:
    """One protocol page: its websocket, what it has been sent (the slider's and preset menu's ids, the verdict's
    revision and word, the slider value shown) and, per move, the times it sent and received."""

    def __init__(self, spec: dict, url: str):
        import zstandard
        self.spec, self.url = spec, url
        self.zstd = zstandard.ZstdDecompressor()
        self.ws, self.reader = None, None
        self.ids: dict[str, str] = {}                 # label → uuid (the slider, "Preset")
        self.headline: str | None = None
        self.revision, self.verdict, self.shown = 0, None, None
        self.changed = asyncio.Event()
        self.received = 0                             # bytes
        self.moves: list[dict] = []                   # {"sent", "received", "packed", "revision"}

    async def open(self, height: int, timeout: float) -> None:
        import viser
        from websockets.asyncio.client import connect

        from granstab_app.headless import CAMERA
        self.ws = await connect(self.url, subprotocols=[f"viser-v{viser.__version__}"], max_size=None)
        self.reader = asyncio.create_task(self._read())
        await self.send({**CAMERA, "image_height": height})
        await self._until(lambda: self.revision > 0 and {self.spec["label"], "Preset"} <= set(self.ids), timeout)
        if self.spec["preset"] != self.spec["default_preset"]:
            start = self.revision
            await self.send({"type": "GuiUpdateMessage", "uuid": self.ids["Preset"],
                             "updates": {"value": self.spec["preset"]}})
            await self._until(lambda: self.revision > start, timeout)

    async def send(self, message: dict) -> None:
        import msgspec
        await self.ws.send(msgspec.msgpack.encode(message))

    async def _until(self, ready, timeout: float) -> None:
        end = time.monotonic() + timeout
        while not ready():
            self.changed.clear()
            await asyncio.wait_for(self.changed.wait(), max(end - time.monotonic(), 0.0))

    async def _read(self) -> None:
        from granstab_app.headless import decode_window
        try:
            async for raw in self.ws:
                got = time.perf_counter()
                self.received += len(raw)
                window = decode_window(raw, self.zstd)
                for m in window["messages"]:
                    self._take(m, got, window["timestampSec"])
        except Exception:  # noqa: BLE001 — the connection closed: the page is gone
            return

    def _take(self, m: dict, got: float, packed: float) -> None:
        """Keep what a message says about the page's state; a new verdict revision ends the move waiting for it."""
        kind, props = m["type"], m.get("props") or {}
        if kind in ("GuiSliderMessage", "GuiDropdownMessage"):
            self.ids.setdefault(props["label"], m["uuid"])
            self.changed.set()
            return
        content = (m.get("updates") or props).get("content")
        found = REVISION.search(content) if isinstance(content, str) else None
        if found and self.headline in (None, m["uuid"]):
            self.headline, self.verdict, revision = m["uuid"], found.group(1), int(found.group(2))
            if revision != self.revision:
                self.revision = revision
                if self.moves and "received" not in self.moves[-1]:
                    self.moves[-1].update(received=got, packed=packed, revision=revision)
                self.changed.set()
        elif kind == "GuiUpdateMessage" and self.moves and m["uuid"] == self.ids.get(self.spec["label"]):
            self.shown = m["updates"].get("value", self.shown)      # the server wrote the page's slider (it should not)

    async def move(self, value: float, lost_s: float) -> None:
        """Send the slider's new value and wait for the verdict of a new revision (counted lost after lost_s)."""
        self.moves.append({"value": value})
        entry, self.shown = self.moves[-1], value            # the page shows what was typed, until the server writes
        entry["sent"] = time.perf_counter()
        await self.send({"type": "GuiUpdateMessage", "uuid": self.ids[self.spec["label"]], "updates": {"value": value}})
        try:
            await self._until(lambda: "received" in entry, lost_s)
        except TimeoutError:
            entry["lost"] = True

    async def close(self) -> None:
        await self.ws.close()
        await self.reader

    def report(self) -> dict:
        return {"i": self.spec["i"], "moves": self.moves, "revision": self.revision, "verdict": self.verdict,
                "shown": self.shown, "received_bytes": self.received}


class ChromiumPage:
    """One Chromium page on the pair: its moves typed into the slider's number box, stamped in the page (STAMPS)."""

    def __init__(self, spec: dict, url: str):
        self.spec, self.url, self.page, self.errors, self.typed = spec, url, None, [], []

    async def open(self, ctx, timeout: float) -> None:
        self.page = await ctx.new_page()
        self.page.on("pageerror", lambda exc: self.errors.append(f"pageerror: {exc}"))
        self.page.on("console", lambda m: self.errors.append(f"console: {m.text}") if m.type == "error" else None)
        await self.page.add_init_script(STAMPS)
        await self.page.goto(self.url)
        await self.page.wait_for_selector(".granstab-verdict:not([data-verdict=none])", timeout=timeout * 1e3)

    async def move(self, value: float, lost_s: float) -> None:
        from playwright.async_api import TimeoutError as PlaywrightTimeout

        from granstab_app.browser import number_box
        badge = self.page.locator(".granstab-verdict")
        before = await badge.get_attribute("data-revision")
        self.typed.append({"value": value, "before": before})
        await number_box(self.page, SimpleNamespace(label=self.spec["label"])).fill(f"{value:g}")
        try:
            await self.page.wait_for_function("r => document.querySelector('.granstab-verdict').dataset.revision !== r",
                                              arg=before, timeout=lost_s * 1e3)
        except PlaywrightTimeout:
            self.typed[-1]["lost"] = True

    async def report(self) -> dict:
        from granstab_app.browser import number_box
        stamps = await self.page.evaluate("window.granstabStamps")
        box = await number_box(self.page, SimpleNamespace(label=self.spec["label"])).input_value()
        badge = self.page.locator(".granstab-verdict")
        canvas = await _colours(await self.page.locator("canvas").first.screenshot())
        return {"i": self.spec["i"], "typed": self.typed, "stamps": stamps, "shown": box,
                "revision": int(await badge.get_attribute("data-revision")),
                "verdict": await badge.get_attribute("data-verdict"), "errors": self.errors, "canvas": canvas}


async def _colours(png: bytes) -> int:
    """Distinct colours in a screenshot of the 3D canvas (a blank or failed canvas has one or two)."""
    import io

    from PIL import Image
    return len(Image.open(io.BytesIO(png)).convert("RGB").getcolors(maxcolors=1 << 24))


async def _moves(page, values, start: float, plan: dict) -> None:
    """The page's moves at start + k·period (later when the previous verdict took longer to come)."""
    for k in range(plan["moves"]):
        await asyncio.sleep(max(0.0, start + k * plan["period"] - time.monotonic()))
        await page.move(values[k], plan["lost_s"])


def _say(event: str, **data) -> None:
    print(MARK + json.dumps({"event": event, **data}), flush=True)


async def _line() -> str:
    return (await asyncio.get_running_loop().run_in_executor(None, sys.stdin.readline)).strip()


async def _class(plan: dict, ctx) -> None:
    """Open every page (the Chromium ones one after the other, then the protocol ones at once), move, close."""
    ws_url = plan["url"].replace("http://", "ws://")
    browsers = [ChromiumPage(s, plan["url"]) for s in plan["pages"] if s["browser"]]
    protocol = [ProtocolPage(s, ws_url) for s in plan["pages"] if not s["browser"]]
    t = time.perf_counter()
    for page in browsers:
        await page.open(ctx, plan["open_s"])
    opened_browsers = time.perf_counter() - t
    t = time.perf_counter()
    await asyncio.gather(*(p.open(900 + i, plan["open_s"]) for i, p in enumerate(protocol)))
    _say("ready", open_browsers_s=opened_browsers, open_protocol_s=time.perf_counter() - t)
    start = float((await _line()).split()[1])
    n = len(plan["pages"])
    pages = sorted([*browsers, *protocol], key=lambda p: p.spec["i"])
    await asyncio.gather(*(_moves(p, p.spec["values"], start + plan["period"] * p.spec["i"] / n, plan)
                           for p in pages))
    reports = [*(await asyncio.gather(*(p.report() for p in browsers))), *(p.report() for p in protocol)]
    _say("moved", pages=reports)
    assert await _line() == "leave"
    for page in browsers:
        await page.page.close()
    await asyncio.gather(*(p.close() for p in protocol))
    _say("closed")


async def main() -> None:
    plan = json.loads(sys.stdin.readline())
    if not any(s["browser"] for s in plan["pages"]):
        await _class(plan, None)
        return
    from playwright.async_api import async_playwright

    from granstab_app.browser import CHROMIUM, FLAGS
    async with async_playwright() as pw:
        with tempfile.TemporaryDirectory() as profile:
            ctx = await pw.chromium.launch_persistent_context(profile, executable_path=str(CHROMIUM), headless=True,
                                                              viewport=plan["viewport"], args=FLAGS)
            try:
                await _class(plan, ctx)
            finally:
                await ctx.close()


if __name__ == "__main__":
    asyncio.run(main())
