"""Tuning results in the store (issue 49, "Plant scale"; docs/tuning.md "Results in the store").

Every tuning job that ends, done, failed or stopped, is one row of ``tuning_results``
(services/db.py, revision 0005): the drive (its ``drive_key``, as services/fleet.py follows a
drive across gateways), the session and gateway it ran on, kind, mode, how it ended, when,
by which user and client, whether its gains were left applied, and the whole TuningResult
as JSON. A row is written once, when the job ends (services/tuning/jobs.py ``_record``, in a
thread), and never changed: an undo or a store after it is in the audit log, not here.

The in-memory result (``GET /sessions/{sid}/tuning/result``) stays the session's last one; the
store is what a restart, another gateway, the commissioning report and the fleet page read.
"""

from __future__ import annotations

import json
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from servodesk.domain.ids import check_id
from servodesk.errors import NotFoundError
from servodesk.services import db
from servodesk.services.outbox import Outbox

#: The metadata of a stored result (the row less its TuningResult).
_META = (
    "id", "drive_key", "session", "gateway", "kind", "mode", "status", "started", "ended",
    "by", "client", "applied",
)  # fmt: skip

#: The most results one history answers.
MAX_HISTORY = 500


def _meta(row: sa.RowMapping) -> dict[str, Any]:
    out = {k: row[k] for k in _META}
    out["applied"] = bool(out["applied"])
    return out


class TuningStore:
    """The ``tuning_results`` table on the store's engine (shared with services/store.py)."""

    def __init__(self, engine: Engine, gateway: str, outbox: Outbox | None = None) -> None:
        self.engine = engine
        #: This gateway's name (the fleet's, services/drift.py): where a tuning ran.
        self.gateway = gateway
        #: Where a result waits while the central store is unreachable (services/outbox.py).
        self.outbox = outbox

    def add(self, record: dict[str, Any]) -> None:
        """Record one ended job (``record``: the metadata of :data:`_META` less ``gateway``,
        and ``result``, the TuningResult). Blocking: call it in a thread."""
        row = {k: record[k] for k in _META if k != "gateway"}
        row |= {
            "gateway": self.gateway,
            "applied": int(bool(record["applied"])),
            "result": json.dumps(record["result"], allow_nan=False, default=str),
        }
        try:
            with db.transaction(self.engine) as conn:
                conn.execute(sa.insert(db.tuning_results).values(row))
        except db.StoreUnavailable as exc:
            if self.outbox is None:
                raise
            # Queued locally and synced when the store answers (services/outbox.py).
            self.outbox.lost(exc)
            self.outbox.add(db.tuning_results, row)

    def _rows(self, statement: sa.Executable) -> list[sa.RowMapping]:
        return db.rows(self.engine, statement)

    def history(self, drive_key: str, limit: int = 100) -> list[dict[str, Any]]:
        """The drive's stored results, newest first, metadata only."""
        t = db.tuning_results
        query = (
            sa.select(*(t.c[k] for k in _META))
            .where(t.c.drive_key == drive_key)
            .order_by(t.c.ended.desc(), t.c.id.desc())
            .limit(max(1, min(limit, MAX_HISTORY)))
        )
        return [_meta(r) for r in self._rows(query)]

    def get(self, rid: str) -> dict[str, Any]:
        """One stored result: its metadata and ``result`` (the TuningResult)."""
        check_id(rid, "id")
        t = db.tuning_results
        rows = self._rows(sa.select(t).where(t.c.id == rid))
        if not rows:
            raise NotFoundError(
                f"no tuning result {rid!r} in the store",
                hint="GET /sessions/{sid}/tuning/results lists a drive's results",
            )
        return _meta(rows[0]) | {"result": json.loads(rows[0]["result"])}

    def latest(self, drive_key: str) -> dict[str, Any] | None:
        """The drive's newest stored result with its TuningResult (None: it has none)."""
        newest = self.history(drive_key, limit=1)
        return self.get(newest[0]["id"]) if newest else None
