"""The Operation page against the real backend and the simulated generic CiA 402 drive.

What a commissioning engineer relies on: take control, servo on, hold the jog button and see
the axis move, let go and see it stop within a second (the page sends a halt, and its
heartbeats end); QUICK STOP works with one click; a second browser (another client) that tries
to jog is refused with a message naming the client that holds control. The 3D view page shows
the viewer or says why it cannot. Control is taken as a person takes it, with the header's
Take control (tests/browser/test_control.py tests control itself).
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.harness import release_control, shown_int, take_control

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"


def client_id(page: Page) -> str:
    cid = page.evaluate("() => sessionStorage.getItem('servodesk.client')")
    assert isinstance(cid, str) and cid, "the UI did not make a client id"
    return cid


def api_state(page: Page) -> dict[str, object]:
    r = page.request.get(f"/api/v1/sessions/{SID}/state")
    assert r.ok, r.text()
    body = r.json()
    assert isinstance(body, dict)
    return body


def open_operation(page: Page) -> None:
    page.goto(f"/#/operation/{SID}")
    expect(page.get_by_test_id("operation-page")).to_be_visible()
    # The dead-man needs the page's WebSocket: the banner is gone once it is connected.
    expect(page.get_by_test_id("socket-banner")).to_have_count(0, timeout=10_000)


def take_control_and_enable(page: Page) -> None:
    """Take control of the drive the page shows (the header's Take control), servo on."""
    take_control(page)
    expect(page.get_by_test_id("control-owner")).to_have_attribute("data-you", "true")
    state = page.get_by_test_id("op-state")
    expect(state).not_to_have_text("—")
    if state.inner_text().strip() != "Operation enabled":
        page.get_by_test_id("servo-on").click()  # Waits until the button is enabled.
    expect(state).to_have_text("Operation enabled", timeout=10_000)


@pytest.fixture
def operator(page: Page) -> Iterator[Page]:
    open_operation(page)
    try:
        yield page
    finally:
        # Leave the drive as other tests expect it: nobody holds control, servo off.
        release_control(page)


def test_hold_jog_moves_and_release_stops(operator: Page) -> None:
    page = operator
    take_control_and_enable(page)
    before = shown_int(page, "op-position")

    jog = page.get_by_test_id("jog-plus")
    jog.hover()
    page.mouse.down()
    expect(page.get_by_test_id("heartbeat-indicator")).to_be_visible()
    expect(page.get_by_test_id("motion-status")).to_have_attribute("data-active", "true")
    page.wait_for_timeout(1000)
    # Still moving after a full second of holding: the heartbeats keep the dead-man quiet.
    moving = shown_int(page, "op-velocity")
    assert moving > 0, f"velocity while holding + is {moving}"
    during = shown_int(page, "op-position")
    assert during > before + 20_000, f"position went {before} -> {during} in 1 s of jogging"
    # Let go: the page sends the halt at once ...
    with page.expect_request(lambda r: r.url.endswith("/motion/halt"), timeout=500):
        released_at = time.monotonic()
        page.mouse.up()
    # ... and the axis stands within a second (0.5 s more for the display on a loaded
    # 2-core machine); the drive stays enabled.
    expect(page.get_by_test_id("op-velocity")).to_have_text("0", timeout=1_500)
    assert time.monotonic() - released_at < 1.5
    expect(page.get_by_test_id("heartbeat-indicator")).to_have_count(0)
    expect(page.get_by_test_id("motion-status")).to_have_attribute("data-state", "halted")
    expect(page.get_by_test_id("op-state")).to_have_text("Operation enabled")
    # Nothing moves any more: the position stays put.
    stopped = shown_int(page, "op-position")
    page.wait_for_timeout(400)
    assert abs(shown_int(page, "op-position") - stopped) < 50
    # The dead-man did not have to fire: the release halted the axis.
    expect(page.get_by_test_id("deadman-banner")).to_have_count(0)


def test_quick_stop_from_the_page(operator: Page) -> None:
    page = operator
    take_control_and_enable(page)
    page.get_by_test_id("tab-velocity").click()
    # In the drive's units (inc/s): the page enters engineering units by default.
    page.get_by_test_id("units-raw").click()
    page.get_by_test_id("pv-velocity").fill("200000")
    page.get_by_test_id("pv-start").click()
    expect(page.get_by_test_id("motion-status")).to_have_attribute("data-active", "true")
    page.wait_for_timeout(500)
    assert shown_int(page, "op-velocity") > 100_000

    page.get_by_test_id("quick-stop").click()
    expect(page.get_by_test_id("motion-status")).to_have_attribute("data-state", "stopped")
    expect(page.get_by_test_id("op-velocity")).to_have_text("0", timeout=2_000)
    # Quick stop leaves Operation enabled (CiA 402-2 transition 11).
    expect(page.get_by_test_id("op-state")).not_to_have_text("Operation enabled")
    state = api_state(page)
    assert state["velocity"] == 0


def test_other_client_jog_is_refused_naming_the_owner(
    operator: Page, browser: Browser, server_url: str
) -> None:
    page = operator
    take_control_and_enable(page)
    owner = client_id(page)

    other_ctx = browser.new_context(base_url=server_url, viewport={"width": 1440, "height": 960})
    other_ctx.set_default_timeout(10_000)
    try:
        other = other_ctx.new_page()
        open_operation(other)
        assert client_id(other) != owner
        expect(other.get_by_test_id("control-owner")).to_have_attribute("data-owner", owner)
        expect(other.get_by_test_id("no-control-note")).to_contain_text(owner)

        other.get_by_test_id("jog-plus").hover()
        other.mouse.down()
        error = other.get_by_test_id("jog-error")
        expect(error).to_be_visible()
        other.mouse.up()
        expect(error).to_contain_text(owner)
        expect(error).to_contain_text("holds control")
        expect(error).to_contain_text("Jog failed")
        # Nothing moved.
        assert api_state(page)["velocity"] == 0

        # Force-take asks first and names the client it takes control from.
        other.get_by_test_id("control-force").click()
        expect(other.get_by_test_id("force-dialog-owner")).to_have_text(owner)
        other.get_by_test_id("force-dialog-cancel").click()
        expect(page.get_by_test_id("control-owner")).to_have_attribute("data-you", "true")
    finally:
        other_ctx.close()


def test_3d_view_page(page: Page) -> None:
    r = page.request.get("/api/v1/viewer")
    page.goto(f"/#/view3d/{SID}")
    expect(page.get_by_test_id("viewer-page")).to_be_visible()
    info = r.json() if r.ok else {}
    if info.get("enabled") and info.get("running", True) and (info.get("url") or info.get("port")):
        frame = page.get_by_test_id("viewer-frame")
        expect(frame).to_be_visible()
        src = frame.get_attribute("src")
        assert src and src.startswith("http")
    else:
        # Switched off or not built into this server: the page says so instead of a blank frame.
        expect(page.get_by_test_id("viewer-disabled")).to_contain_text("3D view not available")


def test_lecsn_jog_starts_from_a_usable_ramp_and_a_readable_number(page: Page) -> None:
    # The LECSN-T gives its ramps as times (6083h in ms from 0 to the rated speed, at most
    # 50000). The panel started at that limit, the gentlest ramp: 50 s to 3000 r/min, a jog
    # that hardly moved. And its long velocity unit squeezed the number to a few digits.
    page.set_viewport_size({"width": 1280, "height": 800})
    page.goto("/#/operation/lecsn-t-1")
    # The drive's own units, the ones its manual gives the ramp and the speed in.
    page.get_by_test_id("units-raw").click()
    acc = page.get_by_test_id("jog-acceleration")
    expect(acc).to_have_value("200")
    vel = page.get_by_test_id("jog-velocity")
    expect(vel).to_have_value(re.compile(r"^\d+$"))
    fits = vel.evaluate("e => e.scrollWidth <= e.clientWidth")
    assert fits, f"the jog velocity {vel.input_value()} does not fit its field"
    unit = page.get_by_test_id("panel-jog").locator(".op-unit").first
    expect(unit).to_have_attribute("title", "0.01 r/min (0.01 mm/s linear)")


def test_entry_units_default_to_engineering_and_are_kept(page: Page) -> None:
    # A commissioning engineer reads rpm, not inc/s: the motion panels take engineering units
    # until the person chooses drive units, and the browser keeps that choice, the same one
    # the object editors use (Parameters' "Enter in").
    open_operation(page)
    eng, raw = page.get_by_test_id("units-eng"), page.get_by_test_id("units-raw")
    expect(eng).to_have_attribute("aria-pressed", "true")
    expect(raw).to_have_attribute("aria-pressed", "false")
    unit = page.get_by_test_id("panel-jog").locator(".op-unit-text").first
    expect(unit).to_have_text("rpm")

    raw.click()
    expect(raw).to_have_attribute("aria-pressed", "true")
    expect(eng).to_have_attribute("aria-pressed", "false")
    expect(unit).to_have_text("inc/s")

    page.reload()
    expect(page.get_by_test_id("operation-page")).to_be_visible()
    expect(page.get_by_test_id("units-raw")).to_have_attribute("aria-pressed", "true")
    page.goto(f"/#/parameters/{SID}/position")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    page.get_by_test_id("edit-0x6081:00").click()
    expect(page.get_by_test_id("entry-raw")).to_have_attribute("aria-pressed", "true")
