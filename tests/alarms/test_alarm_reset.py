"""Alarm reset acts only on a drive in Fault (CiA 402-2 §6.2.1, IEC 61800-7-201).

The fault reset is transition 15 (Fault -> Switch on disabled). servodesk's procedure writes
the controlword 0000h / 0080h / 0000h, and 0000h is "disable voltage": sent to an enabled
drive it switched the power stage off (issue 46: "Alarm reset with no alarm active disabled
an enabled drive"). Outside Fault nothing may be sent, and the answer says so.
"""

from __future__ import annotations

from typing import Any

from tests.operation.support import headers, operation_app, take_and_enable

SID = "cia402-generic-1"
BASE = f"/api/v1/sessions/{SID}"


def test_alarm_reset_leaves_an_enabled_drive_enabled(channel: str, tmp_path: Any) -> None:
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            try:
                controlword = drive.read(0x6040)
                r = client.post(f"{BASE}/alarms/reset", headers=headers("A"))
                assert r.status_code == 200, r.text
                body = r.json()
                assert body["state"] == "Operation enabled"
                assert "No fault reset sent" in body["message"]
                assert "Operation enabled, not in Fault" in body["message"]
                assert drive.state.name == "OPERATION_ENABLED"
                assert drive.read(0x6040) == controlword  # Nothing was written.
                r = client.get(f"{BASE}/state")
                assert r.json()["state"] == "Operation enabled", r.text

                # In Fault the reset is sent and clears it (transition 15).
                drive.raise_fault(0x8611)
                assert drive.state.name in ("FAULT", "FAULT_REACTION_ACTIVE")
                r = client.post(f"{BASE}/alarms/reset", headers=headers("A"))
                assert r.status_code == 200, r.text
                assert r.json()["state"] == "Switch on disabled"
                assert r.json()["message"].startswith("Fault reset done")
            finally:
                beats.stop()
