"""Time and keystrokes to find a parameter by name and change it, starting on the Overview.

Issue 48's measure ("time to find and change a parameter by name from the Overview, keystrokes
and seconds, scripted"). Starts ``servodesk serve --sim`` (tests/browser/harness.py), opens the
Overview of the LECSN-T twin (lecsn-t-1, the largest profile: 2,992 objects) in headless
Chromium, takes control, and then, timed:

- ``by_name``: click "Object dictionary" in the sidebar, type a few words of the name
  ("speed loop gain"), Arrow Down to the first match (the details open: PB09, the speed loop
  gain),
  click the value box, type the value, Enter; done when the drive's read-back shows it;
- ``by_symbol``: the same with the manual's symbol ("PB09");
- ``baseline_by_address``: what a user who already knows the address does on Object access
  (click "Object access", type 0x2089, click the value box, type it, Enter, read-back shown): the
  shortest path the UI has, measured in the same run.

Every step is a real key press or click on the page; the figures are the median of --repeat
runs (each writes a different value, so every run is a real write and read-back).

    python bench/bench_ui_find_change.py [--json] [--repeat 5]

Needs the built UI and Debian's Chromium, like the browser tests.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from playwright.sync_api import Page, expect, sync_playwright  # noqa: E402
from tests.browser.harness import (  # noqa: E402
    CHROMIUM_ARGS,
    chromium_executable,
    running_server,
    take_control,
)

SID = "lecsn-t-1"
TARGET = "PB09"
ADDRESS = "0x2089"


class Counter:
    """Keys and clicks a path takes, counted as they are made."""

    def __init__(self, page: Page) -> None:
        self.page, self.keys, self.clicks = page, 0, 0

    def click(self, test_id: str) -> None:
        self.page.get_by_test_id(test_id).click()
        self.clicks += 1

    def type(self, text: str) -> None:
        self.page.keyboard.type(text)
        self.keys += len(text)

    def press(self, key: str) -> None:
        self.page.keyboard.press(key)
        self.keys += 1


def _to_overview(page: Page) -> None:
    page.goto(f"/#/overview/{SID}")
    expect(page.get_by_test_id("drive-state")).to_be_visible(timeout=15_000)


def _find(words: str) -> Callable[[Page, int], Counter]:
    def path(page: Page, value: int) -> Counter:
        c = Counter(page)
        c.click("nav-dictionary")
        expect(page.get_by_test_id("od-search")).to_be_focused(timeout=15_000)
        c.type(words)
        c.press("ArrowDown")
        expect(page.get_by_test_id("od-detail-name")).to_contain_text(TARGET, timeout=15_000)
        c.click("value-input")
        c.type(str(value))
        c.press("Enter")
        expect(page.get_by_test_id("readback-value")).to_contain_text(str(value), timeout=15_000)
        return c

    return path


def _by_address(page: Page, value: int) -> Counter:
    c = Counter(page)
    c.click("nav-objects")
    c.click("object-address")
    page.keyboard.press("Control+A")
    c.keys += 1
    c.type(ADDRESS)
    c.click("object-value")
    c.type(str(value))
    c.press("Enter")
    expect(page.get_by_test_id("object-result")).to_contain_text(str(value), timeout=15_000)
    return c


PATHS: dict[str, Callable[[Page, int], Counter]] = {
    "by_name": _find("speed loop gain"),
    "by_symbol": _find("PB09"),
    "baseline_by_address": _by_address,
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    ap.add_argument("--repeat", type=int, default=5, help="runs per path (median reported)")
    args = ap.parse_args()
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    result: dict[str, Any] = {"session": SID, "target": TARGET, "repeat": args.repeat}
    with running_server() as base, sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=chromium_executable(), headless=True, args=CHROMIUM_ARGS
        )
        page = browser.new_page(base_url=base, viewport={"width": 1440, "height": 900})
        _to_overview(page)
        take_control(page, SID)
        value = 830
        for name, path in PATHS.items():
            seconds: list[float] = []
            counts = (0, 0)
            for _ in range(args.repeat):
                _to_overview(page)
                value += 1
                t0 = time.perf_counter()
                c = path(page, value)
                seconds.append(time.perf_counter() - t0)
                counts = (c.keys, c.clicks)
            result[name] = {
                "keystrokes": counts[0],
                "clicks": counts[1],
                "seconds_median": round(statistics.median(seconds), 3),
                "seconds_max": round(max(seconds), 3),
            }
        browser.close()
    base_s = result["baseline_by_address"]["seconds_median"]
    for name in ("by_name", "by_symbol"):
        result[name]["ratio_to_baseline"] = round(result[name]["seconds_median"] / base_s, 2)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for name in PATHS:
            r = result[name]
            print(
                f"{name:20s} {r['keystrokes']:3d} keys {r['clicks']} clicks "
                f"{r['seconds_median']:.2f} s median (max {r['seconds_max']:.2f})"
            )


if __name__ == "__main__":
    main()
