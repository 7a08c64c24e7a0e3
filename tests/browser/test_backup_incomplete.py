"""Nothing hidden on the Backup & restore page (issue 48).

The smartris twin of the shared server holds no value for 607Fh (Max profile velocity; it
answers abort 0800 0024h, as a drive whose firmware lacks the value does: conftest.WITHHELD),
so its backup lacks that object. The engineer sees so wherever the backup is shown: the result
of taking it, the history, the comparison, the restore preflight and report, each with the
object and the drive's error. A restore with nothing to write is not offered.
"""

from __future__ import annotations

import uuid

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import take_control

pytestmark = pytest.mark.browser

SID = "smartris-3"
LACKS = "0x607F:00"


def test_incomplete_backup_is_shown_everywhere(page: Page) -> None:
    page.goto(f"/#/backup/{SID}")
    expect(page.get_by_test_id("backup-page")).to_be_visible()
    label = f"incomplete-{uuid.uuid4().hex[:6]}"
    page.get_by_test_id("backup-label").fill(label)
    page.get_by_test_id("backup-take").click()

    # Taken: marked incomplete, with the object and the drive's abort code and text.
    result = page.get_by_test_id("backup-result")
    expect(result).to_contain_text(label, timeout=20_000)
    expect(result).to_have_attribute("data-complete", "false")
    taken = page.get_by_test_id("backup-result-unreadable")
    expect(taken).to_have_attribute("data-count", "1")
    expect(taken).to_contain_text("1 object could not be read")
    taken.locator("summary").click()
    row = page.locator(f'[data-testid="backup-result-unreadable-row"][data-address="{LACKS}"]')
    expect(row).to_contain_text("Max profile velocity")
    expect(row).to_contain_text("0x08000024")
    expect(row).to_contain_text("No data available")

    # History: the row says incomplete; its badge lists what it lacks.
    hist = page.locator(f'[data-testid="history-row"][data-label="{label}"]')
    badge = hist.get_by_test_id("history-incomplete")
    expect(badge).to_have_text("incomplete · 1 unreadable")
    badge.click()
    expect(page.get_by_test_id("history-unreadable-table")).to_contain_text(LACKS)

    # Compare with the live drive: the object is not compared, and the result says why.
    hist.get_by_test_id("history-compare").click()
    expect(page.get_by_test_id("diff-result")).to_be_visible(timeout=20_000)
    expect(page.get_by_test_id("diff-not-compared")).to_contain_text("1 not compared")
    expect(page.get_by_test_id("diff-a-unreadable")).to_contain_text("unreadable in A")
    expect(page.get_by_test_id("diff-b-unreadable")).to_contain_text("unreadable in B")

    # Restore: the preflight names what it cannot restore; with nothing to write (the drive
    # holds every value) "Restore 0 entries" is disabled and says why; the dry run's report
    # names the object again.
    hist.get_by_test_id("history-restore").click()
    pre = page.get_by_test_id("preflight-unreadable")
    expect(pre).to_contain_text("a restore cannot set 1 object", timeout=20_000)
    pre.locator("summary").click()
    expect(pre.get_by_test_id("preflight-unreadable-row")).to_contain_text(LACKS)
    take_control(page, SID)
    run = page.get_by_test_id("restore-run")
    expect(page.get_by_test_id("preflight-to-write")).to_contain_text("0")
    expect(run).to_have_text("Restore 0 entries")
    expect(run).to_be_disabled()
    expect(page.get_by_test_id("restore-nothing")).to_contain_text("nothing to write")
    page.get_by_test_id("restore-dry-run").check()
    expect(run).to_be_enabled()
    run.click()
    rep = page.get_by_test_id("report-unreadable")
    expect(rep).to_contain_text("Would not restore: 1 object", timeout=20_000)
    rep.locator("summary").click()
    expect(rep.get_by_test_id("report-unreadable-row")).to_contain_text("0x08000024")
