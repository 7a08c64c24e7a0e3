"""The status bar's numbers (issue 48): per bus, its link state, traffic, errors and cycle;
and the store's reachability and local queue (issue 49, :func:`store_status`).

Everything here is read from what the sessions, links and cyclic exchanges already keep; no
request goes to a device to produce it, so the UI may ask once a second whatever the bus.
A number a link cannot give is None, and the UI says "not reported" (never a made-up 0).
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import asdict
from typing import Any

from servodesk.services import db
from servodesk.services.session import Session
from servodesk.services.store import Store

#: The EtherCAT line's and the PROFINET IO AR's states (links/ethercat_health.py,
#: links/profinet_io.py) as a bus's state.
_LINE_STATES = {
    "ok": "up",
    "degraded": "degraded",
    "link lost": "down",
    "recovering": "reconnecting",
}


def _state(connected: list[bool], line: str | None) -> str:
    """ "down" when no session on the bus gets answers, "degraded" when some do not; an
    EtherCAT line's own state (its cycles) wins over the sessions' polls, it is seen first."""
    if line is not None and line != "up":
        return line
    if not any(connected):
        return "down"
    return "up" if all(connected) else "degraded"


def _cycle(session: Session) -> dict[str, Any] | None:
    ex = session.cyclic
    if ex is None or not ex.running:
        return None
    syncs = ex.syncs
    elapsed = time.monotonic() - ex.started_at if ex.started_at else 0.0
    return {
        "session": session.id,
        "sync": ex.sync,
        "configured_ms": round(ex.period * 1000, 3),
        # The average since the exchange started: cycles the producer thread counted.
        "measured_ms": round(elapsed / syncs * 1000, 3) if syncs > 0 and elapsed > 0 else None,
        "cycles": syncs,
    }


def _profinet(health: dict[str, Any] | None) -> dict[str, Any] | None:
    """The IO controller AR's counters (links/profinet_io.py ``view``) while it runs."""
    if not health or health.get("cycle_ms") is None:
        return None
    return {
        "output_frames": health["cycles"],
        "input_frames": health.get("frames_received") or 0,
        "lost": health["missing_frames"],
        "data_status_errors": health.get("data_status_errors") or 0,
        "losses": health["losses"],
        "cycle_ms": health["cycle_ms"],
    }


def bus_status(sessions: Iterable[Session]) -> list[dict[str, Any]]:
    """One entry per bus (interface and channel), in the order its first session opened."""
    by_bus: dict[tuple[str, str], list[Session]] = {}
    for s in sessions:
        by_bus.setdefault(s.link.params.bus_key(), []).append(s)
    out = []
    for (interface, channel), members in by_bus.items():
        first = members[0]
        traffic = next((t for t in (s.link.bus_traffic() for s in members) if t), None)
        cycles = [c for c in (_cycle(s) for s in members) if c is not None]
        health = next((h for h in (s.cyclic.link_health() for s in members if s.cyclic) if h), None)
        line = _LINE_STATES.get(str(health["state"])) if health else None
        out.append(
            {
                "link": first.link.fieldbus,
                "interface": interface,
                "channel": channel,
                "bitrate": first.link.params.bitrate,
                "state": _state([s.connected for s in members], line),
                "reason": health.get("reason") if health else None,
                "sessions": [
                    {"id": s.id, "node_id": s.link.params.node_id, "connected": s.connected}
                    for s in members
                ],
                "requests": sum(s.link.requests for s in members),
                "failed_requests": sum(s.link.failures for s in members),
                "traffic": asdict(traffic) if traffic else None,
                "cycle": cycles[0] if cycles else None,
                "ethercat": (
                    {
                        "wkc_errors": health["wkc_errors"],
                        "missing_frames": health["missing_frames"],
                        "losses": health["losses"],
                    }
                    if health and first.link.fieldbus == "ethercat"
                    else None
                ),
                # A PROFINET IO AR has no working counter: its frames, those lost (the
                # input cycle counter's gaps) and those with a bad DataStatus or IOPS.
                "profinet": _profinet(health) if first.link.fieldbus == "profinet" else None,
            }
        )
    return out


def store_status(store: Store) -> dict[str, Any]:
    """The store the gateway writes to (issue 49): its engine and URL (no password), and on
    a central PostgreSQL whether it answers, since when it does not, what waits in the local
    queue (services/outbox.py) and the last sync. Read from what the queue keeps: no request
    goes to the database to answer it (a store that hangs must not hang the status bar)."""
    out: dict[str, Any] = {
        "engine": store.engine.dialect.name,
        "url": db.describe(store.engine),
        "reachable": True,
        "since": None,
        "queued": {},
        "last_sync": None,
        "last_error": None,
        "synced": 0,
    }
    if store.outbox is not None:
        out |= store.outbox.status()
    return out
