"""The Audit page against the real backend (docs/security.md, "Audit log").

What an administrator relies on: taking control of a drive shows up on the page as a record
with its user, source and drive, newest first; the chain is shown verified; the filters
narrow the table; the export downloads the whole log as CSV with its hashes.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import take_control

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"


def test_audit_page_shows_filters_and_exports(page: Page) -> None:
    page.goto(f"/#/overview/{SID}")
    take_control(page, SID)

    page.goto("/#/audit")
    expect(page.get_by_test_id("page-audit")).to_be_visible()
    chain = page.get_by_test_id("audit-chain")
    expect(chain).to_have_attribute("data-ok", "true")
    expect(chain).to_contain_text("chain verified")
    taken = page.locator('[data-testid="audit-record"][data-event="control.taken"]').first
    expect(taken).to_be_visible()
    expect(taken).to_contain_text(SID)
    expect(taken).to_contain_text("local")  # The loopback single-user mode's user.

    # Newest first: the first row has the highest sequence number.
    seqs = [
        int(s)
        for s in page.locator('[data-testid="audit-record"] td:first-child').all_inner_texts()
    ]
    assert seqs == sorted(seqs, reverse=True), seqs

    page.get_by_test_id("audit-category").select_option("control")
    page.get_by_test_id("audit-apply").click()
    expect(
        page.locator('[data-testid="audit-record"]:not([data-event^="control."])')
    ).to_have_count(0)
    expect(
        page.locator('[data-testid="audit-record"][data-event="control.taken"]').first
    ).to_be_visible()

    page.get_by_test_id("audit-user").fill("nobody-by-that-name")
    page.get_by_test_id("audit-apply").click()
    expect(page.get_by_test_id("audit-empty")).to_be_visible()

    with page.expect_download() as info:
        page.get_by_test_id("audit-export-csv").click()
    download = info.value
    assert download.suggested_filename.startswith("servodesk-audit-")
    assert download.suggested_filename.endswith(".csv")
    path = download.path()
    assert path is not None
    text = Path(path).read_text(encoding="utf-8")
    assert text.startswith(
        "seq,time,user,address,category,event,drive,result,message,details,prev,hash"
    )
    assert "control.taken" in text
