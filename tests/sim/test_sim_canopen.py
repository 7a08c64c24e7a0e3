"""The simulated drive as a CANopen device, tested with a plain python-canopen master."""

from __future__ import annotations

import struct
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import can
import canopen
import pytest

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.engine import SIGNATURE_LOAD, SIGNATURE_SAVE

from .support import generic, with_objects

NODE = 5


@dataclass
class Rig:
    sim: SimulatedBus
    net: Any
    node: Any
    spy: can.BusABC

    def u(self, index: int, sub: int = 0, signed: bool = False) -> int:
        return int.from_bytes(self.node.sdo.upload(index, sub), "little", signed=signed)

    def w(self, index: int, sub: int, value: int, size: int) -> None:
        self.node.sdo.download(index, sub, value.to_bytes(size, "little", signed=value < 0))

    def frames(self, cob_id: int, seconds: float) -> list[bytes]:
        out: list[bytes] = []
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            m = self.spy.recv(left)
            if m is not None and m.arbitration_id == cob_id:
                out.append(bytes(m.data))
        return out

    def drain(self) -> None:
        while self.spy.recv(0) is not None:
            pass


@pytest.fixture
def rig(channel: str) -> Iterator[Rig]:
    catalog = ProfileCatalog()
    # A test family: the generic profile with a write-only object, to see 0x06010001.
    test_profile = with_objects(generic(), x6502={"access": "wo"}).model_copy(
        update={"id": "cia402-test"}
    )
    catalog.add(test_profile)
    sim = SimulatedBus.start(drives=[("cia402-test", NODE)], channel=channel, catalog=catalog)
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05  # Quick disconnect.
    net.connect(interface="virtual", channel=channel)
    node = net.add_node(NODE)
    node.sdo.RESPONSE_TIMEOUT = 0.3
    spy = can.Bus(interface="virtual", channel=channel)
    try:
        yield Rig(sim, net, node, spy)
    finally:
        spy.shutdown()
        net.disconnect()
        sim.stop()


def test_identity_and_segmented_device_name(rig: Rig) -> None:
    assert rig.u(0x1000) == 0x00020192
    assert rig.node.sdo.upload(0x1008, 0) == b"servodesk simulated CiA 402 drive"
    assert rig.u(0x1018, 1) == 0x5344534B
    assert rig.u(0x1018, 4) == 1
    assert rig.u(0x1400, 1) == 0x200 + NODE  # $NODEID resolved.


ABORTS = [
    # (operation, index, sub, data, abort code) -- CiA 301 §7.2.4.3.17 table 22.
    ("read", 0x2000, 0, b"", 0x06020000),
    ("read", 0x1018, 7, b"", 0x06090011),
    ("read", 0x6502, 0, b"", 0x06010001),
    ("write", 0x1000, 0, b"\x00\x00\x00\x00", 0x06010002),
    ("write", 0x6041, 0, b"\x00\x00", 0x06010002),
    ("write", 0x1008, 0, b"new device name", 0x06010002),  # Segmented: refused at once.
    ("write", 0x2000, 0, b"\x00", 0x06020000),
    ("write", 0x1018, 9, b"\x00", 0x06090011),
    ("write", 0x6040, 0, b"\x06", 0x06070013),
    ("write", 0x6040, 0, b"\x06\x00\x00\x00", 0x06070012),
    ("write", 0x6060, 0, b"\x08", 0x06090030),
    ("write", 0x6098, 0, b"\x01", 0x06090030),
    ("write", 0x1003, 0, b"\x02", 0x06090030),
    ("write", 0x605A, 0, struct.pack("<h", 9), 0x06090031),
    ("write", 0x605A, 0, struct.pack("<h", -1), 0x06090032),
    ("write", 0x6083, 0, struct.pack("<I", 0), 0x06090032),
    ("write", 0x1010, 1, struct.pack("<I", 0x12345678), 0x08000020),
    ("write", 0x1011, 1, struct.pack("<I", SIGNATURE_SAVE), 0x08000020),
    ("write", 0x1A00, 1, struct.pack("<I", 0x60400010), 0x06040041),  # Not TPDO-mappable.
]


@pytest.mark.parametrize(("op", "index", "sub", "data", "code"), ABORTS)
def test_abort_codes(rig: Rig, op: str, index: int, sub: int, data: bytes, code: int) -> None:
    with pytest.raises(canopen.SdoAbortedError) as exc:
        if op == "read":
            rig.node.sdo.upload(index, sub)
        else:
            rig.node.sdo.download(index, sub, data)
    assert exc.value.code == code


def test_pdo_mapping_writable_in_preop_or_with_the_pdo_disabled(rig: Rig) -> None:
    rig.w(0x1600, 1, 0x60400010, 4)  # PRE-OPERATIONAL after boot: allowed.
    rig.net.nmt.send_command(0x01)  # Start: OPERATIONAL.
    time.sleep(0.02)
    with pytest.raises(canopen.SdoAbortedError) as exc:
        rig.w(0x1600, 1, 0x60400010, 4)
    assert exc.value.code == 0x08000022
    rig.w(0x1400, 1, 0x80000000 | 0x200 + NODE, 4)  # Invalidate RPDO1 (bit 31).
    rig.w(0x1600, 0, 0, 1)
    rig.w(0x1600, 2, 0x60600008, 4)
    rig.w(0x1600, 0, 2, 1)
    assert rig.u(0x1600, 2) == 0x60600008


def test_heartbeat_carries_the_nmt_state(rig: Rig) -> None:
    assert rig.frames(0x700 + NODE, 0.1) == []  # 1017h defaults to 0: no heartbeat.
    rig.w(0x1017, 0, 20, 2)
    beats = rig.frames(0x700 + NODE, 0.2)
    assert len(beats) >= 5 and set(beats) == {b"\x7f"}
    for command, byte in ((0x01, b"\x05"), (0x02, b"\x04"), (0x80, b"\x7f")):
        rig.net.nmt.send_command(command)
        time.sleep(0.05)
        rig.drain()
        assert set(rig.frames(0x700 + NODE, 0.1)) == {byte}
    rig.w(0x1017, 0, 0, 2)
    time.sleep(0.05)
    rig.drain()
    assert rig.frames(0x700 + NODE, 0.1) == []


def test_no_sdo_in_stopped(rig: Rig) -> None:
    rig.net.nmt.send_command(0x02)
    time.sleep(0.02)
    with pytest.raises(canopen.SdoCommunicationError):
        rig.node.sdo.upload(0x1000, 0)
    rig.net.nmt.send_command(0x80)
    time.sleep(0.02)
    assert rig.u(0x1000) == 0x00020192


def test_store_restore_and_reset_node(rig: Rig) -> None:
    rig.w(0x6065, 0, 12345, 4)
    rig.w(0x1017, 0, 25, 2)
    rig.w(0x1010, 1, SIGNATURE_SAVE, 4)
    assert rig.u(0x1010, 1) == 1  # Reads "saves on command".
    rig.w(0x6065, 0, 999, 4)  # Not stored: lost on reset.
    rig.drain()
    rig.net.nmt.send_command(0x81)  # Reset node.
    frames = rig.frames(0x700 + NODE, 0.15)
    assert frames[0] == b"\x00"  # Boot-up.
    assert set(frames[1:]) == {b"\x7f"}  # Stored 1017h: heartbeat from boot on.
    assert rig.u(0x6065) == 12345
    rig.w(0x1011, 1, SIGNATURE_LOAD, 4)
    assert rig.u(0x6065) == 12345  # Defaults apply at the next reset only.
    rig.net.nmt.send_command(0x81)
    time.sleep(0.05)
    assert rig.u(0x6065) == 20000
    assert rig.u(0x1017) == 0


def test_reset_communication_sends_boot_up(rig: Rig) -> None:
    rig.w(0x6065, 0, 777, 4)
    rig.drain()
    rig.net.nmt.send_command(0x82)
    assert rig.frames(0x700 + NODE, 0.1)[:1] == [b"\x00"]
    assert rig.u(0x6065) == 777  # Application parameters are untouched.


def test_following_error_sends_emcy_and_reset_sends_emcy_reset(rig: Rig) -> None:
    for word in (0x06, 0x07, 0x0F):
        rig.w(0x6040, 0, word, 2)
    assert rig.u(0x6041) & 0x6F == 0x27
    rig.w(0x6072, 0, 5, 2)  # Too little torque to move against friction.
    rig.w(0x6065, 0, 2000, 4)
    rig.w(0x607A, 0, 131072, 4)
    rig.drain()
    rig.w(0x6040, 0, 0x1F, 2)
    emcy = rig.frames(0x80 + NODE, 0.5)
    assert emcy[:1] == [bytes([0x11, 0x86, 0x21, 0, 0, 0, 0, 0])]
    assert rig.u(0x6041) & 0x4F == 0x08  # Fault.
    assert rig.u(0x603F) == 0x8611
    assert rig.u(0x1003, 1) == 0x8611
    rig.w(0x6040, 0, 0x00, 2)
    rig.w(0x6040, 0, 0x80, 2)
    assert rig.frames(0x80 + NODE, 0.1)[:1] == [bytes(8)]
    assert rig.u(0x6041) & 0x4F == 0x40  # Switch on disabled.


def test_nmt_to_another_node_is_ignored(rig: Rig) -> None:
    rig.w(0x1017, 0, 20, 2)
    rig.net.send_message(0, bytes([0x01, NODE + 1]))
    time.sleep(0.05)
    rig.drain()
    assert set(rig.frames(0x700 + NODE, 0.08)) == {b"\x7f"}


def test_boot_up_then_heartbeat_from_a_non_zero_1017_default(channel: str) -> None:
    catalog = ProfileCatalog()
    catalog.add(
        with_objects(generic(), x1017={"default": 30}).model_copy(update={"id": "cia402-hb"})
    )
    spy = can.Bus(interface="virtual", channel=channel)
    sim = SimulatedBus.start(drives=[("cia402-hb", NODE)], channel=channel, catalog=catalog)
    try:
        frames: list[bytes] = []
        end = time.monotonic() + 0.2
        while (left := end - time.monotonic()) > 0:
            m = spy.recv(left)
            if m is not None and m.arbitration_id == 0x700 + NODE:
                frames.append(bytes(m.data))
        assert frames[0] == b"\x00"  # Boot-up.
        assert len(frames) >= 4 and set(frames[1:]) == {b"\x7f"}
    finally:
        sim.stop()
        spy.shutdown()
