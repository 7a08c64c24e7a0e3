"""Scope page frame rate while panning 8 channels x 10 s x 4 kHz (320,000 points) in Chromium.

Issue 7 "Measure": the frame rate of the Scope page (uPlot) while the user pans a long recording;
aim 30 fps or more. Starts ``servodesk serve --sim`` itself (tests/browser/harness.py), opens the
Scope page of the simulated generic drive in headless Chromium, opens a recording of 8 channels x
40,000 samples (sines of different frequencies with noise and a few one-sample spikes), and then:

- ``drag``: holds shift and drags the plot left and right for ~5 s (shift-drag is the page's
  pan) with the whole recording in view (all 320,000 points in the window, decimated to min/max
  per pixel column every frame);
- ``wheel``: turns the wheel back and forth for ~5 s (the page's other pan) with half of it in view.

The input: by default synthetic mouse and wheel events dispatched in the page every 4 ms (a
mouse's rate; the browser handles them between frames as it does real ones), so the figure is
the page's drawing rate, not the test driver's. ``--input cdp`` sends Playwright's real input
events instead (DevTools protocol round trips, one at a time: on a loaded machine they, not the
page, limit the rate).

Per phase: draws per second of the plot (uPlot draw hooks counted by the page's model) over each
second of the phase, and the browser's own animation frames per second; the median of the
per-second figures, the ms per drawn frame (1000 / fps), the longest gap between two drawn
frames, and how much of the view each draw covered. ``--via import`` opens the recording through
the page's Import button as an MDF4 file written by servodesk's own exporter (also times the
import); the default injects it into the page's data store (page.evaluate), which measures the
drawing alone.

    python bench/bench_scope_ui.py [--json] [--seconds 5] [--via inject|import] [--input page|cdp]

Needs the built UI (cd frontend && npm run build) and Debian's Chromium, like the browser tests.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    # Run as a script from anywhere: the harness lives in the tests package.
    sys.path.insert(0, str(REPO))

from playwright.sync_api import Page, sync_playwright  # noqa: E402
from tests.browser.harness import CHROMIUM_ARGS, chromium_executable, running_server  # noqa: E402

SESSION = "cia402-generic-1"
CHANNELS = 8
RATE_HZ = 4000
SECONDS = 10
POINTS = CHANNELS * RATE_HZ * SECONDS
TARGET_FPS = 30.0

#: Builds the recording in the page (no 320,000 numbers through the DevTools protocol) and
#: opens it through the page's hook, as an import's answer would be opened.
INJECT = """
([channels, rate, seconds]) => {
  const n = rate * seconds;
  const tRef = Date.now() / 1000;
  const t = new Array(n);
  for (let i = 0; i < n; i++) t[i] = i / rate;
  let seed = 12345;
  const noise = () => ((seed = (seed * 1103515245 + 12345) & 0x7fffffff) / 0x7fffffff - 0.5);
  const chans = [];
  for (let c = 0; c < channels; c++) {
    const v = new Array(n);
    const f = 0.5 + 1.7 * c;
    const amp = 1000 * (c + 1);
    for (let i = 0; i < n; i++) {
      v[i] = Math.round(amp * Math.sin(2 * Math.PI * f * i / rate) + 0.02 * amp * noise());
    }
    // One-sample spikes: min/max decimation must keep them visible.
    for (let k = 1; k < 5; k++) v[Math.floor(k * n / 5) + c] = (k % 2 ? 3 : -3) * amp;
    chans.push({id: c, t, v, name: `bench ${c}`, unit: 'deg', raw_unit: 'inc',
                scale: 0.01, eng_scale: 0.01, display_scale: 1, offset: 0});
  }
  const rec = {t_ref: tRef, trigger_time: null, channels: chans};
  window.__servodeskScope.openRecording(rec, 'bench');
}
"""

#: Counts animation frames and the plot's draws, with their times, until stopped.
PROBE_START = """
() => {
  const m = window.__servodeskScope.model;
  const p = {frames: [], running: true, draws0: m.draws, ms0: m.drawMs};
  const loop = (now) => {
    p.frames.push([now, m.draws]);
    if (p.running) requestAnimationFrame(loop);
  };
  requestAnimationFrame(loop);
  window.__probe = p;
}
"""

PROBE_STOP = """
() => {
  const p = window.__probe;
  p.running = false;
  const plot = document.querySelector('[data-testid="scope-plot"]').dataset;
  const m = window.__servodeskScope.model;
  const draws = m.draws - p.draws0;
  return {frames: p.frames, points: Number(plot.points), length: Number(plot.length),
          decimated: plot.decimated === 'true',
          js_ms_per_draw: draws ? Math.round(100 * (m.drawMs - p.ms0) / draws) / 100 : null};
}
"""


def write_mdf4(path: Path) -> None:
    """The bench recording as an MDF4 file from servodesk's own exporter."""
    import numpy as np

    from servodesk.domain.scope_export import ChannelData, Recording, export_recording

    n = RATE_HZ * SECONDS
    t = np.arange(n) / RATE_HZ
    rng = np.random.default_rng(12345)
    chans = []
    for c in range(CHANNELS):
        amp = 1000.0 * (c + 1)
        v = np.round(amp * np.sin(2 * np.pi * (0.5 + 1.7 * c) * t) + 0.02 * amp * rng.random(n))
        chans.append(
            ChannelData(
                id=c,
                name=f"bench {c}",
                unit="deg",
                raw_unit="inc",
                scale=0.01,
                address=f"0x{0x6064 + c:04X}:00",
                session=SESSION,
                source="recorder",
                t=t,
                v=v,
            )
        )
    data, _media = export_recording(Recording(time.time(), None, chans), "mdf4")
    path.write_bytes(data)


def open_recording(page: Page, via: str) -> float | None:
    """Open the bench recording in the page; the import's duration (s) when imported."""
    if via == "inject":
        page.evaluate(INJECT, [CHANNELS, RATE_HZ, SECONDS])
        page.wait_for_selector(f'[data-testid="scope-view"][data-samples="{POINTS}"]')
        return None
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mf4"
        write_mdf4(path)
        t0 = time.perf_counter()
        page.get_by_test_id("scope-import-file").set_input_files(str(path))
        page.wait_for_selector(
            f'[data-testid="scope-view"][data-samples="{POINTS}"]', timeout=60_000
        )
        return time.perf_counter() - t0


def per_second(frames: list[list[float]]) -> tuple[list[float], list[float], float]:
    """Draws per second and animation frames per second over each whole second, and the
    longest gap between two draws (ms)."""
    if len(frames) < 2:
        return [], [], 0.0
    t0 = frames[0][0]
    draws_fps: list[float] = []
    raf_fps: list[float] = []
    start = 0
    for i, (t, _d) in enumerate(frames):
        if t - frames[start][0] >= 1000.0:
            span = (t - frames[start][0]) / 1000.0
            draws_fps.append((frames[i][1] - frames[start][1]) / span)
            raf_fps.append((i - start) / span)
            start = i
    last_draw_t = t0
    longest = 0.0
    prev = frames[0][1]
    for t, d in frames[1:]:
        if d > prev:
            longest = max(longest, t - last_draw_t)
            last_draw_t = t
            prev = d
    return draws_fps, raf_fps, longest


#: Synthetic pan input in the page: shift-drag (mousedown on the plot, mousemove and mouseup on
#: the window, where the page listens while dragging) or wheel events, every 4 ms.
PAGE_INPUT = """
([phase, seconds]) => new Promise((resolve) => {
  const over = document.querySelector('[data-testid="scope-plot"] .u-over');
  const r = over.getBoundingClientRect();
  const y = r.top + r.height / 2;
  const left = r.left + r.width * 0.3;
  const right = r.left + r.width * 0.7;
  const mouse = (type, x) => new MouseEvent(type, {bubbles: true, cancelable: true, clientX: x,
                                                   clientY: y, shiftKey: true, button: 0});
  let x = left;
  let step = 6;
  let events = 0;
  const end = performance.now() + seconds * 1000;
  if (phase === 'drag') over.dispatchEvent(mouse('mousedown', x));
  const tick = () => {
    if (performance.now() >= end) {
      if (phase === 'drag') window.dispatchEvent(mouse('mouseup', x));
      resolve(events);
      return;
    }
    if (phase === 'drag') {
      x += step;
      if (x > right || x < left) { step = -step; x += 2 * step; }
      window.dispatchEvent(mouse('mousemove', x));
    } else {
      const direction = Math.floor(events / 40) % 2 === 0 ? 1 : -1;
      over.dispatchEvent(new WheelEvent('wheel', {bubbles: true, cancelable: true,
        clientX: (left + right) / 2, clientY: y, deltaY: direction * 12}));
    }
    events++;
    setTimeout(tick, 4);
  };
  tick();
})
"""


def pan_drag(page: Page, seconds: float) -> int:
    """Shift-drag the plot left and right; returns the mouse moves sent."""
    box = page.get_by_test_id("scope-plot").locator(".u-over").bounding_box()
    assert box is not None, "the plot has no drawing area"
    y = box["y"] + box["height"] / 2
    left = box["x"] + box["width"] * 0.3
    right = box["x"] + box["width"] * 0.7
    page.mouse.move(left, y)
    page.keyboard.down("Shift")
    page.mouse.down()
    moves = 0
    end = time.perf_counter() + seconds
    x, step = left, 6.0
    while time.perf_counter() < end:
        x += step
        if x > right or x < left:
            step = -step
            x += 2 * step
        page.mouse.move(x, y)
        moves += 1
    page.mouse.up()
    page.keyboard.up("Shift")
    return moves


def pan_wheel(page: Page, seconds: float) -> int:
    """Turn the wheel over the plot back and forth; returns the wheel events sent."""
    box = page.get_by_test_id("scope-plot").locator(".u-over").bounding_box()
    assert box is not None, "the plot has no drawing area"
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    events = 0
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        direction = 1 if (events // 40) % 2 == 0 else -1
        page.mouse.wheel(0, direction * 12)
        events += 1
    return events


def measure(page: Page, phase: str, seconds: float, source: str) -> dict[str, Any]:
    page.evaluate(PROBE_START)
    if source == "page":
        events = int(page.evaluate(PAGE_INPUT, [phase, seconds]))
    else:
        events = pan_drag(page, seconds) if phase == "drag" else pan_wheel(page, seconds)
    probe = page.evaluate(PROBE_STOP)
    frames = probe["frames"]
    draws_fps, raf_fps, longest = per_second(frames)
    total_s = (frames[-1][0] - frames[0][0]) / 1000.0 if len(frames) > 1 else 0.0
    draws = frames[-1][1] - frames[0][1] if frames else 0
    median = statistics.median(draws_fps) if draws_fps else 0.0
    return {
        "seconds": round(total_s, 2),
        "input_events": events,
        "draws": draws,
        "fps_per_second": [round(x, 1) for x in draws_fps],
        "median_fps": round(median, 1),
        "mean_fps": round(draws / total_s, 1) if total_s else 0.0,
        "ms_per_frame": round(1000.0 / median, 1) if median else None,
        "longest_gap_ms": round(longest, 1),
        "browser_frames_median_fps": round(statistics.median(raf_fps), 1) if raf_fps else 0.0,
        "js_ms_per_draw": probe["js_ms_per_draw"],
        "points_in_view": probe["points"],
        "drawn_points_per_trace": probe["length"],
        "decimated": probe["decimated"],
    }


def run(seconds: float, via: str, source: str) -> dict[str, Any]:
    with running_server() as base, sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=chromium_executable(), headless=False, args=CHROMIUM_ARGS
        )
        try:
            context = browser.new_context(base_url=base, viewport={"width": 1440, "height": 960})
            page = context.new_page()
            page.goto(f"/#/scope/{SESSION}")
            page.wait_for_selector('[data-testid="scope-plot"] .u-over')
            page.wait_for_function("() => !!window.__servodeskScope")
            import_s = open_recording(page, via)
            # The whole recording in view: every point goes through the decimation each frame.
            page.get_by_test_id("scope-reset-zoom").click()
            page.wait_for_timeout(300)
            drag = measure(page, "drag", seconds, source)
            # Half of it in view for the wheel.
            page.evaluate("() => window.__servodeskScope.model.zoomTo(2.5, 7.5)")
            page.wait_for_timeout(300)
            wheel = measure(page, "wheel", seconds, source)
            size = page.get_by_test_id("scope-plot").bounding_box()
        finally:
            browser.close()
    worst = min(drag["median_fps"], wheel["median_fps"])
    return {
        "channels": CHANNELS,
        "rate_hz": RATE_HZ,
        "seconds_recorded": SECONDS,
        "points": POINTS,
        "via": via,
        "input": source,
        "import_s": round(import_s, 2) if import_s is not None else None,
        "plot_px": [round(size["width"]), round(size["height"])] if size else None,
        "drag": drag,
        "wheel": wheel,
        "median_fps": worst,
        "ms_per_frame": round(1000.0 / worst, 1) if worst else None,
        "target_fps": TARGET_FPS,
        "ok": worst >= TARGET_FPS,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON only")
    ap.add_argument("--seconds", type=float, default=5.0, help="seconds of panning per phase")
    ap.add_argument(
        "--via",
        choices=("inject", "import"),
        default="inject",
        help="open the recording by injecting it into the page (default) or importing an MDF4",
    )
    ap.add_argument(
        "--input",
        choices=("page", "cdp"),
        default="page",
        help="synthetic events dispatched in the page (default) or Playwright's input events",
    )
    args = ap.parse_args()
    result = run(args.seconds, args.via, args.input)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(
            f"{result['points']} points ({result['channels']} channels x "
            f"{result['seconds_recorded']} s x {result['rate_hz']} Hz), opened by {result['via']}"
            + (f" in {result['import_s']} s" if result["import_s"] is not None else "")
            + f", input {result['input']}"
        )
        for phase in ("drag", "wheel"):
            r = result[phase]
            print(
                f"{phase:5}: median {r['median_fps']} fps ({r['ms_per_frame']} ms per frame), "
                f"browser {r['browser_frames_median_fps']} fps, longest gap "
                f"{r['longest_gap_ms']} ms, {r['points_in_view']} points in view, "
                f"{r['input_events']} input events, {r['js_ms_per_draw']} ms of script per draw"
            )
        print(
            f"worst median {result['median_fps']} fps = {result['ms_per_frame']} ms per frame "
            f"(target >= {TARGET_FPS} fps): {'ok' if result['ok'] else 'BELOW TARGET'}"
        )
    return 0 if result["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
