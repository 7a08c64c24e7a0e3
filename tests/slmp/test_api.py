"""The CTMM04x over SLMP through the API and the command line, as an engineer uses it.

``serve --sim`` opens the CTMM04x twin over its own fieldbus's object access (SLMP on UDP,
docs/slmp.md), so its parameters, state machine and moves go through the same SLMP link a
real unit would be reached by. What has no meaning over SLMP (cyclic data, NMT) is refused
with the reason.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path
from typing import Any

import pytest

from servodesk.cli import main
from servodesk.sim.bus import SimulatedBus
from tests.operation.support import (
    headers,
    operation_app,
    take,
    take_and_enable,
    wait_motion,
)
from tests.simproc import sim_subprocess

SID = "ctmm04x-1"  # Axis X of the station: node id 1.
A = headers("A")


def test_serve_sim_opens_the_ctmm04x_over_slmp_and_moves_it(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path, "cia402-generic,lecsn-t,ctmm04x") as (client, sim):
        drive = next(d for d in sim.drives if d.profile.id == "ctmm04x")
        assert sim.link_of(drive)[:2] == ("cclink-ie-tsn", "slmp")
        info = client.get(f"/api/v1/sessions/{SID}").json()
        assert (info["fieldbus"], info["link"], info["interface"]) == (
            "cclink-ie-tsn",
            "cclink-ie-tsn",
            "slmp",
        )
        host, port = info["channel"].rsplit(":", 1)
        assert host == "127.0.0.1" and int(port) > 0
        assert info["note"] is None  # No "twin runs on CANopen" note: it is on its own bus.
        assert info["identity"]["device_name"] == "AECAT-AXIS4"
        # The generic drive stays a CANopen node; the LECSN-T twin is on PROFINET.
        assert client.get("/api/v1/sessions/cia402-generic-1").json()["link"] == "canopen"
        lecsn = next(
            s for s in client.get("/api/v1/sessions").json() if s["id"].startswith("lecsn")
        )
        assert lecsn["link"] == "profinet" and lecsn["note"] is None

        # A parameter written through the API lands in the drive, over SLMP (as the holder of
        # its control: every change of a drive needs the control token).
        take(client, SID, "A")
        r = client.put(f"/api/v1/sessions/{SID}/objects/0x6081:00", json={"value": 4321}, headers=A)
        assert r.status_code == 200, r.text
        assert drive.read(0x6081) == 4321
        r = client.put(f"/api/v1/sessions/{SID}/objects/0x6041:00", json={"value": 0}, headers=A)
        assert r.status_code == 400 and r.json()["code"] == 0x06010002, r.text

        # A restore of the defaults with a reset is refused before anything is restored:
        # the reset is the station manager's (NMT).
        r = client.post(
            f"/api/v1/sessions/{SID}/restore-defaults",
            json={"confirm": True, "reset": True},
            headers=A,
        )
        assert r.status_code == 409 and "sends no NMT reset" in r.json()["message"], r.text
        assert drive.read(0x6081) == 4321

        # The state machine and a move run on SLMP object writes (6040h, 607Ah).
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            try:
                r = client.post(
                    f"/api/v1/sessions/{SID}/motion/move",
                    json={"mode": "relative", "target": 5000, "velocity": 4000},
                    headers=A,
                )
                assert r.status_code == 200, r.text
                done = wait_motion(client, SID, timeout=10)
                assert done["state"] == "reached", done
                assert abs(drive.position - 5000) <= 10
            finally:
                beats.stop()

        # The socket closed: the drive was made safe and control lapses after 5 s; A takes
        # it again (the same token while it has not lapsed) for the refusals below.
        take(client, SID, "A")

        # Cyclic data and NMT belong to the station's manager: refused, with the reason.
        r = client.post(f"/api/v1/sessions/{SID}/pdo/cyclic", json={}, headers=A)
        assert r.status_code == 409, r.text
        assert "no cyclic process data" in r.json()["message"]
        assert "manager" in r.json()["hint"]
        # The PDO page knows before anyone presses Start.
        status = client.get(f"/api/v1/sessions/{SID}/pdo/cyclic").json()
        assert status["running"] is False and "003 §3-3" in status["unavailable"]
        generic = client.get("/api/v1/sessions/cia402-generic-1/pdo/cyclic").json()
        assert generic["unavailable"] is None
        # The scope samples it over SLMP; a cyclic-data channel says why there is none.
        ch = {"id": 0, "session": SID, "address": "0x6064:00"}
        r = client.put("/api/v1/scope/channels", json={"channels": [{**ch, "source": "pdo"}]})
        assert r.status_code == 400 and "manager only" in r.json()["hint"], r.text
        r = client.put("/api/v1/scope/channels", json={"channels": [{**ch, "source": "auto"}]})
        assert r.status_code == 200, r.text
        assert r.json()["channels"][0]["source"] in ("recorder", "sdo")
        # The PDO page still shows the fixed mapping (read over SLMP).
        view = client.get(f"/api/v1/sessions/{SID}/pdo").json()
        assert view["kind"] == "fixed"


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_open_session_on_a_station_and_the_errors_of_a_wrong_address(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with (
        SimulatedBus.start(
            drives=[("ctmm04x", 1), ("ctmm04x", 2)], interface="slmp", channel="127.0.0.1:0"
        ) as station,
        operation_app(channel, tmp_path) as (client, _sim),
    ):
        assert station.station is not None
        where = station.station.channel

        def open_(**body: Any) -> Any:
            return client.post("/api/v1/sessions", json={"interface": "slmp", **body})

        r = open_(channel=where, node_id=2)  # Axis Y; the profile from its identity.
        assert r.status_code == 201, r.text
        s = r.json()
        assert (s["id"], s["profile_id"], s["link"]) == ("ctmm04x-2", "ctmm04x", "cclink-ie-tsn")
        r = client.get(f"/api/v1/sessions/{s['id']}/objects/0x607A:00")
        assert r.status_code == 200 and r.json()["value"] == station.drives[1].read(0x607A)

        r = open_(channel=where, node_id=3)  # Axis Z is not on this station.
        assert r.status_code == 404 and "has no axis Z" in r.json()["message"], r.text
        r = open_(channel=where, node_id=5)
        assert r.status_code == 404 and "no axis" in r.json()["message"], r.text
        r = open_(channel=f"127.0.0.1:{_free_udp_port()}", node_id=1)
        assert r.status_code == 404 and "nothing answers SLMP" in r.json()["message"], r.text
        r = open_(channel="127.0.0.1:port", node_id=1)
        assert r.status_code == 400 and r.json()["field"] == "channel", r.text
        r = client.post(
            "/api/v1/sessions", json={"interface": "ethernet", "channel": where, "node_id": 1}
        )
        assert r.status_code == 422 and "slmp" in r.text


@pytest.fixture(autouse=True)
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(d))
    return d


def test_cli_backs_up_and_restores_a_station_run_by_servodesk_sim(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    where = f"127.0.0.1:{_free_udp_port()}"
    node = ["--interface", "slmp", "--channel", where, "--node-id", "1", "--timeout", "0.3"]
    with sim_subprocess("ctmm04x", 1, "slmp", where):
        out = tmp_path / "ctmm.json"
        assert main(["backup", "-o", str(out), *node, "--json"]) == 0
        info = json.loads(capsys.readouterr().out)
        assert info["entries"] > 20 and info["profile_id"] == "ctmm04x"
        assert main(["diff", str(out), "drive", *node]) == 0
        capsys.readouterr()
        # A node id that is no axis: exit 2 with the reason, no traceback.
        assert main(["backup", "-o", str(tmp_path / "b.json"), *node[:-4], "--node-id", "7"]) == 2
        err = capsys.readouterr().err
        assert "no axis" in err and "Traceback" not in err
        assert not (tmp_path / "b.json").exists()
    assert os.path.getsize(out) > 0


def test_sim_refuses_a_bad_station_address_or_axis(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["sim", "--profile", "ctmm04x", "--interface", "slmp"]
    assert main([*args, "--channel", "127.0.0.1:x"]) == 2
    assert "port 'x' is not a number" in capsys.readouterr().err
    assert main([*args, "--channel", "127.0.0.1:0", "--node-id", "6"]) == 2
    err = capsys.readouterr().err
    assert "no axis of an SLMP station" in err and "Traceback" not in err
