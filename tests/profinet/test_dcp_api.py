"""DCP through the API and the command line: ``serve --sim`` with ``SERVODESK_SIM_DCP`` has
the LECSN-T twin answer DCP behind a veth pair, and an engineer finds it, renames and
re-addresses it and opens a session at the new address (needs root, as the EtherCAT tests).
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from servodesk.domain import dcp
from servodesk.sim.profinet_dcp import DcpResponder, DcpStation
from servodesk.sim.veth import create_veth
from tests.operation.support import operation_app

pytestmark = pytest.mark.timeout(90)
SID = "lecsn-t-1"
MAC = "00:30:11:0a:0b:0c"


@pytest.fixture
def app(channel: str, tmp_path: Path) -> Iterator[tuple[TestClient, Any]]:
    with operation_app(channel, tmp_path, "lecsn-t", sim_dcp=True) as pair:
        yield pair


def test_find_rename_readdress_and_open_a_session_there(app: tuple[TestClient, Any]) -> None:
    client, sim = app
    nic = sim.dcp.master
    info = client.get(f"/api/v1/sessions/{SID}").json()
    assert info["note"] == f"DCP: search network interface {nic}."  # and nothing before it
    r = client.post("/api/v1/dcp/identify", json={"nic": nic, "timeout": 0.3})
    assert r.status_code == 200, r.text
    [dev] = r.json()["devices"]
    host, port = info["channel"].rsplit(":", 1)
    assert (dev["name_of_station"], dev["ip"], dev["session_id"]) == ("lecsn-t-1", host, SID)
    assert dev["channel"] == info["channel"]  # the twin's free port, not 34964
    assert (dev["vendor_id"], dev["device_id"], dev["roles"]) == (0x021C, 0x0010, ["IO device"])
    assert dev["profile_id"] == "lecsn-t"  # its vendor and device ID are the profile's
    mac = dev["mac"]

    # With servodesk's own session open the drive is in operation: 409 with what to do.
    new = {"ip": "10.78.0.5", "netmask": "255.255.255.0"}
    r = client.post("/api/v1/dcp/set", json={"nic": nic, "mac": mac, "ip": new})
    assert r.status_code == 409, r.text
    body = r.json()
    assert (body["protocol"], body["code"], body["code_hex"]) == ("dcp", 6, "0x06")
    assert "close servodesk's session" in body["hint"]

    assert client.delete(f"/api/v1/sessions/{SID}").status_code == 204
    r = client.post(
        "/api/v1/dcp/set",
        json={"nic": nic, "mac": mac.upper(), "name_of_station": "press-2-axis1", "ip": new},
        headers={"X-Servodesk-Client": "tab-7"},
    )
    assert r.status_code == 200, r.text
    assert r.json() == {"mac": mac, "done": ["name_of_station", "ip"]}
    # Both changes are in the audit log (the refused one before is not).
    audit = [a for a in client.get("/api/v1/audit/writes").json() if a["session"] == f"dcp:{nic}"]
    assert sorted((a["address"], a["new_value"], a["client"], a["drive_key"]) for a in audit) == [
        ("dcp:ip", "10.78.0.5/255.255.255.0 gateway 0.0.0.0", "tab-7", f"profinet:{mac}"),
        ("dcp:name_of_station", "press-2-axis1", "tab-7", f"profinet:{mac}"),
    ]
    [dev] = client.post("/api/v1/dcp/identify", json={"nic": nic, "timeout": 0.2}).json()["devices"]
    assert (dev["name_of_station"], dev["ip"], dev["session_id"]) == (
        "press-2-axis1",
        "10.78.0.5",
        None,
    )
    assert dev["channel"] == f"10.78.0.5:{port}"
    r = client.post(
        "/api/v1/sessions",
        json={"interface": "profinet", "channel": dev["channel"], "node_id": 1},
    )
    assert r.status_code == 201, r.text
    assert r.json()["profile_id"] == "lecsn-t"
    [dev] = client.post("/api/v1/dcp/identify", json={"nic": nic, "timeout": 0.2}).json()["devices"]
    assert dev["session_id"] == r.json()["id"]

    r = client.post("/api/v1/dcp/signal", json={"nic": nic, "mac": mac})
    assert r.status_code == 200 and r.json()["done"] == ["signal"]
    assert sim.profinet[0].station.flashes == 1
    # Flashing the LED changes nothing on the device: no audit entry.
    audit = [a for a in client.get("/api/v1/audit/writes").json() if a["session"] == f"dcp:{nic}"]
    assert len(audit) == 2


def test_an_address_the_rotary_switches_set_is_refused_with_what_to_do(
    app: tuple[TestClient, Any],
) -> None:
    # SW2/SW3 other than 00h set the LECSN-T's IP address (004 §20.1.3(4)): the device answers
    # BlockError 5, and the hint is its profile's (the dcp quirk's refusals), not the link's.
    client, sim = app
    nic = sim.dcp.master
    assert client.delete(f"/api/v1/sessions/{SID}").status_code == 204
    sim.profinet[0].station.address_switch = 0x10
    [dev] = client.post("/api/v1/dcp/identify", json={"nic": nic, "timeout": 0.2}).json()["devices"]
    new = {"ip": "10.79.0.5", "netmask": "255.255.255.0"}
    r = client.post("/api/v1/dcp/set", json={"nic": nic, "mac": dev["mac"], "ip": new})
    assert r.status_code == 409, r.text
    body = r.json()
    assert (body["protocol"], body["code"]) == ("dcp", 5)
    assert body["hint"].startswith("SMC LECSN-T servo amplifier"), body["hint"]
    assert "SW2/SW3" in body["hint"] and "004 §20.1.3(4)" in body["hint"]
    # The name is still the master's to set.
    r = client.post("/api/v1/dcp/set", json={"nic": nic, "mac": dev["mac"], "name_of_station": "b"})
    assert r.status_code == 200, r.text


#: (path, body, status, field, text of the error)
BAD: list[tuple[str, dict[str, Any], int, str | None, str]] = [
    ("set", {"mac": MAC, "name_of_station": "Axis 1"}, 400, "name_of_station", "capital"),
    ("set", {"mac": MAC, "ip": {"ip": "10.0.0.0", "netmask": "255.0.0.0"}}, 400, "ip",
     "network address"),
    ("set", {"mac": "00:30:11:0a:0b", "name_of_station": "a"}, 422, "mac", "at least 17"),
    ("set", {"mac": "01:0e:cf:00:00:00", "name_of_station": "a"}, 400, "mac", "multicast"),
    ("set", {"mac": MAC}, 400, None, "nothing to set"),
    ("reset", {"mac": MAC, "mode": 3}, 422, None, "mode"),
    ("identify", {"name_of_station": "-x"}, 400, "name_of_station", "has the part"),
]  # fmt: skip


def test_bad_requests_are_refused_before_anything_is_sent(app: tuple[TestClient, Any]) -> None:
    client, sim = app
    for path, body, status, field, text in BAD:
        r = client.post(f"/api/v1/dcp/{path}", json={"nic": sim.dcp.master, **body})
        assert r.status_code == status, (path, body, r.text)
        assert text in r.text, r.text
        if field is not None:
            assert r.json()["field"] == field
    assert sim.profinet[0].station.name_of_station == "lecsn-t-1"


def test_an_interface_that_is_not_there_is_404(app: tuple[TestClient, Any]) -> None:
    client, _ = app
    r = client.post("/api/v1/dcp/identify", json={"nic": "nope0"})
    assert r.status_code == 404 and "no network interface 'nope0'" in r.json()["message"]
    r = client.post("/api/v1/dcp/identify", json={"nic": "a/b"})
    assert r.status_code == 422


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "servodesk", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def test_the_cli_finds_and_names_a_device_served_by_servodesk_sim() -> None:
    with create_veth("sdc") as pair:
        sim = subprocess.Popen(
            [sys.executable, "-m", "servodesk", "sim", "--profile", "lecsn-t",
             "--interface", "profinet", "--channel", "127.0.0.1:0", "--dcp", pair.slave],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            assert sim.stdout is not None
            for _ in range(2):
                line = sim.stdout.readline()
                assert line, sim.stderr.read() if sim.stderr else ""
            assert f"answering PROFINET DCP on {pair.slave}" in line
            done = _cli("dcp", "identify", "--nic", pair.master, "--timeout", "0.3", "--json")
            assert done.returncode == 0, done.stderr
            [dev] = json.loads(done.stdout)["devices"]
            assert (dev["name_of_station"], dev["profile_id"]) == ("lecsn-t-1", "lecsn-t")
            done = _cli("dcp", "set", "--nic", pair.master, "--mac", dev["mac"], "--name", "cell-3")
            assert done.returncode == 0, done.stderr
            assert "set station name cell-3" in done.stdout
            done = _cli("dcp", "identify", "--nic", pair.master, "--timeout", "0.3")
            assert done.returncode == 0 and "cell-3" in done.stdout, done.stdout
            assert "profile lecsn-t" in done.stdout
            # Bad input: exit 2 with the rule, nothing sent.
            for args, text in (
                (["set", "--mac", dev["mac"], "--name", "Cell"], "capital letters"),
                (
                    ["set", "--mac", dev["mac"], "--ip", "10.0.0.5"],
                    "--ip and --netmask go together",
                ),
                (["reset", "--mac", dev["mac"], "--mode", "2"], "add --yes to confirm"),
                (["identify", "--timeout", "50"], "outside 0.1-10 s"),
            ):
                done = _cli("dcp", *args, "--nic", pair.master)
                assert done.returncode == 2, done.stderr
                assert text in done.stderr and "Traceback" not in done.stderr
            done = _cli("dcp", "identify", "--nic", pair.master, "--timeout", "0.3")
            assert "cell-3" in done.stdout
        finally:
            sim.terminate()
            sim.wait(timeout=10)
    done = _cli("sim", "--profile", "lecsn-t", "--dcp", "lo")
    assert done.returncode == 2 and "add --interface profinet" in done.stderr


def test_the_cli_says_what_to_do_about_an_address_the_rotary_switches_set() -> None:
    # The same refusal as through the API (BlockError 5, 004 §20.1.3(4)): `servodesk dcp set`
    # asks the device who it is and gives its profile's hint, not the link's generic one.
    station = DcpStation(
        vendor_id=0x021C,
        device_id=0x0010,
        type_of_station="LECSN-T",
        name_of_station="lecsn-t-1",
        ip="10.80.0.2",
        netmask="255.255.255.0",
        address_switch=0x10,
    )
    with create_veth("sdr") as pair:
        twin = DcpResponder(station, dcp.mac_bytes(MAC)).start(pair.slave)
        try:
            done = _cli(
                "dcp", "set", "--nic", pair.master, "--mac", MAC,
                "--ip", "10.80.0.5", "--netmask", "255.255.255.0",
            )  # fmt: skip
            assert done.returncode != 0 and "Traceback" not in done.stderr, done.stderr
            assert "SMC LECSN-T servo amplifier" in done.stderr, done.stderr
            assert "SW2/SW3" in done.stderr and "004 §20.1.3(4)" in done.stderr
            assert station.ip == "10.80.0.2"
            # The name is still the master's to set.
            done = _cli("dcp", "set", "--nic", pair.master, "--mac", MAC, "--name", "cell-4")
            assert done.returncode == 0, done.stderr
            assert station.name_of_station == "cell-4"
        finally:
            twin.stop()
