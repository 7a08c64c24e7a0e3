"""The manuals' Japanese names are readable on a machine without CJK fonts (issue 48).

The CTMM04x's parameter groups carry the Japanese manual's names as subtitles (profile.yaml
``name_local``). Where no system font has those characters, the UI draws them with the
"Servodesk CJK" subset it ships (frontend/public/fonts, styles.css) rather than as empty boxes,
from the first text a page shows (the face is loaded before the first render). Which font
Chromium drew a node's text with is asked of Chromium itself (DevTools CSS.getPlatformFontsForNode).
"""

from __future__ import annotations

from typing import Any

import pytest
from playwright.sync_api import Page, expect

pytestmark = pytest.mark.browser

CTMM = "ctmm04x-1"
GENERIC = "cia402-generic-1"
FAMILY = "Servodesk CJK"
SUBTITLE = ".params-table-card h2 .local-name"
SPEED = "速度・加減速"  # The "Speed and ramps" group (kanji and the katakana middle dot)
FIRST = "パラメータ保存・初期化"  # The "Store and restore" group, shown first

FACE_STATUS = """async (family) => {
  await document.fonts.ready;
  return [...document.fonts].filter((f) => f.family.replace(/["']/g, '') === family)
    .map((f) => f.status);
}"""


def platform_fonts(page: Page, selector: str) -> list[dict[str, Any]]:
    """The fonts Chromium drew the first ``selector`` node's text with (family, glyph count)."""
    cdp = page.context.new_cdp_session(page)
    cdp.send("DOM.enable")
    cdp.send("CSS.enable")
    root = cdp.send("DOM.getDocument", {"depth": -1})["root"]["nodeId"]
    node = cdp.send("DOM.querySelector", {"nodeId": root, "selector": selector})["nodeId"]
    text = cdp.send("DOM.describeNode", {"nodeId": node, "depth": 1})["node"]["children"][0]
    fonts: list[dict[str, Any]] = cdp.send(
        "CSS.getPlatformFontsForNode", {"nodeId": text["nodeId"]}
    )["fonts"]
    cdp.detach()
    return fonts


def test_japanese_group_subtitle_renders_with_the_shipped_font(page: Page) -> None:
    # The face is loaded before the first render (lib/cjkFont.ts): on demand, Chromium drew
    # the first group's subtitle with the system fallback's boxes and kept them.
    page.goto(f"/#/parameters/{GENERIC}")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    assert page.evaluate(FACE_STATUS, FAMILY) == ["loaded"]

    page.goto(f"/#/parameters/{CTMM}")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    # The first group's subtitle, shown as the page opens.
    expect(page.locator(SUBTITLE)).to_have_text(FIRST)
    fonts = platform_fonts(page, SUBTITLE)
    assert [(f["familyName"], f["glyphCount"]) for f in fonts] == [(FAMILY, len(FIRST))], fonts

    page.get_by_test_id("group-tab-velocity").click()
    expect(page.locator(SUBTITLE)).to_have_text(SPEED)
    assert page.evaluate(FACE_STATUS, FAMILY) == ["loaded"]
    assert page.evaluate(
        '([family, text]) => document.fonts.check(`16px "${family}"`, text)',
        [FAMILY, SPEED],
    )
    fonts = platform_fonts(page, SUBTITLE)
    # Every glyph of the subtitle from the shipped font, none from a fallback (the boxes).
    assert [(f["familyName"], f["glyphCount"]) for f in fonts] == [(FAMILY, len(SPEED))], fonts
    assert all(f["isCustomFont"] for f in fonts)
