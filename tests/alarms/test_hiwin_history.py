"""HIWIN's error history (issue 48): its faults land in the diagnosis history 10F3h.

HIWIN 000 §2.7 sends the drive's faults as emergency messages, which an EtherCAT drive keeps
in its diagnosis history 10F3h (ETG.1020); the manual has no 1003h and its alarm table
3100h-3104h is not supported (§3.3). The history stayed empty after an FF3Eh fault, and its
cause read "the manual gives no cause".
"""

from __future__ import annotations

from typing import Any

from servodesk.domain import diagnosis
from tests.operation.support import operation_app

SID = "hiwin-e-1"


def test_a_fault_is_recorded_in_the_diagnosis_history_newest_first(
    channel: str, tmp_path: Any
) -> None:
    with operation_app(channel, tmp_path, profiles="hiwin-e") as (client, sim):
        drive = sim.drives[0]
        body = client.get(f"/api/v1/sessions/{SID}/alarms").json()
        assert body["history"] == []
        drive.raise_fault(0xFF3E)
        body = client.get(f"/api/v1/sessions/{SID}/alarms").json()
        assert body["current"]["code"] == 0xFF3E
        assert "60F4h" in body["current"]["cause"]  # what 000 documents, not "no cause"
        (first,) = body["history"]
        assert first["source"] == "0x10F3:06" and first["code"] == 0xFF3E
        assert first["name"] == "Position error too big" and "60F4h" in first["cause"]
        # Fault reset (controlword bit 7 rising edge), then a second fault: the ring's next
        # message, shown first.
        drive.write(0x6040, 0, 0x0000)
        drive.write(0x6040, 0, 0x0080)
        drive.write(0x6040, 0, 0x0000)
        drive.raise_fault(0xFF19)
        body = client.get(f"/api/v1/sessions/{SID}/alarms").json()
        assert [(h["source"], h["code"]) for h in body["history"]] == [
            ("0x10F3:07", 0xFF19),
            ("0x10F3:06", 0xFF3E),
        ]


def test_the_diagnosis_message_is_etg1020s() -> None:
    msg = diagnosis.emergency_message(0xFF3E, now_ns=diagnosis.DC_EPOCH_NS + 5)
    assert msg.hex() == "00e83eff020000000500000000000000"
    parsed = diagnosis.parse(msg)
    assert parsed is not None and parsed.emergency_code == 0xFF3E and parsed.stamp == 5
    assert diagnosis.parse(msg[:8]) is None
