"""The fleet: every drive the store knows, across gateways (issue 49, second slice).

A drive is identified across gateways by its ``drive_key`` (services/backup.py: vendor,
product and serial from 1018h, ``VVVVVVVV-PPPPPPPP-serial``; a drive without them is
``profile@interface:channel:node``, i.e. where it sits) or by the plant tag the user gave it
(``L2.Press.X``). Its history follows the key: a drive moved to another line keeps its
backups, approval and drift results; a replacement drive is a new key, to which the old
drive's tag can be moved (clear it on the old one first: tags are unique).

``fleet_drives`` (services/db.py, revision 0003) holds one row per drive, so that the fleet
page is one indexed query however many backups there are. Its backup columns are kept from
``backups`` by :meth:`FleetStore.sync`, which every fleet query runs first: it reads the
backups made since this process last looked (at first: since the newest backup the table
holds; an index on ``backups.created``), less
:data:`SYNC_MARGIN_S`, so that a backup another gateway stamped earlier but committed later
is still seen, and upserts only where the backup is newer than the row's (idempotent: two
gateways syncing at once write the same). The store code (services/store.py) stays unaware
of the fleet.

Gateways: every ``servodesk serve`` registers itself (name, URL, buses) on start and says it
is alive every heartbeat (:data:`HEARTBEAT_S`), also noting the drives it has connected
(gateway, session id: the fleet page's link to the drive on its gateway).
"""

from __future__ import annotations

import contextlib
import json
import re
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, Literal

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine

from servodesk.errors import ConflictError, NotFoundError, ValidationError
from servodesk.services import db

#: How often a gateway says it is alive (and notes its connected drives), s.
HEARTBEAT_S = 30.0
#: A gateway not seen for this many heartbeats is shown as gone.
ALIVE_HEARTBEATS = 3
#: How far before its newest known backup the sync reads again, s: a backup is stamped
#: (``created``) just before its transaction commits, on its gateway's clock. Ten minutes
#: covers a slow commit and a clock a few minutes off (gateways should run NTP).
SYNC_MARGIN_S = 600.0
#: The most drives one fleet page answers.
MAX_PAGE = 500

#: A plant tag: letters, digits and ``. _ -``, starting with a letter or digit (``L2.Press.X``).
TAG_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")

DriftState = Literal["unknown", "in_step", "drifted"]
DRIFT_STATES: tuple[DriftState, ...] = ("unknown", "in_step", "drifted")


def now_iso(t: float | None = None) -> str:
    stamp = datetime.fromtimestamp(time.time() if t is None else t, UTC)
    return stamp.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def check_tag(tag: str) -> str:
    """``tag`` if it is a valid plant tag, else a ValidationError that says what is allowed."""
    if not TAG_RE.match(tag):
        raise ValidationError(
            f"{tag!r} is not a plant tag",
            field="tag",
            hint="1-64 letters, digits, '.', '_' or '-', starting with a letter or digit "
            "(e.g. L2.Press.X)",
        )
    return tag


def serial_of(drive_key: str, identity: dict[str, Any] | None) -> str | None:
    """The serial number of a drive: 1018h's, from the identity a backup recorded."""
    serial = (identity or {}).get("serial")
    if serial is not None:
        return str(serial)
    parts = drive_key.split("-", 2)
    if len(parts) == 3 and all(len(p) == 8 for p in parts[:2]) and "@" not in drive_key:
        return parts[2]
    return None


@dataclass(frozen=True)
class SeenDrive:
    """A drive connected on a gateway now (what the heartbeat notes)."""

    drive_key: str
    profile_id: str
    firmware: str | None
    serial: str | None
    session: str
    alarms: int | None


def _upsert(conn: Connection, table: sa.Table, key: str) -> Any:
    """INSERT ... ON CONFLICT (key) on either engine; the caller adds DO UPDATE."""
    if db.is_postgres(conn):
        from sqlalchemy.dialects.postgresql import insert as pg_insert

        return pg_insert(table), key
    from sqlalchemy.dialects.sqlite import insert as sqlite_insert

    return sqlite_insert(table), key


def _like(text: str) -> str:
    """``text`` as a LIKE pattern matching it anywhere, its wildcards taken literally."""
    escaped = text.lower().replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")
    return f"%{escaped}%"


def _last_tunings(conn: Connection, keys: list[str]) -> dict[str, dict[str, Any]]:
    """The newest stored tuning of each of ``keys`` (time, status, mode; services/
    tuning_store.py): one query on the ``tuning_results_drive`` index for a page of drives."""
    if not keys:
        return {}
    t = db.tuning_results
    newest = (
        sa.select(t.c.drive_key, sa.func.max(t.c.ended).label("ended"))
        .where(t.c.drive_key.in_(keys))
        .group_by(t.c.drive_key)
        .subquery()
    )
    query = (
        sa.select(t.c.drive_key, t.c.id, t.c.ended, t.c.status, t.c.mode)
        .join(newest, sa.and_(t.c.drive_key == newest.c.drive_key, t.c.ended == newest.c.ended))
        .order_by(t.c.id)
    )
    out: dict[str, dict[str, Any]] = {}
    for r in conn.execute(query).mappings():
        # Two ending at the same instant: the larger id (ids sort by time) is the newer.
        out[str(r["drive_key"])] = {
            "id": r["id"],
            "time": now_iso(r["ended"]),
            "status": r["status"],
            "mode": r["mode"],
        }
    return out


class FleetStore:
    """The fleet's tables on the store's engine (shared with services/store.py)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._synced_to: float | None = None
        #: Backups inside the margin that were applied (id -> created): not written again.
        self._applied: dict[str, float] = {}
        self._sync_lock = threading.Lock()

    @contextlib.contextmanager
    def _tx(self) -> Iterator[Connection]:
        try:
            with db.write(self.engine) as conn:
                yield conn
        except sa.exc.IntegrityError:
            raise
        except sa.exc.SQLAlchemyError as exc:
            raise db.store_error(exc) from exc

    def _rows(self, statement: sa.Executable) -> list[sa.RowMapping]:
        return db.rows(self.engine, statement)

    # Gateways ------------------------------------------------------------------------------

    def register_gateway(
        self, name: str, url: str, buses: Sequence[str], version: str, *, started: bool = False
    ) -> None:
        """Insert or refresh this gateway's row (``started``: it has just started)."""
        now = time.time()
        g = db.gateways
        values = {
            "name": name,
            "url": url,
            "buses": json.dumps(sorted(set(buses))),
            "version": version,
            "started": now,
            "last_seen": now,
        }
        with self._tx() as conn:
            stmt, key = _upsert(conn, g, "name")
            update = {"url": url, "buses": values["buses"], "version": version, "last_seen": now}
            if started:
                update["started"] = now
            conn.execute(
                stmt.values(values).on_conflict_do_update(index_elements=[key], set_=update)
            )

    def gateways(self) -> list[dict[str, Any]]:
        g = db.gateways
        now = time.time()
        return [
            {
                "name": r["name"],
                "url": r["url"],
                "buses": json.loads(r["buses"] or "[]"),
                "version": r["version"],
                "started": now_iso(r["started"]),
                "last_seen": now_iso(r["last_seen"]),
                "alive": now - float(r["last_seen"]) < HEARTBEAT_S * ALIVE_HEARTBEATS,
            }
            for r in self._rows(sa.select(g).order_by(g.c.name))
        ]

    def see(self, gateway: str, drives: Sequence[SeenDrive]) -> None:
        """Note the drives ``gateway`` has connected now (a row for a new one)."""
        if not drives:
            return
        f = db.fleet_drives
        now = time.time()
        with self._tx() as conn:
            for d in drives:
                stmt, key = _upsert(conn, f, "drive_key")
                values = {
                    "drive_key": d.drive_key,
                    "serial": d.serial,
                    "profile_id": d.profile_id,
                    "firmware": d.firmware,
                    "gateway": gateway,
                    "session": d.session,
                    "seen": now,
                    "alarms": d.alarms,
                }
                update = {k: v for k, v in values.items() if k != "drive_key"}
                if d.serial is None:
                    del update["serial"]
                conn.execute(
                    stmt.values(values).on_conflict_do_update(index_elements=[key], set_=update)
                )

    # Drives from the backups -----------------------------------------------------------------

    def sync(self) -> int:
        """Bring ``fleet_drives`` up to the backups made since the last sync; the number of
        drives whose last backup changed."""
        with self._sync_lock:
            if self._synced_to is None:
                # This process's first look: the table is as far as every gateway's syncs
                # took it (the newest backup it holds), so only the rest is read; a new
                # table (the first start after revision 0003) reads every backup once.
                f = db.fleet_drives
                rows = self._rows(sa.select(sa.func.max(f.c.last_backup_created).label("top")))
                top = rows[0]["top"] if rows else None
                self._synced_to = float(top) if top is not None else None
            since = None if self._synced_to is None else self._synced_to - SYNC_MARGIN_S
            b = db.backups
            query = sa.select(
                b.c.id, b.c.time, b.c.created, b.c.drive_key, b.c.profile_id, b.c.firmware,
                b.c.identity,
            ).order_by(b.c.created)  # fmt: skip
            if since is not None:
                query = query.where(b.c.created >= since)
            rows = self._rows(query)
            newest: dict[str, sa.RowMapping] = {}
            fresh: dict[str, float] = {}
            top = self._synced_to or 0.0
            for r in rows:
                top = max(top, float(r["created"]))
                if r["id"] in self._applied:
                    continue  # Read again inside the margin; applied already.
                fresh[str(r["id"])] = float(r["created"])
                if str(r["drive_key"]).startswith("dcf:"):
                    continue  # An imported DCF file, not a drive (backup.py names it so).
                seen = newest.get(r["drive_key"])
                if seen is None or (r["created"], r["id"]) >= (seen["created"], seen["id"]):
                    newest[r["drive_key"]] = r
            if newest:
                self._apply_backups(list(newest.values()))
            self._synced_to = top
            self._applied.update(fresh)
            # Only the ids the next sync's margin can read again are kept.
            horizon = top - SYNC_MARGIN_S
            self._applied = {i: c for i, c in self._applied.items() if c >= horizon}
            return len(newest)

    def _apply_backups(self, rows: list[sa.RowMapping]) -> None:
        f = db.fleet_drives
        batch = 500
        with self._tx() as conn:
            for start in range(0, len(rows), batch):
                values = []
                for r in rows[start : start + batch]:
                    try:
                        identity = json.loads(r["identity"])
                    except ValueError:
                        identity = {}
                    values.append(
                        {
                            "drive_key": r["drive_key"],
                            "serial": serial_of(r["drive_key"], identity),
                            "profile_id": r["profile_id"],
                            "firmware": r["firmware"],
                            "last_backup": r["id"],
                            "last_backup_time": r["time"],
                            "last_backup_created": r["created"],
                        }
                    )
                stmt, key = _upsert(conn, f, "drive_key")
                ex = stmt.excluded
                newer = sa.or_(
                    f.c.last_backup_created.is_(None),
                    f.c.last_backup_created < ex.last_backup_created,
                    sa.and_(
                        f.c.last_backup_created == ex.last_backup_created,
                        f.c.last_backup < ex.last_backup,
                    ),
                )
                conn.execute(
                    stmt.values(values).on_conflict_do_update(
                        index_elements=[key],
                        set_={
                            "last_backup": ex.last_backup,
                            "last_backup_time": ex.last_backup_time,
                            "last_backup_created": ex.last_backup_created,
                            "profile_id": ex.profile_id,
                            "firmware": ex.firmware,
                            "serial": sa.func.coalesce(ex.serial, f.c.serial),
                        },
                        where=newer,
                    )
                )

    # Queries ---------------------------------------------------------------------------------

    def fleet(
        self,
        *,
        q: str = "",
        drift: DriftState | None = None,
        gateway: str | None = None,
        offset: int = 0,
        limit: int = 100,
    ) -> dict[str, Any]:
        """One page of drives (tagged first, by tag, then by key) and how many match."""
        self.sync()
        f, g = db.fleet_drives, db.gateways
        where: list[Any] = []
        if q:
            pattern = _like(q)
            where.append(
                sa.or_(
                    *(
                        sa.func.lower(c).like(pattern, escape="\\")
                        for c in (f.c.plant_tag, f.c.drive_key, f.c.serial, f.c.profile_id)
                    )
                )
            )
        if drift is not None:
            where.append(f.c.drift_state == drift)
        if gateway:
            where.append(f.c.gateway == gateway)
        limit = max(1, min(limit, MAX_PAGE))
        page = (
            sa.select(f, g.c.url.label("gateway_url"))
            .select_from(f.outerjoin(g, f.c.gateway == g.c.name))
            .where(*where)
            .order_by(f.c.plant_tag.is_(None), f.c.plant_tag, f.c.drive_key)
            .offset(max(0, offset))
            .limit(limit)
        )
        count = sa.select(sa.func.count()).select_from(f).where(*where)
        try:
            with db.read(self.engine) as conn:
                total = int(conn.execute(count).scalar_one())
                rows = conn.execute(page).mappings().all()
                tunings = _last_tunings(conn, [str(r["drive_key"]) for r in rows])
        except sa.exc.SQLAlchemyError as exc:
            raise db.store_error(exc) from exc
        return {
            "total": total,
            "offset": max(0, offset),
            "limit": limit,
            "drives": [self._drive(r, tunings.get(str(r["drive_key"]))) for r in rows],
        }

    @staticmethod
    def _drive(r: sa.RowMapping, last_tuning: dict[str, Any] | None = None) -> dict[str, Any]:
        url, session = r.get("gateway_url"), r["session"]
        link = None
        if url:
            link = f"{url}/#/overview/{session}" if session else f"{url}/#/axes"
        approved = None
        if r["approved_backup"]:
            approved = {
                "backup": r["approved_backup"],
                "by": r["approved_by"],
                "at": r["approved_at"],
                "reason": r["approved_reason"],
            }
        return {
            "drive_key": r["drive_key"],
            "plant_tag": r["plant_tag"],
            "serial": r["serial"],
            "profile_id": r["profile_id"],
            "firmware": r["firmware"],
            "gateway": r["gateway"],
            "session": session,
            "link": link,
            "seen": now_iso(r["seen"]) if r["seen"] is not None else None,
            "last_backup": r["last_backup"],
            "last_backup_time": r["last_backup_time"],
            "approved": approved,
            "drift": {
                "state": r["drift_state"],
                "count": r["drift_count"],
                "time": r["drift_time"],
            },
            "alarms": r["alarms"],
            "last_tuning": last_tuning,
        }

    def resolve(self, drive: str) -> str:
        """The drive_key of ``drive`` (a drive_key or a plant tag); NotFoundError else."""
        self.sync()
        f = db.fleet_drives
        rows = self._rows(
            sa.select(f.c.drive_key).where(sa.or_(f.c.drive_key == drive, f.c.plant_tag == drive))
        )
        if not rows:
            raise NotFoundError(
                f"no drive {drive!r} in the fleet",
                hint="name a drive by its drive_key (vendor-product-serial) or plant tag, as "
                "GET /fleet lists them; a drive joins the fleet with its first backup or "
                "when a gateway connects it",
            )
        # A drive's tag may spell another drive's key: the exact key wins.
        keys = [str(r["drive_key"]) for r in rows]
        return drive if drive in keys else keys[0]

    def drive(self, drive: str) -> dict[str, Any]:
        key = self.resolve(drive)
        f, g = db.fleet_drives, db.gateways
        query = (
            sa.select(f, g.c.url.label("gateway_url"))
            .select_from(f.outerjoin(g, f.c.gateway == g.c.name))
            .where(f.c.drive_key == key)
        )
        try:
            with db.read(self.engine) as conn:
                row = conn.execute(query).mappings().one()
                tunings = _last_tunings(conn, [key])
        except sa.exc.SQLAlchemyError as exc:
            raise db.store_error(exc) from exc
        return self._drive(row, tunings.get(key))

    # Changes ---------------------------------------------------------------------------------

    def set_tag(self, drive: str, tag: str | None) -> dict[str, Any]:
        """Give ``drive`` the plant tag ``tag`` (None or empty: clear it)."""
        key = self.resolve(drive)
        tag = check_tag(tag) if tag else None
        f = db.fleet_drives
        try:
            with self._tx() as conn:
                if tag is not None:
                    holder = conn.execute(
                        sa.select(f.c.drive_key).where(f.c.plant_tag == tag, f.c.drive_key != key)
                    ).scalar()
                    if holder is not None:
                        raise ConflictError(
                            f"the plant tag {tag!r} is already drive {holder}'s",
                            hint="clear it on that drive first (a replaced drive), or choose "
                            "another tag",
                        )
                conn.execute(sa.update(f).where(f.c.drive_key == key).values(plant_tag=tag))
        except sa.exc.IntegrityError:
            # Another gateway gave the tag away between the check and the update.
            raise ConflictError(
                f"the plant tag {tag!r} is already another drive's", hint="choose another tag"
            ) from None
        return self.drive(key)

    def approve(
        self, drive: str, backup: dict[str, Any], *, by: str, reason: str
    ) -> dict[str, Any]:
        """Make ``backup`` (a BackupInfo) the approved backup of ``drive``. The last drift
        state was against another backup: it is unknown again until the next check."""
        key = self.resolve(drive)
        reason = reason.strip()
        if not reason:
            raise ValidationError(
                "an approval needs a reason",
                field="reason",
                hint="say why this backup is the drive's reference (e.g. 'commissioned, "
                "signed off by QA')",
            )
        row = self.drive(key)
        if backup["drive_key"] != key and backup["profile_id"] != row["profile_id"]:
            raise ConflictError(
                f"backup {backup['id']} is of a {backup['profile_id']} drive, "
                f"drive {key} is a {row['profile_id']}",
                hint="approve a backup of this drive, or of a drive of the same family",
            )
        f = db.fleet_drives
        with self._tx() as conn:
            conn.execute(
                sa.update(f)
                .where(f.c.drive_key == key)
                .values(
                    approved_backup=backup["id"],
                    approved_by=by,
                    approved_at=now_iso(),
                    approved_reason=reason,
                    drift_state="unknown",
                    drift_count=None,
                    drift_time=None,
                )
            )
        return self.drive(key)

    def clear_approval(self, drive: str) -> dict[str, Any]:
        """``drive`` has no approved backup any more (the reference was wrong, the drive was
        rebuilt): its drift state is unknown until a backup is approved again. The caller
        audits it with the reason. ConflictError when it has none to clear."""
        key = self.resolve(drive)
        f = db.fleet_drives
        with self._tx() as conn:
            cleared = conn.execute(
                sa.update(f)
                .where(f.c.drive_key == key, f.c.approved_backup.is_not(None))
                .values(
                    approved_backup=None,
                    approved_by=None,
                    approved_at=None,
                    approved_reason=None,
                    drift_state="unknown",
                    drift_count=None,
                    drift_time=None,
                )
            ).rowcount
        if not cleared:
            raise ConflictError(
                f"drive {key} has no approved backup to clear",
                hint="GET /fleet shows each drive's approved backup",
            )
        return self.drive(key)

    def approved_backup(self, drive_key: str) -> str | None:
        f = db.fleet_drives
        rows = self._rows(sa.select(f.c.approved_backup).where(f.c.drive_key == drive_key))
        return str(rows[0]["approved_backup"]) if rows and rows[0]["approved_backup"] else None

    # Drift results ---------------------------------------------------------------------------

    def add_drift(self, result: dict[str, Any]) -> int:
        """Record one drift check and set the drive's drift state; the result's id."""
        d, f = db.drift_results, db.fleet_drives
        with self._tx() as conn:
            rid = conn.execute(
                sa.insert(d)
                .values(
                    drive_key=result["drive_key"],
                    time=result["time"],
                    created=time.time(),
                    gateway=result["gateway"],
                    session=result["session"],
                    backup=result["backup"],
                    state=result["state"],
                    count=result["count"],
                    differences=json.dumps(result["differences"]),
                    webhook=result.get("webhook"),
                )
                .returning(d.c.id)
            ).scalar_one()
            # Only while the backup checked is still the approved one (an approval between
            # the read and now made this result stale).
            conn.execute(
                sa.update(f)
                .where(
                    f.c.drive_key == result["drive_key"],
                    f.c.approved_backup == result["backup"],
                )
                .values(
                    drift_state=result["state"],
                    drift_count=result["count"],
                    drift_time=result["time"],
                )
            )
        return int(rid)

    def set_webhook(self, rid: int, outcome: str) -> None:
        d = db.drift_results
        with self._tx() as conn:
            conn.execute(sa.update(d).where(d.c.id == rid).values(webhook=outcome))

    def drift_results(self, drive: str | None = None, limit: int = 100) -> list[dict[str, Any]]:
        d, f = db.drift_results, db.fleet_drives
        query = sa.select(d, f.c.plant_tag).select_from(
            d.outerjoin(f, d.c.drive_key == f.c.drive_key)
        )
        if drive:
            query = query.where(d.c.drive_key == self.resolve(drive))
        query = query.order_by(d.c.id.desc()).limit(max(1, min(limit, 1000)))
        return [
            {
                "id": r["id"],
                "drive_key": r["drive_key"],
                "plant_tag": r["plant_tag"],
                "time": r["time"],
                "gateway": r["gateway"],
                "session": r["session"],
                "backup": r["backup"],
                "state": r["state"],
                "count": r["count"],
                "differences": json.loads(r["differences"]),
                "webhook": r["webhook"],
            }
            for r in self._rows(query)
        ]
