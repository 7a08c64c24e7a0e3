"""The Parameters page (the PROFINET card web server's "card parameters", LECSN §20.7).

A commissioning engineer changes 6081h Profile velocity on the generic CiA 402 drive, sees it
marked as not yet saved, saves to EEPROM (CiA 301 1010h:01 <- "save") and sees the mark go;
then restores the factory defaults, which asks first and says what it does. Writing needs
control: the engineer takes it first with the header's Take control.
"""

from __future__ import annotations

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import take_control

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
ADDR = "0x6081:00"


def open_velocity_group(page: Page) -> None:
    page.goto(f"/#/parameters/{SID}")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    take_control(page, SID)
    page.get_by_test_id("group-tab-position").click()
    expect(page.get_by_test_id(f"param-row-{ADDR}")).to_be_visible()
    # The shown group is read from the drive: the value arrives in place of "…".
    expect(page.get_by_test_id(f"param-row-{ADDR}").get_by_test_id("param-value")).not_to_have_text(
        "…"
    )


def test_write_marks_dirty_and_save_clears_it(page: Page) -> None:
    open_velocity_group(page)
    row = page.get_by_test_id(f"param-row-{ADDR}")
    # Engineering value beside the raw one: inc/s raw, rpm engineering.
    expect(row).to_contain_text("inc/s")
    expect(row).to_contain_text("rpm")

    row.get_by_test_id(f"edit-{ADDR}").click()
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    # Raw entry (inc/s); engineering entry is test_engineering_entry.py's.
    editor.get_by_test_id("entry-raw").click()
    value = editor.get_by_test_id("value-input")
    value.fill("-5")
    editor.get_by_test_id("value-write").click()
    expect(editor.get_by_test_id("value-error")).to_contain_text("outside UNSIGNED32")

    value.fill("123456")
    editor.get_by_test_id("value-write").click()
    expect(editor.get_by_test_id("readback-value")).to_have_text("123456")
    expect(row.get_by_test_id("param-value")).to_have_text("123456")
    expect(row).to_have_attribute("data-dirty", "1")
    expect(row.get_by_test_id("dirty-marker")).to_be_visible()
    expect(row.get_by_test_id("differs-marker")).to_be_visible()
    expect(page.get_by_test_id("params-dirty-count")).to_contain_text("written since the last save")

    # The save lists what it will store before it stores it: every object written since the
    # last save (other tests of the package's server may have written some on this drive).
    written = int(page.get_by_test_id("params-dirty-count").inner_text().split()[1])
    page.get_by_test_id("params-store").click()
    dialog = page.get_by_test_id("store-dialog")
    expect(dialog.get_by_test_id(f"store-dirty-{ADDR}")).to_be_visible()
    expect(dialog.get_by_test_id("store-dirty-list").locator("li")).to_have_count(written)
    dialog.get_by_role("button", name="Save", exact=True).click()
    expect(page.get_by_test_id("params-store-result")).to_contain_text("Saved", timeout=20_000)
    expect(page.get_by_test_id("params-store-result")).to_contain_text("0x1010:01")
    expect(row.get_by_test_id("dirty-marker")).to_have_count(0)
    expect(row).to_have_attribute("data-dirty", "0")
    expect(page.get_by_test_id("params-dirty-count")).to_have_text(
        "Nothing written since the last save"
    )
    # Saved, but still not the default.
    expect(row.get_by_test_id("differs-marker")).to_be_visible()


def test_restore_defaults_asks_first(page: Page) -> None:
    open_velocity_group(page)
    row = page.get_by_test_id(f"param-row-{ADDR}")
    row.get_by_test_id(f"edit-{ADDR}").click()
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    editor.get_by_test_id("entry-raw").click()
    editor.get_by_test_id("value-input").fill("300000")
    editor.get_by_test_id("value-write").click()
    expect(row.get_by_test_id("param-value")).to_have_text("300000")

    page.get_by_test_id("params-restore").click()
    dialog = page.get_by_test_id("restore-dialog")
    expect(dialog).to_contain_text("factory defaults")
    expect(dialog).to_contain_text("resets the drive")
    # Cancel changes nothing.
    dialog.get_by_test_id("restore-dialog-cancel").click()
    expect(dialog).to_have_count(0)
    expect(row.get_by_test_id("param-value")).to_have_text("300000")

    page.get_by_test_id("params-restore").click()
    page.get_by_test_id("restore-dialog-confirm").click()
    expect(page.get_by_test_id("params-restore-result")).to_contain_text(
        "defaults restored", timeout=15_000
    )
    # 6081h is back at the profile's default (200000 inc/s), and nothing is dirty.
    expect(row.get_by_test_id("param-value")).to_have_text("200000", timeout=10_000)
    expect(row.get_by_test_id("differs-marker")).to_have_count(0)
    expect(row).to_have_attribute("data-dirty", "0")


def test_every_column_in_view_at_1024_px(page: Page) -> None:
    """At 1024 px the group list beside the table pushed its Default, Range and Edit columns
    out of the card (a scrollbar inside it, issue 48's screenshot set): below 1200 px the
    groups are chips above the table."""
    page.set_viewport_size({"width": 1024, "height": 768})
    try:
        page.goto("/#/parameters/lecsn-t-1")
        table = page.get_by_test_id("params-table")
        expect(table).to_be_visible(timeout=15_000)
        card = page.locator(".params-table-card")
        widths = card.evaluate("(el) => [el.scrollWidth, el.clientWidth]")
        assert widths[0] <= widths[1], widths
        edit = table.get_by_role("button", name="Edit").first
        box = edit.bounding_box()
        assert box is not None and box["x"] + box["width"] <= 1024, box
        assert page.evaluate("() => document.documentElement.scrollWidth") <= 1024
    finally:
        page.set_viewport_size({"width": 1440, "height": 960})
