"""Helpers for the tuning API and CLI tests: the LECSN-T twin's one-touch tuning objects.

The tests run the real protocol: the app's sessions reach the simulated drives over a virtual
CAN bus (tests/operation/support.py), and the drive's built-in one-touch tuning is the twin's
(sim/onetouch.py, 004 §20.8.7).
"""

from __future__ import annotations

import time
from typing import Any

from fastapi.testclient import TestClient

from tests.operation.support import headers

LECSN = "lecsn-t-1"
#: P11600-P11604 (004 §20.9.3.5(27)-(31)) and the gains one-touch tuning sets (PB06-PB10).
P11600, P11601, P11602, P11603, P11604 = 0x2D50, 0x2D51, 0x2D52, 0x2D53, 0x2D54
PB = (0x2086, 0x2087, 0x2088, 0x2089, 0x208A)
#: PB06-PB10 defaults of the profile (raw).
PB_DEFAULTS = (700, 150, 370, 823, 337)
PA10 = 0x200A  # In-position range: the twin's overshoot limit of one-touch tuning (C001h).
REV = 131072  # lecsn-t simulation: counts per revolution.


def pb(drive: Any) -> tuple[int, ...]:
    return tuple(int(drive.read(i, 0)) for i in PB)


def start(
    client: TestClient,
    sid: str,
    who: str,
    *,
    mode: str = "basic",
    travel: float = 0.25,
    torque: float = 100.0,
    move_torque: float | None = None,
) -> Any:
    body: dict[str, Any] = {"mode": mode, "travel_window_rev": travel, "torque_limit_pct": torque}
    if move_torque is not None:
        body["move_torque_pct"] = move_torque
    return client.post(f"/api/v1/sessions/{sid}/tuning/start", json=body, headers=headers(who))


def job(client: TestClient, sid: str) -> dict[str, Any]:
    info: dict[str, Any] = client.get(f"/api/v1/sessions/{sid}/tuning").json()
    j: dict[str, Any] = info["job"]
    return j


def wait_job(client: TestClient, sid: str, timeout: float = 60.0) -> dict[str, Any]:
    """Poll GET /tuning until the job is no longer running."""
    end = time.monotonic() + timeout
    while True:
        j = job(client, sid)
        if j["state"] != "running" or time.monotonic() > end:
            return j
        time.sleep(0.1)


def wait_progress(client: TestClient, sid: str, fraction: float, timeout: float = 30.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        j = job(client, sid)
        assert j["state"] == "running", f"the job ended early: {j}"
        if j["progress"] >= fraction:
            return
        time.sleep(0.05)
    raise AssertionError(f"the job did not reach {fraction} in {timeout} s: {job(client, sid)}")
