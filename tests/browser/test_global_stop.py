"""Many axes at a glance (issue 48): the global stop and the All axes page, in the browser.

What a commissioning engineer with several axes relies on: Esc (on any page, the focus in a
text field included) and the header's STOP ALL both quick-stop every axis they control, here
two twins on different fieldbuses jogging at once; the All axes page lists every open drive
with its state and follows a drive being enabled without a reload.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import control_headers, tab_control, take_control

pytestmark = pytest.mark.browser

GENERIC = "cia402-generic-1"  # CANopen twin
HIWIN = "hiwin-e-2"  # EtherCAT twin
AXES = [GENERIC, HIWIN]
JOG = '{"velocity": 20000, "acceleration": 200000}'


def open_axes(page: Page) -> None:
    page.goto("/#/axes")
    expect(page.get_by_test_id("ws-status")).to_have_attribute("data-status", "open")
    expect(page.get_by_test_id("axes-table")).to_be_visible()


def start_heartbeats(page: Page, token: str) -> None:
    """A second socket in the page, bound to the tab's control of both axes, beating every
    50 ms: the dead-man of the jogs the test starts over the API (harness.start_mover for
    two drives)."""
    page.evaluate(
        """([sids, token]) => new Promise((resolve, reject) => {
            const url = new URL('/api/v1/ws', location.href);
            url.protocol = location.protocol === 'https:' ? 'wss:' : 'ws:';
            url.searchParams.set('client', 'stop-all-mover');
            const ws = new WebSocket(url.toString(), 'servodesk.v1');
            const waiting = new Set(sids);
            const bind = (s) => ws.send(JSON.stringify({type: 'bind', session: s, token}));
            ws.onopen = () => sids.forEach(bind);
            ws.onmessage = (ev) => {
                const m = JSON.parse(ev.data);
                if (m.type !== 'bind' || !waiting.has(m.session)) return;
                if (!m.ok) { ws.close(); reject(new Error('bind refused: ' + m.message)); return; }
                waiting.delete(m.session);
                if (waiting.size) return;
                const beat = () => sids.forEach((s) => ws.readyState === 1 &&
                    ws.send(JSON.stringify({type: 'heartbeat', session: s})));
                beat();
                window.__stopAllMover = {ws, timer: setInterval(beat, 50)};
                resolve(true);
            };
            ws.onerror = () => reject(new Error('the heartbeat socket did not open'));
        })""",
        [AXES, token],
    )


def stop_heartbeats(page: Page) -> None:
    if page.is_closed():
        return
    page.evaluate(
        """() => { const m = window.__stopAllMover; if (!m) return;
                   clearInterval(m.timer); m.ws.close(); window.__stopAllMover = null; }"""
    )


@pytest.fixture
def controlled(page: Page) -> Iterator[Page]:
    """The page's tab holds control of both axes (taken in the header, as a person does) and
    a socket beats for them."""
    for sid in AXES:
        page.goto(f"/#/overview/{sid}")
        take_control(page, sid)
    held = tab_control(page)
    assert held and sorted(held["sessions"]) == sorted(AXES), held
    start_heartbeats(page, held["token"])
    yield page
    stop_heartbeats(page)


def jog_both(page: Page) -> None:
    """Servo on and jog both axes over the API with the tab's token; both are running."""
    h = control_headers(page)
    for sid in AXES:
        r = page.request.post(
            f"/api/v1/sessions/{sid}/state", data='{"command":"enable"}', headers=h
        )
        assert r.ok and r.json()["state"] == "Operation enabled", r.text()
        r = page.request.post(f"/api/v1/sessions/{sid}/motion/jog", data=JOG, headers=h)
        assert r.ok and r.json()["active"], r.text()
    for sid in AXES:
        # The velocity builds up: the axis really turns before the stop.
        deadline = time.monotonic() + 5
        while abs(page.request.get(f"/api/v1/sessions/{sid}/state").json()["velocity"]) < 1000:
            assert time.monotonic() < deadline, f"{sid} did not start turning"
            time.sleep(0.05)


def expect_both_stopped(page: Page) -> None:
    for sid in AXES:
        deadline = time.monotonic() + 5
        while True:
            m = page.request.get(f"/api/v1/sessions/{sid}/motion").json()
            st = page.request.get(f"/api/v1/sessions/{sid}/state").json()
            if not m["active"] and st["state"] != "Operation enabled":
                break
            assert time.monotonic() < deadline, (sid, m, st)
            time.sleep(0.05)
        assert m["state"] == "stopped", m  # The quick stop ended it, not the dead-man.


def test_esc_and_stop_all_quick_stop_two_jogging_axes_at_once(controlled: Page) -> None:
    page = controlled
    open_axes(page)
    jog_both(page)
    for sid in AXES:
        cell = page.get_by_test_id(f"axis-motion-{sid}")
        expect(cell).to_have_attribute("data-active", "true")
        expect(page.get_by_test_id(f"axis-control-{sid}")).to_have_text("you (this tab)")
        expect(page.get_by_test_id(f"axis-row-{sid}")).to_have_attribute("data-stop-all", "true")

    # Esc with the focus in a text field of another page: it stops them all the same.
    page.goto(f"/#/objects/{GENERIC}")
    field = page.locator("input[type=text], input:not([type])").first
    field.click()
    field.press("Escape")
    expect_both_stopped(page)
    notice = page.get_by_test_id("notice-info").filter(has_text="Stop all: 2 axes stopped")
    expect(notice).to_be_visible()
    expect(notice).to_contain_text(GENERIC)
    expect(notice).to_contain_text(HIWIN)

    # The header's button, on the All axes page, which shows the motion stopped.
    open_axes(page)
    jog_both(page)
    button = page.get_by_test_id("global-stop")
    assert "Esc" in (button.get_attribute("title") or "")
    button.click()
    expect_both_stopped(page)
    for sid in AXES:
        expect(page.get_by_test_id(f"axis-motion-{sid}")).to_have_attribute(
            "data-motion", "stopped"
        )
        expect(page.get_by_test_id(f"axis-row-{sid}")).not_to_have_attribute(
            "data-state", "Operation enabled"
        )


def test_stop_all_without_control_says_so_and_stops_nothing(page: Page) -> None:
    open_axes(page)
    page.get_by_test_id("global-stop").click()
    notice = page.get_by_test_id("notice-warning").filter(has_text="you control no axis")
    expect(notice).to_be_visible()
    expect(notice).to_contain_text("Quick stop")


def test_all_axes_lists_every_twin_and_follows_a_drive_being_enabled(page: Page) -> None:
    listed = page.request.get("/api/v1/sessions").json()
    sids = [s["id"] for s in listed]
    assert len(sids) == 5, sids  # The five twins of `servodesk serve --sim`.
    open_axes(page)
    rows = page.locator("[data-testid^=axis-row-]")
    expect(rows).to_have_count(5)
    for sid in sids:
        state = page.request.get(f"/api/v1/sessions/{sid}/state").json()
        row = page.get_by_test_id(f"axis-row-{sid}")
        expect(row).to_have_attribute("data-state", state["state"])
        expect(page.get_by_test_id(f"axis-state-{sid}")).to_contain_text(state["state"])
        # Raw position with its drive unit; engineering value where the profile has a unit.
        expect(page.get_by_test_id(f"axis-position-{sid}")).not_to_contain_text("—")
        expect(page.get_by_test_id(f"axis-alarm-{sid}")).to_have_text("none")
        # Protection comes with who holds control (GET .../control), once per drive.
        expect(page.get_by_test_id(f"axis-protection-{sid}")).to_contain_text("ms")

    # Take control of the generic twin in the header, come back, and enable it (with the
    # tab's token) while the page is open: the row follows the socket, no reload.
    page.goto(f"/#/overview/{GENERIC}")
    take_control(page, GENERIC)
    page.get_by_test_id("nav-axes").click()
    row = page.get_by_test_id(f"axis-row-{GENERIC}")
    expect(page.get_by_test_id(f"axis-control-{GENERIC}")).to_have_text("you (this tab)")
    for command, state in (("enable", "Operation enabled"), ("disable", "Switch on disabled")):
        r = page.request.post(
            f"/api/v1/sessions/{GENERIC}/state",
            data=f'{{"command":"{command}"}}',
            headers=control_headers(page),
        )
        assert r.ok, r.text()
        expect(row).to_have_attribute("data-state", state)
        expect(page.get_by_test_id(f"axis-state-{GENERIC}")).to_contain_text(state)
    # A row opens its drive.
    page.get_by_test_id(f"axis-row-{HIWIN}").click()
    expect(page).to_have_url(f"{page.url.split('#')[0]}#/overview/{HIWIN}")
    expect(page.get_by_test_id("page-overview")).to_be_visible()
