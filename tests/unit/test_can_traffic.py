"""The status bar's CAN counts (links/can_traffic.py): frames, bits and the load they make."""

from __future__ import annotations

import time

import can

from servodesk.links.can_traffic import BusTraffic, frame_bits


def test_the_load_is_the_received_frames_bits_over_the_bitrate() -> None:
    # ISO 11898-1: 47 bits + 8 per data byte (11-bit id), 67 + 8 per byte (29-bit id).
    assert frame_bits(can.Message(arbitration_id=0x601, data=bytes(8), is_extended_id=False)) == 111
    assert frame_bits(can.Message(arbitration_id=0x1, data=b"", is_extended_id=True)) == 67
    traffic = BusTraffic("socketcan", 125_000)
    traffic._started -= 10
    now = int(time.monotonic())
    # 1000 frames of 111 bits in each of the last 5 whole seconds.
    for second in range(now - 5, now):
        traffic._buckets.append([second, 1000, 111_000])
    view = traffic.view(None)
    frames_now = view.frames_per_s
    assert frames_now in (1000.0, 800.0)  # 800: the clock ticked a second during the test
    if frames_now == 1000.0:
        assert view.load_percent == 88.8  # 111 kbit/s of 125 kbit/s
    # SocketCAN hands error frames to python-can: counted, 0 when none came.
    assert view.error_frames == 0
    traffic.on_message_received(can.Message(is_error_frame=True))
    assert traffic.view(None).error_frames == 1


def test_a_bus_without_a_bitrate_or_a_reporting_interface_says_so() -> None:
    traffic = BusTraffic("virtual", None)
    traffic.on_message_received(can.Message(arbitration_id=0x181, data=bytes(4)))
    with can.Bus(interface="virtual", channel="traffic-unit") as bus:
        view = traffic.view(bus)
    assert view.load_percent is None and "without a bitrate" in view.load_basis
    # python-can's base class answers "active" for any bus: not reported, not invented.
    assert view.bus_state is None and view.error_frames is None
