"""Cyclic frames on a CAN bus through canopen's ``Network``: PDO frames and SYNC.

Frames longer than 8 bytes go out as CAN FD frames (the twins of the EtherCAT, CC-Link IE
TSN and PROFINET families carry their process data in one FD frame per PDO; docs/pdo.md).
Receiving uses canopen's subscription table, which is called on the bus's notifier thread.
"""

from __future__ import annotations

from typing import Any

import can
import canopen

from servodesk.links.cyclic import CyclicTransport, FrameCallback, padded_length

#: CiA 301 §7.2.5.1: the SYNC producer's default COB-ID.
SYNC_COB_ID = 0x080


class CanopenCyclic(CyclicTransport):
    def __init__(self, network: canopen.Network) -> None:
        self._network = network
        # canopen calls subscribers as cb(can_id, data, timestamp); ours take (data, time).
        self._adapters: dict[tuple[int, FrameCallback], Any] = {}

    @property
    def bus_key(self) -> object:
        # canopen's Network is a mutable mapping (unhashable); the pool shares one per bus.
        return id(self._network)

    def subscribe(self, ident: int, callback: FrameCallback) -> None:
        def adapter(can_id: int, data: bytearray, timestamp: float) -> None:
            callback(bytes(data), timestamp)

        self._adapters[(ident, callback)] = adapter
        self._network.subscribe(ident, adapter)

    def unsubscribe(self, ident: int, callback: FrameCallback) -> None:
        adapter = self._adapters.pop((ident, callback), None)
        if adapter is not None:
            self._network.unsubscribe(ident, adapter)

    def send(self, ident: int, data: bytes) -> None:
        bus = self._network.bus
        if bus is None:
            return
        length = len(data)
        if length <= 8:
            msg = can.Message(arbitration_id=ident, data=data, is_extended_id=False)
        else:
            padded = data + bytes(padded_length(length) - length)
            msg = can.Message(arbitration_id=ident, data=padded, is_extended_id=False, is_fd=True)
        # canopen serialises sends of all threads with this lock (SDO, NMT, ours).
        with self._network.send_lock:
            bus.send(msg)

    def send_rtr(self, ident: int, length: int) -> None:
        bus = self._network.bus
        if bus is None:
            return
        msg = can.Message(
            arbitration_id=ident, is_remote_frame=True, dlc=min(8, length), is_extended_id=False
        )
        with self._network.send_lock:
            bus.send(msg)

    def send_sync(self, counter: int | None = None) -> None:
        self.send(SYNC_COB_ID, b"" if counter is None else bytes([counter]))
