"""The drive tree in the sidebar (issue 48, docs/ui.md "Drive tree"): every twin's bus and
drive with its CiA 402 state and who holds control; a drive is a link to the same page for
that drive (mouse, Enter, Space); a bus folds; a fault shows its alarm on the drive's row;
the sidebar fits a 1024 px window."""

from __future__ import annotations

import json
import re
from typing import Any

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import control_headers, take_control

pytestmark = pytest.mark.browser

#: How the tree names each of serve --sim's buses (lib/driveTree busLabel): the CANopen twins
#: on the virtual bus, the CTMM04x station on SLMP, the LECSN-T on PROFINET; the HIWIN twin on
#: its EtherCAT line with SERVODESK_SIM_ETHERCAT=1.
BUS_PREFIX = {
    "virtual": "CANopen · virtual:",
    "slmp": "CC-Link IE TSN · SLMP ",
    "profinet": "PROFINET · ",
    "ethercat": "EtherCAT · ",
}


def open_sessions(page: Page) -> list[dict[str, Any]]:
    answer = page.request.get("/api/v1/sessions")
    assert answer.ok, answer.text()
    sessions: list[dict[str, Any]] = answer.json()
    return sessions


def drive_name(s: dict[str, Any]) -> str:
    name: str = s["identity"].get("device_name") or s["profile_name"]
    return name


def test_every_twin_is_in_the_tree_under_its_bus_with_its_state(page: Page) -> None:
    page.set_viewport_size({"width": 1024, "height": 768})
    page.goto("/#/axes")
    expect(page.get_by_test_id("ws-status")).to_have_attribute("data-status", "open")
    sessions = open_sessions(page)
    assert len(sessions) >= 5, [s["id"] for s in sessions]
    tree = page.get_by_test_id("drive-tree")
    for s in sessions:
        bus = tree.locator(f'[data-testid="tree-bus"][data-bus="{s["interface"]}:{s["channel"]}"]')
        expect(bus.get_by_test_id("tree-bus-label")).to_have_text(
            BUS_PREFIX[s["interface"]] + s["channel"]
        )
        row = bus.get_by_test_id(f"tree-drive-{s['id']}")
        expect(row.get_by_test_id("tree-drive-name")).to_have_text(drive_name(s))
        # The state the server reports for the drive, not a placeholder.
        state = row.get_by_test_id("tree-drive-state")
        expect(state).not_to_have_text("—")
        expect(state).not_to_have_text("Unknown")
        expect(row.get_by_test_id("tree-drive-control")).not_to_have_text("…")
    # On a global page no drive page is open: a row leads to the drive's Overview.
    first = sessions[0]["id"]
    expect(tree.get_by_test_id(f"tree-drive-{first}")).to_have_attribute(
        "href", f"#/overview/{first}"
    )
    # Neither the window nor the sidebar scrolls sideways at 1024 px (a long bus address
    # wraps, a long drive name is cut).
    assert page.evaluate("() => document.documentElement.scrollWidth") <= 1024
    nav = page.locator(".nav")
    assert nav.evaluate("n => n.scrollWidth <= n.clientWidth"), nav.evaluate(
        "n => [n.scrollWidth, n.clientWidth]"
    )


def test_a_drive_opens_the_same_page_and_shows_who_holds_control(page: Page) -> None:
    sessions = open_sessions(page)
    first, other = sessions[0], sessions[-1]
    assert first["id"] != other["id"]
    page.goto(f"/#/parameters/{first['id']}")
    expect(page.get_by_test_id("header-drive-name")).to_have_text(drive_name(first))
    tree = page.get_by_test_id("drive-tree")
    expect(tree.get_by_test_id(f"tree-drive-{first['id']}")).to_have_attribute(
        "aria-current", "true"
    )

    row = tree.get_by_test_id(f"tree-drive-{other['id']}")
    row.click()
    # The same page, for the drive clicked: the header's drive changes with it.
    page.wait_for_function(
        "sid => location.hash === `#/parameters/${sid}`", arg=other["id"], timeout=5000
    )
    expect(page.get_by_test_id("header-drive-name")).to_have_text(drive_name(other))
    expect(row).to_have_attribute("aria-current", "true")
    expect(tree.get_by_test_id(f"tree-drive-{first['id']}")).not_to_have_attribute(
        "aria-current", "true"
    )

    # Taking control in the header shows "you" on the drive's row; the others keep theirs.
    take_control(page, other["id"])
    expect(row.get_by_test_id("tree-drive-control")).to_have_text("you")
    expect(row).to_have_attribute("data-control", "you")
    expect(
        tree.get_by_test_id(f"tree-drive-{first['id']}").get_by_test_id("tree-drive-control")
    ).not_to_have_text("you")


def test_the_tree_works_from_the_keyboard_and_a_bus_folds(page: Page) -> None:
    sessions = open_sessions(page)
    first, other = sessions[0], sessions[-1]
    page.goto(f"/#/alarms/{first['id']}")
    tree = page.get_by_test_id("drive-tree")
    row = tree.get_by_test_id(f"tree-drive-{other['id']}")
    # Enter follows the link, Space too (as on a button).
    row.focus()
    page.keyboard.press("Enter")
    page.wait_for_function(
        "sid => location.hash === `#/alarms/${sid}`", arg=other["id"], timeout=5000
    )
    back = tree.get_by_test_id(f"tree-drive-{first['id']}")
    back.focus()
    page.keyboard.press(" ")
    page.wait_for_function(
        "sid => location.hash === `#/alarms/${sid}`", arg=first["id"], timeout=5000
    )
    expect(page.get_by_test_id("header-drive-name")).to_have_text(drive_name(first))

    # The bus folds and unfolds; the header's select stays for switching drives.
    bus = tree.locator(
        f'[data-testid="tree-bus"][data-bus="{other["interface"]}:{other["channel"]}"]'
    )
    head = bus.get_by_test_id("tree-bus-head")
    expect(head).to_have_attribute("aria-expanded", "true")
    head.click()
    expect(head).to_have_attribute("aria-expanded", "false")
    expect(row).to_be_hidden()
    head.press("Enter")
    expect(head).to_have_attribute("aria-expanded", "true")
    expect(row).to_be_visible()
    page.get_by_test_id("session-select").select_option(other["id"])
    page.wait_for_function(
        "sid => location.hash === `#/alarms/${sid}`", arg=other["id"], timeout=5000
    )


GENERIC = "cia402-generic-1"  # CANopen twin
WINDOW = "0x6065:00"  # following error window


def put(page: Page, addr: str, value: int) -> None:
    r = page.request.put(
        f"/api/v1/sessions/{GENERIC}/objects/{addr}",
        data=json.dumps({"value": value}),
        headers=control_headers(page),
    )
    assert r.ok, r.text()


def test_a_fault_shows_its_alarm_on_the_drive_and_goes_with_the_reset(page: Page) -> None:
    """A following error (as tests/browser/test_alarms.py provokes it) puts the profile's
    alarm code on the drive's row; the fault reset takes it away."""
    page.goto(f"/#/operation/{GENERIC}")
    expect(page.get_by_test_id("operation-page")).to_be_visible()
    original = int(page.request.get(f"/api/v1/sessions/{GENERIC}/objects/{WINDOW}").json()["value"])
    row = page.get_by_test_id("drive-tree").get_by_test_id(f"tree-drive-{GENERIC}")
    expect(row.get_by_test_id("tree-drive-alarm")).to_have_count(0)
    take_control(page, GENERIC)
    try:
        if page.get_by_test_id("op-state").inner_text().strip() != "Operation enabled":
            page.get_by_test_id("servo-on").click()
        expect(page.get_by_test_id("op-state")).to_have_text("Operation enabled", timeout=10_000)
        put(page, WINDOW, 10)
        page.get_by_test_id("tab-move").click()
        page.get_by_test_id("move-mode-relative").click()
        page.get_by_test_id("units-raw").click()  # Increments: engineering is the default.
        page.get_by_test_id("move-target").fill("500000")
        page.get_by_test_id("move-velocity").fill("900000")
        page.get_by_test_id("move-acceleration").fill("10000000")
        page.get_by_test_id("move-deceleration").fill("10000000")
        page.get_by_test_id("move-start").click()
        expect(row).to_have_attribute("data-state", "Fault", timeout=5_000)
        alarm = row.get_by_test_id("tree-drive-alarm")
        expect(alarm).to_be_visible()
        expect(alarm).to_have_attribute("title", re.compile("Following error"))
        expect(row.get_by_test_id("tree-drive-state")).to_have_text("Fault")
    finally:
        put(page, WINDOW, original)
        page.request.post(
            f"/api/v1/sessions/{GENERIC}/alarms/reset", data="{}", headers=control_headers(page)
        )
    expect(row.get_by_test_id("tree-drive-alarm")).to_have_count(0, timeout=5_000)
    expect(row).not_to_have_attribute("data-state", "Fault")
