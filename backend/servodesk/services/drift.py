"""Drift detection: a connected drive against its approved backup, on demand and on a
schedule (issue 49, second slice; docs/deployment.md, "Drift").

A check reads every configurable parameter of the drive (the backup's read,
``BackupService.read_set``), opens the approved backup and compares the two with the compare
of POST /compare (``BackupService.compare``: the same differences, raw and engineering
values), then records the result in the store (``drift_results``) and the drive's drift
state in ``fleet_drives``. A drive with differences is *drifted*; the webhook
(``SERVODESK_DRIFT_WEBHOOK``) is then POSTed a JSON summary, and its outcome is recorded with
the result (a webhook that fails never fails the check).

Each gateway's :class:`DriftService` also keeps the gateway's row in the store (registered on
start, refreshed every heartbeat with its buses) and notes the drives it has connected, so
the fleet page knows where each drive is. With ``SERVODESK_DRIFT_INTERVAL_S`` > 0 it checks
every connected drive that has an approved backup at that interval (0, the default: off).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import socket
import urllib.error
import urllib.request
from collections.abc import Awaitable, Callable
from typing import Any

from servodesk import __version__
from servodesk.errors import ConflictError, ServodeskError
from servodesk.services import db
from servodesk.services.backup import BackupService, drive_key, firmware
from servodesk.services.fleet import HEARTBEAT_S, FleetStore, SeenDrive, now_iso, serial_of
from servodesk.services.manager import SessionManager
from servodesk.services.session import Session

log = logging.getLogger(__name__)

#: How long the webhook's server may take to answer, s.
WEBHOOK_TIMEOUT_S = 10.0
#: The most differing parameters a webhook summary names (the store keeps them all).
WEBHOOK_PARAMETERS = 50

#: What a recorded difference keeps of the compare's (DifferenceOut), "a" being the approved
#: backup and "b" the drive.
_KEEP = ("address", "name", "group", "unit", "raw_unit", "kind")
_SIDES = (("a", "approved"), ("b", "drive"))


def gateway_url(host: str, port: int, https: bool) -> str:
    """This gateway's URL as others reach it: the host it serves on, or the machine's name
    where it serves on every address."""
    name = socket.gethostname() if host in ("0.0.0.0", "::", "") else host
    if ":" in name and not name.startswith("["):
        name = f"[{name}]"
    return f"{'https' if https else 'http'}://{name}:{port}"


def difference(d: dict[str, Any]) -> dict[str, Any]:
    """One compare difference as a drift result keeps it (approved vs drive)."""
    out = {k: d.get(k) for k in _KEEP}
    for side, name in _SIDES:
        out[f"{name}_value"] = d.get(f"{side}_value")
        out[f"{name}_raw_hex"] = d.get(f"{side}_raw_hex")
        out[f"{name}_engineering"] = d.get(f"{side}_engineering")
    return out


def post_webhook(url: str, summary: dict[str, Any], timeout: float = WEBHOOK_TIMEOUT_S) -> str:
    """POST ``summary`` as JSON to ``url``; what happened, as one line (never raises)."""
    body = json.dumps(summary).encode("utf-8")
    request = urllib.request.Request(
        url,
        data=body,
        method="POST",
        headers={"Content-Type": "application/json", "User-Agent": f"servodesk/{__version__}"},
    )
    try:
        with urllib.request.urlopen(request, timeout=timeout) as answer:  # http(s) only: settings
            return f"sent: HTTP {answer.status}"
    except urllib.error.HTTPError as exc:
        return f"failed: HTTP {exc.code}"
    except (urllib.error.URLError, OSError, ValueError) as exc:
        reason = getattr(exc, "reason", exc)
        return f"failed: {reason}"


def _fingerprint(result: dict[str, Any]) -> tuple[Any, ...]:
    """What makes a drift result news: the backup, the state and each difference's values."""
    diffs = tuple(
        (d["address"], d["kind"], d["approved_raw_hex"], d["drive_raw_hex"])
        for d in result["differences"]
    )
    return (result["backup"], result["state"], diffs)


class DriftService:
    """This gateway in the fleet: its row, its drives, their drift checks."""

    def __init__(
        self,
        fleet: FleetStore,
        backups: BackupService,
        manager: SessionManager,
        *,
        gateway: str,
        url: str,
        interval_s: float = 0.0,
        webhook: str = "",
        heartbeat_s: float = HEARTBEAT_S,
    ) -> None:
        self.fleet = fleet
        self.backups = backups
        self.manager = manager
        self.gateway = gateway
        self.url = url
        self.interval_s = interval_s
        self.webhook = webhook
        self.heartbeat_s = heartbeat_s
        self._tasks: list[asyncio.Task[None]] = []
        #: Called with each result that found drift (the audit log, in api/state.py).
        self.on_drift: Callable[[dict[str, Any]], None] | None = None

    # The gateway -----------------------------------------------------------------------------

    def _connected(self) -> list[SeenDrive]:
        out = []
        for s in self.manager.all():
            state = s.last_state
            alarms = None
            if state is not None and state.error_code is not None:
                alarms = 1 if state.error_code else 0
            key = drive_key(s)
            out.append(
                SeenDrive(
                    drive_key=key,
                    profile_id=s.profile.id,
                    firmware=firmware(s),
                    serial=serial_of(key, {"serial": s.identity.serial}),
                    session=s.id,
                    alarms=alarms,
                )
            )
        return out

    def _buses(self) -> list[str]:
        return sorted(
            {f"{s.link.params.interface}:{s.link.params.channel}" for s in self.manager.all()}
        )

    def heartbeat(self, *, started: bool = False) -> None:
        """Refresh this gateway's row and note its connected drives (blocking: the store)."""
        self.fleet.register_gateway(
            self.gateway, self.url, self._buses(), __version__, started=started
        )
        self.fleet.see(self.gateway, self._connected())

    async def start(self) -> None:
        """Register this gateway, then keep it alive; the scheduled scan when enabled."""
        try:
            await asyncio.to_thread(self.heartbeat, started=True)
        except ServodeskError:
            log.exception("fleet: cannot register gateway %s in the store", self.gateway)
        self._tasks.append(
            asyncio.create_task(self._every(self.heartbeat_s, self._beat), name="fleet")
        )
        if self.interval_s > 0:
            self._tasks.append(
                asyncio.create_task(self._every(self.interval_s, self.scan_logged), name="drift")
            )

    async def stop(self) -> None:
        tasks, self._tasks = self._tasks, []
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await t

    @staticmethod
    async def _every(period: float, job: Callable[[], Awaitable[Any]]) -> None:
        while True:
            await asyncio.sleep(period)
            try:
                await job()
            except db.StoreUnavailable as exc:
                # The central store is away: the status bar says so (services/outbox.py); one
                # line a period, not a traceback.
                log.warning("fleet: periodic job skipped: %s", exc.message)
            except Exception:  # A store or bus problem: logged, tried again next period.
                log.exception("fleet: periodic job failed")

    async def _beat(self) -> None:
        await asyncio.to_thread(self.heartbeat)

    # Drift -----------------------------------------------------------------------------------

    async def check(self, session: Session, *, operation: str | None = "drift") -> dict[str, Any]:
        """Compare ``session``'s drive with its approved backup; the recorded result.

        ConflictError when the drive has no approved backup (nothing to compare with)."""
        key = drive_key(session)
        seen = [d for d in self._connected() if d.session == session.id]
        await asyncio.to_thread(self.fleet.see, self.gateway, seen)
        approved = await asyncio.to_thread(self.fleet.approved_backup, key)
        if approved is None:
            raise ConflictError(
                f"drive {key} has no approved backup to compare with",
                hint="approve one of its backups first (PUT /fleet/approved, with a reason)",
            )
        ps = await self.backups.read_set(session, operation=operation)

        def compare() -> dict[str, Any]:
            golden = self.backups.load(approved)
            return self.backups.compare(
                (f"approved {approved}", golden), (f"drive {session.id}", ps)
            )

        comparison = await asyncio.to_thread(compare)
        diffs = [difference(d) for d in comparison["differences"] if d["kind"] != "same"]
        result: dict[str, Any] = {
            "drive_key": key,
            "time": now_iso(),
            "gateway": self.gateway,
            "session": session.id,
            "backup": approved,
            "state": "drifted" if diffs else "in_step",
            "count": len(diffs),
            "differences": diffs,
            "webhook": None,
        }
        # The same drift found again (same backup, same parameters, same values on the
        # drive) is recorded, but not announced again: a scan every minute would otherwise
        # call the webhook and write the audit log every minute while a drive stays drifted.
        previous = await asyncio.to_thread(self.fleet.drift_results, key, 1)
        repeat = bool(previous) and _fingerprint(previous[0]) == _fingerprint(result)
        if diffs and self.webhook:
            result["webhook"] = f"not sent: as result {previous[0]['id']}" if repeat else "pending"
        result["id"] = await asyncio.to_thread(self.fleet.add_drift, result)
        drive = await asyncio.to_thread(self.fleet.drive, key)
        result["plant_tag"] = drive["plant_tag"]
        if diffs and not repeat:
            if self.on_drift is not None:
                self.on_drift(result)
            if self.webhook:
                outcome = await asyncio.to_thread(post_webhook, self.webhook, self.summary(result))
                if not outcome.startswith("sent"):
                    log.warning("drift webhook %s: %s", self.webhook, outcome)
                result["webhook"] = outcome
                await asyncio.to_thread(self.fleet.set_webhook, result["id"], outcome)
        return result

    def summary(self, result: dict[str, Any]) -> dict[str, Any]:
        """What the webhook is sent: the drive, where, against which backup, what differs."""
        return {
            "event": "servodesk.drift",
            "gateway": self.gateway,
            "gateway_url": self.url,
            "drive_key": result["drive_key"],
            "plant_tag": result.get("plant_tag"),
            "session": result["session"],
            "approved_backup": result["backup"],
            "time": result["time"],
            "count": result["count"],
            "parameters": [
                {
                    "address": d["address"],
                    "name": d["name"],
                    "approved": d["approved_value"],
                    "drive": d["drive_value"],
                    "raw_unit": d["raw_unit"],
                    "approved_engineering": d["approved_engineering"],
                    "drive_engineering": d["drive_engineering"],
                    "unit": d["unit"],
                }
                for d in result["differences"][:WEBHOOK_PARAMETERS]
            ],
            "result": result["id"],
        }

    async def scan(self) -> list[dict[str, Any]]:
        """Check every connected drive that has an approved backup; their results."""
        results = []
        for session in self.manager.all():
            key = drive_key(session)
            if await asyncio.to_thread(self.fleet.approved_backup, key) is None:
                continue
            try:
                results.append(await self.check(session, operation=None))
            except ServodeskError as exc:  # A drive that stopped answering: the next one.
                log.warning("drift check of %s failed: %s", session.id, exc.message)
        return results

    async def scan_logged(self) -> None:
        results = await self.scan()
        drifted = [r for r in results if r["state"] == "drifted"]
        if drifted:
            log.info(
                "drift scan: %d of %d drives drifted (%s)",
                len(drifted),
                len(results),
                ", ".join(r["drive_key"] for r in drifted),
            )
