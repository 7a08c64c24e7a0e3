"""The Network configuration page against the real backend and the simulated drives.

What a commissioning engineer looks for there (the LEC-S-NP card web server's "network
configuration" page, 004 §20.7, for every family): the link the session runs on, the telegram
the LECSN-T's master chose (P922) read from the drive, the LED decode of the manual, the CTMM04x
reached by SLMP on its axis X; an object the drive refuses says so in its own row. All of it
fits a 1280 x 800 laptop screen.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import running_server

pytestmark = pytest.mark.browser


def _fits(page: Page) -> bool:
    """No horizontal overflow: neither the document nor the page's scrolling area."""
    return bool(
        page.evaluate(
            "() => document.documentElement.scrollWidth <= document.documentElement.clientWidth"
            " && [...document.querySelectorAll('.page, .card')]"
            ".every(e => e.scrollWidth <= e.clientWidth + 1)"
        )
    )


def test_lecsn_shows_the_telegram_read_from_the_drive_and_the_leds(page: Page) -> None:
    page.set_viewport_size({"width": 1280, "height": 800})
    # The telegram the twin holds (P922 = 0x039A:00, 004 §20.4.3.1), as the API reads it.
    r = page.request.post("/api/v1/sessions/lecsn-t-1/read", data={"addresses": ["0x039A:00"]})
    assert r.ok, r.text()
    telegram = r.json()["results"][0]["value"]
    assert telegram in (1, 100, 102, 103)

    page.goto("/#/network/lecsn-t-1")
    expect(page.get_by_test_id("nav-network")).to_be_visible()
    row = page.get_by_test_id("network-row-0x039A:00")
    expect(row).to_contain_text("Telegram selection")
    expect(row).to_contain_text("P922")
    expect(row.get_by_test_id("network-value")).to_have_text(str(telegram))
    expect(row.get_by_test_id("network-hex")).to_have_text(f"0x{telegram:04X}")
    expect(row.get_by_test_id("network-meaning")).to_contain_text("elegram")

    link = page.get_by_test_id("network-link")
    expect(page.get_by_test_id("network-fieldbus")).to_have_text("profinet")
    # The twin is a PROFINET IO device, reached by PNIO-CM record access (docs/profinet.md).
    expect(page.get_by_test_id("network-link-name")).to_have_text("profinet")
    expect(page.get_by_test_id("network-interface")).to_have_text("profinet")
    expect(page.get_by_test_id("network-channel")).to_have_text(re.compile(r"^127\.0\.0\.1:\d+$"))
    expect(page.get_by_test_id("network-note")).to_have_count(0)
    expect(page.get_by_test_id("network-nmt")).to_have_attribute("title", re.compile(r"No NMT"))
    # No NMT on PROFINET: what servodesk has instead is its own supervisor AR (issue 48).
    expect(page.get_by_test_id("network-nmt-label")).to_have_text("AR")
    expect(page.get_by_test_id("network-nmt")).to_have_text("up (servodesk's supervisor AR)")
    expect(link).to_contain_text("DO-ID")
    expect(page.get_by_test_id("network-node-id")).to_have_text("1")

    # The SW2/SW3 rule with its section, and the LED decode (004 §20.2.3.1-3).
    rules = page.get_by_test_id("network-addressing")
    expect(rules).to_contain_text("SW2/SW3 = FFh: DHCP enabled")
    expect(rules).to_contain_text("004 §20.1.3 (4)")
    leds = page.get_by_test_id("network-leds")
    expect(leds.locator("th", has_text="Network Status")).to_be_visible()
    expect(leds.locator("th", has_text="Card Status")).to_be_visible()
    single = leds.get_by_test_id("network-led").filter(has_text="red single flash")
    expect(single).to_contain_text("Station name not set")
    expect(single).to_contain_text("004 §20.2.3.1")
    expect(leds.get_by_test_id("network-led")).to_have_count(15)

    # Read again reads the drive again (and shows the same telegram).
    with page.expect_request(re.compile(r"/sessions/lecsn-t-1/read$")):
        page.get_by_test_id("network-reload").click()
    expect(row.get_by_test_id("network-value")).to_have_text(str(telegram))
    assert _fits(page)


def test_ctmm04x_is_reached_by_slmp_on_axis_x(page: Page) -> None:
    page.set_viewport_size({"width": 1280, "height": 800})
    page.goto("/#/network/ctmm04x-1")
    expect(page.get_by_test_id("network-interface")).to_have_text("slmp")
    expect(page.get_by_test_id("network-link-name")).to_have_text("cclink-ie-tsn")
    expect(page.get_by_test_id("network-axis")).to_have_text("X (node id 1, multidrop 0)")
    # The header names the node as the fieldbus does: the station's axis.
    expect(page.locator(".drive-meta")).to_have_attribute(
        "title", re.compile(r"^axis X · cclink-ie-tsn · slmp:127\.0\.0\.1:\d+$")
    )
    expect(page.get_by_test_id("network-channel")).to_have_text(re.compile(r"^127\.0\.0\.1:\d+$"))
    expect(page.get_by_test_id("network-nmt")).to_have_attribute(
        "title", re.compile(r"manager's command \(003 §3-3\)")
    )
    # No NMT for servodesk over SLMP: whether the station answers instead (issue 48).
    expect(page.get_by_test_id("network-nmt-label")).to_have_text("SLMP link")
    expect(page.get_by_test_id("network-nmt")).to_have_text("answering")
    # Its identity read over SLMP: vendor 0000058Fh (003 §4-3-1).
    vendor = page.get_by_test_id("network-row-0x1018:01")
    expect(vendor.get_by_test_id("network-hex")).to_have_text("0x0000058F")
    expect(page.get_by_test_id("network-addressing")).to_contain_text("192.168.0.250")
    expect(page.get_by_test_id("network-leds")).to_contain_text("DLINK")
    assert _fits(page)


def test_a_refused_object_says_so_in_its_row(page: Page) -> None:
    # The HIWIN twin holds no value for 10F1h:02 here (the sync error counter limit; the
    # shared server withholds it, conftest.WITHHELD, as a drive whose firmware lacks it
    # answers): its row carries the drive's refusal, the others their value, among them
    # the synchronisation type, FreeRun until a master sets up SYNC0 (000 §2.5).
    page.set_viewport_size({"width": 1280, "height": 800})
    page.goto("/#/network/hiwin-e-2")
    refused = page.get_by_test_id("network-row-0x10F1:02").get_by_test_id("network-refused")
    expect(refused).to_contain_text("0x08000024")
    expect(refused).to_contain_text("No data available")
    cycle = page.get_by_test_id("network-row-0x1C32:02").get_by_test_id("network-value")
    expect(cycle).to_have_text(re.compile(r"^\d+ ns$"))
    sync = page.get_by_test_id("network-row-0x1C32:01")
    expect(sync.get_by_test_id("network-value")).to_have_text("0")
    expect(sync).to_contain_text("FreeRun")
    expect(page.get_by_test_id("notice-error")).to_have_count(0)
    assert _fits(page)


@pytest.fixture(scope="module")
def plain_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """serve --sim with one twin of a user profile that has no ``network:`` section (the
    generic profile's objects, extended: the base's network section is not inherited)."""
    root: Path = tmp_path_factory.mktemp("profiles")
    (root / "plain-drive").mkdir()
    (root / "plain-drive" / "profile.yaml").write_text(
        "id: plain-drive\nname: Plain drive\nvendor: test\nfieldbus: canopen\n"
        "extends: cia402-generic\nidentity: {vendor_id: 0x12345678}\n"
    )
    env = {"SERVODESK_PROFILE_DIRS": str(root), "SERVODESK_SIM_PROFILES": "plain-drive"}
    with running_server(env=env) as base:
        yield base


def test_a_profile_without_a_network_section_says_it_documents_none(
    browser: Browser, plain_server: str
) -> None:
    for page in fresh_page(browser, plain_server):
        page.goto("/#/network/plain-drive-1")
        expect(page.get_by_test_id("network-none")).to_contain_text("documents no network section")
        expect(page.get_by_test_id("network-node-id")).to_have_text("1")
        expect(page.get_by_test_id("network-objects")).to_have_count(0)
        expect(page.get_by_test_id("network-leds")).to_have_count(0)
