"""The Homing panel against the real backend: the CTMM04x twin homes with method 1 at the
manual's speeds (6099h:02 = 10 pps, 003 §4-4-8), a run of hours; the panel shows the estimate
and the time-out before the start, the progress while it runs, and, when the dead-man stops
the run, that end (never "running" again, though the CTMM04x's statusword bits 13/12/10 read
000, "in progress", after a cancel: 003 §4-4-7).

The page's heartbeats are dropped on their way to the server (Playwright routes the page's
WebSocket and forwards everything else), so the dead-man fires as it would for a tab whose
machine froze.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, WebSocketRoute, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import HarnessError, running_server
from tests.browser.test_operation import take_control_and_enable

pytestmark = pytest.mark.browser


def ctmm_session(page: Page) -> str:
    r = page.request.get("/api/v1/sessions")
    assert r.ok, r.text()
    sid = next(s["id"] for s in r.json() if s["profile_id"] == "ctmm04x")
    assert isinstance(sid, str)
    return sid


class HeartbeatGate:
    """Forwards the page's WebSocket both ways; drops its heartbeats once closed."""

    def __init__(self) -> None:
        self.open = True
        self.dropped = 0

    def route(self, ws: WebSocketRoute) -> None:
        server = ws.connect_to_server()

        def from_page(message: str | bytes) -> None:
            if not self.open and isinstance(message, str) and '"heartbeat"' in message:
                self.dropped += 1
                return
            server.send(message)

        ws.on_message(from_page)


@pytest.fixture(scope="module")
def ctmm_server() -> Iterator[str]:
    """A server of its own: only the CTMM04x twin, and a dead-man of one second, since the
    heartbeats pass through this test process (Playwright's route) on their way: on a busy
    2-core machine that hop alone can take longer than the default 250 ms."""
    try:
        with running_server(
            env={"SERVODESK_SIM_PROFILES": "ctmm04x", "SERVODESK_DEADMAN_MS": "1000"}
        ) as base:
            yield base
    except HarnessError as e:
        pytest.fail(str(e), pytrace=False)


@pytest.fixture
def gated(browser: Browser, ctmm_server: str) -> Iterator[tuple[Page, HeartbeatGate]]:
    # fresh_page closes its context and checks the page threw nothing once the loop ends.
    for page in fresh_page(browser, ctmm_server):
        yield from _gated(page)


def _gated(page: Page) -> Iterator[tuple[Page, HeartbeatGate]]:
    gate = HeartbeatGate()
    page.route_web_socket(re.compile(r".*/api/v1/ws(\?.*)?$"), gate.route)
    yield page, gate
    gate.open = True  # The server is this module's own: nothing else to put back.


def test_the_panel_shows_the_dead_man_end_of_a_ctmm_homing_run(
    gated: tuple[Page, HeartbeatGate],
) -> None:
    page, gate = gated
    sid = ctmm_session(page)
    page.goto(f"/#/operation/{sid}")
    expect(page.get_by_test_id("operation-page")).to_be_visible()
    expect(page.get_by_test_id("socket-banner")).to_have_count(0, timeout=10_000)
    take_control_and_enable(page)
    page.get_by_test_id("tab-homing").click()
    page.get_by_test_id("homing-method").select_option("1")
    panel = page.get_by_test_id("panel-homing")
    # No claim that homing needs no dead-man: the panel says it runs under it.
    expect(panel).not_to_contain_text("does not need the dead-man")
    expect(panel).to_contain_text("dead-man")
    # Before the start: the estimate at the manual's speeds and the bounded time-out.
    expect(page.get_by_test_id("homing-plan-estimate")).to_contain_text("3 h")
    expect(page.get_by_test_id("homing-plan-timeout")).to_have_text("1 h 0 min")
    crawl = page.get_by_test_id("homing-plan-warning").filter(has_text="index pulse")
    expect(crawl).to_contain_text("a higher 6099h:02 shortens it")

    page.get_by_test_id("homing-start").click()
    status = page.get_by_test_id("homing-status")
    expect(status).to_have_attribute("data-state", "running")
    expect(page.get_by_test_id("homing-progress")).to_have_attribute("data-active", "true")
    expect(page.get_by_test_id("homing-timeout-shown")).to_have_text("1 h 0 min")
    # Heartbeats keep it going for longer than the dead-man time.
    page.wait_for_timeout(800)
    expect(status).to_have_attribute("data-state", "running")

    gate.open = False  # The tab's heartbeats stop reaching the server.
    expect(status).to_have_attribute("data-state", "deadman", timeout=5_000)
    assert gate.dropped > 0
    expect(page.get_by_test_id("homing-state")).to_have_text("stopped by the dead-man")
    expect(page.get_by_test_id("homing-message")).to_contain_text("heartbeat")
    expect(page.get_by_test_id("homing-progress")).to_have_attribute("data-active", "false")
    # It stays so: the statusword polls that follow do not bring "running" back.
    page.wait_for_timeout(2_500)
    expect(status).to_have_attribute("data-state", "deadman")
    api = page.request.get(f"/api/v1/sessions/{sid}/homing").json()
    assert api["run"]["outcome"] == "deadman" and api["state"] != "running", api
