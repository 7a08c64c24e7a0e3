"""Kept scope captures in the store, on SQLite and PostgreSQL (issue 49; docs/scope.md "Kept
captures"): revision 0006 makes the table, a capture is found again by its id and listed per
drive newest first, attached and detached, its CSV opens again in the scope with the same
samples, it is deleted, and ``servodesk store export/import`` carries it to either engine."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from servodesk.cli import main
from servodesk.domain.scope_export import import_csv
from servodesk.errors import NotFoundError, ValidationError
from servodesk.services import db
from servodesk.services.capture_store import MAX_SAMPLES, CaptureStore
from servodesk.services.store import Store

KEY = "5344534B-00000402-1"
SID = "cia402-generic-1"


def recording(n: int = 50, session: str = SID) -> dict[str, Any]:
    """A capture as GET /scope/capture answers it: position at 1 kHz, one sample missing."""
    t = [i / 1000.0 - 0.01 for i in range(n)]
    v: list[float | None] = [float(1000 + 7 * i) for i in range(n)]
    if n > 3:
        v[3] = None
    return {
        "t_ref": 1_765_000_000.25,
        "trigger_time": 1_765_000_000.25,
        "window": [-0.01, n / 1000.0 - 0.01],
        "channels": [
            {
                "id": 0, "name": "Position actual value", "unit": "rev", "raw_unit": "inc",
                "scale": 1 / 131072, "address": "0x6064:00", "session": session,
                "source": "sdo", "t": t, "v": v, "eng_scale": 1 / 131072,
                "label": None, "display_scale": 1.0, "offset": 0.0,
            }
        ],
    }  # fmt: skip


TRIGGER = {"mode": "single", "kind": "level", "channel": 0, "level": 1100.0,
           "slope": "rising", "pre": 0.2, "window_s": 0.05, "holdoff_s": 0.0}  # fmt: skip


def keep(captures: CaptureStore, title: str, **kw: Any) -> dict[str, Any]:
    args: dict[str, Any] = {
        "drive_key": KEY, "session": SID, "title": title, "note": "after the belt change",
        "by": "engineer", "client": "tab-1", "window": "capture", "recording": recording(),
        "trigger": TRIGGER,
    }  # fmt: skip
    return captures.add(**(args | kw))


def test_captures_are_kept_listed_attached_and_deleted(engine_url: str, tmp_path: Path) -> None:
    store = Store(tmp_path, engine_url)
    try:
        assert db.revision(store.engine) == "0006"
        captures = CaptureStore(store.engine, "line-7")
        first = keep(captures, "before tuning")
        second = keep(captures, "after tuning 軸", attached=True)
        assert first["gateway"] == "line-7" and first["samples"] == 50
        assert first["attached"] is False and second["attached"] is True
        (ch,) = first["channels"]
        assert ch["unit"] == "rev" and ch["raw_unit"] == "inc" and ch["samples"] == 50
        assert ch["period_s"] == pytest.approx(0.001)
        assert [c["id"] for c in captures.of_drive(KEY)] == [second["id"], first["id"]]
        assert captures.of_drive("other-drive") == []
        got = captures.get(first["id"])
        assert got["recording"] == recording() and got["trigger"] == TRIGGER
        assert got["title"] == "before tuning" and got["note"] == "after the belt change"
        # Only the attached one goes into the drive's reports.
        assert [c["id"] for c in captures.attached(KEY)] == [second["id"]]
        assert captures.set_attached(first["id"], True)["attached"] is True
        assert [c["id"] for c in captures.attached(KEY)] == [first["id"], second["id"]]
        # The CSV is the scope's: it opens again with the same samples (the gap as a gap).
        data, name = captures.csv(first["id"])
        assert name == f"{first['id']}.csv"
        back = import_csv(data)
        assert back.t_ref == recording()["t_ref"]
        (c,) = back.channels
        assert c.unit == "rev" and c.scale == 1 / 131072 and c.address == "0x6064:00"
        assert c.t.tolist() == recording()["channels"][0]["t"]
        assert math.isnan(c.v[3]) and c.v[4] == 1028.0
        assert captures.delete(first["id"])["id"] == first["id"]
        with pytest.raises(NotFoundError, match="no scope capture"):
            captures.get(first["id"])
        with pytest.raises(NotFoundError):
            captures.delete(first["id"])
    finally:
        store.close()


def test_a_capture_without_the_drive_or_too_big_is_refused(tmp_path: Path) -> None:
    store = Store(tmp_path)
    try:
        captures = CaptureStore(store.engine, "line-7")
        with pytest.raises(ValidationError, match="no channel of session"):
            keep(captures, "x", recording=recording(session="hiwin-e-2"))
        with pytest.raises(ValidationError, match="no samples"):
            keep(captures, "x", recording=recording(n=0))
        with pytest.raises(ValidationError, match=f"more than the {MAX_SAMPLES}"):
            keep(captures, "x", recording=recording(n=MAX_SAMPLES + 1))
        assert captures.of_drive(KEY) == []
    finally:
        store.close()


def test_captures_move_with_the_store(engine_url: str, tmp_path: Path) -> None:
    source = Store(tmp_path / "a")
    try:
        made = keep(CaptureStore(source.engine, "line-7"), "kept", attached=True)
        full = CaptureStore(source.engine, "line-7").get(made["id"])
    finally:
        source.close()
    dump = tmp_path / "store.jsonl"
    assert main(["store", "export", str(dump), "--data-dir", str(tmp_path / "a")]) == 0
    target = ["--url", engine_url] if engine_url else ["--data-dir", str(tmp_path / "b")]
    assert main(["store", "import", str(dump), *target]) == 0
    store = Store(tmp_path / "b", engine_url)
    try:
        moved = CaptureStore(store.engine, "elsewhere")
        assert moved.get(made["id"]) == full
        assert [c["id"] for c in moved.attached(KEY)] == [made["id"]]
    finally:
        store.close()
