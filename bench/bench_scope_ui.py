"""Scope page frame rate in Chromium: while capturing 32 channels x 4 kHz with a 10 s window
(1.28 M points in view), and while panning a recording of 8 channels x 10 s x 4 kHz.

Issue 50 "Browser": the plot redraws at the display's rate, target >= 30 fps with 32 channels
and a 10 s window of 4 kHz data, measured with requestAnimationFrame timestamps in Chromium with
software rendering. Each phase runs twice in the same browser and server, on the two drawing
paths of ScopePlot.tsx: ``main`` (the former path, selected by the page URL's ``?plot=main``:
min/max per pixel column on the main thread, uPlot's polyline through them), the baseline, and
``worker`` (the decimation in a Web Worker, column strokes); the JSON gives the medians of both
and their ratio.

Phases:

- ``recorder`` (issue 50, the real stream): the server's scope with 8 channels of the simulated
  generic drive from its recorder (4 kHz in the drive, uploaded by SDO: the samples arrive a
  few times a second in batches), 10 s window, measured after the window filled. The former
  path redrew only when a batch arrived, as its view followed the newest sample.
- ``capture`` (issue 50): the page receives binary scope frames of 32 channels every 20 ms (80
  samples each, 128,000 samples/s; decoded and stored by the page's own code, ScopePage's
  ``ingestFrame`` hook) after 10 s of them, and follows the newest samples with a 10 s window.
  The server's scope takes 32 channels (8 until 2026-12-08), but its simulated drives do not
  produce 128,000 samples/s (``servodesk bench scope``), so the frames are made in the page at
  the wire's rate; what is measured is the page's drawing while they arrive.
- ``drag`` and ``wheel`` (issue 7): shift-drag and wheel pans of a recording of 8 channels x
  40,000 samples (sines with noise and one-sample spikes), the whole recording and half of it
  in view; the input is synthetic mouse and wheel events dispatched in the page every 4 ms
  (``--input cdp``: Playwright's input events, one DevTools round trip each).

Per phase and path: draws per second of the plot (uPlot draw hooks counted by the page's
model) over each second, the browser's animation frames per second, their medians, the
longest gap between two draws, ms of script per draw on the main thread. ``--via import``
opens the recording through the Import button as an MDF4 file written by servodesk's own
exporter (also times the import).

    python bench/bench_scope_ui.py [--json] [--seconds 5] [--phases capture,drag,wheel]
                                   [--via inject|import] [--input page|cdp] [--ui-dist DIR]

Needs the built UI (cd frontend && npm run build; ``--ui-dist`` serves another build's files
to the page instead) and Debian's Chromium, like the browser tests.
"""

from __future__ import annotations

import argparse
import json
import os
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
#: The recorder phase: the generic twin's recordable objects, one channel each.
RECORDED = [
    "0x6064:00",
    "0x606C:00",
    "0x60F4:00",
    "0x60FD:00",
    "0x6077:00",
    "0x6041:00",
    "0x603F:00",
    "0x6061:00",
]
#: The capture phase: channels, samples per frame (20 ms at 4 kHz).
CAPTURE_CHANNELS = 32
FRAME_SAMPLES = 80
CHANNELS = 8
RATE_HZ = 4000
SECONDS = 10
POINTS = CHANNELS * RATE_HZ * SECONDS
TARGET_FPS = 30.0
#: The drawing paths, baseline first (ScopePlot.tsx plotPath).
PATHS = ("main", "worker")

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


#: The capture phase's stream: binary frames in the wire format (docs/scope.md "Wire format",
#: equidistant blocks) of `channels` channels, `per` samples each, made in the page every
#: per / rate seconds and handed to the page's decoder and model (ScopePage ``ingestFrame``);
#: first `seconds` of them at once, so the window is full from the start.
FEED_START = """
([channels, rate, seconds, per]) => {
  const hook = window.__servodeskScope;
  const traces = [];
  for (let c = 0; c < channels; c++) traces.push({key: `c${c}`, kind: 'channel', id: c,
    label: `bench ${c}`, colour: `hsl(${(c * 47) % 360}, 70%, 38%)`, visible: true, unit: 'deg',
    rawUnit: 'inc', engScale: 0.01, scale: 1, offset: 0});
  hook.setTraces(traces);
  const m = hook.model;
  m.showLive();
  m.clearLive();
  m.span = seconds;
  // One period of each channel's signal (whole periods in `rate` samples) plus noise.
  const table = [];
  let seed = 12345;
  const noise = () => ((seed = (seed * 1103515245 + 12345) & 0x7fffffff) / 0x7fffffff - 0.5);
  for (let c = 0; c < channels; c++) {
    const v = new Float64Array(rate);
    const f = 1 + (c % 7);
    for (let i = 0; i < rate; i++) {
      v[i] = Math.round(1000 * (c + 1) * (Math.sin(2 * Math.PI * f * i / rate) + 0.02 * noise()));
    }
    table.push(v);
  }
  const dt = 1 / rate;
  const t0 = Date.now() / 1000 - seconds;
  let seq = 1;
  let next = 0;
  const frame = (n) => {
    const buf = new ArrayBuffer(32 + channels * (24 + 8 * n));
    const dv = new DataView(buf);
    [83, 68, 83, 67].forEach((b, i) => dv.setUint8(i, b));
    dv.setUint8(4, 1);
    dv.setUint8(5, 1);
    dv.setUint32(8, seq++, true);
    dv.setUint16(16, channels, true);
    dv.setFloat64(24, t0 + next * dt, true);
    let off = 32;
    for (let c = 0; c < channels; c++) {
      dv.setUint8(off, c);
      dv.setUint8(off + 1, 1);
      dv.setUint32(off + 4, n, true);
      dv.setFloat64(off + 8, dt, true);
      off += 24;
      const v = new Float64Array(buf, off, n);
      const src = table[c];
      for (let i = 0; i < n; i++) v[i] = src[(next + i) % rate];
      off += 8 * n;
    }
    next += n;
    hook.ingestFrame(buf);
  };
  for (let k = 0; k < seconds; k++) frame(rate);
  const wall0 = performance.now();
  const start = next;
  window.__feed = setInterval(() => {
    const due = start + Math.floor((performance.now() - wall0) / 1000 * rate);
    while (next + per <= due) frame(per);
  }, per / rate * 1000);
}
"""

FEED_STOP = """
() => {
  clearInterval(window.__feed);
  window.__servodeskScope.setTraces(null);
  window.__servodeskScope.model.clearLive();
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


def api(page: Page, method: str, path: str, body: dict[str, Any]) -> Any:
    r = page.request.fetch(
        path, method=method, data=json.dumps(body), headers={"Content-Type": "application/json"}
    )
    assert r.ok, f"{method} {path}: {r.status} {r.text()}"
    return r.json()


def measure(page: Page, phase: str, seconds: float, source: str) -> dict[str, Any]:
    if phase == "recorder":
        channels = [
            {"id": i, "session": SESSION, "address": a, "source": "recorder"}
            for i, a in enumerate(RECORDED)
        ]
        api(page, "PUT", "/api/v1/scope/channels", {"channels": channels})
        page.reload()  # The page reads the channels at load (a running scope pushes them).
        page.wait_for_selector('[data-testid="scope-plot"] .u-over')
        page.get_by_test_id("scope-run").click()
        page.wait_for_selector('[data-testid="scope-state"][data-running="true"]')
        page.wait_for_timeout((SECONDS + 1) * 1000)  # The 10 s window fills.
        page.evaluate(PROBE_START)
        page.wait_for_timeout(seconds * 1000)
        probe = page.evaluate(PROBE_STOP)
        api(page, "POST", "/api/v1/scope/run", {"action": "stop"})
        api(page, "PUT", "/api/v1/scope/channels", {"channels": []})
        events = 0
    elif phase == "capture":
        page.evaluate(FEED_START, [CAPTURE_CHANNELS, RATE_HZ, SECONDS, FRAME_SAMPLES])
        page.wait_for_timeout(1000)  # The first frames settle (worker started, caches).
        page.evaluate(PROBE_START)
        page.wait_for_timeout(seconds * 1000)
        probe = page.evaluate(PROBE_STOP)
        page.evaluate(FEED_STOP)
        events = 0
    else:
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


def serve_dist(page: Page, dist: Path) -> None:
    """Answer the page's own files (index.html, assets/) from another build's directory."""

    def handle(route: Any) -> None:
        path = route.request.url.split("://", 1)[1].split("/", 1)[1].split("?")[0].split("#")[0]
        f = dist / (path or "index.html")
        if path.startswith("api/") or not f.is_file():
            route.continue_()
            return
        types = {".js": "text/javascript", ".css": "text/css", ".html": "text/html"}
        route.fulfill(path=str(f), content_type=types.get(f.suffix, "application/octet-stream"))

    page.route("**/*", handle)


def run_path(
    page: Page, path: str, phases: list[str], seconds: float, via: str, source: str
) -> dict[str, Any]:
    """All phases on one drawing path (a fresh page load)."""
    query = "?plot=main" if path == "main" else ""
    # The live view shows the trigger's window: 10 s, as a user sets it.
    r = page.request.put(
        "/api/v1/scope/trigger",
        data=json.dumps({"mode": "roll", "window_s": SECONDS}),
        headers={"Content-Type": "application/json"},
    )
    assert r.ok, f"PUT /api/v1/scope/trigger: {r.status} {r.text()}"
    page.goto(f"/{query}#/scope/{SESSION}")
    page.wait_for_selector(f'[data-testid="scope-plot"][data-path="{path}"] .u-over')
    page.wait_for_function("() => !!window.__servodeskScope")
    out: dict[str, Any] = {}
    if "recorder" in phases:
        out["recorder"] = measure(page, "recorder", seconds, source)
        page.goto(f"/{query}#/scope/{SESSION}")
        page.wait_for_selector(f'[data-testid="scope-plot"][data-path="{path}"] .u-over')
        page.wait_for_function("() => !!window.__servodeskScope")
    if "capture" in phases:
        out["capture"] = measure(page, "capture", seconds, source)
    if "drag" in phases or "wheel" in phases:
        import_s = open_recording(page, via)
        out["import_s"] = round(import_s, 2) if import_s is not None else None
        if "drag" in phases:
            # The whole recording in view: every point goes through the decimation.
            page.get_by_test_id("scope-reset-zoom").click()
            page.wait_for_timeout(300)
            out["drag"] = measure(page, "drag", seconds, source)
        if "wheel" in phases:
            # Half of it in view for the wheel.
            page.evaluate("() => window.__servodeskScope.model.zoomTo(2.5, 7.5)")
            page.wait_for_timeout(300)
            out["wheel"] = measure(page, "wheel", seconds, source)
    size = page.get_by_test_id("scope-plot").bounding_box()
    out["plot_px"] = [round(size["width"]), round(size["height"])] if size else None
    return out


def run(
    seconds: float, via: str, source: str, phases: list[str], dist: Path | None
) -> dict[str, Any]:
    with running_server() as base, sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=chromium_executable(), headless=False, args=CHROMIUM_ARGS
        )
        try:
            context = browser.new_context(base_url=base, viewport={"width": 1440, "height": 960})
            page = context.new_page()
            if dist is not None:
                serve_dist(page, dist)
            load = [round(x, 2) for x in os.getloadavg()]
            paths = {path: run_path(page, path, phases, seconds, via, source) for path in PATHS}
        finally:
            browser.close()
    out: dict[str, Any] = {
        "recorder_phase": f"{len(RECORDED)} channels of {SESSION} from its recorder",
        "capture_channels": CAPTURE_CHANNELS,
        "recording_channels": CHANNELS,
        "rate_hz": RATE_HZ,
        "window_s": SECONDS,
        "capture_points_in_view": CAPTURE_CHANNELS * RATE_HZ * SECONDS,
        "recording_points": POINTS,
        "via": via,
        "input": source,
        "load_before": load,
        "load_after": [round(x, 2) for x in os.getloadavg()],
        "paths": paths,
        "target_fps": TARGET_FPS,
    }
    for phase in phases:
        base_fps = paths["main"][phase]["median_fps"]
        new_fps = paths["worker"][phase]["median_fps"]
        out[phase] = {
            "baseline_median_fps": base_fps,
            "median_fps": new_fps,
            "ratio": round(new_fps / base_fps, 2) if base_fps else None,
            "ok": new_fps >= TARGET_FPS,
        }
    out["ok"] = all(out[phase]["ok"] for phase in phases)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON only")
    ap.add_argument("--seconds", type=float, default=5.0, help="seconds measured per phase")
    ap.add_argument(
        "--phases",
        default="recorder,capture,drag,wheel",
        help="comma-separated: recorder (the server's stream), capture (32 channels "
        "arriving), drag, wheel (panning)",
    )
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
    ap.add_argument("--ui-dist", type=Path, help="serve the page's files from this build")
    args = ap.parse_args()
    phases = [x.strip() for x in args.phases.split(",") if x.strip()]
    bad = [x for x in phases if x not in ("recorder", "capture", "drag", "wheel")]
    if bad or not phases:
        ap.error(
            f"--phases: unknown {', '.join(bad) or '(none)'}; use recorder, capture, drag, wheel"
        )
    if args.ui_dist is not None and not (args.ui_dist / "index.html").is_file():
        ap.error(f"--ui-dist {args.ui_dist}: no index.html there (a vite build's outDir)")
    result = run(args.seconds, args.via, args.input, phases, args.ui_dist)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(
            f"capture: {CAPTURE_CHANNELS} channels x {RATE_HZ} Hz, {SECONDS} s window "
            f"({result['capture_points_in_view']} points); recording: {POINTS} points, opened "
            f"by {result['via']}; input {result['input']}; load {result['load_before']}"
        )
        for phase in phases:
            for path in PATHS:
                r = result["paths"][path][phase]
                print(
                    f"{phase:7} {path:6}: median {r['median_fps']} fps ({r['ms_per_frame']} ms "
                    f"per frame), browser {r['browser_frames_median_fps']} fps, longest gap "
                    f"{r['longest_gap_ms']} ms, {r['points_in_view']} points in view, "
                    f"{r['js_ms_per_draw']} ms of script per draw"
                )
            q = result[phase]
            print(
                f"{phase:7} worker / main = {q['ratio']}; target >= {TARGET_FPS} fps: "
                f"{'ok' if q['ok'] else 'BELOW TARGET'}"
            )
    return 0 if result["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
