"""The PDO mapping page against the real backend and the simulated generic CiA 402 drive.

What a commissioning engineer relies on (issue 6 "Done when"): drag an object from the palette
into a TPDO, see the bit budget and the check follow, review the planned steps, apply them,
start the cyclic data and see the mapped object's value update live next to it, raw and
engineering side by side. The drive is left as it was found: the mapping is put back, cyclic
data stopped, the axis disabled and control released. Applying, starting the cyclic data and
moving need control: the page takes it with the header's Take control, and the test's own
requests (and a second socket of the page, the motion's dead-man) use the page's token.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from typing import Any

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import (
    control_headers,
    release_control,
    start_mover,
    stop_mover,
    take_control,
)

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
PDO = f"/api/v1/sessions/{SID}/pdo"
#: The label of the page's second WebSocket that carries the dead-man heartbeat of the motion
#: the test starts over the API (bound to the page's own control token).
MOVER = "pdo-test-mover"
#: Target velocity (60FFh, raw counts/s): slow enough to stay far from the simulated
#: drive's limit switches (-1.7 / +3.7 revolutions of 131072 counts) for the whole test.
VELOCITY = 20_000


def layout_of(view: dict[str, Any]) -> dict[str, Any]:
    """A PdoLayout (docs/pdo.md) that writes back exactly the PDOs of ``view``."""
    pdos = []
    for p in view["pdos"]:
        out: dict[str, Any] = {
            "direction": p["direction"],
            "number": p["number"],
            "entries": [
                {"index": e["index"], "subindex": e["subindex"], "bits": e["bits"]}
                for e in p["entries"]
            ],
        }
        if p["comm_index"] is not None:
            out.update(
                cob_id=p["cob_id"] & 0x7FF,
                enabled=p["enabled"],
                transmission_type=p["transmission_type"],
                inhibit_time=p["inhibit_time"],
                event_timer=p["event_timer"],
            )
            if p["direction"] == "tx":
                out.update(rtr_allowed=p["rtr_allowed"], sync_start=p["sync_start"])
        pdos.append(out)
    layout: dict[str, Any] = {"pdos": pdos}
    if view.get("assignment") is not None:
        layout["assignment"] = view["assignment"]
    if view.get("telegram") is not None:
        layout["telegram"] = view["telegram"]
    return layout


def post(page: Page, path: str, body: dict[str, Any], headers: dict[str, str] | None = None) -> Any:
    r = page.request.post(
        path,
        data=json.dumps(body),
        headers=headers or {"Content-Type": "application/json"},
    )
    assert r.ok, f"POST {path}: {r.status} {r.text()}"
    return r.json()


@pytest.fixture
def pdo_page(page: Page) -> Iterator[Page]:
    original = page.request.get(PDO)
    assert original.ok, f"GET {PDO}: {original.status} {original.text()}"
    restore = layout_of(original.json())
    # Control first (an apply changes the drive), from the page's header.
    page.goto(f"/#/overview/{SID}")
    take_control(page, SID)
    # A known start, whatever ran before: TPDO1 carries the statusword only, event-driven.
    tpdo1 = {"direction": "tx", "number": 1, "entries": ["0x6041:00"], "transmission_type": 255}
    report = post(page, f"{PDO}/apply", {"pdos": [tpdo1], "dry_run": False}, control_headers(page))
    assert report["ok"], report
    page.goto(f"/#/pdo/{SID}")
    expect(page.get_by_test_id("pdo-page")).to_be_visible()
    try:
        yield page
    finally:
        # Leave the drive as the other tests expect it.
        headers = control_headers(page)
        page.request.post(f"/api/v1/sessions/{SID}/motion/halt", data="{}", headers=headers)
        page.request.post(
            f"/api/v1/sessions/{SID}/state", data='{"command":"disable"}', headers=headers
        )
        stop_mover(page)
        page.request.delete(f"{PDO}/cyclic", headers=headers)
        r = page.request.post(
            f"{PDO}/apply", data=json.dumps({**restore, "dry_run": False}), headers=headers
        )
        release_control(page)
        assert r.ok and r.json()["ok"], f"putting the mapping back failed: {r.status} {r.text()}"


def live_raw(page: Page, testid: str) -> int:
    raw = page.get_by_test_id(testid).get_attribute("data-raw")
    assert raw is not None and re.fullmatch(r"-?\d+", raw), f"{testid} shows raw {raw!r}"
    return int(raw)


def test_drag_into_tpdo_apply_and_see_it_live(pdo_page: Page) -> None:
    page = pdo_page
    card = page.get_by_test_id("pdo-card-TPDO1")
    expect(card).to_be_visible()
    # A CANopen drive's NMT state heads the page, with what it rests on (this twin sends no
    # heartbeat: unknown until servodesk sends an NMT command).
    nmt = page.get_by_test_id("pdo-nmt")
    expect(nmt).to_contain_text("NMT")
    expect(nmt).to_have_attribute("title", re.compile(r"^NMT state"))
    # TPDO1 starts with the statusword only (16 of 64 bits).
    expect(page.get_by_test_id("pdo-TPDO1-budget")).to_have_attribute("data-used", "16")
    expect(page.get_by_test_id("pdo-TPDO1-entry-1")).to_have_count(0)

    # Find the object in the palette and drag it into TPDO1.
    page.get_by_test_id("pdo-palette-tx").click()
    page.get_by_test_id("pdo-palette-search").fill("position actual")
    item = page.get_by_test_id("pdo-palette-item-0x6064:00")
    expect(item).to_be_visible()
    # The palette stays on screen (sticky) while the tables scroll: bring the drop place into
    # view first, as a person would, so the page does not scroll in the middle of the drag.
    dropzone = page.get_by_test_id("pdo-TPDO1-dropzone")
    dropzone.scroll_into_view_if_needed()
    item.drag_to(dropzone)

    entry = page.get_by_test_id("pdo-TPDO1-entry-1")
    expect(entry).to_have_attribute("data-address", "0x6064:00")
    expect(entry).to_contain_text("Position actual value")
    # Byte offset 2, bit 0: right after the 16-bit statusword.
    expect(entry.locator("td").nth(1)).to_have_text("2")
    expect(entry.locator("td").nth(2)).to_have_text("0")
    expect(page.get_by_test_id("pdo-TPDO1-budget")).to_have_attribute("data-used", "48")
    expect(page.get_by_test_id("pdo-TPDO1-changed")).to_be_visible()

    # Send it on every SYNC (CiA 301 transmission type 1), so the cyclic data carries it.
    page.get_by_test_id("pdo-TPDO1-transmission_type").select_option("n")
    expect(page.get_by_test_id("pdo-TPDO1-transmission_n")).to_have_value("1")

    # The live check passes, which enables the review.
    check = page.get_by_test_id("pdo-check")
    expect(check).to_have_attribute("data-state", "done", timeout=10_000)
    expect(check).to_have_attribute("data-problems", "0")
    review = page.get_by_test_id("pdo-review")
    expect(review).to_be_enabled()

    # A dry run says what would be written and writes nothing.
    page.get_by_test_id("pdo-dry-run").click()
    expect(page.get_by_test_id("pdo-report")).to_have_attribute("data-dry-run", "true")
    expect(page.get_by_test_id("pdo-report-result")).to_contain_text("nothing was written")
    before = page.request.get(PDO).json()
    assert [e["address"] for e in before["pdos"][4]["entries"]] == ["0x6041:00"]

    review.click()

    # The plan lists the steps in order, with why each is there; confirm it.
    plan = page.get_by_test_id("pdo-plan")
    expect(plan).to_be_visible(timeout=10_000)
    steps = page.get_by_test_id("pdo-plan-steps")
    expect(steps).to_contain_text("0x1A00:00")
    expect(steps).to_contain_text("0x60640020")
    page.get_by_test_id("pdo-apply-confirm").click()
    report = page.get_by_test_id("pdo-report")
    expect(report).to_have_attribute("data-ok", "true", timeout=20_000)
    expect(page.get_by_test_id("pdo-report-flags")).to_contain_text("verified")
    # The editor now shows the drive's mapping: nothing left to apply.
    expect(page.get_by_test_id("pdo-TPDO1-changed")).to_have_count(0)
    expect(page.get_by_test_id("pdo-TPDO1-entry-1")).to_have_attribute("data-address", "0x6064:00")
    drive = page.request.get(PDO).json()
    tpdo1 = next(p for p in drive["pdos"] if p["name"] == "TPDO1")
    assert [e["address"] for e in tpdo1["entries"]] == ["0x6041:00", "0x6064:00"]
    assert tpdo1["transmission_type"] == 1

    # The PLC programmer's export has the new layout.
    with page.expect_download() as download:
        page.get_by_test_id("pdo-export-csv").click()
    csv = download.value.path().read_text(encoding="utf-8")
    # pdo, COB-ID, byte offset, bit offset, bits, address, name.
    assert "TPDO1,0x181,2,0,32,0x6064:00,Position actual value" in csv, csv

    # Start the cyclic data at the default 10 ms SYNC.
    expect(page.get_by_test_id("pdo-cyclic-period")).to_have_value("10")
    page.get_by_test_id("pdo-cyclic-start").click()
    expect(page.get_by_test_id("pdo-cyclic-state")).to_have_attribute("data-running", "true")
    live = "pdo-live-TPDO1-0x6064:00"
    expect(page.get_by_test_id(live)).to_have_attribute(
        "data-raw", re.compile(r"^-?\d+$"), timeout=5_000
    )
    # Raw and engineering side by side, each with its unit (profile: inc and deg).
    expect(page.get_by_test_id(live)).to_contain_text("inc")
    expect(page.get_by_test_id(live)).to_contain_text("deg")

    # Move the axis (over the API with the page's token; a second socket of the page, bound
    # to that control, carries the motion's dead-man heartbeat) ...
    headers = control_headers(page)
    start_mover(page, SID, headers["X-Servodesk-Control"], MOVER)
    post(page, f"/api/v1/sessions/{SID}/state", {"command": "enable"}, headers)
    post(page, f"/api/v1/sessions/{SID}/motion/velocity", {"velocity": VELOCITY}, headers)

    # ... and the value next to the mapped object follows, live.
    first = live_raw(page, live)
    expect(page.get_by_test_id(live)).not_to_have_attribute("data-raw", str(first), timeout=3_000)
    second = live_raw(page, live)
    page.wait_for_timeout(300)
    third = live_raw(page, live)
    assert first != second != third, f"position shown {first}, {second}, {third}"
    assert third > first, f"moving forward, the position went {first} -> {third}"
    expect(page.get_by_test_id("pdo-TPDO1-rate")).to_be_visible()


def test_a_fixed_telegram_names_its_words(page: Page) -> None:
    # Telegram 1's STW1 / NSOLL_A and ZSW1 / NIST_A are no objects of the dictionary (004
    # §20.3 (1)): the drive's mapping holds them as 16-bit entries of index 0. The page showed
    # them as "Reserved (16 bits)"; the server's layout names them, and so does the page now.
    r = page.request.get("/api/v1/sessions/lecsn-t-1/pdo")
    assert r.ok and r.json()["telegram"] == 1, r.text()
    page.goto("/#/pdo/lecsn-t-1")
    expect(page.get_by_test_id("pdo-page")).to_be_visible()
    words = {
        "setpoint telegram": ("STW1 (Control word 1)", "UNSIGNED16", "NSOLL_A", "INTEGER16"),
        "actual-value telegram": ("ZSW1 (Status word 1)", "UNSIGNED16", "NIST_A", "INTEGER16"),
    }
    for pdo, (first, first_type, second, second_type) in words.items():
        row0 = page.get_by_test_id(f"pdo-{pdo}-entry-0")
        expect(row0).to_contain_text(first)
        expect(row0).to_contain_text(first_type)
        row1 = page.get_by_test_id(f"pdo-{pdo}-entry-1")
        expect(row1).to_contain_text(second)
        expect(row1).to_contain_text(second_type)
        expect(row0).not_to_contain_text("Reserved")
        # A fixed telegram's layout is the telegram: nothing to move, remove or drop in.
        expect(page.get_by_test_id(f"pdo-{pdo}-entry-0-remove")).to_have_count(0)
        expect(page.get_by_test_id(f"pdo-{pdo}-dropzone")).to_have_count(0)
    # The telegram choice is labelled from the profile's telegrams (004 §20.3).
    options = page.get_by_test_id("pdo-telegram-select").locator("option")
    expect(options).to_have_text(
        [
            "1 · Standard telegram 1 (fixed)",
            "102 · Telegram 102, variable, at most 48 bytes / 24 entries",
            "103 · Telegram 103, variable, at most 60 bytes / 30 entries",
        ]
    )


def test_idle_event_driven_tpdo_says_why_and_offers_the_fix(pdo_page: Page) -> None:
    # Issue 48: cyclic data "running · 0 frames/s" with TPDO1 event-driven (type 255, no event
    # timer) on an idle axis. The page says why nothing arrives and offers the fix; the user
    # confirms it (a PDO change, under control) and frames arrive with every SYNC.
    page = pdo_page
    page.get_by_test_id("pdo-cyclic-start").click()
    expect(page.get_by_test_id("pdo-cyclic-state")).to_have_attribute("data-running", "true")
    idle = page.get_by_test_id("pdo-idle-TPDO1")
    expect(idle).to_contain_text("event-driven (transmission type 255)", timeout=10_000)
    expect(idle).to_contain_text("no event timer")
    expect(page.get_by_test_id("pdo-idle")).to_contain_text("Nothing arrives from TPDO1")
    page.get_by_test_id("pdo-idle-fix-0").click()
    dialog = page.get_by_test_id("pdo-idle-dialog")
    expect(dialog).to_contain_text("transmission type 1")
    page.get_by_test_id("pdo-idle-dialog-confirm").click()
    expect(dialog).to_have_count(0, timeout=15_000)
    expect(page.get_by_test_id("pdo-idle")).to_have_count(0, timeout=10_000)
    view = page.request.get(PDO).json()
    tpdo1 = next(p for p in view["pdos"] if p["direction"] == "tx" and p["number"] == 1)
    assert tpdo1["transmission_type"] == 1
    rate = page.get_by_test_id("pdo-rate-TPDO1").locator("td").nth(4)
    expect(rate).not_to_have_text(re.compile(r"^(0\.0|—)$"), timeout=10_000)
