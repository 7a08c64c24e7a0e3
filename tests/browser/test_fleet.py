"""The Fleet page against the real backend (issue 49, second slice; docs/deployment.md).

What a maintenance engineer relies on: the drive connected on this gateway is listed with the
plant tag and approved backup set through the API; after a parameter is changed on the drive,
the gateway's scheduled drift scan marks it drifted, the drift filter finds it, and its row
opens the differing parameter by address; the search narrows the table; the gateway column
links to the drive's page on its gateway.

Its own ``servodesk serve --sim`` with ``SERVODESK_DRIFT_INTERVAL_S=1`` (the package's shared
server runs without the scan).
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import HarnessError, api_take_control, running_server

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
TAG = "L2.Press.X"
#: Generous: the scan reads every parameter of the drive, on a loaded 2-core machine.
DRIFT_WAIT_S = 90.0


@pytest.fixture(scope="module")
def drift_server() -> Iterator[str]:
    env = {"SERVODESK_DRIFT_INTERVAL_S": "1", "SERVODESK_SIM_PROFILES": "cia402-generic"}
    try:
        with running_server(env=env) as base:
            yield base
    except HarnessError as e:
        pytest.fail(str(e), pytrace=False)


@pytest.fixture
def fleet_page(browser: Browser, drift_server: str) -> Iterator[Page]:
    yield from fresh_page(browser, drift_server)


def _call(page: Page, method: str, path: str, body: object, **headers: str) -> dict[str, object]:
    r = page.request.fetch(
        f"/api/v1{path}",
        method=method,
        data=json.dumps(body),
        headers={"Content-Type": "application/json", "X-Servodesk-Client": "fleet-test", **headers},
    )
    assert r.ok, f"{method} {path}: {r.status} {r.text()}"
    answer = r.json()
    assert isinstance(answer, dict)
    return answer


def _drifted(page: Page, key: str) -> bool:
    r = page.request.get("/api/v1/fleet?drift=drifted")
    assert r.ok, r.text()
    return any(d["drive_key"] == key for d in r.json()["drives"])


def test_fleet_page_shows_tag_approval_and_drift(fleet_page: Page) -> None:
    page = fleet_page
    page.goto("/#/fleet")
    expect(page.get_by_test_id("page-fleet")).to_be_visible()
    row = page.get_by_test_id("fleet-row").first
    expect(row).to_be_visible(timeout=30_000)
    key = row.get_attribute("data-drive")
    assert key

    backup = _call(page, "POST", f"/sessions/{SID}/backups", {"label": "commissioned"})
    _call(page, "PUT", "/fleet/tag", {"drive": key, "tag": TAG})
    reason = "commissioned, signed off"
    _call(page, "PUT", "/fleet/approved", {"drive": TAG, "backup": backup["id"], "reason": reason})

    page.reload()
    row = page.locator(f'[data-testid="fleet-row"][data-drive="{key}"]')
    expect(row.get_by_test_id("fleet-tag")).to_have_text(TAG)
    expect(row.get_by_test_id("fleet-approved")).to_contain_text(str(backup["id"]))
    expect(row.get_by_test_id("fleet-approved")).to_contain_text(reason)
    link = row.get_by_test_id("fleet-link")
    assert (link.get_attribute("href") or "").endswith(f"/#/overview/{SID}")

    # The drive changes behind the approved backup's back: 6065h, the following error window.
    token = api_take_control(page, SID, "fleet-test")
    control = {"X-Servodesk-Control": token}
    r = page.request.get(f"/api/v1/sessions/{SID}/objects/0x6065:00")
    assert r.ok, r.text()
    window = int(r.json()["value"])
    _call(page, "PUT", f"/sessions/{SID}/objects/0x6065:00", {"value": window + 1000}, **control)
    _call(page, "POST", f"/sessions/{SID}/control", {"action": "release"}, **control)

    # The scheduled scan finds it; the drift filter shows only drifted drives.
    page.get_by_test_id("fleet-drift-filter").select_option("drifted")
    drifted = page.locator(f'[data-testid="fleet-row"][data-drive="{key}"][data-drift="drifted"]')
    refresh = page.get_by_role("button", name="Refresh")
    expect(refresh).to_be_enabled()
    deadline = time.monotonic() + DRIFT_WAIT_S
    while not _drifted(page, key):
        assert time.monotonic() < deadline, "the scheduled drift scan did not mark the drive"
        time.sleep(1.0)
    refresh.click()
    expect(drifted).to_be_visible()
    expect(drifted.get_by_test_id("fleet-drift")).to_contain_text("drifted · 1 parameter")
    drifted.get_by_test_id("fleet-drift-toggle").click()
    diff = page.get_by_test_id("fleet-difference")
    expect(diff).to_have_count(1)
    assert "6065" in (diff.get_attribute("data-address") or "")
    expect(diff).to_contain_text(str(window + 1000))

    page.get_by_test_id("fleet-drift-filter").select_option("")
    page.get_by_test_id("fleet-search").fill("no-drive-by-this-name")
    page.get_by_test_id("fleet-apply").click()
    expect(page.get_by_test_id("fleet-empty")).to_be_visible()
    page.get_by_test_id("fleet-search").fill("l2.press")
    page.get_by_test_id("fleet-apply").click()
    expect(page.get_by_test_id("fleet-row")).to_have_count(1)
    expect(page.get_by_test_id("fleet-count")).to_contain_text("1–1 of 1 drives")
