"""The HIWIN E twin as an EtherCAT slave through the API and the command line: a session
opened with interface ethercat, ``servodesk sim --interface ethercat`` in its own process
(where SOEM's state calls get answers, docs/ethercat.md), AL state requests and a backup."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest

from servodesk.cli import main
from servodesk.domain.address import ObjectAddress
from servodesk.errors import ConflictError, LinkTimeoutError
from servodesk.links.base import LinkParams
from servodesk.links.ethercat_link import EthercatLink
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.veth import VethPair
from tests.operation.support import headers, operation_app, take
from tests.simproc import sim_subprocess

A = headers("A")


@pytest.fixture(autouse=True)
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(d))
    return d


def test_api_opens_a_session_on_an_ethercat_slave(
    veth: VethPair, channel: str, tmp_path: Path
) -> None:
    with (
        SimulatedBus.start(
            drives=[("hiwin-e", 1), ("hiwin-e", 2)], interface="ethercat", channel=veth.slave
        ) as line,
        operation_app(channel, tmp_path) as (client, _sim),
    ):
        assert line.link_of(line.drives[1]) == ("ethercat", "ethercat", veth.slave, 2)

        def open_(**body: Any) -> Any:
            return client.post("/api/v1/sessions", json={"interface": "ethercat", **body})

        r = open_(channel=veth.master, node_id=2)  # The profile from its identity (1018h).
        assert r.status_code == 201, r.text
        s = r.json()
        assert (s["profile_id"], s["link"], s["interface"], s["channel"]) == (
            "hiwin-e",
            "ethercat",
            "ethercat",
            veth.master,
        )
        assert s["identity"]["device_name"] == "HIWIN E series EtherCAT drive"
        sid = s["id"]
        # The ESCs run in a process of their own (SimulatedBus): SOEM's state read, which
        # holds the GIL, is answered in this process too.
        r = client.get(f"/api/v1/sessions/{sid}/state")
        assert r.status_code == 200 and r.json()["nmt_state"] == "preop", r.text
        r = client.get(f"/api/v1/sessions/{sid}/objects/0x6081:00")
        assert r.status_code == 200 and r.json()["value"] == line.drives[1].read(0x6081)
        take(client, sid, "A")  # Every change of a drive needs its control token.
        r = client.put(f"/api/v1/sessions/{sid}/objects/0x6081:00", json={"value": 777}, headers=A)
        assert r.status_code == 200, r.text
        assert line.drives[1].read(0x6081) == 777 and line.drives[0].read(0x6081) != 777
        r = client.put(f"/api/v1/sessions/{sid}/objects/0x6041:00", json={"value": 0}, headers=A)
        assert r.status_code == 400 and r.json()["code"] == 0x06010002, r.text

        # A restore with a reset is refused before anything is restored: no NMT reset here.
        r = client.post(
            f"/api/v1/sessions/{sid}/restore-defaults",
            json={"confirm": True, "reset": True},
            headers=A,
        )
        assert r.status_code == 409 and "sends no NMT reset" in r.json()["message"], r.text
        assert line.drives[1].read(0x6081) == 777

        # A scan of the line lists both slaves with their identity and profile; the one with
        # a session keeps it, and the scan leaves that session working.
        r = client.post("/api/v1/bus/scan", json={"interface": "ethercat", "channel": veth.master})
        assert r.status_code == 200, r.text
        nodes = r.json()["nodes"]
        assert [(n["node_id"], n["profile_id"], n["session_id"]) for n in nodes] == [
            (1, "hiwin-e", None),
            (2, "hiwin-e", sid),
        ]
        assert nodes[0]["device_name"] == "HIWIN E series EtherCAT drive"
        r = client.get(f"/api/v1/sessions/{sid}/objects/0x6081:00")
        assert r.status_code == 200 and r.json()["value"] == 777, r.text
        r = client.post("/api/v1/bus/scan", json={"interface": "ethercat", "channel": "sdnothere0"})
        assert r.status_code == 404 and "no network interface" in r.text, r.text
        r = client.post("/api/v1/bus/scan", json={"interface": "profinet", "channel": "x"})
        assert r.status_code == 422 and "/dcp/identify" in r.text, r.text

        r = open_(channel=veth.master, node_id=3)
        assert r.status_code == 404 and "no EtherCAT slave at position 3" in r.text, r.text
        r = open_(channel="sdnothere0", node_id=1)
        assert r.status_code == 404 and "no network interface" in r.text, r.text


def test_state_requests_to_the_simulated_bus_in_this_process(veth: VethPair) -> None:
    with SimulatedBus.start(drives=[("hiwin-e", 1)], interface="ethercat", channel=veth.slave):

        async def states() -> None:
            link = EthercatLink(LinkParams(interface="ethercat", channel=veth.master, node_id=1))
            async with link:
                assert await link.network_state() == "preop"
                # OP: the process data mapped (SAFE-OP on the way), as cyclic data needs.
                await link.nmt("start")
                assert await link.network_state() == "op"
                await link.nmt("stop")
                assert await link.network_state() == "init"
                await link.nmt("preop")
                assert len(await link.read(ObjectAddress(0x6041))) == 2

        asyncio.run(states())


def test_sim_process_state_requests_and_backup(
    veth: VethPair, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with sim_subprocess("hiwin-e", 1, "ethercat", veth.slave):

        async def states() -> None:
            link = EthercatLink(
                LinkParams(interface="ethercat", channel=veth.master, node_id=1, timeout=0.3)
            )
            async with link:
                assert await link.network_state() == "preop"
                await link.nmt("start")  # through SAFE-OP, the drive in its own process
                assert await link.network_state() == "op"
                await link.nmt("preop")
                assert await link.network_state() == "preop"
                await link.nmt("stop")
                assert await link.network_state() == "init"
                with pytest.raises(LinkTimeoutError):  # No mailbox in INIT.
                    await link.read(ObjectAddress(0x6041))
                await link.nmt("preop")
                assert await link.network_state() == "preop"
                assert len(await link.read(ObjectAddress(0x6041))) == 2
                with pytest.raises(ConflictError, match="no NMT command 'reset'"):
                    await link.nmt("reset")

        asyncio.run(states())

        # servodesk scan lists the line's slave with its profile.
        assert main(["scan", "--interface", "ethercat", "--channel", veth.master, "--json"]) == 0
        nodes = json.loads(capsys.readouterr().out)["nodes"]
        assert [(n["node_id"], n["profile_id"]) for n in nodes] == [(1, "hiwin-e")]

        node = ["--interface", "ethercat", "--channel", veth.master, "--node-id", "1"]
        out = tmp_path / "hiwin.json"
        assert main(["backup", "-o", str(out), *node, "--json"]) == 0
        info = json.loads(capsys.readouterr().out)
        assert info["entries"] > 20 and info["profile_id"] == "hiwin-e"
        assert main(["backup", "-o", str(tmp_path / "b.json"), *node[:-2], "--node-id", "4"]) == 2
        err = capsys.readouterr().err
        assert "no EtherCAT slave at position 4" in err and "Traceback" not in err


def test_sim_refuses_a_missing_interface_and_a_bad_node(
    capsys: pytest.CaptureFixture[str],
) -> None:
    args = ["sim", "--profile", "hiwin-e", "--interface", "ethercat"]
    assert main([*args, "--channel", "sdnothere0"]) == 2
    err = capsys.readouterr().err
    assert "no network interface 'sdnothere0'" in err and "Traceback" not in err
    assert main([*args, "--channel", "lo", "--node-id", "2"]) == 2
    assert "not the position of drive 1" in capsys.readouterr().err
