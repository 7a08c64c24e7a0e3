"""The Object dictionary page on the largest profile (SMC LECSN-T, about 3000 objects).

What a commissioning engineer does there: find an object the way the manual writes it
(6083h, 0x6083, P24707) or by words of its name, narrow the list by group, access and PDO,
read live values, and write one object from its detail panel. The object is 6083h Profile
acceleration (PNU 24707): writable, limits 0..50000 ms in the lecsn-t profile (LECSN manual
§20.9.3.10), so a value above the maximum is refused in the browser before anything is sent,
and a good one is written and read back from the simulated drive. Writing needs control of
the drive, taken with the header's Take control.
"""

from __future__ import annotations

import functools
import re

import httpx
import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import take_control

pytestmark = pytest.mark.browser

SID = "lecsn-t-1"
ADDR = "0x6083:00"


@functools.cache
def total(base_url: str) -> int:
    """Every entry of the profile, as the API counts it (the page must show them all)."""
    n = httpx.get(f"{base_url}/api/v1/profiles/lecsn-t", timeout=10).json()["variables"]
    assert n > 2500
    return int(n)


def open_dictionary(page: Page, server_url: str) -> int:
    page.goto(f"/#/dictionary/{SID}")
    n = total(server_url)
    expect(page.get_by_test_id("od-count")).to_contain_text(f"of {n} objects", timeout=15_000)
    return n


def test_search_accepts_every_address_spelling(page: Page, server_url: str) -> None:
    n = open_dictionary(page, server_url)
    search = page.get_by_test_id("od-search")
    row = page.get_by_test_id(f"od-row-{ADDR}")
    for text in ("6083h", "0x6083", "P24707", "6083"):
        search.fill(text)
        expect(row).to_be_visible()
        expect(row).to_contain_text("P24707")
    # The PNU form finds exactly that object, not every PNU that starts with its digits.
    search.fill("P24707")
    expect(page.get_by_test_id("od-count")).to_have_text(f"1 of {n} objects")
    # Words of the name; the drive's own symbol (PA01 = P8193 = 2001h, §20.1.5.1).
    search.fill("PA01")
    expect(page.get_by_test_id("od-row-0x2001:00")).to_be_visible()
    search.fill("zzzz-no-such-object")
    expect(page.get_by_test_id("od-count")).to_have_text(f"0 of {n} objects")


def test_filters_narrow_the_list(page: Page, server_url: str) -> None:
    n = open_dictionary(page, server_url)
    count = page.get_by_test_id("od-count")
    page.get_by_test_id("od-search").fill("acceleration")
    expect(count).not_to_have_text(f"0 of {n} objects")
    all_hits = int(count.inner_text().split()[0])

    page.get_by_test_id("od-group").select_option("profile_position")
    expect(page.get_by_test_id(f"od-row-{ADDR}")).to_be_visible()
    in_group = int(count.inner_text().split()[0])
    assert 0 < in_group < all_hits
    # Every row shown belongs to the group's 6xxxh objects, none of the point tables (28xxh).
    expect(page.locator('[data-testid^="od-row-0x28"]')).to_have_count(0)

    page.get_by_test_id("od-pdo").check()
    expect(page.get_by_test_id(f"od-row-{ADDR}")).to_contain_text("Rx")
    page.get_by_test_id("od-access").select_option("writable")
    expect(page.get_by_test_id(f"od-row-{ADDR}")).to_be_visible()


def test_write_refused_in_place_then_written_and_read_back(page: Page, server_url: str) -> None:
    open_dictionary(page, server_url)
    take_control(page, SID)  # Writes need control of the drive.
    page.get_by_test_id("od-search").fill("P24707")
    page.get_by_test_id(f"od-row-{ADDR}").click()
    detail = page.get_by_test_id("od-detail")
    expect(detail.get_by_test_id("od-detail-name")).to_have_text("Profile acceleration")
    expect(detail.get_by_test_id("od-detail-section")).to_contain_text("§")

    value = detail.get_by_test_id("value-input")
    value.fill("60000")
    detail.get_by_test_id("value-write").click()
    error = detail.get_by_test_id("value-error")
    expect(error).to_contain_text("above the maximum 50000")
    expect(detail.get_by_test_id("readback")).to_have_count(0)

    # Hex entry: 5DC is 1500 ms. The refused value is converted when the base changes; the
    # test waits for that before typing, so that each step's failure names itself (this step
    # failed once in CI, 2026-11-26, with the error still shown; not reproduced in six runs
    # on a loaded machine).
    detail.get_by_test_id("value-hex").click()
    expect(detail.get_by_test_id("value-hex")).to_have_attribute("aria-pressed", "true")
    expect(value).to_have_value("0000EA60")
    value.fill("5DC")
    expect(value).to_have_value("5DC")
    expect(error).to_have_count(0)
    detail.get_by_test_id("value-write").click()
    expect(detail.get_by_test_id("readback-value")).to_have_text("1500")
    expect(detail.get_by_test_id("od-detail-value")).to_contain_text("1500")
    expect(page.get_by_test_id(f"od-row-{ADDR}")).to_contain_text("1500")


def test_read_values_and_differs_from_default(page: Page, server_url: str) -> None:
    open_dictionary(page, server_url)
    take_control(page, SID)
    page.get_by_test_id("od-group").select_option("profile_position")
    page.get_by_test_id("od-search").fill("P24707")
    page.get_by_test_id(f"od-row-{ADDR}").click()
    detail = page.get_by_test_id("od-detail")
    detail.get_by_test_id("value-input").fill("2500")
    detail.get_by_test_id("value-write").click()
    expect(detail.get_by_test_id("readback-value")).to_have_text("2500")

    page.get_by_test_id("od-search").fill("")
    page.get_by_test_id("od-read-values").click()
    expect(page.get_by_test_id("od-read-values")).to_be_visible(timeout=15_000)
    expect(page.get_by_test_id("od-known")).to_contain_text(re.compile(r"\d+ with live values"))
    # 6083h now differs from its default (0); the filter keeps it and drops unchanged ones.
    page.get_by_test_id("od-differs").check()
    expect(page.get_by_test_id(f"od-row-{ADDR}")).to_be_visible()
    expect(page.get_by_test_id(f"od-row-{ADDR}")).to_contain_text(re.compile(r"≠\s*2500"))
    shown = int(page.get_by_test_id("od-count").inner_text().split()[0])
    assert shown < 14
