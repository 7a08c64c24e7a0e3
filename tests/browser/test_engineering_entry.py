"""Entering a parameter in engineering units (issue 48, "units a person reads").

A commissioning engineer sets 6081h Profile velocity of the generic CiA 402 twin in rpm, not in
the drive's inc/s: the Parameters page converts it (raw = rpm / scale, the session profile's
scale), shows both units before the write, sends the raw value, and the drive reads back that
raw value. A value that is not a whole number of inc/s is rounded and the page says so; one
outside the type's range is refused in place, naming the range in both units, and nothing is
sent. The choice of units is kept by the browser.
"""

from __future__ import annotations

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import take_control

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
ADDR = "0x6081:00"


def session_scale(page: Page) -> float:
    """The session's rpm per inc/s (the session's profile: the drive's encoder's)."""
    r = page.request.get(f"/api/v1/sessions/{SID}/profile")
    assert r.ok, r.text()
    obj = next(o for o in r.json()["object_list"] if o["address"] == ADDR)
    assert (obj["unit"], obj["raw_unit"]) == ("rpm", "inc/s")
    return float(obj["scale"])


def drive_value(page: Page) -> int:
    r = page.request.get(f"/api/v1/sessions/{SID}/objects/{ADDR}")
    assert r.ok, r.text()
    return int(r.json()["value"])


def open_editor(page: Page) -> None:
    page.goto(f"/#/parameters/{SID}/position")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    take_control(page, SID)
    row = page.get_by_test_id(f"param-row-{ADDR}")
    expect(row.get_by_test_id("param-value")).not_to_have_text("…")
    row.get_by_test_id(f"edit-{ADDR}").click()


def test_a_velocity_written_in_rpm_reads_back_as_its_raw_value(page: Page) -> None:
    scale = session_scale(page)
    open_editor(page)
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    value = editor.get_by_test_id("value-input")
    # Engineering entry by default for an object with a real unit.
    expect(editor.get_by_test_id("entry-eng")).to_have_attribute("aria-pressed", "true")
    expect(editor.get_by_test_id("entry-eng")).to_have_text("rpm")
    expect(editor.get_by_test_id("entry-raw")).to_have_text("raw (inc/s)")

    raw = round(1500 / scale)
    value.fill("1500")
    expect(editor.get_by_test_id("value-preview")).to_contain_text(f"1500 rpm = {raw} raw (inc/s)")
    expect(editor.get_by_test_id("value-rounded")).to_have_count(0)
    editor.get_by_test_id("value-write").click()
    expect(editor.get_by_test_id("readback-value")).to_have_text(str(raw))
    assert drive_value(page) == raw
    row = page.get_by_test_id(f"param-row-{ADDR}")
    expect(row.get_by_test_id("param-value")).to_have_text(str(raw))

    # Not a whole number of inc/s: rounded to the nearest, and said.
    typed = 1000.0001
    raw = round(typed / scale)
    assert abs(raw - typed / scale) > 1e-6
    value.fill(str(typed))
    expect(editor.get_by_test_id("value-rounded")).to_contain_text(f"rounded to {raw} raw = ")
    editor.get_by_test_id("value-write").click()
    expect(editor.get_by_test_id("readback-value")).to_have_text(str(raw))
    assert drive_value(page) == raw

    # Outside UNSIGNED32: refused in place, in both units; the drive keeps its value.
    value.fill("-1")
    editor.get_by_test_id("value-write").click()
    error = editor.get_by_test_id("value-error")
    expect(error).to_contain_text("is below the minimum: allowed 0 .. ")
    expect(error).to_contain_text("rpm (0 .. 4294967295 inc/s)")
    assert drive_value(page) == raw


def test_raw_entry_is_kept_by_the_browser(page: Page) -> None:
    open_editor(page)
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    value = editor.get_by_test_id("value-input")
    value.fill("1500")
    # Switching keeps the value: 1500 rpm shown as its inc/s.
    editor.get_by_test_id("entry-raw").click()
    expect(editor.get_by_test_id("entry-raw")).to_have_attribute("aria-pressed", "true")
    raw = round(1500 / session_scale(page))
    expect(value).to_have_value(str(raw))
    expect(editor.get_by_test_id("value-preview")).to_contain_text(f"{raw} raw (inc/s) = ")

    page.reload()
    open_editor(page)
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    expect(editor.get_by_test_id("entry-raw")).to_have_attribute("aria-pressed", "true")
    # And back with the keyboard.
    editor.get_by_test_id("entry-eng").focus()
    page.keyboard.press("Enter")
    expect(editor.get_by_test_id("entry-eng")).to_have_attribute("aria-pressed", "true")


def test_object_access_takes_rpm_too(page: Page) -> None:
    scale = session_scale(page)
    page.goto(f"/#/objects/{SID}")
    take_control(page, SID)
    page.get_by_test_id("object-address").fill("0x6081")
    expect(page.get_by_test_id("object-entry-eng")).to_have_attribute("aria-pressed", "true")
    expect(page.get_by_test_id("object-value-label")).to_have_text("Value (rpm)")
    value = page.get_by_test_id("object-value")
    raw = round(1200 / scale)
    value.fill("1200")
    expect(page.get_by_test_id("object-entry-preview")).to_have_text(
        f"1200 rpm = {raw} raw (inc/s)"
    )
    page.get_by_test_id("object-write").click()
    expect(page.get_by_test_id("object-value-dec")).to_contain_text(str(raw))
    assert drive_value(page) == raw
    # What the drive holds, shown again in rpm.
    expect(value).to_have_value("1200")

    # Not a number: said in place, and the write is refused before anything is sent.
    value.fill("12OO")
    expect(page.get_by_test_id("object-entry-error")).to_contain_text('"12OO" is not a number')
    page.get_by_test_id("object-write").click()
    expect(page.get_by_test_id("object-error-message")).to_contain_text("is not a number")
    assert drive_value(page) == raw
