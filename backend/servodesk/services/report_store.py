"""The commissioning reports made, in the store (issue 49; docs/report.md).

Each report is one row of ``reports`` (services/db.py, revision 0004): who made it of which
drive and when, the canonical SHA-256 of its data (services/report.py, printed in the
report), the HTML exactly as it was served and, once it was printed, the PDF. A report is
never changed after it was made; only its PDF is added, once (the first print is the one a
later print of the same report returns, so that every copy verifies).
"""

from __future__ import annotations

import contextlib
import hashlib
import time
from collections.abc import Iterator
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine

from servodesk.domain.ids import check_id
from servodesk.errors import NotFoundError
from servodesk.services import db

#: What a report's metadata holds (the row less its bytes).
_META = ("id", "drive_key", "plant_tag", "session", "time", "by", "sha256", "html_sha256")


class ReportStore:
    """The ``reports`` table on the store's engine (shared with services/store.py)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    @contextlib.contextmanager
    def _tx(self) -> Iterator[Connection]:
        with db.transaction(self.engine) as conn:
            yield conn

    def _one(self, rid: str, *columns: sa.ColumnElement[Any]) -> sa.RowMapping:
        check_id(rid, "report")
        r = db.reports
        try:
            with db.read(self.engine) as conn:
                row = conn.execute(sa.select(*columns).where(r.c.id == rid)).mappings().first()
        except sa.exc.SQLAlchemyError as exc:
            raise db.store_error(exc) from exc
        if row is None:
            raise NotFoundError(
                f"no report {rid!r} in the store",
                hint="a report's id is printed in its footer; POST /sessions/{sid}/report "
                "makes one",
            )
        return row

    def add(self, meta: dict[str, Any], html: bytes) -> dict[str, Any]:
        """Record a report just made (``meta``: id, drive_key, plant_tag, session, time, by,
        sha256); its metadata."""
        row = {k: meta[k] for k in _META if k != "html_sha256"}
        row |= {
            "created": time.time(),
            "html": html,
            "html_sha256": hashlib.sha256(html).hexdigest(),
        }
        with self._tx() as conn:
            conn.execute(sa.insert(db.reports).values(row))
        return {k: row[k] for k in _META} | {"pdf_sha256": None}

    def get(self, rid: str) -> dict[str, Any]:
        """A report's metadata; NotFoundError when the store has none of that id."""
        r = db.reports
        row = self._one(rid, *(r.c[k] for k in _META), r.c.pdf_sha256)
        return dict(row)

    def html(self, rid: str) -> bytes:
        return bytes(self._one(rid, db.reports.c.html)["html"])

    def pdf(self, rid: str) -> bytes | None:
        """The PDF printed of the report (None: not printed yet)."""
        data = self._one(rid, db.reports.c.pdf)["pdf"]
        return bytes(data) if data is not None else None

    def set_pdf(self, rid: str, pdf: bytes) -> bytes:
        """Keep ``pdf`` as the report's print unless one was kept meanwhile (two prints at
        once: the first wins); the PDF that is kept."""
        r = db.reports
        with self._tx() as conn:
            conn.execute(
                sa.update(r)
                .where(r.c.id == rid, r.c.pdf.is_(None))
                .values(pdf=pdf, pdf_sha256=hashlib.sha256(pdf).hexdigest())
            )
        kept = self.pdf(rid)
        assert kept is not None  # Set above, or by the other print.
        return kept

    def by_file_hash(self, sha256: str) -> dict[str, Any] | None:
        """The report whose HTML or PDF has exactly this SHA-256 (None: none has)."""
        r = db.reports
        query = sa.select(*(r.c[k] for k in _META), r.c.pdf_sha256).where(
            sa.or_(r.c.html_sha256 == sha256, r.c.pdf_sha256 == sha256)
        )
        try:
            with db.read(self.engine) as conn:
                row = conn.execute(query).mappings().first()
        except sa.exc.SQLAlchemyError as exc:
            raise db.store_error(exc) from exc
        return dict(row) if row is not None else None
