"""Kept scope captures and the tuning history against the real backend (issue 49; docs/ui.md
"Scope" and "Tuning").

What a commissioning engineer relies on: after recording the drive's position on the Scope
page, "Keep capture" with a title and note stores it, and the list of the drive's kept captures
shows it with its channels, units and sample period; Open shows it in the plot as a recording;
the report box attaches it, and the Overview's report card counts it. The Tuning page lists the
drive's tunings kept in the store (a finished one with its margins and bandwidth) and opens one
to its Bode plot.

Its own ``servodesk serve --sim`` with a data directory known here: the stored tuning is put
into the store as a tuning job's end puts it (services/tuning_store.py ``TuningStore.add``, the
job's recorder), since a tuning run on the twin takes minutes on this machine; everything the
test checks is what the page reads back through the API.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import HarnessError, running_server

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
POSITION = "0x6064:00"


@pytest.fixture(scope="module")
def data_dir() -> Path:
    return Path(tempfile.mkdtemp(prefix="servodesk-kept-"))


@pytest.fixture(scope="module")
def kept_server(data_dir: Path) -> Iterator[str]:
    env = {"SERVODESK_DATA_DIR": str(data_dir), "SERVODESK_SIM_PROFILES": "cia402-generic"}
    try:
        with running_server(env=env) as base:
            yield base
    except HarnessError as e:
        pytest.fail(str(e), pytrace=False)


@pytest.fixture
def kept_page(browser: Browser, kept_server: str) -> Iterator[Page]:
    yield from fresh_page(browser, kept_server)


def _call(page: Page, method: str, path: str, body: object | None = None) -> Any:
    r = page.request.fetch(
        f"/api/v1{path}",
        method=method,
        data=None if body is None else json.dumps(body),
        headers={"Content-Type": "application/json", "X-Servodesk-Client": "kept-test"},
    )
    assert r.ok, f"{method} {path}: {r.status} {r.text()}"
    return r.json()


def test_keep_a_capture_and_find_it_in_the_drives_list(kept_page: Page) -> None:
    page = kept_page
    page.goto(f"/#/scope/{SID}")
    expect(page.get_by_test_id("scope-page")).to_be_visible()
    # Position actual value, polled by SDO, recorded for a moment.
    channel = {"id": 0, "session": SID, "address": POSITION, "source": "sdo", "rate_hz": 100.0}
    _call(page, "PUT", "/scope/channels", {"channels": [channel]})
    _call(page, "POST", "/scope/run", {"action": "start"})
    time.sleep(1.0)
    _call(page, "POST", "/scope/run", {"action": "stop"})

    kept = page.get_by_test_id("scope-kept")
    expect(kept.get_by_test_id("scope-kept-empty")).to_be_visible()
    # A blank title is refused on the page, in the server's words, before any request.
    keep = kept.get_by_test_id("scope-keep")
    expect(keep).to_be_enabled()
    keep.click()
    expect(kept.get_by_test_id("scope-keep-problem")).to_contain_text("title")
    kept.get_by_test_id("scope-keep-title").fill("position at rest")
    kept.get_by_test_id("scope-keep-note").fill("before the belt change")
    expect(kept.get_by_test_id("scope-keep-window")).to_have_value("buffer")
    # From the keyboard: Enter in the title submits the form.
    kept.get_by_test_id("scope-keep-title").press("Enter")

    row = kept.get_by_test_id("scope-kept-row")
    expect(row).to_have_count(1)
    expect(row).to_contain_text("position at rest")
    expect(row).to_contain_text("before the belt change")
    unit = _call(page, "GET", f"/scope/captures/{row.get_attribute('data-id')}")
    ch = unit["channels"][0]
    expect(row).to_contain_text(f"{ch['name']} [{ch['unit'] or ch['raw_unit']}]")
    expect(row).to_contain_text("Hz)")  # the sample period with its rate
    assert ch["samples"] > 10 and unit["title"] == "position at rest"

    # Open: the plot shows it as a recording.
    row.get_by_test_id("scope-kept-open").click()
    expect(page.get_by_test_id("scope-back-live")).to_be_visible()
    # Attached to the drive's report.
    row.get_by_test_id("scope-kept-attach").check()
    expect(row.get_by_test_id("scope-kept-attach")).to_be_checked()
    # The box shows the choice at once; the server has it when its PATCH has been answered.
    deadline = time.monotonic() + 10.0
    while True:
        listed = _call(page, "GET", f"/sessions/{SID}/scope/captures")
        if [c["attached"] for c in listed] == [True] or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    assert [c["attached"] for c in listed] == [True]
    # Another tab, later: the list comes from the store.
    page.reload()
    expect(page.get_by_test_id("scope-kept-row")).to_have_count(1)
    _call(page, "PUT", "/scope/channels", {"channels": []})
    # The Overview's report card says what its report will show.
    page.goto(f"/#/overview/{SID}")
    expect(page.get_by_test_id("report-captures")).to_contain_text("1 scope capture attached")


def _stored_tuning(data_dir: Path, drive_key: str) -> str:
    """A finished tuning of the drive put into the store as the job's end puts it."""
    from servodesk.services.store import Store
    from servodesk.services.tuning_store import TuningStore

    f = [10.0 * 1.2**i for i in range(30)]
    mag = [20 * math.log10(200 / x) for x in f]
    phase = [-90.0 - x / 10 for x in f]
    t = [i / 1000 for i in range(100)]
    step = {
        "t_s": t,
        "position": [1000 * (1 - math.exp(-x / 0.01)) for x in t],
        "target": 1000.0,
        "unit": "inc",
        "metrics": {"settling_s": 0.04, "overshoot": 0.02, "following_error_rms": 12.0},
    }
    result: dict[str, Any] = {
        "kind": "gains", "status": "done", "error": None, "drive_code": None, "mode": "standard",
        "job": f"{SID}-t9", "identified": None,
        "bode": {"freq_hz": f, "measured_mag_db": mag, "measured_phase_deg": phase,
                 "coherence": [0.99] * 30, "model_mag_db": mag, "model_phase_deg": phase},
        "margins": {"phase_margin_deg": 47.5, "gain_margin_db": 9.25, "crossover_hz": 42.0,
                    "bandwidth_hz": 118.0},
        "gains": [], "step": {"before": step, "after": step}, "axis_time_s": 31.0,
        "excursion_rev": 0.2, "travel": None, "peak_torque_pct": 35.0,
        "peak_torque_polled_s": None, "applied": True, "stored": False, "notes": [],
    }  # fmt: skip
    ended = time.time() - 60
    record = {
        "id": "tuning-browser-1", "drive_key": drive_key, "session": SID,
        "kind": "gains", "mode": "standard", "status": "done", "started": ended - 95,
        "ended": ended, "by": "engineer", "client": "tab-1", "applied": True,
        "result": result,
    }  # fmt: skip
    store = Store(data_dir)
    try:
        TuningStore(store.engine, "line-7").add(record)
    finally:
        store.close()
    return "tuning-browser-1"


def test_the_tuning_history_lists_a_finished_tuning(kept_page: Page, data_dir: Path) -> None:
    page = kept_page
    page.goto(f"/#/tuning/{SID}")
    history = page.get_by_test_id("tuning-history")
    expect(history.get_by_test_id("tuning-history-empty")).to_be_visible(timeout=20_000)
    fleet = _call(page, "GET", "/fleet", None)
    (drive,) = [d for d in fleet["drives"] if d["session"] == SID]
    rid = _stored_tuning(data_dir, drive["drive_key"])

    history.get_by_test_id("tuning-history-refresh").click()
    row = history.get_by_test_id("tuning-history-row")
    expect(row).to_have_count(1)
    expect(row).to_have_attribute("data-id", rid)
    expect(row.get_by_test_id("tuning-history-status")).to_have_text("finished, gains applied")
    expect(row).to_contain_text("engineer")
    expect(row).to_contain_text("standard")
    expect(row).to_contain_text("1 min 35 s")
    expect(row.get_by_test_id("tuning-history-margins")).to_have_text("PM 47.5 °, GM 9.25 dB")
    expect(row).to_contain_text("118 Hz (crossover 42 Hz)")
    row.get_by_test_id("tuning-history-open").click()
    detail = history.get_by_test_id("tuning-history-detail")
    expect(detail).to_have_attribute("data-id", rid)
    expect(detail.get_by_test_id("tuning-history-detail-margins")).to_contain_text(
        "bandwidth 118 Hz"
    )
    expect(detail.locator("canvas").first).to_be_visible()  # the Bode and step plots
