"""PDO mapping end to end: the REST API against every family's simulated drive on a bus.

For each family: the templates and a custom mapping are applied through the API, cyclic data
is started, and the frames a plain python-can listener sees on the bus carry exactly the mapped
objects (compared with SDO reads of the same objects at standstill); a plain canopen script
reads the mapping objects back; an invalid mapping is refused before any frame is sent to the
drive; a drive that aborts halfway keeps its previous mapping and the report says so.
"""

from __future__ import annotations

import itertools
import os
import threading
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

import can
import canopen
import httpx
import pytest
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.domain import pdo as pdomod
from servodesk.domain.address import ObjectAddress
from servodesk.settings import Settings
from servodesk.sim.engine import SimAbort
from tests.control_helpers import bind_in_process, take_control
from tests.pdo.support import layout_of

pytestmark = pytest.mark.asyncio(loop_scope="module")

FAMILIES = {
    "cia402-generic": 1,
    "hiwin-e": 2,
    "smartris": 3,
    "ctmm04x": 4,
    "lecsn-t": 5,
}
HDR = {"X-Servodesk-Client": "pdo-test"}
_n = itertools.count()


class Spy:
    """A plain python-can listener on the drives' channel: every frame, with its time."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.frames: list[can.Message] = []
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            m = self.bus.recv(0.05)
            if m is not None:
                self.frames.append(m)

    def clear(self) -> None:
        self.frames = []

    def on(self, cob_id: int) -> list[can.Message]:
        return [
            m for m in list(self.frames) if m.arbitration_id == cob_id and not m.is_remote_frame
        ]

    def close(self) -> None:
        self._stop.set()
        self._t.join(1)
        self.bus.shutdown()


@dataclass
class Rig:
    client: httpx.AsyncClient
    channel: str
    spy: Spy
    app: Any
    extra: dict[str, Any] = field(default_factory=dict)

    def drive(self, node: int) -> Any:
        for d in self.app.state.servodesk.sim.drives:
            if d.node_id == node:
                return d
        raise KeyError(node)


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rig(tmp_path_factory) -> AsyncIterator[Rig]:  # type: ignore[no-untyped-def]
    channel = f"pdo-api-{os.getpid()}-{next(_n)}"
    settings = Settings(
        sim=True,
        sim_channel=channel,
        sim_profiles=",".join(FAMILIES),
        data_dir=tmp_path_factory.mktemp("data"),
        # The CTMM04x and LECSN-T twins on the CAN bus too: these tests read their PDOs'
        # frames there (serve --sim puts them on SLMP and PROFINET, which carry no cyclic data
        # for servodesk: tests/slmp/test_api.py, tests/profinet/test_api.py).
        sim_slmp="",
        sim_profinet="",
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        spy = Spy(channel)
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(
            transport=transport, base_url="http://test", headers=HDR, timeout=30
        ) as c:
            # Applying mappings and running cyclic data change the drives: the test client
            # holds control of all of them (one token); servo on needs its dead-man, here an
            # in-process connection bound as a browser tab's WebSocket would be.
            for family in FAMILIES:
                token = await take_control(c, sid(family), HDR["X-Servodesk-Client"])
            bind_in_process(app, sid("cia402-generic"), token, HDR["X-Servodesk-Client"])
            try:
                yield Rig(c, channel, spy, app)
            finally:
                spy.close()


def sid(family: str) -> str:
    return f"{family}-{FAMILIES[family]}"


_UNREADABLE = object()


async def read_value(rig: Rig, family: str, address: str) -> Any:
    r = await rig.client.get(f"/api/v1/sessions/{sid(family)}/objects/{address}")
    if r.status_code == 400 and r.json().get("protocol") == "sdo":
        return _UNREADABLE  # e.g. a write-only command object (LECSN 2D11h: no data).
    assert r.status_code == 200, r.text
    return r.json()["value"]


async def wait_frames(rig: Rig, cob_id: int, n: int, timeout: float = 3.0) -> list[can.Message]:
    import asyncio

    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        got = rig.spy.on(cob_id)
        if len(got) >= n:
            return got
        await asyncio.sleep(0.02)
    return rig.spy.on(cob_id)


async def check_frames_carry_mapping(rig: Rig, family: str) -> int:
    """Start cyclic data; every active TX PDO's frames carry the mapped objects' values."""
    s = sid(family)
    profile = rig.app.state.servodesk.manager.get(s).profile
    view = (await rig.client.get(f"/api/v1/sessions/{s}/pdo")).json()
    rig.spy.clear()
    r = await rig.client.post(f"/api/v1/sessions/{s}/pdo/cyclic", json={"sync_period_ms": 5})
    assert r.status_code == 200, r.text
    checked = 0
    try:
        for p in view["pdos"]:
            if p["direction"] != "tx" or not p["active"] or not p["entries"]:
                continue
            # A synchronous TPDO goes out at every n-th SYNC; an event-driven one at standstill
            # only once, on entering OPERATIONAL (its first event), unless an event timer runs.
            t = p["transmission_type"]
            # RTR-only ones (252/253) when asked: the exchange asks every cycle.
            periodic = t is None or 1 <= t <= 240 or t in (252, 253) or bool(p["event_timer"])
            frames = await wait_frames(rig, p["cob_id"], 3 if periodic else 1)
            assert frames, (
                f"{family} {p['name']}: no frame on COB-ID {p['cob_id_hex']} (type {t}, "
                f"event timer {p['event_timer']}, inhibit {p['inhibit_time']})"
            )
            data = bytes(frames[-1].data)
            assert len(data) >= p["bytes"], (family, p["name"], len(data), p["bytes"])
            cfg_pdo = pdomod.Pdo(
                direction=pdomod.Direction.TX,
                number=p["number"],
                mapping_index=p["mapping_index"],
                comm_index=p["comm_index"],
                comm=None,
                entries=tuple(
                    pdomod.MapEntry(e["index"], e["subindex"], e["bits"]) for e in p["entries"]
                ),
            )
            decoded = pdomod.unpack(profile, cfg_pdo, data)
            for e in p["entries"]:
                if e["padding"]:
                    continue
                address = ObjectAddress.parse(e["address"])
                sdo_value = await read_value(rig, family, e["address"])
                if sdo_value is _UNREADABLE:
                    continue
                # At standstill every mapped object is constant: the PDO must carry the
                # value the drive reports by SDO (floats compared exactly as well: same bits).
                assert decoded[address] == sdo_value, (family, p["name"], e["address"])
                checked += 1
    finally:
        r = await rig.client.delete(f"/api/v1/sessions/{s}/pdo/cyclic")
        assert r.status_code == 200, r.text
    return checked


@pytest.mark.parametrize("family", [f for f in FAMILIES if f != "ctmm04x"])
async def test_every_template_applies_verifies_and_goes_on_the_bus(rig: Rig, family: str) -> None:
    s = sid(family)
    templates = (await rig.client.get(f"/api/v1/sessions/{s}/pdo/templates")).json()
    assert templates, f"{family} has no PDO templates"
    for t in templates:
        proposal = await rig.client.post(f"/api/v1/sessions/{s}/pdo/templates/{t['id']}")
        assert proposal.status_code == 200, proposal.text
        body = proposal.json()
        assert not body["problems"], (t["id"], body["problems"])
        r = await rig.client.post(f"/api/v1/sessions/{s}/pdo/apply", json=layout_of(body))
        assert r.status_code == 200, r.text
        rep = r.json()
        assert rep["ok"] and rep["verified"], (t["id"], rep["error"], rep["failed_step"])
        objects = [
            e
            for p in body["pdos"]
            if p["direction"] == "tx" and p["active"]
            for e in p["entries"]
            if not e["padding"]
        ]
        checked = await check_frames_carry_mapping(rig, family)
        # Telegram 1's words (STW1, NSOLL_A, ...) are not objects: nothing to compare there.
        assert checked > 0 or not objects, t["id"]


async def test_fixed_family_is_shown_and_refused_before_any_write(rig: Rig) -> None:
    s = sid("ctmm04x")
    view = (await rig.client.get(f"/api/v1/sessions/{s}/pdo")).json()
    assert view["kind"] == "fixed"
    tx = next(p for p in view["pdos"] if p["direction"] == "tx")
    assert len(tx["entries"]) == 10 and tx["bytes"] == 29  # 003 §4-1
    rig.spy.clear()
    r = await rig.client.post(
        f"/api/v1/sessions/{s}/pdo/apply",
        json={"pdos": [{"direction": "tx", "number": 1, "entries": ["0x6041:00"]}]},
    )
    assert r.status_code == 422, r.text
    assert r.json()["problems"]
    downloads = [
        m for m in rig.spy.frames if m.arbitration_id == 0x600 + 4 and m.data[0] & 0xE0 == 0x20
    ]
    assert downloads == [], "nothing may be written to a fixed mapping"
    assert await check_frames_carry_mapping(rig, "ctmm04x") == 10


async def test_custom_mapping_on_generic_drive_and_plain_canopen_reads_it_back(rig: Rig) -> None:
    s = sid("cia402-generic")
    layout = {
        "pdos": [
            {
                "direction": "tx",
                "number": 2,
                "entries": ["0x6041:00", "0x6064:00", "0x6061:00"],
                "transmission_type": 1,
                "enabled": True,
            }
        ]
    }
    r = await rig.client.post(f"/api/v1/sessions/{s}/pdo/apply", json=layout)
    assert r.status_code == 200, r.text
    assert r.json()["ok"]
    # A plain canopen master on the same bus sees the mapping (CiA 301 1A01h).
    net = canopen.Network()
    net.connect(interface="virtual", channel=rig.channel)
    try:
        node = canopen.RemoteNode(1, canopen.ObjectDictionary())
        net.add_node(node)
        import asyncio

        def read() -> list[int]:
            n = int.from_bytes(node.sdo.upload(0x1A01, 0), "little")
            return [int.from_bytes(node.sdo.upload(0x1A01, i), "little") for i in range(n + 1)]

        # One SDO client per channel (CiA 301): the session's status poll waits meanwhile,
        # or the plain master may get the answer to its read of 6041h.
        async with rig.app.state.servodesk.manager.get(s).link.exclusive():
            got = await asyncio.to_thread(read)
    finally:
        net.disconnect()
    assert got == [3, 0x60410010, 0x60640020, 0x60610008]
    assert await check_frames_carry_mapping(rig, "cia402-generic") >= 3


async def test_invalid_mapping_is_refused_before_anything_is_written(rig: Rig) -> None:
    s = sid("cia402-generic")
    before = (await rig.client.get(f"/api/v1/sessions/{s}/pdo")).json()
    rig.spy.clear()
    # Nine 32-bit objects cannot fit 64 bits; 0x1000 is not mappable.
    bad = {
        "pdos": [
            {"direction": "tx", "number": 1, "entries": ["0x6064:00", "0x606C:00", "0x6041:00"]},
            {"direction": "tx", "number": 3, "entries": ["0x1000:00"]},
        ]
    }
    r = await rig.client.post(f"/api/v1/sessions/{s}/pdo/apply", json=bad)
    assert r.status_code == 422, r.text
    problems = r.json()["problems"]
    assert {p["pdo"] for p in problems} >= {"TPDO1", "TPDO3"}, problems
    downloads = [
        m for m in rig.spy.frames if m.arbitration_id == 0x601 and m.data[0] & 0xE0 == 0x20
    ]
    assert downloads == [], "nothing may be written when the mapping is refused"
    after = (await rig.client.get(f"/api/v1/sessions/{s}/pdo")).json()
    assert after["pdos"] == before["pdos"]


async def test_drive_abort_halfway_keeps_the_old_mapping_and_reports(rig: Rig) -> None:
    s = sid("smartris")
    before = (await rig.client.get(f"/api/v1/sessions/{s}/pdo")).json()
    drive = rig.drive(FAMILIES["smartris"])
    writes: list[tuple[int, int]] = []
    armed = {"on": True}

    def fail_on_third_entry(index: int, sub: int, value: object) -> None:
        writes.append((index, sub))
        # The drive aborts the write of TPDO1's second mapping entry once (an EEPROM or
        # internal error, 0800 0020h): the remap is half done at that moment.
        if armed["on"] and index == 0x1A00 and sub == 2:
            armed["on"] = False
            raise SimAbort(0x08000020, "injected failure")

    drive.on_write(fail_on_third_entry)
    try:
        r = await rig.client.post(
            f"/api/v1/sessions/{s}/pdo/apply",
            json={
                "pdos": [{"direction": "tx", "number": 1, "entries": ["0x6041:00", "0x6064:00"]}]
            },
        )
    finally:
        drive._write_listeners.remove(fail_on_third_entry)
    assert r.status_code == 200, r.text
    rep = r.json()
    assert not rep["ok"]
    assert rep["failed_step"]["address"] == "0x1A00:02"
    assert "0800 0020" in rep["error"] or "08000020" in rep["error"].replace(" ", "")
    assert rep["rolled_back"], rep
    after = (await rig.client.get(f"/api/v1/sessions/{s}/pdo")).json()
    assert [p["entries"] for p in after["pdos"]] == [p["entries"] for p in before["pdos"]]
    assert [p["enabled"] for p in after["pdos"]] == [p["enabled"] for p in before["pdos"]]


async def test_cyclic_outputs_write_the_drive_and_follow_sdo_writes(rig: Rig) -> None:
    s = sid("cia402-generic")
    # Outputs need control of the drive: the client holds it (the rig took it), and taking
    # it again with its token keeps it.
    r = await rig.client.post(f"/api/v1/sessions/{s}/control", json={"action": "take"})
    assert r.status_code in (200, 201), r.text
    assert r.json()["token"] == rig.client.headers["X-Servodesk-Control"]
    try:
        r = await rig.client.post(
            f"/api/v1/sessions/{s}/pdo/cyclic", json={"sync_period_ms": 2, "outputs": True}
        )
        assert r.status_code == 200, r.text
        st = r.json()
        assert st["running"] and st["outputs"]
        rx_addresses = {a for a, v in st["values"].items() if v["pdo"].startswith("RPDO")}
        assert "0x6040:00" in rx_addresses, st["values"]
        import asyncio

        await asyncio.sleep(0.1)
        # Turning outputs on changed nothing: the drive is still in its state.
        state0 = (await rig.client.get(f"/api/v1/sessions/{s}/state")).json()["state"]
        # An SDO write through servodesk (the Operation page) updates the output image...
        r = await rig.client.post(f"/api/v1/sessions/{s}/state", json={"command": "enable"})
        assert r.status_code == 200, r.text
        await asyncio.sleep(0.2)
        # ...so the RPDOs that follow carry it and do not switch the drive back off.
        st1 = (await rig.client.get(f"/api/v1/sessions/{s}/state")).json()["state"]
        assert st1 == "Operation enabled", (state0, st1)
        # An output value through the API reaches the drive by RPDO.
        r = await rig.client.put(
            f"/api/v1/sessions/{s}/pdo/cyclic/outputs", json={"values": {"0x6040:00": 6}}
        )
        assert r.status_code == 200, r.text
        await asyncio.sleep(0.3)
        st2 = (await rig.client.get(f"/api/v1/sessions/{s}/state")).json()["state"]
        assert st2 == "Ready to switch on"
        # A value the profile refuses never reaches the bus.
        r = await rig.client.put(
            f"/api/v1/sessions/{s}/pdo/cyclic/outputs", json={"values": {"0x1000:00": 1}}
        )
        assert r.status_code == 400, r.text
    finally:
        await rig.client.delete(f"/api/v1/sessions/{s}/pdo/cyclic")
        await rig.client.post(f"/api/v1/sessions/{s}/state", json={"command": "disable"})


async def test_exports_name_every_mapped_object(rig: Rig) -> None:
    s = sid("hiwin-e")
    view = (await rig.client.get(f"/api/v1/sessions/{s}/pdo")).json()
    mapped = {e["address"] for p in view["pdos"] if p["active"] for e in p["entries"]}
    for fmt in ("csv", "dcf", "esi", "json"):
        r = await rig.client.get(f"/api/v1/sessions/{s}/pdo/export", params={"format": fmt})
        assert r.status_code == 200, (fmt, r.text)
        text = r.text.upper()
        for a in mapped:
            idx = a[2:6]
            assert idx in text, (fmt, a)
    r = await rig.client.get(f"/api/v1/sessions/{s}/pdo/export", params={"format": "xls"})
    assert r.status_code == 422


async def test_sessions_on_one_bus_share_one_sync_producer(rig: Rig) -> None:
    import asyncio

    a, b, c = sid("cia402-generic"), sid("hiwin-e"), sid("smartris")
    try:
        for s in (a, b):
            r = await rig.client.post(
                f"/api/v1/sessions/{s}/pdo/cyclic", json={"sync_period_ms": 5}
            )
            assert r.status_code == 200, r.text
        # CiA 301 §7.2.5: one SYNC producer per network; a different period is refused.
        r = await rig.client.post(f"/api/v1/sessions/{c}/pdo/cyclic", json={"sync_period_ms": 10})
        assert r.status_code == 409, r.text
        assert "5 ms" in r.json()["message"]
        rig.spy.clear()
        await asyncio.sleep(1.0)
        syncs = [m for m in list(rig.spy.frames) if m.arbitration_id == 0x080]
        assert len(syncs) > 1
        span = syncs[-1].timestamp - syncs[0].timestamp
        rate = (len(syncs) - 1) / span
        assert 120 <= rate <= 230, f"SYNC at {rate:.0f}/s: one producer at 5 ms gives ~200/s"
        # Stopping one session leaves the other's cyclic data running.
        await rig.client.delete(f"/api/v1/sessions/{a}/pdo/cyclic")
        st = (await rig.client.get(f"/api/v1/sessions/{b}/pdo/cyclic")).json()
        assert st["running"]
    finally:
        for s in (a, b, c):
            await rig.client.delete(f"/api/v1/sessions/{s}/pdo/cyclic")


async def test_an_idle_event_driven_tpdo_says_why_and_the_fix_works(rig: Rig) -> None:
    """Issue 48: "running · 0 frames/s" with TPDO1 of type 255 and no event timer on an idle
    axis. The status says why (event-driven, no event timer) and names the two fixes; the
    first (transmission type 1, every SYNC) applied as a PDO change makes frames arrive."""
    import asyncio

    s = sid("cia402-generic")
    base = f"/api/v1/sessions/{s}/pdo"
    view = (await rig.client.get(base)).json()
    tpdo1 = next(p for p in view["pdos"] if p["direction"] == "tx" and p["number"] == 1)
    assert tpdo1["transmission_type"] == 255 and tpdo1["event_timer"] == 0
    r = await rig.client.post(f"{base}/cyclic", json={"sync_period_ms": 5})
    assert r.status_code == 200, r.text
    try:
        await asyncio.sleep(1.6)
        st = (await rig.client.get(f"{base}/cyclic")).json()
        tx = {c["name"]: c for c in st["tx_pdos"]}
        idle = tx[tpdo1["name"]]["idle"]
        assert idle is not None, tx
        assert "event-driven (transmission type 255)" in idle["why"]
        assert "1800h:05 = 0" in idle["why"] and "CiA 301" in idle["why"]
        assert [f["transmission_type"] for f in idle["fixes"]] == [1, None]
        assert [f["event_timer"] for f in idle["fixes"]] == [None, 100]
        # The fix is a PDO change like any other (control, plan, verify).
        fix = idle["fixes"][0]
        body = {
            "dry_run": False,
            "pdos": [
                {
                    "direction": "tx",
                    "number": 1,
                    "entries": [
                        {"index": e["index"], "subindex": e["subindex"], "bits": e["bits"]}
                        for e in tpdo1["entries"]
                    ],
                    "transmission_type": fix["transmission_type"],
                }
            ],
        }
        r = await rig.client.post(f"{base}/apply", json=body)
        assert r.status_code == 200 and r.json()["ok"], r.text
        await asyncio.sleep(1.6)
        st = (await rig.client.get(f"{base}/cyclic")).json()
        after = {c["name"]: c for c in st["tx_pdos"]}[tpdo1["name"]]
        assert st["running"] and after["idle"] is None and after["rate_hz"] > 50, after
    finally:
        await rig.client.delete(f"{base}/cyclic")
        body = {
            "dry_run": False,
            "pdos": [
                {
                    "direction": "tx",
                    "number": 1,
                    "entries": [
                        {"index": e["index"], "subindex": e["subindex"], "bits": e["bits"]}
                        for e in tpdo1["entries"]
                    ],
                    "transmission_type": 255,
                }
            ],
        }
        await rig.client.post(f"{base}/apply", json=body)


async def test_a_telegram_is_refused_where_no_io_ar_takes_one(rig: Rig) -> None:
    """``telegram`` chooses the expected submodule of servodesk's PROFINET IO AR (issue 47);
    on CANopen the PDO mapping says what is exchanged, so the request is refused before a
    frame goes out, and the status offers no telegram."""
    s = sid("cia402-generic")
    url = f"/api/v1/sessions/{s}/pdo/cyclic"
    assert (await rig.client.get(url)).json()["telegrams"] is None
    rig.spy.clear()
    r = await rig.client.post(url, json={"sync_period_ms": 5, "telegram": 102})
    assert r.status_code == 400, r.text
    body = r.json()
    assert body["field"] == "telegram" and "PROFINET IO AR only" in body["message"], body
    assert "leave telegram out" in body["hint"]
    assert not [m for m in rig.spy.frames if m.arbitration_id in (0x000, 0x080)]
    assert not (await rig.client.get(url)).json()["running"]
