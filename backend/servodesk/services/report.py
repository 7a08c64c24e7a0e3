"""The commissioning report of a drive (issue 49, "Commissioning report"; docs/report.md).

:func:`assemble` gathers what servodesk knows of a connected drive into one plain dict (the
report's *data*): its identity and firmware, plant tag and approval (services/fleet.py), the
parameters that differ from the profile's defaults and from the approved backup (the compare
of services/backup.py, as a drift check does), the PDO layout (services/pdo.py), the limits
(services/motion/limits.py), the homing settings (CiA 402-2 §6.8: 6098h, 6099h, 609Ah,
607Ch), the last tuning result of this server, the scope captures the user attached
(services/capture_store.py: every sample, so the content hash covers them), the alarms
(services/alarms.py) and the audit extract of the drive. Nothing here knows a device: every
object comes from the profile.

:func:`content_hash` is the SHA-256 of the data's canonical JSON (keys sorted, no spaces,
UTF-8, non-finite numbers as null): it is printed in the report with the report's id and
recorded in the store, so a printed copy can be checked later (``servodesk report verify``).
:class:`ReportService` makes a report: assembles, renders (services/report_html.py), records
(services/report_store.py).
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import json
import math
import secrets
from collections.abc import Awaitable, Callable
from dataclasses import asdict
from datetime import UTC, datetime
from typing import Any

from servodesk import __version__
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    HOME_OFFSET,
    HOMING_ACC,
    HOMING_METHOD,
    HOMING_SPEED_SWITCH,
    HOMING_SPEED_ZERO,
)
from servodesk.errors import LinkError, NotFoundError, ServodeskError
from servodesk.services import alarms, homing, pdo
from servodesk.services.audit import AuditLog
from servodesk.services.backup import BackupService, bus_of, drive_key, firmware
from servodesk.services.fleet import FleetStore, now_iso
from servodesk.services.motion.limits import read_limits
from servodesk.services.report_store import ReportStore
from servodesk.services.session import Session

#: The report data's layout; a reader of an old report's data knows which one it has.
FORMAT = "servodesk.report/1"
#: The most audit records a report's extract holds (newest first).
AUDIT_RECORDS = 200
#: The homing settings a report shows, where the profile has the object (CiA 402-2 §6.8).
HOMING_OBJECTS: tuple[tuple[str, ObjectAddress], ...] = (
    ("method", HOMING_METHOD),
    ("speed_switch", HOMING_SPEED_SWITCH),
    ("speed_zero", HOMING_SPEED_ZERO),
    ("acceleration", HOMING_ACC),
    ("home_offset", HOME_OFFSET),
)
#: What a report keeps of a compare difference: the reference side ("a") and the drive's.
_KEEP = ("address", "name", "group", "unit", "raw_unit", "kind")


def new_report_id() -> str:
    """Sortable, readable and a safe id (domain/ids.py): ``report-20261207t142600z-a1b2c3``."""
    stamp = datetime.now(UTC).strftime("%Y%m%dt%H%M%Sz")
    return f"report-{stamp}-{secrets.token_hex(3)}"


def plain(value: Any) -> Any:
    """``value`` as JSON's types only: tuples as lists, non-finite floats as None (JSON has no
    NaN), keys as text, private keys (``_loop``) and other objects left out or as text."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items() if not str(k).startswith("_")}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, bool | int | str):
        return value
    tolist = getattr(value, "tolist", None)  # numpy arrays and scalars
    if callable(tolist):
        return plain(tolist())
    return str(value)


def canonical(data: dict[str, Any]) -> bytes:
    """The canonical JSON of report data: sorted keys, no whitespace, UTF-8 (RFC 8785's
    ordering and separators; numbers as Python writes them)."""
    return json.dumps(
        plain(data), sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False
    ).encode("utf-8")


def content_hash(data: dict[str, Any]) -> str:
    """The SHA-256 (hex) a report prints and the store records."""
    return hashlib.sha256(canonical(data)).hexdigest()


def _difference(d: dict[str, Any]) -> dict[str, Any]:
    out = {k: d.get(k) for k in _KEEP}
    for side, name in (("a", "reference"), ("b", "drive")):
        out[f"{name}_value"] = d.get(f"{side}_value")
        out[f"{name}_raw_hex"] = d.get(f"{side}_raw_hex")
        out[f"{name}_engineering"] = d.get(f"{side}_engineering")
    return out


def _object(address: ObjectAddress, value: Any) -> dict[str, Any]:
    """A value read from the drive with its raw and engineering views and units."""
    return {
        "address": str(address),
        "name": value.name,
        "value": value.value,
        "raw_hex": value.raw_hex,
        "raw_unit": value.raw_unit,
        "engineering": value.engineering,
        "unit": value.unit,
        "text": value.value_text,
    }


async def _homing(session: Session) -> dict[str, Any]:
    """The homing settings the drive holds now, and the method's description."""
    profile = session.profile
    settings: list[dict[str, Any]] = []
    method: int | None = None
    for key, address in HOMING_OBJECTS:
        spec = profile.spec(address)
        if spec is None or not spec.access.readable:
            continue
        try:
            value = await session.read_object(address)
        except ServodeskError as exc:
            settings.append({"address": str(address), "name": spec.name, "error": exc.message})
            continue
        settings.append({"key": key, **_object(address, value)})
        if key == "method" and isinstance(value.value, int):
            method = value.value
    described = next((m for m in homing.methods(profile) if m.get("method") == method), None)
    return {"method": method, "method_description": described, "settings": settings}


def _pdo(view: dict[str, Any]) -> dict[str, Any]:
    """The layout a PLC programmer needs: each PDO's COB-ID, transmission and entries."""
    pdos = []
    for p in view["pdos"]:
        pdos.append(
            {
                k: p.get(k)
                for k in (
                    "direction",
                    "number",
                    "name",
                    "cob_id_hex",
                    "enabled",
                    "active",
                    "transmission_type",
                    "transmission_text",
                    "inhibit_time_ms",
                    "event_timer",
                    "bits",
                )
            }
            | {
                "entries": [
                    {
                        k: e.get(k)
                        for k in ("address", "name", "bits", "offset_byte", "unit", "padding")
                    }
                    for e in p["entries"]
                ]
            }
        )
    return {"kind": view.get("kind"), "telegram": view.get("telegram"), "pdos": pdos}


def _tuning(result: dict[str, Any] | None) -> dict[str, Any] | None:
    """The last tuning's outcome: gains before/after, margins, Bode, steps before/after."""
    if result is None:
        return None
    keep = (
        "kind",
        "status",
        "mode",
        "error",
        "margins",
        "gains",
        "identified",
        "bode",
        "step",
        "notes",
        "applied",
        "stored",
        "loop_rate_hz",
        "counts_per_rev",
    )
    out: dict[str, Any] = plain({k: result[k] for k in keep if k in result})
    return out


def _capture(c: dict[str, Any]) -> dict[str, Any]:
    """A kept scope capture as the report holds it: who kept it, when and why, its trigger,
    and each channel with its units, scale, period and every sample (raw, as the scope had
    them; engineering = raw x scale)."""
    rec = c["recording"]
    periods = {ch["id"]: ch.get("period_s") for ch in c.get("channels") or []}
    keep = ("id", "name", "unit", "raw_unit", "scale", "address", "session", "source", "t", "v")
    return {
        **{k: c.get(k) for k in ("id", "title", "note", "time", "by", "gateway", "window")},
        "sha256": c.get("sha256"),
        "trigger": c.get("trigger"),
        "t_ref": rec.get("t_ref"),
        "trigger_time": rec.get("trigger_time"),
        "channels": [
            {k: ch.get(k) for k in keep} | {"period_s": periods.get(ch.get("id"))}
            for ch in rec.get("channels") or []
        ],
    }


async def _section(what: str, job: Awaitable[dict[str, Any]]) -> dict[str, Any]:
    """One section of the report; a drive that refuses a part of it leaves that part's error
    in the report instead of failing the whole report (a lost link still fails it)."""
    try:
        return await job
    except LinkError:
        raise
    except ServodeskError as exc:
        return {"error": exc.message, "hint": exc.hint, "section": what}


class ReportService:
    """Makes commissioning reports of connected drives and records them in the store."""

    def __init__(
        self,
        reports: ReportStore,
        backups: BackupService,
        fleet: FleetStore,
        audit: AuditLog,
        tuning_result: Callable[[str], dict[str, Any]] | None = None,
        stored_tuning: Callable[[str], dict[str, Any] | None] | None = None,
        captures: Callable[[str], list[dict[str, Any]]] | None = None,
    ) -> None:
        self.reports = reports
        self.backups = backups
        self.fleet = fleet
        #: The hash-chained audit log (services/audit.py): its ``query`` gives the extract.
        self.audit = audit
        #: ``sid -> TuningResult`` of the last tuning on this server (raises NotFoundError).
        self.tuning_result = tuning_result
        #: ``drive_key -> `` the drive's newest tuning in the store (services/tuning_store.py
        #: ``TuningStore.latest``; blocking), for a session with none in memory (a restart).
        self.stored_tuning = stored_tuning
        #: ``drive_key -> `` the kept scope captures attached to the drive's reports
        #: (services/capture_store.py ``CaptureStore.attached``; blocking).
        self.captures = captures

    async def assemble(self, session: Session, *, rid: str, by: str) -> dict[str, Any]:
        """The report data of ``session``'s drive (reads the drive: every parameter)."""
        key = drive_key(session)
        profile = session.profile
        fleet_row: dict[str, Any] | None = None
        with contextlib.suppress(NotFoundError):
            fleet_row = await asyncio.to_thread(self.fleet.drive, key)
        drive = {
            "drive_key": key,
            "plant_tag": fleet_row["plant_tag"] if fleet_row else None,
            "session": session.id,
            "profile_id": profile.id,
            "profile_name": profile.name,
            "profile_version": profile.version,
            "fieldbus": profile.fieldbus,
            "identity": asdict(session.identity),
            "firmware": firmware(session),
            "bus": bus_of(session),
            "simulated": session.simulated,
            "approved": fleet_row["approved"] if fleet_row else None,
            "drift": fleet_row["drift"] if fleet_row else None,
        }
        ps = await self.backups.read_set(session, operation="report")
        defaults = self.backups.defaults(profile.id, session.link.params.node_id)
        vs_defaults = self.backups.compare(("profile defaults", defaults), ("drive", ps))
        approved = (fleet_row or {}).get("approved") or {}
        vs_approved: dict[str, Any] | None = None
        if approved.get("backup"):
            bid = approved["backup"]
            try:
                golden = await asyncio.to_thread(self.backups.load, bid)
                cmp = self.backups.compare((f"approved {bid}", golden), ("drive", ps))
                vs_approved = {
                    "backup": bid,
                    "differences": [_difference(d) for d in cmp["differences"]],
                    "same": cmp["same"],
                }
            except ServodeskError as exc:
                vs_approved = {"backup": bid, "error": exc.message, "hint": exc.hint}
        parameters = {
            "read": len(ps.entries),
            "unreadable": [asdict(u) | {"address": str(u.address)} for u in ps.unreadable],
            "vs_defaults": {
                "differences": [_difference(d) for d in vs_defaults["differences"]],
                "same": vs_defaults["same"],
            },
            "vs_approved": vs_approved,
        }
        tuning: dict[str, Any] | None = None
        if self.tuning_result is not None:
            with contextlib.suppress(NotFoundError):
                tuning = _tuning(self.tuning_result(session.id))
        if tuning is None and self.stored_tuning is not None:
            stored = await asyncio.to_thread(self.stored_tuning, key)
            if stored is not None:
                tuning = _tuning(stored["result"])
                assert tuning is not None
                # Which run it is: the report says it is one from the store, and when.
                tuning["record"] = {
                    "id": stored["id"],
                    "ended": now_iso(stored["ended"]),
                    "gateway": stored["gateway"],
                    "session": stored["session"],
                }
        limits = await _section("limits", self._limits(session))
        audit = await asyncio.to_thread(self._audit, session.id, key)
        captures: list[dict[str, Any]] = []
        if self.captures is not None:
            captures = [_capture(c) for c in await asyncio.to_thread(self.captures, key)]
        data: dict[str, Any] = plain(
            {
                "format": FORMAT,
                "report": {
                    "id": rid,
                    "generated_at": now_iso(),
                    "generated_by": by,
                    "tool": f"servodesk {__version__}",
                },
                "drive": drive,
                "parameters": parameters,
                "pdo": await _section("pdo", self._pdo(session)),
                "limits": limits,
                "homing": await _section("homing", _homing(session)),
                "tuning": tuning,
                "captures": captures,
                "alarms": await _section("alarms", alarms.alarms(session)),
                "audit": audit,
            }
        )
        return data

    @staticmethod
    async def _limits(session: Session) -> dict[str, Any]:
        return (await read_limits(session)).as_dict()

    @staticmethod
    async def _pdo(session: Session) -> dict[str, Any]:
        return _pdo(await pdo.view(session))

    def _audit(self, sid: str, key: str) -> list[dict[str, Any]]:
        """The audit log's records of this drive: those of its session, less those whose
        details name another drive (a session id is reused when another drive takes the node
        later)."""
        records = self.audit.query(drive=sid, limit=AUDIT_RECORDS)
        out = []
        for r in records:
            details = r.get("details") or {}
            other = details.get("drive_key") if isinstance(details, dict) else None
            if other is not None and other != key:
                continue
            out.append({k: r.get(k) for k in ("seq", "time", "user", "event", "result", "message")})
        return out

    async def make(self, session: Session, *, by: str) -> dict[str, Any]:
        """Assemble, render and record a report of ``session``'s drive; its metadata."""
        # Here, not at the top: report_html takes canonical() from this module.
        from servodesk.services.report_html import render

        rid = new_report_id()
        data = await self.assemble(session, rid=rid, by=by)
        digest = content_hash(data)
        html = render(data, digest).encode("utf-8")
        meta = {
            "id": rid,
            "drive_key": data["drive"]["drive_key"],
            "plant_tag": data["drive"]["plant_tag"],
            "session": session.id,
            "time": data["report"]["generated_at"],
            "by": by,
            "sha256": digest,
        }
        return await asyncio.to_thread(self.reports.add, meta, html)
