"""What one CAN bus carries, counted from the frames servodesk receives on it.

A python-can listener on the shared bus's notifier (links/canopen_link.py ``NetworkPool``)
counts every frame the bus delivers, in one-second buckets, for the status bar (issue 48).
Nothing is sent to produce the numbers. What it cannot see, it does not invent:

- servodesk's own frames: python-can does not hand a bus's sent frames back to its receivers
  (``receive_own_messages`` is off, and must stay so: canopen would dispatch them), so the
  frames per second and the load are those of the *other* nodes (the drives' answers, PDOs,
  heartbeats, EMCY). The basis sentence says so.
- the load needs the bitrate; a bus opened without one (the virtual bus) has frames only.
- the controller's state (error active / passive / bus off) only where the python-can
  interface reports it (pcan, ixxat, systec, etas); python-can's base class answers "active"
  for every other, which would be made up, so those answer None.
- error frames only where the interface delivers them to the application (SocketCAN:
  python-can sets CAN_RAW_ERR_FILTER unless told not to); elsewhere None.
"""

from __future__ import annotations

import threading
import time
from collections import deque

import can

from servodesk.links.base import TrafficView

#: Seconds of traffic the rate and the load are averaged over.
WINDOW_S = 5
#: Interfaces that hand error frames to the application (python-can socketcan, default
#: ``ignore_rx_error_frames=False``).
ERROR_FRAME_INTERFACES = frozenset({"socketcan"})


def frame_bits(msg: can.Message) -> int:
    """Bits of a classic CAN data or remote frame on the wire, bit stuffing not counted (ISO
    11898-1 §10.4: SOF, arbitration, control, data, CRC, ACK, EOF and the 3-bit intermission;
    47 + 8 x data bytes with an 11-bit identifier, 67 + 8 x data bytes with a 29-bit one).
    Stuffing adds up to a fifth more, so a load from these is a lower bound."""
    data = 0 if msg.is_remote_frame else len(msg.data)
    return (67 if msg.is_extended_id else 47) + 8 * data


class BusTraffic(can.Listener):
    """Frames and bits received per second over the last :data:`WINDOW_S` seconds.

    ``on_message_received`` runs on the notifier's thread; :meth:`view` on the event loop:
    the buckets are guarded by a lock (two integer additions per frame).
    """

    def __init__(self, interface: str, bitrate: int | None) -> None:
        self.interface = interface
        self.bitrate = bitrate
        self._lock = threading.Lock()
        #: (second, frames, bits) per whole second, the newest last.
        self._buckets: deque[list[int]] = deque(maxlen=WINDOW_S + 1)
        self._started = time.monotonic()
        self.frames = 0
        self.error_frames = 0
        self.fd_frames = 0

    def on_message_received(self, msg: can.Message) -> None:
        second = int(time.monotonic())
        with self._lock:
            if msg.is_error_frame:
                self.error_frames += 1
                return
            self.frames += 1
            if msg.is_fd:
                # A CAN FD frame's data phase runs at its own bitrate, which python-can does
                # not tell per frame: the load is not computed on such a bus.
                self.fd_frames += 1
            buckets = self._buckets
            if not buckets or buckets[-1][0] != second:
                buckets.append([second, 0, 0])
            bucket = buckets[-1]
            bucket[1] += 1
            bucket[2] += frame_bits(msg)

    def view(self, bus: can.BusABC | None) -> TrafficView:
        now = time.monotonic()
        second = int(now)
        with self._lock:
            # Whole seconds before the present one, and no further back than the counting.
            span = min(WINDOW_S, max(1, int(now - self._started)))
            recent = [b for b in self._buckets if second - span <= b[0] < second]
            frames = sum(b[1] for b in recent)
            bits = sum(b[2] for b in recent)
            fd = self.fd_frames
            errors = self.error_frames
        per_s = frames / span
        basis = (
            f"frames received from the other nodes over the last {span} s "
            "(servodesk's own not counted)"
        )
        load: float | None = None
        if fd:
            basis += "; no load: CAN FD frames (their data phase's bitrate is not known)"
        elif not self.bitrate:
            basis += "; no load: the bus was opened without a bitrate"
        else:
            load = round(100.0 * bits / span / self.bitrate, 1)
            basis += f"; load = their bits without stuffing / {self.bitrate} bit/s"
        return TrafficView(
            frames_per_s=round(per_s, 1),
            load_percent=load,
            load_basis=basis,
            error_frames=errors if self.interface in ERROR_FRAME_INTERFACES else None,
            bus_state=reported_state(bus),
        )


def reported_state(bus: can.BusABC | None) -> str | None:
    """The controller's state as the interface reports it ("active", "passive", "error"), or
    None where the interface does not override python-can's default (which is always
    "active" whatever the controller does)."""
    if bus is None or type(bus).state is can.BusABC.state:
        return None
    try:
        return str(bus.state.name).lower()
    except Exception:  # A driver call that fails: not reported, not a failed status.
        return None
