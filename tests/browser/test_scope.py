"""The Scope page against the real backend and the simulated generic CiA 402 drive.

What a commissioning engineer relies on (issue 7 "Done when"): pick position and velocity
actual of a drive, start the scope and see the traces follow the moving axis; set a level
trigger, single, with 20 % pre-trigger, arm it and get the captured window with the trigger
sample at 0 s and a fifth of the window before it; export the capture as CSV and as MDF4 with
the page's buttons and open both files again in the scope, with the same channels and samples.
The drive and the scope are left as they were found: the scope stopped and empty, the axis
halted and disabled, control released.
"""

from __future__ import annotations

import csv
import io
import json
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import api_take_control, start_mover, stop_mover

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
#: The client that moves the axis: a script with its own control token and a WebSocket bound
#: to it (the dead-man heartbeat), so the page under test does not have to hold control.
MOVER = "scope-test-mover"
#: Target velocity (60FFh, raw inc/s): slow enough to stay far from the simulated drive's
#: limit switches (-1.7 / +3.7 revolutions of 131072 inc) for the whole test.
VELOCITY = 20_000
REVOLUTION = 131_072
POSITION = "0x6064:00"
VELOCITY_ACTUAL = "0x606C:00"


def post(page: Page, path: str, body: dict[str, Any], headers: dict[str, str] | None = None) -> Any:
    r = page.request.post(
        path, data=json.dumps(body), headers=headers or {"Content-Type": "application/json"}
    )
    assert r.ok, f"POST {path}: {r.status} {r.text()}"
    return r.json()


def put(page: Page, path: str, body: dict[str, Any]) -> Any:
    r = page.request.put(path, data=json.dumps(body), headers={"Content-Type": "application/json"})
    assert r.ok, f"PUT {path}: {r.status} {r.text()}"
    return r.json()


class Mover:
    """The script that moves the axis: takes control over the API, binds a WebSocket of the
    page to it (harness.start_mover) and sends its requests with the token."""

    def __init__(self, page: Page) -> None:
        self.page = page
        self.token: str | None = None

    @property
    def headers(self) -> dict[str, str]:
        h = {"X-Servodesk-Client": MOVER, "Content-Type": "application/json"}
        if self.token:
            h["X-Servodesk-Control"] = self.token
        return h

    def start(self) -> None:
        self.token = api_take_control(self.page, SID, MOVER)
        start_mover(self.page, SID, self.token, MOVER)

    def post(self, path: str, body: dict[str, Any]) -> Any:
        return post(self.page, f"/api/v1/sessions/{SID}/{path}", body, self.headers)

    def stop(self) -> None:
        """Halt, servo off, release control, close the socket (quiet: cleanup)."""
        base = f"/api/v1/sessions/{SID}"
        self.page.request.post(f"{base}/motion/halt", data="{}", headers=self.headers)
        if self.token:
            self.page.request.post(
                f"{base}/state", data='{"command":"disable"}', headers=self.headers
            )
            self.page.request.post(
                f"{base}/control", data='{"action":"release"}', headers=self.headers
            )
        self.token = None
        stop_mover(self.page)


def reset_scope(page: Page) -> None:
    page.request.post(
        "/api/v1/scope/run", data='{"action":"stop"}', headers={"Content-Type": "application/json"}
    )
    put(page, "/api/v1/scope/channels", {"channels": []})
    put(page, "/api/v1/scope/trigger", {"mode": "roll"})


@pytest.fixture
def mover(page: Page) -> Iterator[Mover]:
    m = Mover(page)
    try:
        yield m
    finally:
        m.stop()


@pytest.fixture
def scope_page(page: Page) -> Iterator[Page]:
    page.goto(f"/#/overview/{SID}")
    reset_scope(page)
    page.goto(f"/#/scope/{SID}")
    expect(page.get_by_test_id("scope-page")).to_be_visible()
    expect(page.get_by_test_id("scope-connection")).to_have_attribute(
        "data-connected", "true", timeout=10_000
    )
    try:
        yield page
    finally:
        reset_scope(page)


def pick_object(page: Page, channel: int, query: str, address: str) -> None:
    page.get_by_test_id("scope-add-channel").click()
    picker = page.get_by_test_id(f"scope-channel-{channel}-object")
    picker.click()
    picker.fill(query)
    page.get_by_test_id(f"scope-object-{address}").click()
    row = page.get_by_test_id(f"scope-channel-{channel}")
    expect(row).to_have_attribute("data-address", address)


def plot_int(page: Page, attribute: str) -> int:
    value = page.get_by_test_id("scope-plot").get_attribute(attribute)
    assert value is not None and value.isdigit(), f"scope-plot {attribute}={value!r}"
    return int(value)


def latest_raw(page: Page, channel: int) -> float:
    raw = page.get_by_test_id(f"scope-channel-{channel}-latest").get_attribute("data-raw")
    assert raw, f"channel {channel} shows no newest value"
    return float(raw)


def view_counts(page: Page) -> tuple[int, int]:
    view = page.get_by_test_id("scope-view")
    return int(view.get_attribute("data-channels") or -1), int(
        view.get_attribute("data-samples") or -1
    )


def import_file(page: Page, path: Path, name: str) -> None:
    page.get_by_test_id("scope-import-file").set_input_files(
        {"name": name, "mimeType": "application/octet-stream", "buffer": path.read_bytes()}
    )


def test_scope_traces_trigger_export_and_reimport(
    scope_page: Page, mover: Mover, tmp_path: Path
) -> None:
    page = scope_page

    # Two channels of the drive the page was opened for, source chosen by the server.
    pick_object(page, 0, "position actual", POSITION)
    pick_object(page, 1, "velocity actual", VELOCITY_ACTUAL)
    # The server took them and says which source each got and the rate it achieves.
    achieved = page.get_by_test_id("scope-channel-0-achieved")
    expect(achieved).not_to_have_attribute("data-source", "", timeout=10_000)
    expect(page.get_by_test_id("scope-channel-0-unit")).to_contain_text("deg")
    expect(page.get_by_test_id("scope-channel-0-unit")).to_contain_text("inc")

    # Roll: start and see samples arrive.
    page.get_by_test_id("scope-trigger-mode-roll").click()
    page.get_by_test_id("scope-run").click()
    expect(page.get_by_test_id("scope-state")).to_have_attribute("data-state", "rolling")
    expect(page.get_by_test_id("scope-channel-0-latest")).not_to_have_attribute(
        "data-raw", "", timeout=10_000
    )
    expect(achieved).not_to_have_attribute("data-rate", "", timeout=10_000)
    rate = float(achieved.get_attribute("data-rate") or 0)
    assert rate > 10, f"achieved rate {rate} Hz"

    # Move the axis (another client, with its own dead-man heartbeat), away from the nearer
    # limit switch.
    mover.start()
    position = page.request.get(f"/api/v1/sessions/{SID}/objects/{POSITION}").json()["value"]
    direction = -1 if position > REVOLUTION else 1
    mover.post("state", {"command": "enable"})
    mover.post("motion/velocity", {"velocity": direction * VELOCITY})

    # The traces follow: the stored samples grow and the newest position changes.
    samples0 = plot_int(page, "data-samples")
    first = latest_raw(page, 0)
    page.wait_for_timeout(1_000)
    assert plot_int(page, "data-samples") > samples0
    second = latest_raw(page, 0)
    assert (second - first) * direction > 0, f"moving {direction:+d}: position {first} -> {second}"
    assert plot_int(page, "data-length") > 0
    expect(page.get_by_test_id("scope-stats-c1")).not_to_have_attribute("data-n", "0")

    # Level trigger on the position, single, 20 % pre-trigger, 1 s window: the level two
    # seconds ahead of the axis, entered as shown (deg) and sent raw.
    page.get_by_test_id("scope-trigger-mode-single").click()
    page.get_by_test_id("scope-trigger-kind").select_option("level")
    page.get_by_test_id("scope-trigger-channel").select_option("0")
    page.get_by_test_id("scope-trigger-slope").select_option(
        "rising" if direction > 0 else "falling"
    )
    page.get_by_test_id("scope-trigger-pre").fill("20")
    page.get_by_test_id("scope-trigger-pre").press("Enter")
    page.get_by_test_id("scope-trigger-window").fill("1")
    page.get_by_test_id("scope-trigger-window").press("Enter")
    status = page.request.get("/api/v1/scope").json()
    eng_per_raw = next(c["eng_scale"] for c in status["channels"] if c["id"] == 0)
    now = page.request.get(f"/api/v1/sessions/{SID}/objects/{POSITION}").json()["value"]
    level_raw = now + direction * VELOCITY * 2
    page.get_by_test_id("scope-trigger-level").fill(f"{level_raw * eng_per_raw:.9f}")
    page.get_by_test_id("scope-trigger-level").press("Enter")
    level_sent = page.get_by_test_id("scope-trigger-level-raw")
    # The raw level the drive compares: a whole number of increments.
    expect(level_sent).to_have_attribute("data-raw", str(level_raw))

    page.get_by_test_id("scope-arm").click()
    view = page.get_by_test_id("scope-view")
    expect(view).to_have_attribute("data-kind", "capture", timeout=20_000)
    state = page.get_by_test_id("scope-state")
    expect(state).to_have_attribute("data-state", "done", timeout=10_000)
    expect(view).not_to_have_attribute("data-samples", "0")

    # The captured window: the trigger sample at 0 s with a fifth of the window before it,
    # and the position crossing the level there.
    capture = page.evaluate(
        """() => {
            const m = window.__servodeskScope.model;
            const s = m.seriesOf(0);
            const o = m.origin;
            let i = 0;
            while (i < s.n && s.t[i] < o) i++;
            return {first: s.t[0] - o, last: s.t[s.n - 1] - o, at: s.v[i], before: s.v[i - 1],
                    trigger: m.triggerTime === null ? null : m.triggerTime - o};
        }"""
    )
    assert capture["trigger"] == 0
    assert -0.2 - 0.01 <= capture["first"] <= -0.2 + 0.01, capture
    assert 0.8 - 0.05 <= capture["last"] <= 0.8 + 0.01, capture
    sent = float(level_sent.get_attribute("data-raw") or 0)
    if direction > 0:
        assert capture["before"] < sent <= capture["at"], capture
    else:
        assert capture["before"] > sent >= capture["at"], capture
    channels, samples = view_counts(page)
    assert channels == 2 and samples > 1000, (channels, samples)

    # Export the capture with the page's buttons (both while it is shown) ...
    files: list[tuple[Path, str]] = []
    for fmt, ext in (("csv", "csv"), ("mdf4", "mf4")):
        with page.expect_download() as download:
            page.get_by_test_id(f"scope-export-{fmt}").click()
        name = download.value.suggested_filename
        assert name.endswith(f".{ext}"), name
        path = tmp_path / name
        download.value.save_as(path)
        assert path.stat().st_size > 1000, f"{name}: {path.stat().st_size} bytes"
        files.append((path, name))

    # ... and open each file again: the same channels and samples.
    for path, name in files:
        import_file(page, path, name)
        expect(view).to_have_attribute("data-kind", "recording", timeout=10_000)
        expect(view).to_have_attribute("data-name", name)
        assert view_counts(page) == (channels, samples), f"{name} reopened with other counts"
    expect(page.get_by_test_id("scope-failure")).to_have_count(0)


def test_one_click_adds_the_drives_motion_channels(scope_page: Page) -> None:
    # The generic twin has 6064h, 60F4h, 606Ch and 6077h (no 6062h): four rows in that
    # order, the server takes them, and live values arrive; a second click has nothing to add.
    page = scope_page
    add = page.get_by_test_id("scope-add-motion")
    expect(add).to_be_enabled()
    motion = ("0x6064:00", "0x60F4:00", "0x606C:00", "0x6077:00")
    expect(add).to_have_attribute("title", re.compile(rf"^adds {', '.join(motion)} "))
    add.click()
    table = page.get_by_test_id("scope-channels")
    expect(table).to_have_attribute("data-count", "4")
    for i, address in enumerate(motion):
        expect(page.get_by_test_id(f"scope-channel-{i}")).to_have_attribute("data-address", address)
    expect(add).to_be_disabled()

    def server_channels() -> list[str]:
        r = page.request.get("/api/v1/scope")
        return [c["address"] for c in r.json()["channels"]]

    deadline = time.monotonic() + 5.0
    while server_channels() != list(motion):
        assert time.monotonic() < deadline, server_channels()
        time.sleep(0.1)
    page.get_by_test_id("scope-run").click()
    expect(page.get_by_test_id("scope-channel-3-latest")).to_have_attribute(
        "data-raw", re.compile(r"^-?\d"), timeout=10_000
    )


def test_reset_zoom_after_stop_shows_the_whole_run(scope_page: Page) -> None:
    # Issue 48: with a 1 s window the live view follows the newest second; after Stop, Reset
    # zoom shows the whole run (here about 3 s), not its last second.
    page = scope_page
    put(page, "/api/v1/scope/trigger", {"mode": "roll", "window_s": 1})
    page.get_by_test_id("scope-add-motion").click()
    expect(page.get_by_test_id("scope-channels")).to_have_attribute("data-count", "4")
    page.get_by_test_id("scope-run").click()
    expect(page.get_by_test_id("scope-state")).to_have_attribute("data-running", "true")
    page.wait_for_timeout(3000)

    def shown_span() -> float:
        w = page.evaluate("() => window.__servodeskScope.model.window()")
        return float(w[1] - w[0])

    page.get_by_test_id("scope-reset-zoom").click()
    assert shown_span() == pytest.approx(1.0, abs=0.01)  # Running: the newest second.
    page.get_by_test_id("scope-stop").click()
    expect(page.get_by_test_id("scope-state")).to_have_attribute("data-running", "false")
    page.get_by_test_id("scope-reset-zoom").click()
    extent = page.evaluate("() => window.__servodeskScope.model.extent()")
    assert extent is not None and extent[1] - extent[0] > 2.0
    assert shown_span() == pytest.approx(extent[1] - extent[0], rel=1e-6)


def test_channels_of_another_drive_are_said_and_kept_only_by_choice(page: Page) -> None:
    # Issue 48: the scope is one capture; the smartris page must not show the generic drive's
    # channels as its own. It names them with their drive and lets the user keep or remove them.
    page.goto(f"/#/overview/{SID}")
    reset_scope(page)
    other = {"id": 0, "session": SID, "address": POSITION}
    try:
        put(page, "/api/v1/scope/channels", {"channels": [other]})
        page.goto("/#/scope/smartris-3")
        note = page.get_by_test_id("scope-other-drives")
        expect(note).to_have_attribute("data-kept", "false")
        expect(note).to_contain_text(f"1 channel of another drive: {SID} (1), not smartris-3")
        expect(page.get_by_test_id("scope-channel-0-session")).to_have_value(SID)
        # Keeping them is a choice the page remembers (the note stays, quiet).
        page.get_by_test_id("scope-other-keep").click()
        expect(note).to_have_attribute("data-kept", "true")
        page.reload()
        expect(page.get_by_test_id("scope-other-drives")).to_have_attribute("data-kept", "true")
        # Removing them leaves a capture of this drive only.
        put(page, "/api/v1/scope/channels", {"channels": [other, {**other, "id": 1}]})
        page.reload()
        note = page.get_by_test_id("scope-other-drives")
        expect(note).to_have_attribute("data-kept", "false")
        page.get_by_test_id("scope-other-remove").click()
        expect(note).to_have_count(0)
        deadline = time.monotonic() + 5.0
        while page.request.get("/api/v1/scope").json()["channels"]:
            assert time.monotonic() < deadline
            time.sleep(0.1)
    finally:
        reset_scope(page)


def test_32_channels_of_four_drives_are_listed_drawn_and_exported(
    scope_page: Page, tmp_path: Path
) -> None:
    # Issue 50: 4 drives x 8 channels. Set over the API (polled, 20 Hz each, from four
    # sessions on three fieldbuses), run from the page: the measurements (the page's legend)
    # list all 32 traces with samples in view, each in a colour of its own, the channel table
    # holds the 32 rows in a box that scrolls inside its card, and the CSV export has 32
    # value columns.
    page = scope_page
    sessions = [s["id"] for s in page.request.get("/api/v1/sessions").json()]
    drives = [SID, *[s for s in sessions if s != SID and not s.startswith("cia402-generic")]][:4]
    assert len(drives) == 4, sessions
    channels = [
        {
            "id": i,
            "session": drives[i // 8],
            "address": (POSITION, "0x6041:00")[i % 2],
            "source": "sdo",
            "rate_hz": 20,
            "label": f"ch{i:02d} {drives[i // 8]}",
        }
        for i in range(32)
    ]
    put(page, "/api/v1/scope/channels", {"channels": channels})
    put(page, "/api/v1/scope/trigger", {"mode": "roll", "window_s": 2})
    page.reload()
    expect(page.get_by_test_id("scope-channels")).to_have_attribute("data-count", "32")
    expect(page.get_by_test_id("scope-add-channel")).to_be_disabled()
    page.get_by_test_id("scope-run").click()
    expect(page.get_by_test_id("scope-state")).to_have_attribute("data-state", "rolling")
    for i in range(32):
        expect(page.get_by_test_id(f"scope-stats-c{i}")).not_to_have_attribute(
            "data-n", "0", timeout=10_000
        )
    drawn = page.evaluate(
        """() => {
            const m = window.__servodeskScope.model;
            return {traces: m.traces.map((t) => t.colour),
                    live: [...m.live.entries()].filter(([, s]) => s.n > 0).map(([id]) => id)};
        }"""
    )
    assert len(set(drawn["traces"])) == 32, drawn["traces"]
    assert sorted(drawn["live"]) == list(range(32)), drawn["live"]

    # The rows scroll inside the card (at 1440 px wide): the box is shorter than its rows
    # and the last row is reached by scrolling it.
    box = page.get_by_test_id("scope-channel-rows")
    size = box.evaluate("(e) => ({client: e.clientHeight, scroll: e.scrollHeight})")
    assert size["client"] <= 560 < size["scroll"], size
    last = page.get_by_test_id("scope-channel-31-remove")
    last.scroll_into_view_if_needed()
    expect(last).to_be_in_viewport()

    page.get_by_test_id("scope-stop").click()
    expect(page.get_by_test_id("scope-state")).to_have_attribute("data-running", "false")
    with page.expect_download() as download:
        page.get_by_test_id("scope-export-csv").click()
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    text = path.read_text(encoding="utf-8-sig")
    header = next(row for row in csv.reader(io.StringIO(text)) if row[:1] == ["time_s"])
    assert sum(1 for h in header if h != "time_s") == 32, header
