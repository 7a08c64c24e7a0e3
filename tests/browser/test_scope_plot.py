"""The Scope page's plot draws decimated data without losing what matters (issue 50).

The plot shows min/max per pixel column (computed in a worker, drawn as one stroke per column;
``?plot=main``: the former path on the main thread). What a user relies on:

- a spike one sample wide, whose samples lie either side of the boundary between two pixel
  columns, is drawn to its full height and depth, on both paths;
- the decimation is for display only: the export (the server's full-rate buffer) has every
  sample the page received, while the plot drew far fewer points.

No frame rate is asserted here (bench/bench_scope_ui.py measures it).
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from servodesk.domain.scope_export import import_csv

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
RATE = 4000
SECONDS = 10

#: A recording of one flat channel with a spike: +1000 on the last sample before the start
#: of pixel column `c` (the columns are the plot's width over the window, decimate.ts),
#: -1000 on the first sample of it. Returns where it is.
SPIKE = """
() => {
  const over = document.querySelector('[data-testid="scope-plot"] .u-over');
  const cols = Math.max(50, Math.round(over.clientWidth));
  const n = %(n)d;
  const rate = %(rate)d;
  const x1 = (n - 1) / rate;
  const w = Number((x1 / cols).toPrecision(10));
  const c = Math.floor(cols / 2);
  // The first sample at or after the column's start, and the one before it.
  const after = Math.ceil(c * w * rate - 1e-9);
  const t = new Array(n);
  const v = new Array(n);
  for (let i = 0; i < n; i++) { t[i] = i / rate; v[i] = 0; }
  v[after - 1] = 1000;
  v[after] = -1000;
  window.__servodeskScope.openRecording({t_ref: 1000, trigger_time: null, channels: [
    {id: 0, t, v, name: 'spike', unit: 'inc', raw_unit: 'inc', scale: 1, eng_scale: 1,
     display_scale: 1, offset: 0}]}, 'spike');
  return {cols, w, before: (after - 1) / rate, after: after / rate};
}
"""

#: Rows of the plot's canvas that hold the trace's colour (saturated pixels: the grid and the
#: axes are grey), within `dx` CSS pixels of the spike's x; in CSS pixels from the plot area's top.
TRACE_ROWS = """
([time, dx]) => {
  const host = document.querySelector('[data-testid="scope-plot"]');
  const over = host.querySelector('.u-over');
  const canvas = host.querySelector('canvas');
  const d = host.dataset;
  const x0 = Number(d.x0), x1 = Number(d.x1);
  const ratio = canvas.width / canvas.getBoundingClientRect().width;
  const o = over.getBoundingClientRect();
  const c = canvas.getBoundingClientRect();
  const left = (o.left - c.left) * ratio;
  const top = (o.top - c.top) * ratio;
  const width = o.width * ratio;
  const height = o.height * ratio;
  const at = left + (time - x0) / (x1 - x0) * width;
  const from = Math.max(0, Math.floor(at - dx * ratio));
  const span = Math.ceil(2 * dx * ratio) + 1;
  const img = canvas.getContext('2d').getImageData(from, Math.floor(top), span, Math.ceil(height));
  let first = null, last = null;
  for (let y = 0; y < img.height; y++) {
    for (let x = 0; x < img.width; x++) {
      const k = 4 * (y * img.width + x);
      const [r, g, b, a] = [img.data[k], img.data[k + 1], img.data[k + 2], img.data[k + 3]];
      if (a > 128 && Math.max(r, g, b) - Math.min(r, g, b) > 60) {
        if (first === null) first = y;
        last = y;
      }
    }
  }
  return {first: first === null ? null : first / ratio, last: last === null ? null : last / ratio,
          height: height / ratio, decimated: d.decimated, path: d.path};
}
"""


def put(page: Page, path: str, body: dict[str, Any]) -> Any:
    r = page.request.put(path, data=json.dumps(body), headers={"Content-Type": "application/json"})
    assert r.ok, f"PUT {path}: {r.status} {r.text()}"
    return r.json()


def reset_scope(page: Page) -> None:
    page.request.post(
        "/api/v1/scope/run", data='{"action":"stop"}', headers={"Content-Type": "application/json"}
    )
    put(page, "/api/v1/scope/channels", {"channels": []})
    put(page, "/api/v1/scope/trigger", {"mode": "roll"})


@pytest.fixture
def clean_scope(page: Page) -> Iterator[Page]:
    page.goto(f"/#/overview/{SID}")
    reset_scope(page)
    try:
        yield page
    finally:
        reset_scope(page)


@pytest.mark.parametrize("path", ["worker", "main"])
def test_a_spike_between_two_pixel_columns_is_drawn_to_its_full_height(
    clean_scope: Page, path: str
) -> None:
    page = clean_scope
    page.goto(f"/{'?plot=main' if path == 'main' else ''}#/scope/{SID}")
    plot = page.get_by_test_id("scope-plot")
    expect(plot).to_have_attribute("data-path", path)
    page.wait_for_function("() => !!window.__servodeskScope")
    spike = page.evaluate(SPIKE % {"n": RATE * SECONDS, "rate": RATE})
    expect(page.get_by_test_id("scope-view")).to_have_attribute("data-kind", "recording")
    expect(plot).to_have_attribute("data-points", str(RATE * SECONDS), timeout=10_000)
    expect(plot).to_have_attribute("data-decimated", "true")
    # The two samples are 1/4000 s apart, either side of a column boundary (40,000 samples
    # over about a thousand columns: about 40 samples per column).
    assert spike["before"] < spike["cols"] // 2 * spike["w"] <= spike["after"], spike

    def rows() -> dict[str, Any]:
        return dict(page.evaluate(TRACE_ROWS, [spike["after"], 3]))

    deadline = time.monotonic() + 10.0
    got = rows()
    # The drawing follows the data by a frame (and the worker's answer): wait for it.
    while (got["first"] is None or got["last"] is None) and time.monotonic() < deadline:
        page.wait_for_timeout(100)
        got = rows()
    assert got["first"] is not None and got["last"] is not None, got
    # The y axis spans -1000..+1000 (and a margin): the flat line is at mid-height, the spike's
    # max near the top and its min near the bottom. Without them the colour would stay in the
    # middle rows.
    h = got["height"]
    assert got["first"] < 0.15 * h, f"the spike's max is not drawn: {got}"
    assert got["last"] > 0.85 * h, f"the spike's min is not drawn: {got}"
    # Away from the spike the trace is the flat line only (the check above can fail).
    flat = dict(page.evaluate(TRACE_ROWS, [spike["after"] / 2, 3]))
    assert flat["first"] is not None and 0.3 * h < flat["first"] <= flat["last"] < 0.7 * h, flat


def test_the_export_has_every_sample_while_the_plot_draws_columns(
    clean_scope: Page, tmp_path: Path
) -> None:
    page = clean_scope
    # Position actual from the drive's recorder: 4 kHz, more samples than pixel columns.
    put(
        page,
        "/api/v1/scope/channels",
        {"channels": [{"id": 0, "session": SID, "address": "0x6064:00", "source": "recorder"}]},
    )
    put(page, "/api/v1/scope/trigger", {"mode": "roll", "window_s": SECONDS})
    page.goto(f"/#/scope/{SID}")
    expect(page.get_by_test_id("scope-connection")).to_have_attribute(
        "data-connected", "true", timeout=10_000
    )
    expect(page.get_by_test_id("scope-channel-0")).to_have_attribute("data-address", "0x6064:00")
    page.get_by_test_id("scope-run").click()
    expect(page.get_by_test_id("scope-state")).to_have_attribute("data-running", "true")
    plot = page.get_by_test_id("scope-plot")

    def samples() -> int:
        return int(plot.get_attribute("data-samples") or 0)

    # Enough samples that the plot decimates (about a thousand columns).
    deadline = time.monotonic() + 30.0
    while samples() < 4000:
        assert time.monotonic() < deadline, f"only {samples()} samples arrived in 30 s"
        page.wait_for_timeout(200)
    page.get_by_test_id("scope-stop").click()
    expect(page.get_by_test_id("scope-state")).to_have_attribute("data-running", "false")
    # Every frame sent before the stop arrives: the count holds still for a second.
    last, still = -1, time.monotonic()
    deadline = time.monotonic() + 20.0
    while time.monotonic() - still < 1.0:
        assert time.monotonic() < deadline, "the page's sample count did not settle"
        n = samples()
        if n != last:
            last, still = n, time.monotonic()
        page.wait_for_timeout(100)
    expect(plot).to_have_attribute("data-decimated", "true")
    drawn = int(plot.get_attribute("data-length") or 0)
    page_samples = page.evaluate(
        """() => {
            const m = window.__servodeskScope.model;
            const s = m.live.get(0);
            return {t: Array.from(s.t.subarray(0, s.n)), v: Array.from(s.v.subarray(0, s.n)),
                    skipped: m.skipped};
        }"""
    )
    n = len(page_samples["v"])
    assert drawn < n / 2, f"the plot drew {drawn} points of {n}: not decimated"

    with page.expect_download() as download:
        page.get_by_test_id("scope-export-csv").click()
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    rec = import_csv(path.read_bytes())
    (chan,) = [c for c in rec.channels if c.id == 0]
    t = np.asarray(chan.t, dtype=float) + rec.t_ref
    v = np.asarray(chan.v, dtype=float)
    # Every sample the page received is in the export, with its value and time (the CSV's
    # times are text: matched to the nearest, far closer than the 250 us between samples).
    pt = np.asarray(page_samples["t"])
    order = np.argsort(t, kind="stable")
    pos = np.clip(np.searchsorted(t[order], pt), 1, len(t) - 1)
    near = np.where(np.abs(t[order][pos - 1] - pt) <= np.abs(t[order][pos] - pt), pos - 1, pos)
    rows = order[near]
    off = np.abs(t[rows] - pt)
    missing = int(np.count_nonzero(off > 50e-6))
    assert missing == 0, f"{missing} of {n} samples the page shows are not in the export"
    assert len(set(rows.tolist())) == n, "two samples of the page matched one of the export"
    assert np.array_equal(v[rows], np.asarray(page_samples["v"])), "values differ"
    if page_samples["skipped"] == 0:
        # The page kept up: the export holds exactly what it received.
        assert len(v) == n, (len(v), n)
