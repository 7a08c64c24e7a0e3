"""The 3D view: the viser client page of the real backend, in headless Chromium.

The UI's 3D view page embeds this page in an iframe (its URL comes from GET /api/v1/viewer);
the test loads that URL directly, as the iframe does. What a user relies on: the page connects
(the backend counts it as a client and raises the drives' poll rate), scene updates stream in
while an axis moves, so the picture keeps moving with the axis, and it stands still when the
axis does. (viser's websocket lives in a web worker, out of Playwright's sight: the update
rate a client sees is measured by bench/bench_viewer.py.)
"""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import time
import urllib.request
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import Browser, Page
from scipy import ndimage  # type: ignore[import-untyped]
from websockets.sync.client import connect

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
#: Changed pixels (of 640 x 420) below which the picture stands, above which it moved.
STILL, MOVED = 20, 60
#: Pixels of a drawn scene (the disc, the axis, the grid) at least.
DRAWN = 2000


#: The control token this test holds (changing the drive needs it: docs/safety.md).
HEADERS: dict[str, str] = {}


def api(base: str, method: str, path: str, body: dict[str, Any] | None = None) -> Any:
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(
        f"{base}/api/v1{path}",
        data=data,
        method=method,
        headers={"Content-Type": "application/json", **HEADERS},
    )
    with urllib.request.urlopen(req, timeout=5) as r:
        return json.loads(r.read() or b"null")


def wait_for(cond: Any, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.1)


def picture(page: Page) -> np.ndarray:
    # Software WebGL on a loaded 2-core machine can take many seconds to give a frame.
    png = page.screenshot(timeout=60_000)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def changed_pixels(a: np.ndarray, b: np.ndarray) -> int:
    return int((np.abs(a - b).sum(axis=2) > 30).sum())


def drawn_pixels(a: np.ndarray) -> int:
    """Pixels that are not the empty canvas's white: the scene has been drawn."""
    return int((a.sum(axis=2) < 3 * 240).sum())


@pytest.fixture
def viewer_page(browser: Browser, server_url: str) -> Iterator[Page]:
    info = api(server_url, "GET", "/viewer")
    assert info["enabled"] and info["running"], info
    context = browser.new_context(viewport={"width": 640, "height": 420})
    context.set_default_timeout(15_000)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(info["url"])
    yield page
    context.close()
    assert not errors, f"uncaught errors in the viewer page: {errors}"


@contextlib.contextmanager
def holding_control(server_url: str) -> Iterator[None]:
    """Take control of the drive as a script and bind a WebSocket as its dead-man (servo on
    needs one); the socket stays open for the block (closing it disables the drive)."""
    base_ws = server_url.replace("http://", "ws://")
    HEADERS.clear()
    HEADERS["X-Servodesk-Client"] = "viewer-test"
    with connect(f"{base_ws}/api/v1/ws?client=viewer-test", subprotocols=["servodesk.v1"]) as ws:  # type: ignore[list-item]
        r = api(server_url, "POST", f"/sessions/{SID}/control", {"action": "take"})
        HEADERS.update({"X-Servodesk-Client": "viewer-test", "X-Servodesk-Control": r["token"]})
        ws.send(json.dumps({"type": "bind", "session": SID, "token": r["token"]}))
        while json.loads(ws.recv(5)).get("type") != "bind":
            pass
        try:
            yield
        finally:
            api(server_url, "POST", f"/sessions/{SID}/control", {"action": "release"})
            HEADERS.clear()


def test_viewer_page_connects_and_moves_with_the_axis(viewer_page: Page, server_url: str) -> None:
    with holding_control(server_url):
        _connects_and_moves(viewer_page, server_url)


def _connects_and_moves(viewer_page: Page, server_url: str) -> None:
    page = viewer_page
    # Connected: the backend counts the browser as a viewer client.
    wait_for(lambda: api(server_url, "GET", "/viewer")["clients"] >= 1, 20, "the client")
    # The client bundle (800 kB) and its WebGL start-up on a loaded 2-core machine: like a shot.
    page.locator("canvas").first.wait_for(state="visible", timeout=60_000)
    # The panel says what the colours mean; viser's developer controls stay folded away.
    legend = page.get_by_text("servodesk 3D view")
    legend.wait_for(state="visible", timeout=30_000)
    assert page.get_by_text("blue ghost: the target").is_visible()
    assert not page.get_by_text("Dev Settings").is_visible()
    assert not page.get_by_text("Save Canvas").is_visible()
    api(server_url, "PUT", f"/sessions/{SID}/objects/0x60FF", {"value": 0})
    api(server_url, "POST", f"/sessions/{SID}/state", {"command": "disable"})
    # The scene arrives, the client settles its render resolution; then the picture of a
    # standing axis stands still. Two blank canvases are no scene standing still: on a loaded
    # machine the first frames can take seconds (a CI run once compared white with white).
    still_b = picture(page)
    for _ in range(40):
        time.sleep(0.5)
        still_a, still_b = still_b, picture(page)
        if drawn_pixels(still_b) > DRAWN and changed_pixels(still_a, still_b) < STILL:
            break
    else:
        raise AssertionError(
            "the scene was not drawn"
            if drawn_pixels(still_b) <= DRAWN
            else "the picture keeps changing while the axis stands"
        )

    # Profile velocity (CiA 402-2 §6.7) at 1/8 revolution per second, towards the middle of
    # the simulated limit switches (-1.7 and +3.7 revolutions): software rendering is slow,
    # and the shots below take seconds.
    state = api(server_url, "GET", f"/sessions/{SID}/state")
    if state["state"] == "Fault":
        api(server_url, "POST", f"/sessions/{SID}/state", {"command": "fault_reset"})
    velocity = (1 << 14) if (state["position"] or 0) < (1 << 17) else -(1 << 14)
    api(server_url, "POST", f"/sessions/{SID}/state", {"command": "enable"})
    api(server_url, "PUT", f"/sessions/{SID}/objects/0x6060", {"value": 3})
    try:
        api(server_url, "PUT", f"/sessions/{SID}/objects/0x60FF", {"value": velocity})
        # The picture keeps moving: shots half a second (1/16 revolution) apart until three
        # have each differed from the one before. Software WebGL on a loaded machine may let
        # a shot repeat the last frame now and then, so shots are taken for up to 10 s (1.25
        # revolutions, well within the limit switches from where the axis starts).
        shots = [picture(page)]
        moves = 0
        end = time.monotonic() + 10.0
        while moves < 3 and time.monotonic() < end:
            time.sleep(0.5)
            shots.append(picture(page))
            moves += changed_pixels(shots[-2], shots[-1]) > MOVED
        moving = api(server_url, "GET", f"/sessions/{SID}/state")
    finally:
        api(server_url, "PUT", f"/sessions/{SID}/objects/0x60FF", {"value": 0})
        api(server_url, "POST", f"/sessions/{SID}/state", {"command": "disable"})
    assert moving["state"] == "Operation enabled", moving["state"]
    assert moves >= 3, (
        f"the picture moved in {moves} of {len(shots) - 1} shots while the axis moved: "
        f"{[changed_pixels(a, b) for a, b in itertools.pairwise(shots)]} pixels changed"
    )
    assert changed_pixels(still_b, shots[-1]) > MOVED, "the picture is back where it stood"


def label_boxes(shot: np.ndarray) -> list[tuple[int, int, int, int]]:
    """The stage labels in a picture of the canvas, as (left, top, right, bottom) pixels.

    viser draws the labels in WebGL, not as HTML: they are found in the picture. Their text
    is the only neutral dark grey there (the housings are blue-grey, the discs light), and the
    letters of one label are a few pixels apart, the labels far more (their gaps are the
    point): dark pixels within 3 px of each other are one label; specks are left out.
    """
    r, g, b = shot[..., 0], shot[..., 1], shot[..., 2]
    ink = (shot.sum(axis=2) < 3 * 110) & (np.abs(b - r) <= 2) & (np.abs(g - r) <= 2)
    near, _ = ndimage.label(ndimage.binary_dilation(ink, structure=np.ones((7, 7), bool)))
    boxes = []
    for i, (rows, cols) in enumerate(ndimage.find_objects(near), start=1):
        if int((ink & (near == i)).sum()) >= 100:
            boxes.append((cols.start, rows.start, cols.stop, rows.stop))
    return sorted(boxes)


def test_the_stage_labels_stay_apart_at_640_px(viewer_page: Page, server_url: str) -> None:
    # A 640 px browser: the docked panel leaves the row about 380 px, some 70 px a stage,
    # while a label keeps its size on screen (about 95 px). Side by side they overlapped
    # into one band of text; now each label is whole on the canvas and clear of the others.
    page = viewer_page
    stages = len(api(server_url, "GET", "/viewer")["axes"])
    assert stages >= 5, stages
    canvas = page.locator("canvas").first
    canvas.wait_for(state="visible", timeout=60_000)
    # Only the canvas: the panel and the software-WebGL notice are HTML above it.
    page.add_style_tag(
        content="body * { visibility: hidden !important } canvas { visibility: visible !important }"
    )
    box = canvas.bounding_box()
    assert box is not None and box["width"] < 640, box
    left, top = int(box["x"]), int(box["y"])
    width, height = int(box["width"]), int(box["height"])
    # Each label is whole once its drive's state has arrived (five lines, about 55 px high).
    end = time.monotonic() + 60.0
    while True:
        shot = picture(page)[top : top + height, left : left + width]
        boxes = label_boxes(shot)
        if len(boxes) == stages and all(b[3] - b[1] > 45 for b in boxes):
            break
        if time.monotonic() > end:
            raise AssertionError(
                f"{len(boxes)} separate labels for {stages} stages (overlapping labels merge): "
                f"{boxes}"
            )
        time.sleep(1.0)
    for a, b in itertools.combinations(boxes, 2):
        apart = a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
        assert apart, f"labels {a} and {b} overlap"
    # Whole: no label runs off the canvas's sides (at 640 px the first one did).
    assert all(b[0] > 0 and b[2] < width for b in boxes), (width, boxes)
