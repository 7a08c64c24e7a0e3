"""Clearing an approval on the Fleet page, and its "Last tuning" column (issue 49).

What a maintenance engineer relies on: an approved backup that is no longer the drive's
reference is cleared from its row, only after confirming with a reason, which the audit log
keeps; the drive then has no approved backup and its drift state is unknown. A drive that was
never tuned says so in the "Last tuning" column.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import HarnessError, running_server

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"


@pytest.fixture(scope="module")
def approval_server() -> Iterator[str]:
    env = {"SERVODESK_SIM_PROFILES": "cia402-generic"}
    try:
        with running_server(env=env) as base:
            yield base
    except HarnessError as e:
        pytest.fail(str(e), pytrace=False)


@pytest.fixture
def fleet_page(browser: Browser, approval_server: str) -> Iterator[Page]:
    yield from fresh_page(browser, approval_server)


def _call(page: Page, method: str, path: str, body: object) -> dict[str, object]:
    r = page.request.fetch(
        f"/api/v1{path}",
        method=method,
        data=json.dumps(body),
        headers={"Content-Type": "application/json", "X-Servodesk-Client": "fleet-test"},
    )
    assert r.ok, f"{method} {path}: {r.status} {r.text()}"
    answer = r.json()
    assert isinstance(answer, dict)
    return answer


def test_an_approval_is_cleared_with_a_reason(fleet_page: Page) -> None:
    page = fleet_page
    page.goto("/#/fleet")
    row = page.get_by_test_id("fleet-row").first
    expect(row).to_be_visible(timeout=30_000)
    key = row.get_attribute("data-drive")
    assert key
    backup = _call(page, "POST", f"/sessions/{SID}/backups", {"label": "commissioned"})
    _call(page, "PUT", "/fleet/approved", {"drive": key, "backup": backup["id"], "reason": "QA"})

    page.reload()
    row = page.locator(f'[data-testid="fleet-row"][data-drive="{key}"]')
    expect(row.get_by_test_id("fleet-approved")).to_contain_text(str(backup["id"]))
    expect(page.get_by_role("columnheader", name="Last tuning")).to_be_visible()
    expect(row.get_by_test_id("fleet-last-tuning")).to_have_text("none")

    # Cancel leaves it; confirming needs a reason.
    row.get_by_test_id("fleet-clear-approval").click()
    row.get_by_role("button", name="Cancel").click()
    expect(row.get_by_test_id("fleet-approved")).to_contain_text(str(backup["id"]))
    row.get_by_test_id("fleet-clear-approval").click()
    confirm = row.get_by_test_id("fleet-clear-confirm")
    expect(confirm).to_be_disabled()
    reason = "drive rebuilt, new reference follows"
    row.get_by_test_id("fleet-clear-reason").fill(reason)
    confirm.click()

    expect(row.get_by_test_id("fleet-approved")).to_have_text("none")
    expect(row.get_by_test_id("fleet-drift")).to_have_text("unknown")
    r = page.request.get("/api/v1/audit", params={"event": "backup.approval_cleared"})
    assert r.ok, r.text()
    (rec,) = r.json()
    assert rec["message"] == reason
    assert rec["details"] == {"drive_key": key, "backup": backup["id"]}
