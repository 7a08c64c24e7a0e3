"""All axes' "Back up every drive" (issue 50): one click backs up every open twin, the drives
read at once (POST /backups/plant); the line beside the button says how many were saved and
in what time, each drive's Last backup follows, and each drive has its own backup file."""

from __future__ import annotations

import re

import pytest
from playwright.sync_api import Page, expect

pytestmark = pytest.mark.browser


def test_back_up_every_drive_from_the_all_axes_page(page: Page) -> None:
    sessions = page.request.get("/api/v1/sessions").json()
    assert len(sessions) >= 5, [s["id"] for s in sessions]
    page.goto("/#/axes")
    expect(page.get_by_test_id("axes-table")).to_be_visible()
    button = page.get_by_test_id("axes-backup-all")
    expect(button).to_have_text("Back up every drive")
    button.click()
    result = page.get_by_test_id("axes-backup-result")
    n = len(sessions)
    expect(result).to_have_text(
        re.compile(rf"^\s*{n} of {n} backed up in \d+\.\d s$"), timeout=60_000
    )
    expect(result).to_have_attribute("data-failed", "0")
    expect(button).to_be_enabled()
    for s in sessions:
        backups = page.request.get(f"/api/v1/backups?profile={s['profile_id']}").json()
        mine = [b for b in backups if b["label"] == "all drives"]
        assert mine and mine[0]["entries"] > 0, (s["id"], backups[:2])
        # The row's Last backup is that one (the list is read again when a backup ends).
        expect(page.get_by_test_id(f"axis-backup-{s['id']}")).not_to_have_text("none")
