"""Homing over CANopen with a plain python-canopen master (no servodesk client code).

servodesk is imported only to start the simulated drive on a virtual bus; the master side is
canopen's own SDO client, as a third-party PLC would use it.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError

from tests.conftest import StartSims

NODE = 5
REV = 8388608  # hiwin-e simulation: 23-bit encoder.


@pytest.fixture
def hiwin(channel: str, sim_bus: StartSims) -> Iterator[Any]:
    sim_bus(("hiwin-e", NODE), ("lecsn-t", NODE + 1))
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="virtual", channel=channel)
    try:
        yield net
    finally:
        net.disconnect()


def _w(node: Any, index: int, sub: int, value: int, size: int, signed: bool = False) -> None:
    node.sdo.download(index, sub, value.to_bytes(size, "little", signed=signed))


def _u(node: Any, index: int, sub: int = 0, signed: bool = False) -> int:
    return int.from_bytes(node.sdo.upload(index, sub), "little", signed=signed)


def _wait_bits(node: Any, mask: int, timeout: float) -> int:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        sw = _u(node, 0x6041)
        if sw & mask == mask:
            return sw
        time.sleep(0.02)
    raise AssertionError(f"statusword {sw:04X} never had {mask:04X}")


def test_undocumented_method_is_refused_with_0609_0030(hiwin: Any) -> None:
    node = hiwin.add_node(NODE)
    # 000 §3.2.4: methods 3-6, 15, 16, 19-22, 31, 32, 35 are not supported by the E series.
    for method in (3, 35, -1):
        with pytest.raises(SdoAbortedError) as exc:
            _w(node, 0x6098, 0, method, 1, signed=True)
        assert exc.value.code == 0x06090030
    assert _u(node, 0x6098, signed=True) == 37
    # LECSN-T -4 (stopper type) is documented but not simulated: refused the same way.
    lecsn = hiwin.add_node(NODE + 1)
    with pytest.raises(SdoAbortedError) as exc:
        _w(lecsn, 0x6098, 0, -4, 1, signed=True)
    assert exc.value.code == 0x06090030


def test_plain_canopen_homes_hiwin_with_37_and_with_the_home_switch(hiwin: Any) -> None:
    node = hiwin.add_node(NODE)
    node.sdo.RESPONSE_TIMEOUT = 0.5
    # Method 37 works without Operation enabled (000 §3.2.4 table 3.2.4.4).
    _w(node, 0x6060, 0, 6, 1)
    _w(node, 0x607C, 0, 2000, 4, signed=True)
    _w(node, 0x6098, 0, 37, 1)
    _w(node, 0x6040, 0, 0x06, 2)
    _w(node, 0x6040, 0, 0x16, 2)
    sw = _wait_bits(node, 0x1400, 1.0)
    assert not sw & 0x2000
    assert _u(node, 0x6064, signed=True) == 2000
    # Method 24: home switch, positive initial direction, home = lower switch edge (1.3 rev).
    _w(node, 0x6098, 0, 24, 1)
    _w(node, 0x607C, 0, 0, 4, signed=True)
    _w(node, 0x6099, 1, 4 * REV, 4)
    _w(node, 0x6099, 2, REV // 2, 4)
    _w(node, 0x609A, 0, 60 * REV, 4)
    for word in (0x06, 0x07, 0x0F):
        _w(node, 0x6040, 0, word, 2)
    _w(node, 0x6040, 0, 0x1F, 2)
    time.sleep(0.05)
    assert _u(node, 0x6041) & 0x3400 == 0  # In progress: bits 13, 12, 10 all 0.
    sw = _wait_bits(node, 0x1400, 5.0)
    assert not sw & 0x2000
    time.sleep(0.1)
    assert abs(_u(node, 0x6064, signed=True)) < REV // 500  # 6064h = 607Ch = 0 at home.
