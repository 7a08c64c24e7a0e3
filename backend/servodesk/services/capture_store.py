"""Scope captures the user keeps, in the store (issue 49, "Plant scale"; docs/scope.md "Kept
captures").

A kept capture is one row of ``scope_captures`` (services/db.py, revision 0006): the drive (its
``drive_key``, as services/fleet.py follows a drive across gateways), the session and gateway
it was kept on, when, by which user and client, the user's title and note, which window of the
scope it is (the triggered capture or the whole buffer), a summary of its channels for the
list, whether the drive's commissioning reports show it (``attached``), and the recording
itself as JSON: every channel's name, units, raw-to-engineering scale, address, source, sample
times and raw values as the scope had them (GET /scope/capture's shape), with the trigger.

A capture is never changed but for ``attached``; it is deleted only with a reason, which the
caller puts in the audit log (api/routes/scope.py). Every call blocks: run it in a thread.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import secrets
import statistics
import time
from datetime import UTC, datetime
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.engine import Engine

from servodesk.domain import scope_export as export
from servodesk.domain.ids import check_id
from servodesk.errors import NotFoundError, ValidationError
from servodesk.services import db

#: The most samples (all channels together) one kept capture holds: about 8 MB of JSON, and
#: each sample is also in the report of a capture attached to one. A full buffer of eight
#: channels at 4 kHz (320 000) is more: a triggered window is what a report shows anyway.
MAX_SAMPLES = 200_000
#: The most captures one list answers.
MAX_LIST = 500

#: The columns of a capture's metadata (the row less its recording).
_META = (
    "id", "drive_key", "session", "gateway", "title", "note", "time", "created", "by",
    "client", "window", "samples", "channels", "attached", "sha256",
)  # fmt: skip


def new_capture_id() -> str:
    """Sortable, readable and a safe id (domain/ids.py): ``capture-20261207t142600z-a1b2c3``."""
    stamp = datetime.now(UTC).strftime("%Y%m%dt%H%M%Sz")
    return f"capture-{stamp}-{secrets.token_hex(3)}"


def _iso(t: float) -> str:
    return datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def period_of(t: list[float | None]) -> float | None:
    """A channel's sample period [s]: the median spacing of its samples (None: fewer than two).
    The median, as a PDO channel's jitter and a recorder's gaps between uploads are not it."""
    times = [x for x in t if x is not None]
    if len(times) < 2:
        return None
    return float(statistics.median(b - a for a, b in itertools.pairwise(times)))


def summary(channel: dict[str, Any]) -> dict[str, Any]:
    """What the list shows of a channel: no samples."""
    keys = ("id", "name", "unit", "raw_unit", "scale", "address", "session", "source")
    return {k: channel.get(k) for k in keys} | {
        "samples": len(channel.get("t") or []),
        "period_s": period_of(channel.get("t") or []),
    }


def _meta(row: sa.RowMapping) -> dict[str, Any]:
    out = {k: row[k] for k in _META}
    out["attached"] = bool(out["attached"])
    out["channels"] = json.loads(out["channels"])
    return out


def to_recording(recording: dict[str, Any]) -> export.Recording:
    """A kept capture's recording as the scope's export has it (CSV, domain/scope_export.py)."""
    chans = [
        export.ChannelData(
            id=int(c["id"]),
            name=str(c["name"]),
            unit=str(c.get("unit") or ""),
            raw_unit=str(c.get("raw_unit") or ""),
            scale=float(c["scale"]),
            address=str(c["address"]),
            session=str(c["session"]),
            source=str(c["source"]),
            t=np.asarray([math.nan if x is None else x for x in c["t"]], dtype=np.float64),
            v=np.asarray([math.nan if x is None else x for x in c["v"]], dtype=np.float64),
        )
        for c in recording["channels"]
    ]
    return export.Recording(float(recording["t_ref"]), recording.get("trigger_time"), chans)


class CaptureStore:
    """The ``scope_captures`` table on the store's engine (shared with services/store.py)."""

    def __init__(self, engine: Engine, gateway: str) -> None:
        self.engine = engine
        #: This gateway's name (the fleet's, services/drift.py): where a capture was kept.
        self.gateway = gateway

    def add(
        self,
        *,
        drive_key: str,
        session: str,
        title: str,
        note: str,
        by: str,
        client: str,
        window: str,
        recording: dict[str, Any],
        trigger: dict[str, Any] | None,
        attached: bool = False,
    ) -> dict[str, Any]:
        """Keep ``recording`` (the scope's capture or buffer JSON) of ``session``'s drive; its
        metadata. A recording without a channel of the session, without samples or with more
        than :data:`MAX_SAMPLES` is refused (ValidationError saying what to do)."""
        channels = recording.get("channels") or []
        if not any(c.get("session") == session for c in channels):
            raise ValidationError(
                f"the scope's {window} has no channel of session {session!r}",
                field="session",
                hint="add a channel of this drive to the scope and record it, or keep the "
                "capture from the page of the drive whose channels it shows",
            )
        samples = sum(len(c.get("t") or []) for c in channels)
        if samples == 0:
            raise ValidationError(
                f"the scope's {window} holds no samples", hint="record something first"
            )
        if samples > MAX_SAMPLES:
            raise ValidationError(
                f"the scope's {window} holds {samples} samples, more than the {MAX_SAMPLES} a "
                "kept capture may hold",
                field="window",
                hint="keep a triggered capture (a shorter window) or fewer channels",
            )
        data = {"recording": recording, "trigger": trigger}
        text = json.dumps(data, allow_nan=False, sort_keys=True, separators=(",", ":"))
        created = time.time()
        row = {
            "id": new_capture_id(),
            "drive_key": drive_key,
            "session": session,
            "gateway": self.gateway,
            "title": title,
            "note": note,
            "time": _iso(created),
            "created": created,
            "by": by,
            "client": client,
            "window": window,
            "samples": samples,
            "channels": json.dumps([summary(c) for c in channels], allow_nan=False),
            "attached": int(attached),
            "sha256": hashlib.sha256(text.encode("utf-8")).hexdigest(),
            "data": text,
        }
        with db.transaction(self.engine) as conn:
            conn.execute(sa.insert(db.scope_captures).values(row))
        return self.meta(str(row["id"]))

    def of_drive(self, drive_key: str, limit: int = 100) -> list[dict[str, Any]]:
        """The drive's kept captures, newest first, metadata only."""
        t = db.scope_captures
        query = (
            sa.select(*(t.c[k] for k in _META))
            .where(t.c.drive_key == drive_key)
            .order_by(t.c.created.desc(), t.c.id.desc())
            .limit(max(1, min(limit, MAX_LIST)))
        )
        return [_meta(r) for r in db.rows(self.engine, query)]

    def _row(self, cid: str, *columns: Any) -> sa.RowMapping:
        check_id(cid, "id")
        t = db.scope_captures
        rows = db.rows(self.engine, sa.select(*columns).where(t.c.id == cid))
        if not rows:
            raise NotFoundError(
                f"no scope capture {cid!r} in the store",
                hint="GET /sessions/{sid}/scope/captures lists a drive's kept captures",
            )
        return rows[0]

    def meta(self, cid: str) -> dict[str, Any]:
        t = db.scope_captures
        return _meta(self._row(cid, *(t.c[k] for k in _META)))

    def get(self, cid: str) -> dict[str, Any]:
        """One kept capture: its metadata, ``trigger`` and ``recording``."""
        row = self._row(cid, db.scope_captures)
        data = json.loads(row["data"])
        return _meta(row) | {"trigger": data["trigger"], "recording": data["recording"]}

    def csv(self, cid: str) -> tuple[bytes, str]:
        """(the capture as the scope's CSV, its file name)."""
        cap = self.get(cid)
        return export.export_csv(to_recording(cap["recording"])), f"{cid}.csv"

    def set_attached(self, cid: str, attached: bool) -> dict[str, Any]:
        """Show the capture in the drive's commissioning reports from now on (or no more)."""
        self._row(cid, db.scope_captures.c.id)
        t = db.scope_captures
        with db.transaction(self.engine) as conn:
            conn.execute(sa.update(t).where(t.c.id == cid).values(attached=int(attached)))
        return self.meta(cid)

    def delete(self, cid: str) -> dict[str, Any]:
        """Delete a kept capture; its metadata as it was (the caller audits it)."""
        meta = self.meta(cid)
        t = db.scope_captures
        with db.transaction(self.engine) as conn:
            conn.execute(sa.delete(t).where(t.c.id == cid))
        return meta

    def attached(self, drive_key: str) -> list[dict[str, Any]]:
        """The drive's captures attached to its reports, oldest first, with their recordings."""
        t = db.scope_captures
        query = (
            sa.select(t.c.id)
            .where(t.c.drive_key == drive_key, t.c.attached != 0)
            .order_by(t.c.created, t.c.id)
            .limit(MAX_LIST)
        )
        return [self.get(r["id"]) for r in db.rows(self.engine, query)]
