"""Screenshots of every UI page against the simulated drives, for a person to look at.

Run: ``.venv/bin/python -m tests.browser.shoot /tmp/servodesk-shots``. Not a test: it makes
the drive move (profile velocity mode) so the live plot has something to show.
"""

from __future__ import annotations

import json
import sys
import urllib.request
from pathlib import Path

from playwright.sync_api import sync_playwright

from tests.browser.harness import (
    CHROMIUM_ARGS,
    chromium_executable,
    running_server,
    tab_control,
    take_control,
)


def _put(base: str, sid: str, addr: str, value: int, token: str) -> None:
    """Write with the page's control token (writes need control)."""
    req = urllib.request.Request(
        f"{base}/api/v1/sessions/{sid}/objects/{addr}",
        data=json.dumps({"value": value}).encode(),
        headers={"Content-Type": "application/json", "X-Servodesk-Control": token},
        method="PUT",
    )
    urllib.request.urlopen(req, timeout=5).read()


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with running_server() as base, sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=chromium_executable(), headless=False, args=CHROMIUM_ARGS
        )
        page = browser.new_page(base_url=base, viewport={"width": 1440, "height": 960})
        page.goto("/#/connect")
        page.get_by_test_id("sessions").wait_for()
        page.get_by_test_id("scan-bus").click()
        page.get_by_test_id("scan-results").wait_for()
        page.wait_for_timeout(500)
        page.screenshot(path=str(out / "connect.png"), full_page=True)

        sid = page.locator('tr[data-profile="cia402-generic"]').first.get_attribute("data-testid")
        assert sid
        sid = sid.removeprefix("session-row-")
        page.goto(f"/#/overview/{sid}")
        page.get_by_test_id("control-take").wait_for()
        page.wait_for_timeout(300)
        page.screenshot(path=str(out / "overview-no-control.png"), full_page=False)
        take_control(page, sid)
        held = tab_control(page)
        assert held
        token = held["token"]
        # Profile velocity mode with a target velocity, so enabling makes the axis turn.
        _put(base, sid, "0x6060", 3, token)
        _put(base, sid, "0x60FF", 200000, token)
        page.get_by_test_id("cmd-enable").click()
        page.get_by_test_id("drive-state").get_by_text("Operation enabled").wait_for()
        page.wait_for_timeout(4000)
        page.screenshot(path=str(out / "overview.png"), full_page=True)

        page.get_by_test_id("nav-objects").click()
        page.get_by_test_id("object-address").fill("0x6061")
        page.get_by_test_id("object-read").click()
        page.get_by_test_id("object-result").wait_for()
        page.get_by_test_id("object-address").fill("0x6081")
        page.get_by_test_id("value-mode-hex").click()
        page.get_by_test_id("object-value").fill("3E8")
        page.get_by_test_id("object-write").click()
        page.wait_for_timeout(300)
        page.get_by_test_id("object-address").fill("0x6064")
        page.get_by_test_id("object-read").click()
        page.wait_for_timeout(300)
        page.screenshot(path=str(out / "objects.png"), full_page=True)
        page.get_by_test_id("object-address").fill("0x6041")
        page.get_by_test_id("object-value").fill("1")
        page.get_by_test_id("object-write").click()
        page.get_by_test_id("object-error").wait_for()
        page.screenshot(path=str(out / "objects-error.png"), full_page=True)

        # A refused state command shows as a notice: what failed, why, what to do.
        page.get_by_test_id("nav-overview").click()
        page.get_by_test_id("cmd-quick_stop").click()
        page.wait_for_timeout(800)
        page.get_by_test_id("cmd-switch_on").click()
        page.wait_for_timeout(1200)
        page.screenshot(path=str(out / "overview-notice.png"), full_page=False)

        # A following error (CiA 402-2 §6.5.7): tiny window, no time-out, a long fast move.
        for addr, value in (
            ("0x6060", 1),
            ("0x6065", 10),
            ("0x6066", 0),
            ("0x607A", 5_000_000),
            ("0x6081", 2_000_000),
            ("0x6083", 10_000_000),
        ):
            _put(base, sid, addr, value, token)
        page.get_by_test_id("cmd-enable").click()
        page.get_by_test_id("drive-state").get_by_text("Operation enabled").wait_for()
        _put(base, sid, "0x6040", 0x1F, token)
        page.get_by_test_id("fault").wait_for()
        page.wait_for_timeout(800)
        page.screenshot(path=str(out / "overview-fault.png"), full_page=False)
        browser.close()
    print(f"screenshots in {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/servodesk-shots"))
