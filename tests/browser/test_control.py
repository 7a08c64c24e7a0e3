"""Control of a drive in the browser (docs/api.md "Control and motion as built").

Every request that changes a drive needs the control token of the tab that took control, and
servo on and motion also that tab's WebSocket bound as the dead-man. What a commissioning
engineer sees: a tab without control has its write buttons disabled with the reason beside
them, and servo on is refused; Take control in the header (on any page) makes them work.
Closing the controlling tab while the drive is enabled disables the drive, and another tab is
told why. A second tab cannot take control while the first holds it (it is shown the
holder); Force take asks first, then moves control and disables the drive.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.harness import (
    CONTROL_LAPSE_MS,
    control_headers,
    release_control,
    tab_control,
    take_control,
)

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
ADDR = "0x6081:00"


def client_id(page: Page) -> str:
    cid = page.evaluate("() => sessionStorage.getItem('servodesk.client')")
    assert isinstance(cid, str) and cid, "the UI did not make a client id"
    return cid


@contextmanager
def other_tab(browser: Browser, server_url: str) -> Iterator[Page]:
    """Another browser tab of another person: a context of its own (its own sessionStorage,
    so its own client label and control token)."""
    ctx = browser.new_context(base_url=server_url, viewport={"width": 1440, "height": 960})
    ctx.set_default_timeout(10_000)
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        yield pg
    finally:
        release_control(pg)
        ctx.close()
    assert not errors, f"uncaught errors in the other tab: {errors}"


def open_overview(page: Page) -> None:
    page.goto(f"/#/overview/{SID}")
    expect(page.get_by_test_id("ws-status")).to_have_attribute("data-status", "open")
    indicator = page.get_by_test_id("control-indicator")
    expect(indicator).to_have_attribute("data-session", SID)
    expect(indicator).to_have_attribute("data-known", "true")


def wait_nobody_holds(page: Page) -> None:
    """A closed tab of an earlier test may hold control for its 5 s grace."""
    expect(page.get_by_test_id("control-indicator")).to_have_attribute(
        "data-owner", "", timeout=CONTROL_LAPSE_MS
    )


def enable(page: Page) -> None:
    page.get_by_test_id("cmd-enable").click()
    expect(page.get_by_test_id("drive-state")).to_have_text("Operation enabled", timeout=10_000)


def test_without_control_writes_are_disabled_and_explained_until_take(page: Page) -> None:
    open_overview(page)
    wait_nobody_holds(page)
    indicator = page.get_by_test_id("control-indicator")
    expect(indicator).to_have_attribute("data-you", "false")
    expect(page.get_by_test_id("control-holder")).to_have_text("nobody")
    expect(page.get_by_test_id("control-take")).to_be_visible()
    expect(page.get_by_test_id("drive-state")).not_to_have_text("Operation enabled")

    # Overview: the state commands are disabled and say why; Quick stop never is.
    note = page.get_by_test_id("control-note")
    expect(note).to_contain_text("This tab does not hold control")
    expect(page.get_by_test_id("control-note-reason")).to_contain_text(
        f"Nobody holds control of {SID}"
    )
    servo_on = page.get_by_test_id("cmd-enable")
    expect(servo_on).to_be_disabled()
    expect(servo_on).to_have_attribute("title", re.compile("take control first"))
    expect(page.get_by_test_id("cmd-fault_reset")).to_be_disabled()
    expect(page.get_by_test_id("cmd-quick_stop")).to_be_enabled()
    # The server refuses servo on from this tab too (no token): nothing reaches the drive.
    r = page.request.post(
        f"/api/v1/sessions/{SID}/state", data='{"command":"enable"}', headers=control_headers(page)
    )
    assert r.status == 409, r.text()
    assert "nobody holds control" in r.json()["message"]
    expect(page.get_by_test_id("drive-state")).not_to_have_text("Operation enabled")

    # Parameters: Save, Restore defaults and the editor's Write are disabled and explained.
    page.goto(f"/#/parameters/{SID}")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    expect(page.get_by_test_id("control-note")).to_contain_text("Save to EEPROM")
    expect(page.get_by_test_id("params-store")).to_be_disabled()
    expect(page.get_by_test_id("params-restore")).to_be_disabled()
    page.get_by_test_id("group-tab-position").click()
    row = page.get_by_test_id(f"param-row-{ADDR}")
    row.get_by_test_id(f"edit-{ADDR}").click()
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    expect(editor.get_by_test_id("value-write")).to_be_disabled()
    expect(editor.get_by_test_id("value-blocked")).to_contain_text("take control first")

    # Object access, Alarms, PDO: the same.
    page.goto(f"/#/objects/{SID}")
    expect(page.get_by_test_id("object-write")).to_be_disabled()
    expect(page.get_by_test_id("control-note")).to_contain_text("Write is disabled")
    expect(page.get_by_test_id("object-read")).to_be_enabled()
    page.goto(f"/#/alarms/{SID}")
    expect(page.get_by_test_id("control-note")).to_contain_text("Fault reset")
    expect(page.get_by_test_id("fault-reset")).to_be_disabled()
    page.goto(f"/#/pdo/{SID}")
    expect(page.get_by_test_id("pdo-dry-run")).to_be_disabled()
    expect(page.get_by_test_id("pdo-apply-control-note")).to_be_visible()

    # Take control from the page's note (the header's button does the same).
    page.goto(f"/#/parameters/{SID}")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    page.get_by_test_id("control-note-take").click()
    expect(indicator).to_have_attribute("data-you", "true")
    expect(indicator).to_have_attribute("data-bound", "true")
    expect(page.get_by_test_id("control-holder")).to_have_text("you")
    expect(page.get_by_test_id("control-deadman")).to_have_text("dead-man bound")
    expect(page.get_by_test_id("control-note")).to_have_count(0)
    expect(page.get_by_test_id("params-store")).to_be_enabled()
    held = page.evaluate("() => JSON.parse(sessionStorage.getItem('servodesk.control'))")
    assert held["sessions"] == [SID] and held["token"], held

    # Now servo on works from the Overview, and a reload keeps control (the token is in the
    # tab's sessionStorage; the socket binds again within the server's grace).
    open_overview(page)
    expect(page.get_by_test_id("control-note")).to_have_count(0)
    enable(page)
    page.reload()
    expect(indicator).to_have_attribute("data-you", "true")
    expect(indicator).to_have_attribute("data-bound", "true")
    # The reload closed the old socket: the server made the drive safe meanwhile.
    expect(page.get_by_test_id("drive-state")).to_have_text("Switch on disabled")
    enable(page)
    page.get_by_test_id("cmd-disable").click()
    expect(page.get_by_test_id("drive-state")).to_have_text("Switch on disabled")

    # Release: the token goes with the last session.
    page.get_by_test_id("control-release").click()
    expect(indicator).to_have_attribute("data-owner", "")
    expect(page.get_by_test_id("cmd-enable")).to_be_disabled()
    page.wait_for_function("() => sessionStorage.getItem('servodesk.control') === null")


def test_closing_the_controlling_tab_disables_the_drive_and_tells_the_others(
    page: Page, browser: Browser, server_url: str
) -> None:
    open_overview(page)
    take_control(page, SID)
    enable(page)
    holder = client_id(page)

    with other_tab(browser, server_url) as watcher:
        open_overview(watcher)
        indicator = watcher.get_by_test_id("control-indicator")
        expect(indicator).to_have_attribute("data-owner", holder)
        expect(watcher.get_by_test_id("control-holder")).to_have_text(holder)
        expect(watcher.get_by_test_id("drive-state")).to_have_text("Operation enabled")

        page.close()  # The controlling tab is gone: its WebSocket closes.

        notice = watcher.get_by_test_id("notice-warning").filter(has_text="stopped and disabled")
        expect(notice).to_be_visible(timeout=10_000)
        expect(notice).to_contain_text(f"the WebSocket of '{holder}' closed")
        expect(notice).to_contain_text(f"Control was held by client {holder}.")
        expect(watcher.get_by_test_id("drive-state")).to_have_text("Switch on disabled")
        r = watcher.request.get(f"/api/v1/sessions/{SID}/state")
        assert r.ok and r.json()["state"] == "Switch on disabled", r.text()
        # Control waits 5 s for a reload of the closed tab, then lapses.
        expect(indicator).to_have_attribute("data-orphaned", "true")
        expect(indicator).to_have_attribute("data-owner", "", timeout=CONTROL_LAPSE_MS)
        expect(watcher.get_by_test_id("control-take")).to_be_visible()


def test_a_second_tab_cannot_take_control_and_force_take_moves_it(
    page: Page, browser: Browser, server_url: str
) -> None:
    open_overview(page)
    take_control(page, SID)
    enable(page)
    first = client_id(page)
    held = tab_control(page)
    assert held is not None
    old_headers = control_headers(page)

    with other_tab(browser, server_url) as second:
        open_overview(second)
        indicator = second.get_by_test_id("control-indicator")
        # Shown the holder, offered no Take; its writes are disabled with the holder named.
        expect(indicator).to_have_attribute("data-owner", first)
        expect(indicator).to_have_attribute("data-you", "false")
        expect(second.get_by_test_id("control-holder")).to_have_text(first)
        expect(second.get_by_test_id("control-take")).to_have_count(0)
        expect(second.get_by_test_id("control-note-reason")).to_contain_text(
            f"Client {first} holds control of {SID}"
        )
        expect(second.get_by_test_id("cmd-disable")).to_be_disabled()
        # Taking it is refused, naming the holder.
        r = second.request.post(
            f"/api/v1/sessions/{SID}/control",
            data='{"action":"take"}',
            headers=control_headers(second),
        )
        assert r.status == 409, r.text()
        assert first in r.json()["message"]

        # Force take asks first and names the holder; Cancel changes nothing.
        second.get_by_test_id("control-force").click()
        dialog = second.get_by_test_id("force-dialog")
        expect(second.get_by_test_id("force-dialog-owner")).to_have_text(first)
        expect(dialog).to_contain_text("disables the drive")
        second.get_by_test_id("force-dialog-cancel").click()
        expect(dialog).to_have_count(0)
        expect(page.get_by_test_id("control-indicator")).to_have_attribute("data-you", "true")
        expect(page.get_by_test_id("drive-state")).to_have_text("Operation enabled")

        second.get_by_test_id("control-force").click()
        second.get_by_test_id("force-dialog-confirm").click()
        expect(indicator).to_have_attribute("data-you", "true")
        expect(indicator).to_have_attribute("data-bound", "true")
        # The previous holder's drive was made safe, and it is told why.
        expect(second.get_by_test_id("drive-state")).to_have_text(
            "Switch on disabled", timeout=10_000
        )
        expect(page.get_by_test_id("drive-state")).to_have_text("Switch on disabled")
        notice = page.get_by_test_id("notice-warning").filter(has_text="stopped and disabled")
        expect(notice).to_contain_text("control taken over by")
        expect(notice).to_contain_text("Control was held by this tab.")
        # The first tab now watches: the new holder is named and its writes are disabled.
        first_indicator = page.get_by_test_id("control-indicator")
        expect(first_indicator).to_have_attribute("data-you", "false")
        expect(first_indicator).to_have_attribute("data-owner", client_id(second))
        expect(page.get_by_test_id("cmd-enable")).to_be_disabled()
        page.wait_for_function("() => sessionStorage.getItem('servodesk.control') === null")
        # Its old token no longer changes the drive.
        r = page.request.post(
            f"/api/v1/sessions/{SID}/state", data='{"command":"shutdown"}', headers=old_headers
        )
        assert r.status == 409, r.text()
        assert client_id(second) in r.json()["message"]
        # The new holder switches the servo on again itself.
        enable(second)
        second.get_by_test_id("cmd-disable").click()
        expect(second.get_by_test_id("drive-state")).to_have_text("Switch on disabled")
