"""Helpers for the operation tests: an app with simulated drives, a CAN bus spy, heartbeats.

The spy is a plain python-can Bus on the same virtual channel: it sees every frame the
backend sends, with the time the frame was put on the bus (``msg.timestamp``, ``time.time()``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import can
from fastapi.testclient import TestClient
from starlette.testclient import WebSocketTestSession

from servodesk.api.app import create_app
from servodesk.settings import Settings

CONTROLWORD = 0x6040


@dataclass(frozen=True)
class Download:
    """An expedited SDO download request (client -> drive)."""

    time: float
    node: int
    index: int
    subindex: int
    value: int


class BusSpy:
    """Records the SDO download requests on a virtual CAN channel."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.downloads: list[Download] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            msg = self.bus.recv(0.05)
            if msg is None or not 0x601 <= msg.arbitration_id <= 0x67F or len(msg.data) < 8:
                continue
            cs = msg.data[0]
            if cs & 0xE0 != 0x20:  # Not a download request (CiA 301 §7.2.4.3.3).
                continue
            self.downloads.append(
                Download(
                    time=msg.timestamp,
                    node=msg.arbitration_id - 0x600,
                    index=int.from_bytes(msg.data[1:3], "little"),
                    subindex=msg.data[3],
                    value=int.from_bytes(msg.data[4:8], "little"),
                )
            )

    def controlwords(self, node: int, after: float = 0.0) -> list[Download]:
        return [
            d
            for d in list(self.downloads)
            if d.node == node and d.index == CONTROLWORD and d.time >= after
        ]

    def writes(self, node: int, after: float, before: float) -> list[Download]:
        return [d for d in list(self.downloads) if d.node == node and after <= d.time <= before]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        self.bus.shutdown()


def is_stop(word: int) -> bool:
    """Halt (bit 8 with enable operation) or quick stop (CiA 402-2 table 28: 0xxx x01xb)."""
    return bool(word & 0x0100) or word & 0x0086 == 0x0002


@contextmanager
def operation_app(
    channel: str,
    tmp_path: Any,
    profiles: str = "cia402-generic",
    deadman_ms: int = 1000,
    **settings: Any,
) -> Iterator[tuple[TestClient, Any]]:
    """A TestClient on an app that simulates ``profiles``; yields (client, simulated bus).
    ``settings``: further Settings fields (``sim_ethercat``, ``sim_dcp``, ...).

    Tests that are not about the dead-man give it a second, so that a starved heartbeat
    thread on a busy 2-core machine does not stop their motion.
    """
    s = Settings(
        sim=True,
        sim_channel=channel,
        sim_profiles=profiles,
        data_dir=tmp_path,
        deadman_ms=deadman_ms,
        viewer_port=0,
        **settings,
    )
    app = create_app(s)
    with TestClient(app) as client:
        yield client, app.state.servodesk.sim


#: The control token each test client got when it took control (by its label). A label
#: gives no authority (services/control.py); these tokens do. A stale token of an earlier
#: test is simply not the holder's.
TOKENS: dict[str, str] = {}


class LiveHeaders(Mapping[str, str]):
    """The label and, once the client took control, its control token: read at each request,
    so a module's ``A = headers("A")`` carries the token A holds when the request is sent."""

    def __init__(self, client_id: str) -> None:
        self.client_id = client_id

    def _now(self) -> dict[str, str]:
        out = {"X-Servodesk-Client": self.client_id}
        token = TOKENS.get(self.client_id)
        if token:
            out["X-Servodesk-Control"] = token
        return out

    def __getitem__(self, key: str) -> str:
        return self._now()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._now())

    def __len__(self) -> int:
        return len(self._now())


def headers(client_id: str) -> LiveHeaders:
    return LiveHeaders(client_id)


def take(client: TestClient, sid: str, who: str, *, force: bool = False) -> str:
    """Take (or force-take) control of ``sid`` as ``who``; its token, kept in TOKENS."""
    body = {"action": "force_take", "confirm": True} if force else {"action": "take"}
    r = client.post(f"/api/v1/sessions/{sid}/control", json=body, headers=headers(who))
    assert r.status_code == 200, r.text
    token: str = r.json()["token"]
    assert token
    TOKENS[who] = token
    return token


def bind(ws: WebSocketTestSession, sid: str, who: str) -> None:
    """Make ``ws`` the dead-man of ``who``'s control of ``sid`` and wait for the answer."""
    ws.send_json({"type": "bind", "session": sid, "token": TOKENS.get(who, "")})
    while True:
        msg = ws.receive_json()
        if msg.get("type") == "bind" and msg.get("session") == sid:
            assert msg["ok"], msg
            return


class Heartbeats:
    """Sends dead-man heartbeats over a WebSocket from a thread until stopped."""

    def __init__(self, ws: WebSocketTestSession, sid: str, period: float = 0.05) -> None:
        self.ws, self.sid, self.period = ws, sid, period
        self.last = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            sent = time.time()  # Before sending: the server cannot have it any earlier.
            try:
                self.ws.send_json({"type": "heartbeat", "session": self.sid})
            except Exception:  # The socket closed under us: that is the test's business.
                return
            self.last = sent
            self._stop.wait(self.period)

    def stop(self) -> float:
        """Stop sending; the time of the last heartbeat sent."""
        self._stop.set()
        self._thread.join(1.0)
        return self.last


def take_and_enable(client: TestClient, sid: str, who: str, ws: WebSocketTestSession) -> Heartbeats:
    """Take control as ``who``, bind ``ws`` as its dead-man, beat, and servo on."""
    take(client, sid, who)
    bind(ws, sid, who)
    beats = Heartbeats(ws, sid)
    r = client.post(
        f"/api/v1/sessions/{sid}/state", json={"command": "enable"}, headers=headers(who)
    )
    assert r.status_code == 200, r.text
    assert r.json()["state"] == "Operation enabled"
    return beats


def wait_motion(client: TestClient, sid: str, timeout: float = 5.0) -> dict[str, Any]:
    """Poll GET /motion until the motion is no longer active."""
    end = time.monotonic() + timeout
    while True:
        m: dict[str, Any] = client.get(f"/api/v1/sessions/{sid}/motion").json()
        if not m["active"] or time.monotonic() > end:
            return m
        time.sleep(0.02)


def wait_until(pred: Any, timeout: float, step: float = 0.001) -> float | None:
    """time.time() when ``pred()`` first held, or None after ``timeout``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return time.time()
        time.sleep(step)
    return None
