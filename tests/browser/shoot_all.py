"""Screenshots of every page on every twin at 1440x900 and 1024x768, with contact sheets.

Run: ``.venv/bin/python -m tests.browser.shoot_all /tmp/servodesk-shots-all [page ...]`` (no page:
all of them). Not a test: it is
the set a person looks through before a UI change lands (issue 48's "screenshots of every page
at 1440x900 and 1024x768 on every twin, checked by eye"). It starts ``servodesk serve --sim``
(the five twins), visits every page of the registry for each open session and the global pages
once, and writes ``<page>/<twin>-<width>.png`` plus one contact sheet per page
(``sheets/<page>.png``: the twins in rows, the two sizes in columns), so a page's look on every
drive is compared at a glance. Nothing is written to a drive: pages are opened, not used.
"""

from __future__ import annotations

import json
import sys
import urllib.request
from collections.abc import Sequence
from pathlib import Path

from PIL import Image, ImageDraw
from playwright.sync_api import sync_playwright

from tests.browser.harness import CHROMIUM_ARGS, chromium_executable, running_server

#: The sizes issue 48 names: a laptop and the smallest layout the UI promises to fit.
SIZES = ((1440, 900), (1024, 768))
#: Page ids from frontend/src/pages/registry.ts, by scope.
SESSION_PAGES = (
    "network",
    "overview",
    "operation",
    "tuning",
    "scope",
    "alarms",
    "parameters",
    "objects",
    "dictionary",
    "pdo",
    "backup",
    "view3d",
)
GLOBAL_PAGES = ("connect", "axes", "fleet", "audit", "users")
#: How long a page gets to load its data and draw (polls, the WebSocket's first values).
SETTLE_MS = 1800
#: Width of one screenshot on a contact sheet.
THUMB_W = 560


def _sessions(base: str) -> list[tuple[str, str]]:
    with urllib.request.urlopen(f"{base}/api/v1/sessions", timeout=10) as r:
        body = json.load(r)
    items = body["items"] if isinstance(body, dict) else body
    return [(str(s["id"]), str(s.get("profile_id") or s["id"])) for s in items]


def _sheet(shots: list[tuple[str, list[Path]]], out: Path) -> None:
    """The shots of one page: a row per twin, a column per size, scaled to THUMB_W."""
    rows: list[list[Image.Image]] = []
    for _, paths in shots:
        row = []
        for path in paths:
            img = Image.open(path)
            scale = THUMB_W / img.width
            row.append(img.resize((THUMB_W, int(img.height * scale))))
        rows.append(row)
    label_h = 18
    row_h = [max(i.height for i in row) + label_h for row in rows]
    sheet = Image.new("RGB", (THUMB_W * len(SIZES) + 10, sum(row_h) + 10), "white")
    draw = ImageDraw.Draw(sheet)
    y = 5
    for (name, _), row, h in zip(shots, rows, row_h, strict=True):
        draw.text((5, y), name, fill="black")
        for col, img in enumerate(row):
            sheet.paste(img, (5 + col * THUMB_W, y + label_h))
        y += h
    sheet.save(out)


def main(out: Path, only: Sequence[str] = ()) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "sheets").mkdir(exist_ok=True)
    with running_server() as base, sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=chromium_executable(), headless=True, args=CHROMIUM_ARGS
        )
        sessions = _sessions(base)
        targets: list[tuple[str, list[tuple[str, str]]]] = [
            (page, [(sid, label) for sid, label in sessions]) for page in SESSION_PAGES
        ]
        targets += [(page, [("", "global")]) for page in GLOBAL_PAGES]
        if only:
            targets = [t for t in targets if t[0] in only]
        for page_id, drives in targets:
            (out / page_id).mkdir(exist_ok=True)
            shots: list[tuple[str, list[Path]]] = []
            for sid, label in drives:
                paths = []
                for width, height in SIZES:
                    ctx = browser.new_context(
                        base_url=base, viewport={"width": width, "height": height}
                    )
                    page = ctx.new_page()
                    page.goto(f"/#/{page_id}/{sid}" if sid else f"/#/{page_id}")
                    page.wait_for_timeout(SETTLE_MS)
                    path = out / page_id / f"{label}-{width}.png"
                    page.screenshot(path=str(path), full_page=False)
                    ctx.close()
                    paths.append(path)
                shots.append((label, paths))
            _sheet(shots, out / "sheets" / f"{page_id}.png")
            print(f"{page_id}: {len(shots)} drives", flush=True)
        browser.close()
    print(f"screenshots in {out}, contact sheets in {out / 'sheets'}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/servodesk-shots-all"), sys.argv[2:])
