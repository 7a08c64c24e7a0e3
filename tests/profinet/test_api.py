"""The LECSN-T over PROFINET through the API and the command line, as an engineer uses it.

``serve --sim`` opens the LECSN-T twin over PROFIdrive parameter access (PNIO-CM record read
/ write on UDP, docs/profinet.md), so its parameters, state machine and moves go through the
same link a real drive would be reached by. What has no meaning over PROFINET for a
supervisor (the telegram's cyclic data, NMT) is refused with the reason.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path
from typing import Any

import pytest

from servodesk.cli import main
from servodesk.domain import pnio
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.profinet_device import ProfinetDevice
from tests.operation.support import (
    headers,
    operation_app,
    take,
    take_and_enable,
    wait_motion,
)
from tests.simproc import sim_subprocess

SID = "lecsn-t-1"  # DO-ID 1
A = headers("A")


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_serve_sim_opens_the_lecsn_over_profinet_and_moves_it(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path, "cia402-generic,lecsn-t") as (client, sim):
        drive = next(d for d in sim.drives if d.profile.id == "lecsn-t")
        assert sim.link_of(drive)[:2] == ("profinet", "profinet")
        info = client.get(f"/api/v1/sessions/{SID}").json()
        assert (info["fieldbus"], info["link"], info["interface"]) == (
            "profinet",
            "profinet",
            "profinet",
        )
        host, port = info["channel"].rsplit(":", 1)
        assert host == "127.0.0.1" and int(port) > 0
        assert info["note"] is None
        # The identity is the card's I&M0 (004 §20.4.4).
        assert info["identity"]["vendor_id"] == 540
        assert info["identity"]["device_name"] == "MR-J4-TM"
        # Its RPC calls name the device's vendor and device ID in the object UUID, as DCP
        # gives them (021Ch / 0010h), not 0 (IEC 61158-6-10; issue 47).
        dev: ProfinetDevice = sim.profinet[0]
        seen: list[str] = []
        answers = dev.answers

        def spy(frame: bytes) -> list[bytes]:
            seen.append(str(pnio.parse_rpc(frame).object_uuid))
            return answers(frame)

        dev.answers = spy  # type: ignore[method-assign]
        assert client.get(f"/api/v1/sessions/{SID}/objects/0x6041:00").status_code == 200
        dev.answers = answers  # type: ignore[method-assign]
        assert seen and all(u.endswith("0001" + "0010" + "021c") for u in seen), seen

        # A parameter written through the API lands in the drive, over PROFIdrive (as the
        # holder of its control: every change of a drive needs the control token).
        take(client, SID, "A")
        r = client.put(f"/api/v1/sessions/{SID}/objects/0x6081:00", json={"value": 4321}, headers=A)
        assert r.status_code == 200, r.text
        assert drive.read(0x6081) == 4321
        # Many objects read at once (the Parameters page, a backup) go in one parameter
        # request of up to 39 parameters: a record write and a record read, where one at a
        # time takes two per object (72 here).
        device = sim.profinet[0]
        many = [f"0x{i:04X}:00" for i in (0x6041, 0x6064, 0x606C, 0x6081, 0x6083, 0x6084)] * 6
        client.post(f"/api/v1/sessions/{SID}/read", json={"addresses": many})  # learn shapes
        before = device.answered
        r = client.post(f"/api/v1/sessions/{SID}/read", json={"addresses": many})
        calls = device.answered - before
        assert r.status_code == 200 and all("value" in x for x in r.json()["results"]), r.text
        assert calls < 12, f"{calls} RPC calls for 36 objects"  # 2, and the state poll's

        # The drive's state (statusword, mode, position, velocity, error code) in one
        # request too: the session polls it up to 20 times a second.
        before = device.answered
        r = client.get(f"/api/v1/sessions/{SID}/state")
        calls = device.answered - before
        assert r.status_code == 200 and r.json()["statusword"] is not None, r.text
        assert calls < 8, f"{calls} RPC calls for the state"  # 2, and the poll's; was 10

        # A read-only object is refused from the profile before anything is sent.
        r = client.put(f"/api/v1/sessions/{SID}/objects/0x6041:00", json={"value": 0}, headers=A)
        assert r.status_code == 400 and r.json()["protocol"] == "profile", r.text
        # The drive's refusals carry the PROFIdrive error number and map to the HTTP status
        # of their meaning: a bad value 400, no such parameter 404.
        r = client.put(
            f"/api/v1/sessions/{SID}/objects/0x2D52:00", json={"value": 0x1234}, headers=A
        )
        body = r.json()
        assert r.status_code == 400 and (body["protocol"], body["code"]) == ("profidrive", 2)
        assert body["meaning"] == "Low or high limit exceeded", r.text
        assert body["code_hex"] == "0x02"
        r = client.post(f"/api/v1/sessions/{SID}/read", json={"addresses": ["0x7777:00"]})
        assert r.json()["results"][0]["error"]["code"] == 0, r.text
        r = client.get(f"/api/v1/sessions/{SID}/objects/0x6099:05")
        assert r.status_code == 404 and "PROFIdrive error 03h" in r.json()["message"], r.text

        # The state machine and a move run on parameter writes (6040h, 607Ah).
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            start = drive.position
            try:
                r = client.post(
                    f"/api/v1/sessions/{SID}/motion/move",
                    json={"mode": "relative", "target": 5000, "velocity": 2000},
                    headers=A,
                )
                assert r.status_code == 200, r.text
                done = wait_motion(client, SID, timeout=15)
                assert done["state"] == "reached", done
                assert abs(drive.position - start - 5000) <= 20
            finally:
                beats.stop()

        # The socket closed: the drive was made safe and control lapses after 5 s; A takes
        # it again (the same token while it has not lapsed) for the refusals below.
        take(client, SID, "A")

        # The telegram is the IO controller's: no cyclic data from a supervisor, and why.
        r = client.post(f"/api/v1/sessions/{SID}/pdo/cyclic", json={}, headers=A)
        assert r.status_code == 409 and "GSD file" in r.json()["hint"], r.text
        status = client.get(f"/api/v1/sessions/{SID}/pdo/cyclic").json()
        assert status["running"] is False and "004 §20.1.1" in status["unavailable"]
        # ... and which AR servodesk's session uses, and why (issue 47).
        assert "IO supervisor AR with device access" in status["unavailable"]
        # The PDO page still shows the telegram the drive holds (read over PROFINET).
        view = client.get(f"/api/v1/sessions/{SID}/pdo").json()
        assert view["telegram"] == 1
        # ... and says why it is not written from here; an apply is refused before anything
        # is read or written (the IO controller sets the telegram up).
        assert "GSD file" in view["apply_unavailable"]
        r = client.post(f"/api/v1/sessions/{SID}/pdo/apply", json={"telegram": 102}, headers=A)
        assert r.status_code == 409 and "GSD file" in r.json()["hint"], r.text
        assert drive.read(0x039A) == 1
        generic = client.get("/api/v1/sessions/cia402-generic-1/pdo").json()
        assert generic["apply_unavailable"] is None
        # No NMT: a restore of the defaults with a reset is refused before anything changes.
        velocity = drive.read(0x6081)
        r = client.post(
            f"/api/v1/sessions/{SID}/restore-defaults",
            json={"confirm": True, "reset": True},
            headers=A,
        )
        assert r.status_code == 409, r.text
        assert drive.read(0x6081) == velocity


def test_open_session_on_a_device_and_the_errors_of_a_wrong_address(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with (
        SimulatedBus.start(
            drives=[("lecsn-t", 1)], interface="profinet", channel="127.0.0.1:0"
        ) as device,
        operation_app(channel, tmp_path) as (client, _sim),
    ):
        where = device.profinet[0].channel

        def open_(**body: Any) -> Any:
            return client.post("/api/v1/sessions", json={"interface": "profinet", **body})

        r = open_(channel=where, node_id=1)  # The profile from the card's I&M0.
        assert r.status_code == 201, r.text
        s = r.json()
        assert (s["id"], s["profile_id"], s["link"]) == ("lecsn-t-1", "lecsn-t", "profinet")
        r = client.get(f"/api/v1/sessions/{s['id']}/objects/0x6081:00")
        assert r.status_code == 200 and r.json()["value"] == device.drives[0].read(0x6081)
        assert device.profinet[0].ars == 1
        assert client.delete(f"/api/v1/sessions/{s['id']}").status_code in (200, 204)
        assert device.profinet[0].ars == 0  # The AR is released with the session.

        r = open_(channel=where, node_id=2)  # No drive object 2 on this device.
        assert r.status_code == 404 and "no drive object 2" in r.json()["message"], r.text
        r = open_(channel=f"127.0.0.1:{_free_udp_port()}", node_id=1)
        assert r.status_code == 404 and "nothing answers PNIO-CM" in r.json()["message"], r.text
        r = open_(channel="127.0.0.1:port", node_id=1)
        assert r.status_code == 400 and r.json()["field"] == "channel", r.text


@pytest.fixture(autouse=True)
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(d))
    return d


def test_cli_backs_up_a_device_run_by_servodesk_sim(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    where = f"127.0.0.1:{_free_udp_port()}"
    node = ["--interface", "profinet", "--channel", where, "--node-id", "1", "--timeout", "0.5"]
    with sim_subprocess("lecsn-t", 1, "profinet", where):
        out = tmp_path / "lecsn.json"
        assert main(["backup", "-o", str(out), *node, "--json"]) == 0
        info = json.loads(capsys.readouterr().out)
        assert info["entries"] > 100 and info["profile_id"] == "lecsn-t"
        assert main(["diff", str(out), "drive", *node]) == 0
        capsys.readouterr()
        # A DO-ID the device lacks: exit 2 with the reason, no traceback, no file.
        assert main(["backup", "-o", str(tmp_path / "b.json"), *node[:-4], "--node-id", "3"]) == 2
        err = capsys.readouterr().err
        assert "no drive object 3" in err and "Traceback" not in err
        assert not (tmp_path / "b.json").exists()
    assert os.path.getsize(out) > 0


def test_sim_refuses_a_bad_device_address_or_node(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["sim", "--profile", "lecsn-t", "--interface", "profinet"]
    assert main([*args, "--channel", "127.0.0.1:x"]) == 2
    assert "port 'x' is not a number" in capsys.readouterr().err
    assert main([*args, "--channel", "127.0.0.1:0", "--node-id", "2"]) == 2
    err = capsys.readouterr().err
    assert "one drive object, node id 1" in err and "Traceback" not in err
