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


def profile_object(page: Page, address: str) -> dict[str, object]:
    r = page.request.get(f"/api/v1/sessions/{SID}/profile")
    assert r.ok, r.text()
    obj: dict[str, object] = next(o for o in r.json()["object_list"] if o["address"] == address)
    return obj


def test_a_new_address_keeps_the_typed_unit(page: Page) -> None:
    # 3000 typed in rpm for 6081h, then the address changed: an object in rpm keeps 3000 rpm
    # (its raw value worked out with that object's scale); one in degrees or raw never reads
    # the number as 3000 deg or 3000 raw, nor converts it with its own scale: it is held,
    # with a note, and not sent.
    max_velocity = profile_object(page, "0x607F:00")
    target = profile_object(page, "0x607A:00")
    assert (max_velocity["unit"], target["unit"], target["raw_unit"]) == ("rpm", "deg", "inc")
    page.goto(f"/#/objects/{SID}")
    take_control(page, SID)
    address = page.get_by_test_id("object-address")
    value = page.get_by_test_id("object-value")
    preview = page.get_by_test_id("object-entry-preview")
    held = page.get_by_test_id("object-entry-held")

    address.fill("0x6081")
    value.fill("3000")
    expect(preview).to_have_text(f"3000 rpm = {round(3000 / session_scale(page))} raw (inc/s)")

    address.fill("0x607F")
    expect(preview).to_have_text(
        f"3000 rpm = {round(3000 / float(str(max_velocity['scale'])))} raw (inc/s)"
    )
    expect(held).to_have_count(0)

    address.fill("0x607A")
    expect(page.get_by_test_id("object-value-label")).to_have_text("Value (deg)")
    expect(held).to_have_text(
        "“3000” is in rpm (for 0x6081:00); 0x607A:00 is entered in deg: type the value in deg."
    )
    expect(preview).to_have_count(0)
    expect(value).to_have_value("3000")
    before = page.request.get(f"/api/v1/sessions/{SID}/objects/0x607A:00").json()["value"]
    page.get_by_test_id("object-write").click()
    expect(page.get_by_test_id("object-error-message")).to_contain_text("“3000” is in rpm")
    after = page.request.get(f"/api/v1/sessions/{SID}/objects/0x607A:00").json()["value"]
    assert after == before
    # Switching to raw does not convert it with 607Ah's scale either.
    page.get_by_test_id("object-entry-raw").click()
    expect(value).to_have_value("3000")
    expect(held).to_contain_text("0x607A:00 takes raw values")
    page.get_by_test_id("object-entry-eng").click()

    address.fill("0x6041")
    expect(held).to_contain_text("0x6041:00 takes raw values: type the raw value.")

    # Back at an object in rpm the number is usable again; typed anew, it is in the new unit.
    address.fill("0x6081")
    expect(held).to_have_count(0)
    expect(preview).to_have_text(f"3000 rpm = {round(3000 / session_scale(page))} raw (inc/s)")
    address.fill("0x607A")
    value.fill("90")
    expect(preview).to_have_text(f"90 deg = {round(90 / float(str(target['scale'])))} raw (inc)")
