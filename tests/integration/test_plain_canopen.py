"""Acceptance: ``servodesk sim`` in its own process, driven by plain python-canopen code.

The drive runs as ``python -m servodesk sim --profile cia402-generic --node-id 5 --interface
udp_multicast --channel 239.74.163.x`` (a group per test run); this file imports nothing from
servodesk: what a third-party master sees is what is tested.
"""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Iterator
from typing import Any

import canopen
import pytest
from tests.simproc import sim_subprocess

NODE = 5
REV = 131072
GROUP = f"239.74.163.{10 + os.getpid() % 240}"


@pytest.fixture(scope="module")
def sim_process() -> Iterator[subprocess.Popen[str]]:
    with sim_subprocess("cia402-generic", NODE, "udp_multicast", GROUP) as proc:
        yield proc


@pytest.fixture(scope="module")
def node(sim_process: subprocess.Popen[str]) -> Iterator[Any]:
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.1
    net.connect(interface="udp_multicast", channel=GROUP)
    try:
        n = net.add_node(NODE)
        n.sdo.RESPONSE_TIMEOUT = 1.0
        yield n
    finally:
        net.disconnect()


def u(node: Any, index: int, sub: int = 0, signed: bool = False) -> int:
    return int.from_bytes(node.sdo.upload(index, sub), "little", signed=signed)


def w(node: Any, index: int, sub: int, value: int, size: int) -> None:
    node.sdo.download(index, sub, value.to_bytes(size, "little", signed=value < 0))


def statusword(node: Any) -> int:
    return u(node, 0x6041)


def wait_for(cond: Any, timeout: float) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.01)


def to_switch_on_disabled(node: Any) -> None:
    w(node, 0x6040, 0, 0x00, 2)
    w(node, 0x6040, 0, 0x80, 2)  # Fault reset, if there is a fault.
    w(node, 0x6040, 0, 0x00, 2)
    assert statusword(node) & 0x4F == 0x40


def test_identity(node: Any) -> None:
    assert u(node, 0x1000) == 0x00020192
    assert node.sdo.upload(0x1008, 0) == b"servodesk simulated CiA 402 drive"  # Segmented.
    assert u(node, 0x1018, 0) == 4
    assert u(node, 0x1018, 1) == 0x5344534B
    assert u(node, 0x1018, 2) == 0x00000402


def test_heartbeat_reports_the_nmt_state(node: Any) -> None:
    w(node, 0x1017, 0, 50, 2)
    assert node.nmt.wait_for_heartbeat(1.0) == "PRE-OPERATIONAL"
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.12)
    assert node.nmt.wait_for_heartbeat(1.0) == "OPERATIONAL"
    node.nmt.state = "PRE-OPERATIONAL"
    time.sleep(0.12)
    assert node.nmt.wait_for_heartbeat(1.0) == "PRE-OPERATIONAL"


def test_state_machine_walk(node: Any) -> None:
    to_switch_on_disabled(node)
    for word, mask, pattern in (
        (0x06, 0x6F, 0x21),  # Ready to switch on.
        (0x07, 0x6F, 0x23),  # Switched on.
        (0x0F, 0x6F, 0x27),  # Operation enabled.
        (0x07, 0x6F, 0x23),  # Disable operation.
        (0x06, 0x6F, 0x21),  # Shutdown.
        (0x00, 0x4F, 0x40),  # Disable voltage: Switch on disabled.
    ):
        w(node, 0x6040, 0, word, 2)
        wait_for(lambda mask=mask, pattern=pattern: statusword(node) & mask == pattern, 1.0)


def test_profile_position_move(node: Any) -> None:
    to_switch_on_disabled(node)
    w(node, 0x6060, 0, 1, 1)
    for word in (0x06, 0x07, 0x0F):
        w(node, 0x6040, 0, word, 2)
    start = u(node, 0x6064, signed=True)
    target = start + 2 * REV
    w(node, 0x607A, 0, target, 4)
    w(node, 0x6040, 0, 0x1F, 2)  # New set-point.
    wait_for(lambda: statusword(node) & 0x1000, 1.0)  # Set-point acknowledge.
    w(node, 0x6040, 0, 0x0F, 2)
    wait_for(lambda: statusword(node) & 0x400, 5.0)  # Target reached.
    window = u(node, 0x6067)
    assert abs(u(node, 0x6064, signed=True) - target) <= window
    assert statusword(node) & 0x6F == 0x27


@pytest.mark.parametrize(
    ("op", "index", "sub", "data", "code"),
    [
        ("read", 0x2000, 0, b"", 0x06020000),
        ("read", 0x1018, 7, b"", 0x06090011),
        ("write", 0x1000, 0, b"\x00\x00\x00\x00", 0x06010002),
        ("write", 0x6040, 0, b"\x06", 0x06070013),
        ("write", 0x6060, 0, b"\x08", 0x06090030),
        ("write", 0x605A, 0, b"\x09\x00", 0x06090031),
        ("write", 0x1010, 1, b"\x00\x00\x00\x00", 0x08000020),
    ],
)
def test_standard_abort_codes(
    node: Any, op: str, index: int, sub: int, data: bytes, code: int
) -> None:
    with pytest.raises(canopen.SdoAbortedError) as exc:
        if op == "read":
            node.sdo.upload(index, sub)
        else:
            node.sdo.download(index, sub, data)
    assert exc.value.code == code


def test_following_error_sends_emcy_and_sets_fault(node: Any) -> None:
    to_switch_on_disabled(node)
    w(node, 0x6060, 0, 1, 1)
    w(node, 0x6065, 0, 2000, 4)  # Following error window (counts).
    w(node, 0x6072, 0, 5, 2)  # 0.5 % torque: the axis cannot follow.
    for word in (0x06, 0x07, 0x0F):
        w(node, 0x6040, 0, word, 2)
    w(node, 0x607A, 0, u(node, 0x6064, signed=True) + REV, 4)
    node.emcy.reset()
    w(node, 0x6040, 0, 0x1F, 2)
    err = node.emcy.wait(0x8611, timeout=3.0)
    assert err is not None, "no EMCY 8611h"
    assert err.register & 0x01
    wait_for(lambda: statusword(node) & 0x4F == 0x08, 2.0)  # Fault (after the reaction).
    assert u(node, 0x603F) == 0x8611
    # Clean up for other tests: restore the torque and reset the fault.
    w(node, 0x6072, 0, 3000, 2)
    to_switch_on_disabled(node)
