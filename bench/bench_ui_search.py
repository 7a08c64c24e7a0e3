"""Object dictionary search speed in the browser UI, on the largest profile (lecsn-t, 2912 objects).

Starts ``servodesk serve --sim`` itself (tests/browser/harness.py), opens the Object dictionary
of the simulated LECSN-T drive (session lecsn-t-1) in headless Chromium, and measures:

- keystroke latency: from the ``keydown`` of each typed character in the search box
  (``performance.now()`` in a capture listener) to the filtered table drawn: the DOM change
  seen by a MutationObserver on the table (``dom``) and the start of the next animation frame
  after it (``frame``, the figure to keep under 50 ms). Median, p95 and max over every
  character of several search strings (>= 30 keystrokes);
- profile load: GET /api/v1/profiles/lecsn-t (resource timing: duration and size) and the
  first render of the table (the page's ``servodesk:od-rendered`` mark), over a few fresh loads.

    python bench/bench_ui_search.py [--json] [--loads 3]

Needs the built UI (cd frontend && npm run build) and Debian's Chromium, like the browser tests.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    # Run as a script from anywhere: the harness lives in the tests package.
    sys.path.insert(0, str(REPO))

from playwright.sync_api import Browser, Page, sync_playwright  # noqa: E402
from tests.browser.harness import CHROMIUM_ARGS, chromium_executable, running_server  # noqa: E402

SESSION = "lecsn-t-1"
PROFILE = "lecsn-t"
TARGET_MS = 50.0
# Index spellings (hex, 0x, h suffix, PNU), symbols and words of names and descriptions.
SEARCHES = [
    "6040",
    "0x607a",
    "6081h",
    "P24640",
    "velocity",
    "torque limit",
    "acceleration",
    "PA01",
    "point table",
    "homing",
]

INSTRUMENT = """
() => {
  const input = document.querySelector('[data-testid="od-search"]');
  const table = document.querySelector('[data-testid="od-table"]');
  window.__lat = [];
  let t0 = null;
  input.addEventListener('keydown', () => { t0 = performance.now(); }, true);
  new MutationObserver(() => {
    if (t0 === null) return;
    const start = t0;
    t0 = null;
    const dom = performance.now() - start;
    requestAnimationFrame(() => {
      window.__lat.push({ dom, frame: performance.now() - start,
                          query: table.getAttribute('data-query'),
                          count: Number(table.getAttribute('data-count')) });
    });
  }).observe(table, { attributes: true, childList: true, subtree: true, characterData: true });
}
"""


def stats(values: list[float]) -> dict[str, float]:
    s = sorted(values)
    p95 = s[min(len(s) - 1, round(0.95 * (len(s) - 1)))]
    return {
        "median": round(statistics.median(s), 2),
        "p95": round(p95, 2),
        "max": round(s[-1], 2),
        "mean": round(statistics.fmean(s), 2),
    }


def open_dictionary(browser: Browser, base: str) -> tuple[Page, dict[str, Any]]:
    """A fresh page on the Object dictionary; returns it and the load timings."""
    context = browser.new_context(base_url=base, viewport={"width": 1440, "height": 960})
    page = context.new_page()
    page.goto(f"/#/dictionary/{SESSION}")
    page.wait_for_selector('[data-testid="od-table"][data-count]', timeout=30_000)
    page.wait_for_function(
        "() => performance.getEntriesByName('servodesk:od-rendered').length > 0", timeout=30_000
    )
    timing: dict[str, Any] = page.evaluate(
        """(profile) => {
          const r = performance.getEntriesByType('resource')
            .find((e) => e.name.endsWith('/api/v1/profiles/' + profile));
          const m = performance.getEntriesByName('servodesk:od-rendered')[0];
          return {
            fetch_ms: r ? r.duration : null,
            bytes: r ? (r.decodedBodySize || r.transferSize) : null,
            fetch_end_ms: r ? r.responseEnd : null,
            first_render_ms: m ? m.startTime : null,
            objects: Number(document.querySelector('[data-testid="od-table"]')
              .getAttribute('data-count')),
          };
        }""",
        PROFILE,
    )
    return page, timing


def measure_typing(page: Page) -> tuple[list[dict[str, Any]], list[str]]:
    page.evaluate(INSTRUMENT)
    search = page.get_by_test_id("od-search")
    samples: list[dict[str, Any]] = []
    problems: list[str] = []
    for text in SEARCHES:
        search.fill("")
        page.wait_for_selector('[data-testid="od-table"][data-query=""]')
        page.evaluate("() => { window.__lat = []; }")
        search.click()
        for n, ch in enumerate(text, start=1):
            page.keyboard.type(ch)
            page.wait_for_function(f"() => window.__lat.length >= {n}", timeout=10_000)
        got: list[dict[str, Any]] = page.evaluate("() => window.__lat")
        if got and got[-1]["query"] != text:
            problems.append(f"typed {text!r}, the table shows {got[-1]['query']!r}")
        for g in got:
            g["search"] = text
        samples.extend(got)
    return samples, problems


def run(loads: int) -> dict[str, Any]:
    with running_server() as base, sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=chromium_executable(), headless=False, args=CHROMIUM_ARGS
        )
        try:
            load_timings = []
            page: Page | None = None
            # Each load in a fresh context (no cache); typing is measured on the last one.
            for _ in range(max(1, loads)):
                if page is not None:
                    page.context.close()
                page, timing = open_dictionary(browser, base)
                load_timings.append(timing)
            assert page is not None
            samples, problems = measure_typing(page)
        finally:
            browser.close()

    frame = [s["frame"] for s in samples]
    dom = [s["dom"] for s in samples]
    fetch = [t["fetch_ms"] for t in load_timings if t["fetch_ms"] is not None]
    first = [t["first_render_ms"] for t in load_timings if t["first_render_ms"] is not None]
    after = [
        t["first_render_ms"] - t["fetch_end_ms"]
        for t in load_timings
        if t["first_render_ms"] is not None and t["fetch_end_ms"] is not None
    ]
    result: dict[str, Any] = {
        "profile": PROFILE,
        "session": SESSION,
        "objects": load_timings[-1]["objects"],
        "keystrokes": len(samples),
        "searches": SEARCHES,
        "keystroke_to_frame_ms": stats(frame),
        "keystroke_to_dom_ms": stats(dom),
        "target_ms": TARGET_MS,
        "profile_load": {
            "loads": len(load_timings),
            "get_profile_ms": stats(fetch) if fetch else None,
            "profile_bytes": load_timings[-1]["bytes"],
            "first_render_since_navigation_ms": stats(first) if first else None,
            "first_render_after_response_ms": stats(after) if after else None,
        },
        "problems": problems,
    }
    result["ok"] = (
        not problems and len(samples) >= 30 and result["keystroke_to_frame_ms"]["p95"] < TARGET_MS
    )
    return result


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON only")
    ap.add_argument("--loads", type=int, default=3, help="fresh page loads for the load timing")
    args = ap.parse_args()
    result = run(args.loads)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        k = result["keystroke_to_frame_ms"]
        pl = result["profile_load"]
        print(
            f"{result['keystrokes']} keystrokes on {result['objects']} objects: keystroke to "
            f"table drawn median {k['median']} ms, p95 {k['p95']} ms (target < {TARGET_MS} ms)"
        )
        print(
            f"GET /profiles/{PROFILE}: {pl['get_profile_ms']} ms, {pl['profile_bytes']} bytes; "
            f"first render {pl['first_render_since_navigation_ms']} ms after navigation"
        )
        for p in result["problems"]:
            print(f"problem: {p}")
    return 0 if result["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
