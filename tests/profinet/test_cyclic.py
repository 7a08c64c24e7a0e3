"""Cyclic PROFINET IO: servodesk as the LECSN-T's IO controller (links/profinet_io.py) and the
twin as its IO device (sim/profinet_io.py), RT frames on a veth pair (docs/profinet.md,
"Cyclic data"; needs root, as the EtherCAT and DCP tests).

The connect blocks and the RT frames are dissected with scapy's own PROFINET layers
(``pnio_rpc``, ``pnio``, ``dcerpc``), not with servodesk's decoder.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import itertools
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scapy.contrib.pnio import PNIORealTimeCyclicPDU, ProfinetIO
from scapy.contrib.pnio_rpc import (
    AlarmCRBlockReq,
    ARBlockReq,
    ExpectedSubmoduleBlockReq,
    IOCRBlockReq,
    IODControlReq,
    PNIOServiceReqPDU,
)
from scapy.layers.dcerpc import DceRpc4
from scapy.layers.l2 import Ether

from servodesk.domain import pnio
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import ConflictError, ValidationError
from servodesk.links.base import LinkParams
from servodesk.links.profinet_io import IoController
from servodesk.links.profinet_link import ProfinetLink
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.profinet_dcp import interface_mac
from servodesk.sim.profinet_device import ProfinetDevice
from servodesk.sim.runner import SimRunner
from servodesk.sim.veth import VethPair, create_veth
from tests.operation.support import (
    bind,
    headers,
    operation_app,
    take,
    take_and_enable,
    wait_motion,
)

pytestmark = pytest.mark.timeout(90)
SID = "lecsn-t-1"
A = headers("A")
P922 = 0x039A


@pytest.fixture(scope="module")
def veth() -> Iterator[VethPair]:
    pair = create_veth("sdio")
    try:
        yield pair
    finally:
        pair.delete()


@contextlib.contextmanager
def _twin(veth: VethPair, telegram: int = 102) -> Iterator[tuple[ProfinetDevice, SimulatedDrive]]:
    """The LECSN-T twin (PNIO-CM on loopback, RT frames on the pair's slave end), its drive
    stepped in real time and configured with ``telegram``."""
    drive = SimulatedDrive(ProfileCatalog().get("lecsn-t"), 1)
    drive.write(P922, 0, telegram)
    runner = SimRunner([drive])
    runner.start()
    dev = ProfinetDevice(drive).start()
    dev.serve_io(veth.slave)
    try:
        yield dev, drive
    finally:
        dev.stop()
        runner.stop()


def _link(veth: VethPair, dev: ProfinetDevice) -> ProfinetLink:
    return ProfinetLink(
        LinkParams(interface="profinet", channel=dev.channel, node_id=1, extra={"nic": veth.master})
    )


async def _start(link: ProfinetLink, telegram: int = 102, rx: int = 48, tx: int = 48,
                 period: float = 0.001) -> None:  # fmt: skip
    await link.open()
    link.prepare_io(telegram, rx, tx, period, True)
    await link.nmt("start")


def _outputs(controlword: int, mode: int = 1) -> bytes:
    """Telegram 102's default setpoint mapping: 6060h (1 byte), Reserved 8, 6040h, ..."""
    return bytes([mode, 0]) + controlword.to_bytes(2, "big") + bytes(44)


def _until(ok: Any, timeout: float = 2.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if ok():
            return True
        time.sleep(0.005)
    return bool(ok())


def test_the_io_connect_and_the_rt_frames_as_scapy_reads_them(veth: VethPair) -> None:
    captured: list[bytes] = []
    frames: list[bytes] = []
    stop = threading.Event()

    def capture() -> None:
        # ETH_P_ALL: a socket of one Ethertype is not shown the frames its host sends.
        with socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(0x0003)) as s:
            s.bind((veth.master, 0x0003))
            s.settimeout(0.05)
            while not stop.is_set():
                with contextlib.suppress(TimeoutError):
                    frames.append(s.recv(1600))

    with _twin(veth) as (dev, drive):
        answers = dev.answers

        def spy(frame: bytes) -> list[bytes]:
            captured.append(frame)
            return answers(frame)

        dev.answers = spy  # type: ignore[method-assign]
        link = _link(veth, dev)

        async def run() -> None:
            await _start(link)
            t = threading.Thread(target=capture)
            t.start()
            await asyncio.sleep(0.3)
            stop.set()
            t.join()
            assert dev.io is not None and dev.io.ar is not None and dev.io.ar.exchanging
            assert drive.nmt_state == "operational"
            await link.close()

        asyncio.run(run())
        assert dev.io is not None and dev.io.ar is None  # released with the session

    requests = [DceRpc4(f) for f in captured]
    [connect] = [r for r in requests if r.opnum == 0 and len(r.payload) > 200]
    blocks = connect[PNIOServiceReqPDU].blocks
    ar = next(b for b in blocks if isinstance(b, ARBlockReq))
    assert ar.ARType == 0x0001  # IOCARSingle
    assert (ar.ARProperties_State, ar.ARProperties_DeviceAccess) == (1, 0)
    assert ar.CMInitiatorMacAdd == interface_mac(veth.master).hex(":")
    assert ar.CMInitiatorUDPRTPort == 0x8892
    iocrs = {b.IOCRType: b for b in blocks if isinstance(b, IOCRBlockReq)}
    assert sorted(iocrs) == [1, 2]
    for b in iocrs.values():
        assert (b.LT, b.IOCRProperties_RTClass) == (0x8892, 1)
        assert (b.SendClockFactor, b.ReductionRatio) == (32, 1)  # 1 ms
        assert b.WatchdogFactor == b.DataHoldFactor == 200  # 200 ms
        assert 0x8000 <= b.FrameID < 0xC000
    inp, out = iocrs[1], iocrs[2]
    # Input CR: DAP and drive object without IO data (IOPS only), the actual-value
    # telegram (48 bytes) and its IOPS, then the IOCS of the setpoint telegram.
    assert [(o.SlotNumber, o.SubslotNumber, o.FrameOffset) for o in inp.APIs[0].IODataObjects] == [
        (0, 1, 0),
        (1, 1, 1),
        (1, 2, 2),
    ]
    assert [(o.SlotNumber, o.SubslotNumber, o.FrameOffset) for o in inp.APIs[0].IOCSs] == [
        (1, 2, 51)
    ]
    assert inp.DataLength == 52 and out.DataLength == 52
    assert [(o.SlotNumber, o.SubslotNumber, o.FrameOffset) for o in out.APIs[0].IODataObjects] == [
        (1, 2, 0)
    ]
    assert any(isinstance(b, AlarmCRBlockReq) and b.LT == 0x8892 for b in blocks)
    [expected] = [b for b in blocks if isinstance(b, ExpectedSubmoduleBlockReq)]
    subs = {(api.SlotNumber, s.SubslotNumber): s for api in expected.APIs for s in api.Submodules}
    tel = subs[(1, 2)]
    assert tel.SubmoduleIdentNumber == 102 and tel.SubmoduleProperties_Type == 3
    assert [(d.DataDescription, d.SubmoduleDataLength) for d in tel.DataDescription] == [
        (1, 48),
        (2, 48),
    ]
    [prm_end] = [
        b
        for r in requests
        if r.opnum == 4 and PNIOServiceReqPDU in r
        for b in r[PNIOServiceReqPDU].blocks
        if isinstance(b, IODControlReq)
    ]
    assert prm_end.block_type == 0x0110 and prm_end.ControlCommand_PrmEnd == 1

    # RT_CLASS_1 frames both ways, every 1 ms: FrameID, C_SDU, cycle counter (+32 per
    # frame), DataStatus 35h (primary, valid, run, no problem), TransferStatus 0.
    rt = [Ether(f) for f in frames]
    out_frames = [p for p in rt if ProfinetIO in p and p[ProfinetIO].frameID == out.FrameID]
    in_frames = [p for p in rt if ProfinetIO in p and p[ProfinetIO].frameID == inp.FrameID]
    assert len(out_frames) > 100 and len(in_frames) > 100, (len(out_frames), len(in_frames))
    for p in out_frames[-50:] + in_frames[-50:]:
        pdu = p[PNIORealTimeCyclicPDU]
        assert (int(pdu.dataStatus), pdu.transferStatus) == (0x35, 0)
        assert len(bytes(p[ProfinetIO].payload)) == 52 + 4
    counters = [p[PNIORealTimeCyclicPDU].cycleCounter for p in out_frames[-50:]]
    assert all((b - a) & 0xFFFF == 32 for a, b in itertools.pairwise(counters))
    assert out_frames[-1].src == interface_mac(veth.master).hex(":")
    assert in_frames[-1].src == interface_mac(veth.slave).hex(":")
    # The IOPS of the setpoint telegram (after its 48 bytes) is good (80h).
    assert bytes(out_frames[-1][ProfinetIO].payload)[48] == 0x80


def test_watchdogs_on_both_sides(veth: VethPair) -> None:
    with _twin(veth) as (dev, drive):
        link = _link(veth, dev)

        async def run() -> None:
            await _start(link)
            io = link.io
            assert io is not None
            assert _until(lambda: io.health.state == "ok")
            # Servo on through the setpoint telegram (CiA 402: shutdown, switch on, enable).
            for word in (0x0006, 0x0007, 0x000F):
                io.set_outputs(_outputs(word))
                await asyncio.sleep(0.05)
            assert _until(lambda: int(drive.read(0x6041)) & 0x6F == 0x27), hex(
                int(drive.read(0x6041))
            )
            # The controller falls silent (its thread gone, no Release): the device's data
            # hold timer ends the AR and the drive goes to Switch on disabled (004 §20.5.2).
            io._stop.set()
            assert io._thread is not None
            io._thread.join()
            assert _until(lambda: dev.io is not None and dev.io.aborts == 1, 1.0)
            assert _until(lambda: int(drive.read(0x6041)) & 0x4F == 0x40, 3.0)
            assert drive.nmt_state == "preop"
            await link.nmt("preop")

            # Now the device falls silent: the controller's watchdog makes its inputs stale
            # and says why.
            await link.nmt("start")
            io = link.io
            assert io is not None and _until(lambda: io.health.state == "ok")
            assert dev.io is not None
            dev.io.stop()
            assert _until(lambda: io.health.state == "link lost", 1.0)
            view = io.view()
            assert view["stale"] and "watchdog 200 x 1 ms" in view["reason"], view
            await link.close()

        asyncio.run(run())


def _cable(name: str, up: bool) -> None:
    """The cable at the device's end of the pair out (down) or back in (up)."""
    subprocess.run(["ip", "link", "set", name, "up" if up else "down"], check=True)


def test_the_io_ar_comes_back_by_itself_after_the_link_was_lost(veth: VethPair) -> None:
    with _twin(veth) as (dev, drive):
        link = _link(veth, dev)

        async def run() -> None:
            await _start(link)
            io = link.io
            assert io is not None and dev.io is not None
            assert _until(lambda: io.health.state == "ok")
            for word in (0x0006, 0x0007, 0x000F):
                io.set_outputs(_outputs(word))
                await asyncio.sleep(0.05)
            assert _until(lambda: int(drive.read(0x6041)) & 0x6F == 0x27)
            first_ar, key = dev.io.ar, io.session_key
            # What the exchange does at the loss (services/cyclic.py hold_on_link_loss):
            # a quick stop in the outputs, so that the new AR does not enable the axis.
            _cable(veth.slave, up=False)
            try:
                assert _until(lambda: io.health.state == "link lost", 1.0)
                io.set_outputs(_outputs(0x0002))
                view = io.view()
                assert view["carrier"] is False and "no carrier" in view["reason"], view
                # The device's data hold timer ends its AR: Switch on disabled (004 §20.5.2).
                assert _until(lambda: dev.io is not None and dev.io.aborts == 1, 2.0)
                assert _until(lambda: int(drive.read(0x6041)) & 0x4F == 0x40, 3.0)
                await asyncio.sleep(0.3)  # no try while the carrier is out
                assert io.health.recoveries == 0 and io.health.state == "link lost"
            finally:
                _cable(veth.slave, up=True)
            # Back by itself: a new Connect (the next session key), PrmEnd, ApplicationReady.
            assert _until(lambda: io.health.state == "ok", 5.0), io.view()
            assert io.health.recoveries == 1 and io.session_key == key + 1
            assert dev.io.ar is not None and dev.io.ar is not first_ar and dev.io.ar.exchanging
            assert link.io is io and io.health.losses == 1
            assert io.health.last_recovery_s is not None and io.health.last_recovery_s < 5
            # The inputs show the drive's own state, and it stays there.
            got: list[bytes] = []
            io.subscribe(lambda data, _t: got.append(data))
            assert _until(lambda: bool(got))
            await asyncio.sleep(0.3)
            assert int(drive.read(0x6041)) & 0x4F == 0x40
            # The person in control enables it again through the same AR.
            for word in (0x0006, 0x0007, 0x000F):
                io.set_outputs(_outputs(word))
                await asyncio.sleep(0.05)
            assert _until(lambda: int(drive.read(0x6041)) & 0x6F == 0x27)
            assert dev.io.aborts == 1 and io.health.losses == 1
            await link.close()

        asyncio.run(run())


def test_a_second_io_controller_is_refused_and_the_first_keeps_its_ar(veth: VethPair) -> None:
    with _twin(veth) as (dev, _drive):
        first, second = _link(veth, dev), _link(veth, dev)

        async def run() -> None:
            await _start(first)
            with pytest.raises(ConflictError) as err:
                await _start(second)
            assert "another IO controller (the PLC)" in err.value.message
            assert "does not take" in (err.value.hint or "")
            assert second.io is None
            io = first.io
            assert io is not None
            received = io.health.received
            await asyncio.sleep(0.1)
            assert io.health.state == "ok" and io.health.received > received + 50
            await second.close()
            await first.close()

        asyncio.run(run())


def test_the_twin_checks_the_connect_as_a_device_does(veth: VethPair) -> None:
    with _twin(veth) as (dev, drive):
        host, port = dev.address

        async def refused(telegram: int, rx: int, tx: int) -> str:
            link = _link(veth, dev)
            try:
                with pytest.raises(ConflictError) as err:
                    await _start(link, telegram, rx, tx)
                return err.value.message
            finally:
                await link.close()

        async def run() -> None:
            # IO data lengths that are not the telegram's (48 bytes each way).
            msg = await refused(102, 48, 44)
            assert "faulty ExpectedSubmoduleBlockReq, field 12 (data_length)" in msg, msg
            assert "(PNIOStatus DB81030Ch)" in msg, msg  # ErrorCode1 03h, ErrorCode2 field
            # A submodule the device does not have (no telegram 999).
            msg = await refused(999, 48, 48)
            assert "field 9 (submodule_ident)" in msg, msg
            # An input CR shorter than its submodules' data, IOPS and IOCS (52 bytes).
            c = IoController(host, port, veth.master, object_uuid=pnio.object_uuid(0, 0),
                             telegram=102, rx_bytes=48, tx_bytes=48, cycle_s=0.001)  # fmt: skip
            c.in_layout = dataclasses.replace(c.in_layout, length=44)
            with pytest.raises(ConflictError) as err:
                await asyncio.to_thread(c.connect)
            assert "faulty IOCRBlockReq, field 8 (data_length)" in err.value.message
            # A cycle servodesk does not offer is refused before anything is sent.
            link = _link(veth, dev)
            await link.open()
            with pytest.raises(ValidationError):
                link.prepare_io(102, 48, 48, 0.003, True)
            await link.close()
            assert dev.io is not None and dev.io.ar is None
            # The controller's configuration chooses the telegram: P922 follows it.
            link = _link(veth, dev)
            await _start(link, 100, 4, 4)
            assert drive.read(P922) == 100
            await link.close()

        asyncio.run(run())

    # A device that serves no IO data refuses the IO AR's type (ARBlockReq field 4).
    drive = SimulatedDrive(ProfileCatalog().get("lecsn-t"), 1)
    with ProfinetDevice(drive) as plain:
        link = _link(veth, plain)

        async def no_io() -> None:
            with pytest.raises(ConflictError) as err:
                await _start(link)
            assert "faulty ARBlockReq, field 4 (ar_type)" in err.value.message
            await link.close()

        asyncio.run(no_io())
    assert pnio.AR_FIELD["ar_type"] == 4


@pytest.fixture
def app(channel: str, tmp_path: Path) -> Iterator[tuple[Any, Any]]:
    with operation_app(channel, tmp_path, "lecsn-t", sim_dcp=True) as pair:
        yield pair


def test_the_api_runs_cyclic_data_over_profinet_and_moves_the_lecsn(
    app: tuple[Any, Any],
) -> None:
    client, sim = app
    drive = sim.drives[0]
    # A fresh twin has standard telegram 1 (STW1/NSOLL_A, no CiA 402 objects): P922 is
    # read-only over PROFINET (004 §20.4.3.1), so servodesk's IO AR chooses the telegram as an
    # IO controller's configuration does (its expected submodule, 004 §20.1.1).
    assert int(drive.read(P922)) == 1
    info = client.get(f"/api/v1/sessions/{SID}").json()
    assert info["ar"].startswith("IO supervisor AR with device access")
    status = client.get(f"/api/v1/sessions/{SID}/pdo/cyclic").json()
    assert status["unavailable"] is None, status
    assert [t["number"] for t in status["telegrams"]] == [1, 100, 102, 103], status
    assert status["telegram"] is None
    url = f"/api/v1/sessions/{SID}/pdo/cyclic"
    with client.websocket_connect("/api/v1/ws?client=A") as ws:
        beats = take_and_enable(client, SID, "A", ws)
        try:
            r = client.post(url, json={"sync_period_ms": 3, "outputs": True}, headers=A)
            assert r.status_code == 400 and "1, 2, 4, 8 or 16 ms" in r.json()["hint"], r.text
            r = client.post(url, json={"sync_period_ms": 1, "telegram": 111}, headers=A)
            assert r.status_code == 400, r.text
            assert r.json()["field"] == "telegram" and "102" in r.json()["hint"], r.text
            assert int(drive.read(P922)) == 1 and sim.profinet[0].io.ar is None
            # The PDO page's Start asks for inputs only: an IO controller sends its setpoint
            # telegram every cycle, so it runs with outputs on, from the drive's present
            # values (it changes nothing on the axis, checked below).
            r = client.post(
                url, json={"sync_period_ms": 1, "outputs": False, "telegram": 102}, headers=A
            )
            assert r.status_code == 200 and r.json()["outputs"] is True, r.text
            assert r.json()["telegram"] == 102
            assert int(drive.read(P922)) == 102  # the drive took the AR's telegram
            info = client.get(f"/api/v1/sessions/{SID}").json()
            assert "IO controller AR (ARType 0001h" in info["ar"], info
            assert info["nmt_state"] in ("operational", "unknown")
            # Starting cyclic data changed nothing on the axis: still servo on.
            assert int(drive.read(0x6041)) & 0x6F == 0x27
            assert _until(lambda: client.get(url).json()["link"]["state"] == "ok")
            st = client.get(url).json()
            assert st["link"]["ar"].startswith("IO controller AR") and st["link"]["cycle_ms"] == 1
            assert st["values"]["0x6041:00"]["stale"] is False

            # A move: controlword and target go in the setpoint telegram.
            sent = dev_outputs = sim.profinet[0].io
            assert dev_outputs is not None
            before = sent.outputs_received
            start = drive.position
            r = client.post(
                f"/api/v1/sessions/{SID}/motion/move",
                json={"mode": "relative", "target": 5000, "velocity": 2000},
                headers=A,
            )
            assert r.status_code == 200, r.text
            done = wait_motion(client, SID, timeout=15)
            assert done["state"] == "reached", (done, client.get(url).json()["link"])
            assert abs(drive.position - start - 5000) <= 20
            assert sent.outputs_received > before + 100
            assert client.get(url).json()["values"]["0x607A:00"]["value"] == start + 5000
            # A jog, then a stop.
            r = client.post(
                f"/api/v1/sessions/{SID}/motion/jog",
                json={"velocity": 2000, "acceleration": 50000},
                headers=A,
            )
            assert r.status_code == 200, r.text
            time.sleep(0.3)
            r = client.post(f"/api/v1/sessions/{SID}/motion/stop", json={}, headers=A)
            assert r.status_code == 200, r.text
            wait_motion(client, SID, timeout=5)
            assert drive.position > start + 5000 + 100
            # Started again at the same cycle: the AR stays (a Release would take the axis
            # to Switch on disabled) and the drive's state does not change.
            ar, word = dev_outputs.ar, int(drive.read(0x6041))
            r = client.post(url, json={"sync_period_ms": 1, "outputs": True}, headers=A)
            assert r.status_code == 200, r.text
            assert dev_outputs.ar is ar and ar is not None and dev_outputs.aborts == 0
            assert int(drive.read(0x6041)) & 0x6F == word & 0x6F
        finally:
            beats.stop()
    r = client.delete(url, headers=A)
    assert r.status_code == 200, r.text
    info = client.get(f"/api/v1/sessions/{SID}").json()
    assert info["ar"] == "IO supervisor AR with device access (ARType 0006h)"
    dev = sim.profinet[0].io
    assert dev is not None and dev.ar is None


def test_after_a_lost_link_the_api_shows_the_drive_as_it_is_and_nothing_moves_by_itself(
    app: tuple[Any, Any],
) -> None:
    client, sim = app
    drive = sim.drives[0]
    drive.write(P922, 0, 102)
    url = f"/api/v1/sessions/{SID}/pdo/cyclic"
    with client.websocket_connect("/api/v1/ws?client=A") as ws:
        beats = take_and_enable(client, SID, "A", ws)
        try:
            r = client.post(url, json={"sync_period_ms": 1, "outputs": True}, headers=A)
            assert r.status_code == 200, r.text
            assert _until(lambda: client.get(url).json()["link"]["state"] == "ok")
            dev = sim.profinet[0].io
            assert dev is not None
            # The status bar's PROFINET bus: the IO AR's counters while cyclic data runs.
            bar = _profinet_bus(client)
            assert bar["state"] == "up" and bar["profinet"]["cycle_ms"] == 1, bar
            assert bar["profinet"]["output_frames"] > 0 and bar["profinet"]["input_frames"] > 0
            assert bar["profinet"]["lost"] == 0 and bar["profinet"]["losses"] == 0
            r = client.post(
                f"/api/v1/sessions/{SID}/motion/jog",
                json={"velocity": 2000, "acceleration": 50000},
                headers=A,
            )
            assert r.status_code == 200, r.text
            time.sleep(0.2)
            _cable(dev.ifname, up=False)
            try:
                assert _until(lambda: client.get(url).json()["link"]["state"] == "link lost", 1.0)
                # The bus is down in the status bar, though the supervisor AR answers.
                bar = _profinet_bus(client)
                assert bar["state"] == "down" and "no carrier" in bar["reason"], bar
                assert bar["profinet"]["losses"] == 1
                assert _until(lambda: dev.aborts == 1, 2.0)
                assert _until(lambda: int(drive.read(0x6041)) & 0x4F == 0x40, 3.0)
            finally:
                _cable(dev.ifname, up=True)
            assert _until(lambda: client.get(url).json()["link"]["state"] == "ok", 5.0)
            st = client.get(url).json()
            # The drive's own state (Switch on disabled), fresh; the outputs hold the quick
            # stop the exchange put in at the loss (CiA 402-2 §6.2.1).
            assert _until(lambda: int(client.get(url).json()["values"]["0x6041:00"]["value"])
                          & 0x4F == 0x40)  # fmt: skip
            st = client.get(url).json()
            assert st["values"]["0x6041:00"]["stale"] is False, st
            assert st["values"]["0x6040:00"]["value"] == 0x0002, st["values"]["0x6040:00"]
            position = drive.position
            time.sleep(0.5)
            assert int(drive.read(0x6041)) & 0x4F == 0x40 and drive.position == position
            # The person in control enables the axis again: over the new AR.
            r = client.post(f"/api/v1/sessions/{SID}/state", json={"command": "enable"}, headers=A)
            assert r.status_code == 200 and r.json()["state"] == "Operation enabled", r.text
            assert dev.aborts == 1
            bar = _profinet_bus(client)
            assert bar["state"] == "up" and bar["reason"] is None, bar
        finally:
            beats.stop()
    r = client.delete(url, headers=A)
    assert r.status_code == 200, r.text
    assert _profinet_bus(client)["profinet"] is None


def _profinet_bus(client: Any) -> dict[str, Any]:
    buses = client.get("/api/v1/status").json()["buses"]
    bus: dict[str, Any] = next(b for b in buses if b["link"] == "profinet")
    return bus


def test_the_scope_samples_the_telegram_at_every_send_clock_cycle(app: tuple[Any, Any]) -> None:
    # Issue 50: the actual-value telegram's objects as scope channels (source pdo), one sample
    # per cycle of the IO controller's send clock, none lost between the IO thread and the
    # scope. 6064h and 606Ch are in telegram 102's actual values (profiles/lecsn-t).
    client, sim = app
    drive = sim.drives[0]
    drive.write(P922, 0, 102)
    url = f"/api/v1/sessions/{SID}/pdo/cyclic"
    cycle = 0.002
    with client.websocket_connect("/api/v1/ws?client=A") as ws:
        take(client, SID, "A")
        bind(ws, SID, "A")
        r = client.post(url, json={"sync_period_ms": cycle * 1000, "outputs": True}, headers=A)
        assert r.status_code == 200, r.text
        assert _until(lambda: client.get(url).json()["link"]["state"] == "ok")
        # Every actual-value telegram the exchange decoded, stamped as the scope stamps its
        # samples (in the IO thread): what the scope should have, frame for frame.
        exchange = client.app.state.servodesk.manager.get(SID).cyclic
        seen: list[float] = []
        exchange.add_listener(lambda t, addresses, values: seen.append(time.time()))
        chans = [
            {"id": 0, "session": SID, "address": "0x6064:00", "source": "pdo"},
            {"id": 1, "session": SID, "address": "0x606C:00", "source": "auto"},
        ]
        r = client.put("/api/v1/scope/channels", json={"channels": chans})
        assert r.status_code == 200, r.text
        assert [c["source"] for c in r.json()["channels"]] == ["pdo", "pdo"], r.text
        assert client.post("/api/v1/scope/run", json={"action": "start"}).status_code == 200
        time.sleep(1.0)
        st = client.post("/api/v1/scope/run", json={"action": "stop"}).json()
        rec = client.app.state.servodesk.scope.buffer_recording()
        r = client.delete(url, headers=A)
        assert r.status_code == 200, r.text
    pos, vel = rec.channels
    assert [c["error"] for c in st["channels"]] == [None, None], st
    assert len(pos.t) == len(vel.t) == st["channels"][0]["samples"] == st["channels"][1]["samples"]
    # About one sample per cycle over the second (the IO thread's clock, which a busy
    # machine's other work can delay, never hasten) ...
    assert 0.7 / cycle <= len(pos.t) <= 1.05 / cycle, len(pos.t)
    assert st["channels"][0]["rate_hz"] == pytest.approx(1 / cycle, rel=0.3), st
    assert float(np.median(np.diff(pos.t))) == pytest.approx(cycle, rel=0.25)
    # ... and exactly every telegram that arrived while the scope listened.
    first, last = rec.t_ref + pos.t[0], rec.t_ref + pos.t[-1]
    arrived = sum(1 for t in seen if first - cycle / 2 <= t <= last + cycle / 2)
    assert len(pos.t) == arrived, (len(pos.t), arrived)
    # The values are the drive's: an idle axis at its position, at rest.
    assert set(pos.v.tolist()) == {float(drive.position)}
    assert set(vel.v.tolist()) == {0.0}


def test_homing_over_profinet_cyclic_io(app: tuple[Any, Any]) -> None:
    # Issue 47: homing runs over PROFINET as over EtherCAT. Telegram 102 carries the mode
    # (6060h) and the controlword: the homing's mode and start bit go in the setpoint
    # telegram while cyclic data runs. Method 37: homing on the present position (CiA 402-2
    # §6.7.2, in the LECSN-T's homing_methods): the home offset 607Ch becomes the position.
    client, sim = app
    drive = sim.drives[0]
    drive.write(P922, 0, 102)
    url = f"/api/v1/sessions/{SID}/pdo/cyclic"
    with client.websocket_connect("/api/v1/ws?client=A") as ws:
        beats = take_and_enable(client, SID, "A", ws)
        try:
            r = client.post(url, json={"sync_period_ms": 1, "outputs": True}, headers=A)
            assert r.status_code == 200, r.text
            assert _until(lambda: client.get(url).json()["link"]["state"] == "ok")
            # Away from the home offset first, by the setpoint telegram.
            r = client.post(
                f"/api/v1/sessions/{SID}/motion/move",
                json={"mode": "relative", "target": 3000, "velocity": 2000},
                headers=A,
            )
            assert r.status_code == 200, r.text
            assert wait_motion(client, SID, timeout=15)["state"] == "reached"
            offset = int(drive.read(0x607C))  # Read-only on the LECSN-T (its Pr. PT07).
            assert abs(drive.position - offset) > 2000, (drive.position, offset)
            r = client.post(f"/api/v1/sessions/{SID}/homing", json={"method": 37}, headers=A)
            assert r.status_code in (200, 202), r.text
            assert _until(
                lambda: (
                    client.get(f"/api/v1/sessions/{SID}/homing").json()["state"]
                    in ("attained", "error", "failed", "timeout")
                ),
                15.0,
            )
            st = client.get(f"/api/v1/sessions/{SID}/homing").json()
            assert st["state"] == "attained", st
            assert _until(lambda: abs(drive.position - offset) <= 5, 3.0), (drive.position, offset)
            link = client.get(url).json()["link"]
            assert link["state"] == "ok" and link["ar"].startswith("IO controller AR"), link
        finally:
            beats.stop()
    assert client.delete(url, headers=A).status_code == 200
