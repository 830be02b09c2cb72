"""What a slider move makes the server send (issue 29, a class on one server): what changed, as updates of the nodes
already in the page, never the scene again. Read from a protocol page (granstab_app.headless: viser's websocket
protocol, every message decoded), not timed: the bytes and the messages are what each of a class's pages costs the
server's one process (the class benchmark, benchmarks/classroom.py, times it)."""
from __future__ import annotations

import threading
import time

import pytest

from granstab_app.headless import HeadlessPage
from granstab_app.server import App

pytestmark = pytest.mark.serial   # a move's messages are those before QUIET s of silence: timing
QUIET = 0.5                    # s without a message after the move's callback has finished: the move's messages are in
# Updates of a node already in the page; any other message naming a scene node ("/…") adds one anew or removes it.
UPDATES = {"SceneNodeUpdateMessage", "SetPositionMessage", "SetOrientationMessage"}
# The pair's ρ/r changes the two outlines: their vertices, (4·96 + 2) × 3 float32 = 4.6 kB each (meshes.extruded_outline),
# are the largest part of a move; with the body markers, the verdict's texts and the spectrum's 1.8 kB of JSON a move
# sent 14 kB here. The bound leaves 10 kB above that; the explorer before this bound sent 62 kB per move (the λ⁽⁶⁾
# contour's 49 kB picture, re-sent to move its ★, and a spectrum plot carrying plotly's 7 kB template).
MOVE_BYTES = 24_000
LARGEST = 6_000                # bytes of any one message of a move: one outline's vertices and their message
BURST = 15                     # slider events sent at once (a drag of 0.75 s at viser's 50 ms)


@pytest.fixture(scope="module")
def page():
    app = App(host="127.0.0.1", port=0)
    try:
        with HeadlessPage(app, record=True) as page:
            yield page
    finally:
        app.stop()


def moved(page, key: str, value: float) -> list:
    """The messages one slider move of the page made the server send (as a browser sends it: GuiUpdateMessage)."""
    ui = page.ui
    quiet(page)
    page.messages.clear()
    revision = ui.session.revision
    page.send({"type": "GuiUpdateMessage", "uuid": ui.sliders[key]._impl.uuid, "updates": {"value": value}})
    end = time.monotonic() + 60
    while ui.session.revision == revision and time.monotonic() < end:
        time.sleep(0.01)
    assert ui.session.revision != revision, f"the {key} move was not analysed within 60 s"
    with ui.lock:                          # its callback has written everything
        pass
    quiet(page)
    return list(page.messages)


def quiet(page) -> None:
    """Wait until the page has received nothing for QUIET s."""
    seen, since = len(page.messages), time.monotonic()
    while time.monotonic() - since < QUIET:
        time.sleep(0.05)
        if len(page.messages) != seen:
            seen, since = len(page.messages), time.monotonic()


def added_or_removed(messages) -> list:
    return [(m.type, m.name) for m in messages if m.name.startswith("/") and m.type not in UPDATES]


@pytest.mark.parametrize("value", [0.7, 1.3])
def test_a_rho_move_sends_the_new_outlines_not_the_scene(page, value):
    sent = moved(page, "rho_r", value)
    headline = page.ui.headline._impl.uuid
    assert any(m.name == headline for m in sent)                              # the new verdict went out
    assert added_or_removed(sent) == []                                        # no node made again
    assert {m.name for m in sent if "vertices" in m.props} == {
        f"/particles/{p}/body/{part}" for p in "pq" for part in ("mesh", "marker")}   # the shapes ρ/r changes
    assert sum(m.size for m in sent) <= MOVE_BYTES, sorted(sent, key=lambda m: -m.size)[:5]
    assert max(m.size for m in sent) <= LARGEST, max(sent, key=lambda m: m.size)


def test_a_force_move_sends_no_shape(page):
    """f/(kr) loads the contact: the outlines and the λ⁽⁶⁾ picture stay, the ★ and the marker on the surface move."""
    sent = moved(page, "f_kr", 0.004)
    assert added_or_removed(sent) == []
    assert not any("vertices" in m.props for m in sent)
    assert any(m.name == "/field/current" for m in sent)                        # the surface's marker moved
    assert any(m.name == page.ui.star._impl.uuid for m in sent)                 # the ★ over the contour moved
    assert not any(m.name == page.ui.contour._impl.uuid for m in sent)          # its picture was not sent again
    assert sum(m.size for m in sent) <= MOVE_BYTES - 9_300                      # less the two outlines' vertices


def test_a_burst_of_slider_events_runs_the_callback_a_few_times_and_ends_on_the_last_value(page):
    """A dragged slider sends an event every 50 ms (viser's page); a tab's events are coalesced while its callback
    runs (panels.ClientUI._slider_moved), so they hold one of viser's 32 pool threads, not one each waiting for the
    tab's lock. BURST events sent at once: the first runs, the others arrive while it runs (a pair's analysis alone
    takes ~10 ms of CPU here) and make at most a few runs more; the old code ran the callback once per event."""
    ui, calls = page.ui, []
    apply = ui._apply_sliders
    ui._apply_sliders = lambda: (calls.append(threading.get_ident()), apply())[1]
    try:
        quiet(page)
        uuid, values = ui.sliders["rho_r"]._impl.uuid, [round(0.8 + 0.01 * k, 2) for k in range(BURST)]
        for value in values:
            page.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}})
        end = time.monotonic() + 60
        while ui.session.params["rho_r"] != values[-1] and time.monotonic() < end:
            time.sleep(0.01)
        quiet(page)
    finally:
        ui._apply_sliders = apply
    assert ui.session.params["rho_r"] == values[-1]                  # the last value wins
    assert 1 <= len(calls) <= BURST // 3, len(calls)
