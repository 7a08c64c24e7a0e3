"""A drive write made with the CLI (``servodesk restore``) is in the hash-chained audit log
under the CLI's user, and ``servodesk audit verify`` accepts the log it wrote."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from servodesk.cli import main
from servodesk.cli.backup import client_id
from servodesk.sim.bus import SimulatedBus


def test_a_cli_restore_is_audited(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    data = tmp_path / "data"
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(data))
    channel = f"cli-audit-{os.getpid()}"
    bus = SimulatedBus.start([("cia402-generic", 3)], channel=channel)
    try:
        node = [
            "--interface",
            "virtual",
            "--channel",
            channel,
            "--timeout",
            "0.3",
            "--node-id",
            "3",
        ]
        out = tmp_path / "a.json"
        assert main(["backup", "-o", str(out), *node]) == 0
        bus.drives[0].write(0x6081, 0, 4321)
        assert main(["restore", str(out), *node, "--json"]) == 0
    finally:
        bus.stop()
    capsys.readouterr()
    assert main(["audit", "export", "--data-dir", str(data)]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    writes = [r for r in records if r["event"] == "write.object"]
    assert any(r["details"]["address"] == "0x6081:00" for r in writes), records
    assert {r["user"] for r in writes} == {client_id()}
    assert main(["audit", "verify", "--data-dir", str(data)]) == 0
