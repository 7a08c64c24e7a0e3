"""Light and dark (issue 48, docs/ui.md "Colours"): the UI follows the system's preference,
the toggle at the foot of the navigation overrides it (Auto -> Light -> Dark) and the choice
survives a reload; in the dark set no panel of the drive pages stays white (a colour written
as a literal instead of a token would)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, expect

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
#: Elements of the page whose computed background is near-white (luminance > 0.85).
_WHITE = """() => {
  const lum = (c) => {
    const m = c.match(/rgba?\\(([\\d.]+), ([\\d.]+), ([\\d.]+)(?:, ([\\d.]+))?\\)/);
    if (!m || (m[4] !== undefined && Number(m[4]) < 0.5)) return null;
    return (0.2126 * m[1] + 0.7152 * m[2] + 0.0722 * m[3]) / 255;
  };
  return [...document.querySelectorAll('main *, .nav *, main, .nav')]
    .filter((e) => e.getClientRects().length > 0)
    .filter((e) => {
      const l = lum(getComputedStyle(e).backgroundColor);
      return l !== null && l > 0.85;
    })
    .map((e) => `${e.tagName.toLowerCase()}.${[...e.classList].join('.')}`);
}"""
#: The luminance of the first ``sel``'s own background (None where it is transparent).
_LUM = """(sel) => {
  const c = getComputedStyle(document.querySelector(sel)).backgroundColor;
  const m = c.match(/rgba?\\(([\\d.]+), ([\\d.]+), ([\\d.]+)(?:, ([\\d.]+))?\\)/);
  if (!m || (m[4] !== undefined && Number(m[4]) === 0)) return null;
  return (0.2126 * m[1] + 0.7152 * m[2] + 0.0722 * m[3]) / 255;
}"""


@pytest.fixture
def dark_page(browser: Browser, server_url: str) -> Iterator[Page]:
    ctx = browser.new_context(
        base_url=server_url, viewport={"width": 1440, "height": 960}, color_scheme="dark"
    )
    ctx.set_default_timeout(10_000)
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    yield pg
    ctx.close()
    assert not errors, f"uncaught errors in the page: {errors}"


def test_the_ui_follows_a_dark_system_and_the_toggle_overrides_it(dark_page: Page) -> None:
    page = dark_page
    page.goto(f"/#/overview/{SID}")
    toggle = page.get_by_test_id("theme-toggle")
    expect(toggle).to_have_attribute("data-choice", "system")
    expect(toggle).to_have_text("◐ Auto (dark)")
    expect(page.locator("html")).to_have_attribute("data-theme", "dark")
    expect(page.get_by_test_id("page-overview")).to_be_visible()
    assert page.evaluate(_LUM, "html") < 0.15
    expect(page.locator(".card").first).to_be_visible()
    assert page.evaluate(_LUM, ".card") < 0.2

    toggle.click()  # Auto -> Light
    expect(page.locator("html")).to_have_attribute("data-theme", "light")
    assert page.evaluate(_LUM, "html") > 0.85
    assert page.evaluate(_LUM, ".card") > 0.85
    page.reload()  # The choice is kept in this browser.
    expect(page.get_by_test_id("theme-toggle")).to_have_attribute("data-choice", "light")
    expect(page.locator("html")).to_have_attribute("data-theme", "light")

    page.get_by_test_id("theme-toggle").click()  # Light -> Dark
    expect(page.locator("html")).to_have_attribute("data-theme", "dark")
    page.get_by_test_id("theme-toggle").click()  # Dark -> Auto: the system's again
    expect(page.get_by_test_id("theme-toggle")).to_have_attribute("data-choice", "system")
    expect(page.locator("html")).to_have_attribute("data-theme", "dark")


@pytest.mark.parametrize("where", ["overview", "parameters", "operation", "pdo", "backup"])
def test_no_panel_stays_white_in_the_dark(dark_page: Page, where: str) -> None:
    page = dark_page
    page.goto(f"/#/{where}/{SID}")
    expect(page.get_by_test_id(f"page-{where}")).to_be_visible()
    page.wait_for_load_state("networkidle")
    page.wait_for_timeout(500)  # the page's own reads fill its tables
    assert page.evaluate(_WHITE) == []
