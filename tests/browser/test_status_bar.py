"""The status bar (issue 48, docs/ui.md "Status bar"): on every main page, at the foot of the
window, one entry per bus of the twins with its link state, traffic, errors and cycle time;
what an interface cannot report is said, not shown as 0. With ``SERVODESK_SIM_ETHERCAT=1``
(root: the veth pair) the HIWIN twin's EtherCAT line shows its cycle while cyclic data runs."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import api_take_control, running_server

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
#: The pages of the navigation (frontend/src/pages/registry.ts), global and per drive.
PAGES = [
    "connect",
    "axes",
    "network",
    "overview",
    "operation",
    "tuning",
    "scope",
    "alarms",
    "parameters",
    "objects",
    "dictionary",
    "pdo",
    "fleet",
    "backup",
    "audit",
    "users",
]
GLOBAL = {"connect", "axes", "fleet", "audit", "users"}
#: serve --sim's buses: the CANopen twins on the virtual bus, the CTMM04x on SLMP, the
#: LECSN-T on PROFINET (services/simulation.py).
BUSES = ["virtual", "slmp", "profinet"]


def test_the_bar_is_at_the_foot_of_every_page_with_the_twins_links_up(page: Page) -> None:
    page.set_viewport_size({"width": 1024, "height": 768})
    for pid in PAGES:
        page.goto(f"/#/{pid}" if pid in GLOBAL else f"/#/{pid}/{SID}")
        expect(page.get_by_test_id(f"page-{pid}")).to_be_visible()
        bar = page.get_by_test_id("status-bar")
        expect(bar).to_be_visible()
        for bus in BUSES:
            expect(
                page.get_by_test_id(f"status-bus-{bus}").get_by_test_id("status-bus-state")
            ).to_have_text("link up")
        box = bar.bounding_box()
        assert box is not None
        # At the foot of the window (the page scrolls above it), and within its width at 1024 px.
        assert abs(box["y"] + box["height"] - 768) <= 1, (pid, box)
        assert box["x"] >= 0 and box["x"] + box["width"] <= 1024, (pid, box)
        assert page.evaluate("() => document.documentElement.scrollWidth") <= 1024, pid
        # One line a bus: the CANopen bus's error counters wrapped it onto two at 1024 px
        # and the bar took 85 of the window's 768 px; they end in an ellipsis now.
        for bus in BUSES:
            line = page.get_by_test_id(f"status-bus-{bus}").bounding_box()
            assert line is not None and line["height"] <= 24, (pid, bus, line)
        expect(page.get_by_test_id("status-bus-virtual")).to_have_attribute(
            "title", re.compile("requests failed")
        )


def test_the_virtual_bus_says_what_it_cannot_report(page: Page) -> None:
    page.goto("/#/axes")
    can_bus = page.get_by_test_id("status-bus-virtual")
    # The twins' answers to the sessions' polls are frames on the bus.
    expect(can_bus.get_by_test_id("status-bus-traffic")).to_contain_text("frames/s, load —")
    errors = can_bus.get_by_test_id("status-bus-errors")
    expect(errors).to_contain_text(
        "error frames and controller state not reported by this interface"
    )
    expect(can_bus.get_by_test_id("status-bus-cycle")).to_have_text("cycle —")
    slmp = page.get_by_test_id("status-bus-slmp")
    expect(slmp.get_by_test_id("status-bus-traffic")).to_have_text(
        "load not reported by this interface"
    )
    # Only a change of state is announced; the counters are not a live region.
    announce = page.get_by_test_id("status-bar-announce")
    expect(announce).to_have_attribute("role", "status")
    expect(announce).to_have_attribute("aria-live", "polite")
    expect(announce).to_have_text("")
    expect(page.get_by_test_id("status-bar")).not_to_have_attribute("aria-live", "polite")


def test_the_bar_is_dark_in_the_dark_theme(browser: Browser, server_url: str) -> None:
    ctx = browser.new_context(
        base_url=server_url, viewport={"width": 1024, "height": 768}, color_scheme="dark"
    )
    try:
        pg = ctx.new_page()
        pg.goto("/#/axes")
        expect(pg.locator("html")).to_have_attribute("data-theme", "dark")
        expect(pg.get_by_test_id("status-bus-virtual")).to_be_visible()
        lum = pg.evaluate(
            """() => {
              const c = getComputedStyle(document.querySelector('.status-bar')).backgroundColor;
              const m = c.match(/rgba?\\(([\\d.]+), ([\\d.]+), ([\\d.]+)/);
              return (0.2126 * m[1] + 0.7152 * m[2] + 0.0722 * m[3]) / 255;
            }"""
        )
        assert lum < 0.25, lum
    finally:
        ctx.close()


@pytest.fixture(scope="module")
def ethercat_url() -> Iterator[str]:
    env = {
        "SERVODESK_SIM_ETHERCAT": "1",
        "SERVODESK_SIM_PROFILES": "hiwin-e",
        "SERVODESK_DEADMAN_MS": "1000",
    }
    with running_server(env=env) as base:
        yield base


@pytest.fixture
def ethercat_page(browser: Browser, ethercat_url: str) -> Iterator[Page]:
    yield from fresh_page(browser, ethercat_url)


def test_the_ethercat_twins_cycle_shows_while_cyclic_data_runs(ethercat_page: Page) -> None:
    pg = ethercat_page
    sessions = pg.request.get("/api/v1/sessions").json()
    (hiwin,) = sessions
    # serve --sim makes the veth pair as root; without root the twin stays on CANopen and
    # its note says why (tests/ethercat/test_serve_sim.py).
    assert hiwin["link"] == "ethercat", hiwin["note"]
    pg.goto("/#/axes")
    line = pg.get_by_test_id("status-bus-ethercat")
    # The bar polls once a second; on a loaded 2-core machine the page, the first poll and the
    # EtherCAT line's first health took longer than expect's 5 s (a clean-clone run).
    expect(line.get_by_test_id("status-bus-state")).to_have_text("link up", timeout=20_000)
    expect(line.get_by_test_id("status-bus-cycle")).to_have_text("cycle —", timeout=10_000)
    sid = hiwin["id"]
    token = api_take_control(pg, sid, "status-bar-test")
    headers = {
        "X-Servodesk-Client": "status-bar-test",
        "X-Servodesk-Control": token,
        "Content-Type": "application/json",
    }
    url = f"/api/v1/sessions/{sid}/pdo/cyclic"
    r = pg.request.post(
        url, data=json.dumps({"sync_period_ms": 2, "outputs": False}), headers=headers
    )
    assert r.ok, r.text()
    try:
        cycle = line.get_by_test_id("status-bus-cycle")
        expect(cycle).to_contain_text("2 ms set", timeout=10_000)
        expect(cycle).to_contain_text(" ms measured", timeout=10_000)
        expect(cycle).not_to_contain_text("— measured", timeout=10_000)
        errors = line.get_by_test_id("status-bus-errors")
        expect(errors).to_contain_text("WKC errors", timeout=10_000)
    finally:
        pg.request.delete(url, headers=headers)
        pg.request.post(
            f"/api/v1/sessions/{sid}/control", data='{"action":"release"}', headers=headers
        )
    expect(line.get_by_test_id("status-bus-cycle")).to_have_text("cycle —", timeout=10_000)
