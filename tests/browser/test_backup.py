"""The Backup & restore page against the real backend and a simulated CiA 402 drive.

What a commissioning engineer relies on: take a backup, change a parameter, see exactly that
parameter differ between the live drive and the backup (engineering value and raw bytes),
restore the backup through the preflight-checked wizard, get a report that says the entry was
written and verified, and see the comparison go back to "No differences". The write is in the
audit log under this browser tab's client id. Writing and restoring need control of the drive:
the tab takes it with the header's Take control, and the test's own writes use its token.
"""

from __future__ import annotations

import json
import re
import uuid

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import control_headers, take_control

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
ADDR = "0x6081:00"  # Profile velocity: a stored, writable parameter with a unit (rpm)


def read_raw(page: Page) -> tuple[int, str]:
    r = page.request.get(f"/api/v1/sessions/{SID}/objects/{ADDR}")
    assert r.ok, r.text()
    body = r.json()
    return int(body["value"]), str(body["raw_hex"])


def write_value(page: Page, value: int) -> None:
    """Write as the page's tab (its control token)."""
    r = page.request.put(
        f"/api/v1/sessions/{SID}/objects/{ADDR}",
        data=json.dumps({"value": value}),
        headers=control_headers(page),
    )
    assert r.ok, r.text()


def take_backup(page: Page, label: str) -> str:
    page.get_by_test_id("backup-label").fill(label)
    page.get_by_test_id("backup-note").fill("taken by test_backup.py")
    page.get_by_test_id("backup-take").click()
    expect(page.get_by_test_id("backup-result")).to_contain_text(label, timeout=20_000)
    row = page.locator(f'[data-testid="history-row"][data-label="{label}"]')
    expect(row).to_have_count(1)
    bid = row.get_attribute("data-backup-id")
    assert bid
    return bid


def test_backup_change_compare_restore(page: Page) -> None:
    original, original_raw = read_raw(page)
    page.goto(f"/#/backup/{SID}")
    expect(page.get_by_test_id("backup-page")).to_be_visible()
    take_control(page, SID)

    label = f"before change {uuid.uuid4().hex[:6]}"
    take_backup(page, label)
    row = page.locator(f'[data-testid="history-row"][data-label="{label}"]')

    changed = original + 12_345
    write_value(page, changed)

    # Live drive (A) against the backup (B): exactly the changed parameter differs.
    row.get_by_test_id("history-compare").click()
    result = page.get_by_test_id("diff-result")
    expect(result).to_have_attribute("data-equal", "false")
    diff = page.locator(f'[data-testid="diff-row"][data-address="{ADDR}"]')
    expect(diff).to_have_attribute("data-kind", "changed")
    expect(page.get_by_test_id("diff-row")).to_have_count(1)
    # Engineering value with its unit, and the raw bytes side by side.
    expect(diff.get_by_test_id("diff-a-value")).to_contain_text("rpm")
    expect(diff.get_by_test_id("diff-b-value")).to_contain_text("rpm")
    want_b_raw = " ".join(original_raw[i : i + 2] for i in range(0, len(original_raw), 2)).upper()
    expect(diff.get_by_test_id("diff-b-raw")).to_have_text(want_b_raw)
    expect(page.get_by_test_id("diff-group").first).to_contain_text("Position")

    # Restore: the preflight passes and counts the one entry to write.
    row.get_by_test_id("history-restore").click()
    expect(page.get_by_test_id("preflight-verdict")).to_have_attribute("data-ok", "true")
    expect(page.get_by_test_id("preflight-to-write")).to_contain_text("1")
    page.get_by_test_id("restore-run").click()

    report = page.get_by_test_id("restore-report")
    expect(report).to_be_visible(timeout=30_000)
    item = report.locator(f'[data-testid="report-row"][data-address="{ADDR}"]')
    expect(item).to_have_attribute("data-status", "written")
    expect(page.get_by_test_id("report-failed")).to_contain_text("0")
    # The automatic pre-restore backup is linked and is in the history.
    expect(page.get_by_test_id("report-pre-backup-link")).to_be_visible()

    # The shown comparison runs again after the restore: nothing differs any more.
    expect(page.get_by_test_id("diff-equal")).to_have_text(re.compile(r"^No differences"))
    assert read_raw(page) == (original, original_raw)

    # The restore's write is in the audit log under this tab's client id.
    audit = page.locator(f'[data-testid="audit-row"][data-address="{ADDR}"]').first
    expect(audit).to_contain_text("this tab")
    expect(audit).to_contain_text("ui-")


def test_note_edit_and_download(page: Page) -> None:
    page.goto(f"/#/backup/{SID}")
    label = f"notes {uuid.uuid4().hex[:6]}"
    take_backup(page, label)
    row = page.locator(f'[data-testid="history-row"][data-label="{label}"]')

    row.get_by_test_id("history-edit").click()
    row.get_by_test_id("edit-note").fill("checked by the night shift")
    row.get_by_test_id("edit-save").click()
    expect(row.get_by_test_id("history-note")).to_have_text("checked by the night shift")
    # PATCH changed the stored metadata, not just the screen.
    page.reload()
    expect(
        page.locator(f'[data-testid="history-row"][data-label="{label}"]').get_by_test_id(
            "history-note"
        )
    ).to_have_text("checked by the night shift")

    row = page.locator(f'[data-testid="history-row"][data-label="{label}"]')
    with page.expect_download() as dl:
        row.get_by_test_id("download-json").click()
    path = dl.value.path()
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["label"] == label
    assert any(e["address"] == ADDR for e in data["entries"])


def drive_command(page: Page, command: str) -> None:
    """A state command as the page's tab: its token, and its socket bound (servo on)."""
    r = page.request.post(
        f"/api/v1/sessions/{SID}/state",
        data=json.dumps({"command": command}),
        headers=control_headers(page),
    )
    assert r.ok, r.text()


def test_failed_preflight_lists_problems_and_disables_restore(page: Page) -> None:
    page.goto(f"/#/backup/{SID}")
    take_control(page, SID)
    label = f"preflight {uuid.uuid4().hex[:6]}"
    take_backup(page, label)
    # A restore needs the drive not enabled: the preflight says so, with what to do.
    drive_command(page, "enable")
    try:
        row = page.locator(f'[data-testid="history-row"][data-label="{label}"]')
        row.get_by_test_id("history-restore").click()
        expect(page.get_by_test_id("preflight-verdict")).to_have_attribute("data-ok", "false")
        problem = page.get_by_test_id("preflight-problem").first
        expect(problem).to_contain_text("operation enabled")
        expect(problem).to_contain_text("What to do:")
        expect(page.get_by_test_id("restore-run")).to_be_disabled()
        expect(page.get_by_test_id("restore-blocked")).to_be_visible()

        # Servo off, check again: the preflight passes; with nothing to write (the drive
        # holds every value of the backup) "Restore 0 entries" is disabled and says why
        # (issue 48); once a value differs, Restore is allowed.
        drive_command(page, "disable")
        page.get_by_test_id("restore-check").click()
        expect(page.get_by_test_id("preflight-verdict")).to_have_attribute("data-ok", "true")
        expect(page.get_by_test_id("restore-blocked")).to_have_count(0)
        expect(page.get_by_test_id("restore-run")).to_have_text("Restore 0 entries")
        expect(page.get_by_test_id("restore-run")).to_be_disabled()
        expect(page.get_by_test_id("restore-nothing")).to_contain_text("nothing to write")
        original, _ = read_raw(page)
        write_value(page, original + 1)
        page.get_by_test_id("restore-check").click()
        expect(page.get_by_test_id("restore-run")).to_have_text("Restore 1 entry")
        expect(page.get_by_test_id("restore-run")).to_be_enabled()
        write_value(page, original)
    finally:
        drive_command(page, "disable")
