"""Cyclic process data on an EtherCAT line: the :class:`~servodesk.links.cyclic.CyclicTransport`
of the EtherCAT link.

The cyclic exchange (services/cyclic.py) speaks in PDO frames by identifier and a SYNC that
paces them, as on CAN. On EtherCAT a slave's assigned RxPDO is its output image and its
assigned TxPDO its input image (HIWIN 000 §2.8: one of each, assigned in 1C12h / 1C13h), so
the identifiers are those the exchange already uses for them, 200h + node and 180h + node, and
"SYNC" is one process data cycle of the line: SOEM's ``send_processdata`` (one LRW through
the FMMUs) and ``receive_processdata``, after which every subscribed slave's inputs are handed
on. The transports of the slaves of one line share their master's receivers and outputs, so
that the one cycle thread of the line (one "SYNC producer" per bus) serves them all.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from servodesk.links.cyclic import CyclicTransport
from servodesk.links.ethercat_link import PROCESS_DATA_TIMEOUT_US

if TYPE_CHECKING:
    from servodesk.links.ethercat_link import EthercatLink


class EthercatCyclic(CyclicTransport):
    """The process data of the slaves of one EtherCAT line (see the module docstring)."""

    def __init__(self, link: EthercatLink) -> None:
        self._shared = link.line()
        self._channel = link.params.channel
        # A new exchange starts without the outputs of the last one (it may run inputs only).
        self._shared.outputs.pop(link.params.node_id - 1, None)
        #: Cycles whose working counter fell short (a slave did not take part).
        self.missed = 0

    @property
    def bus_key(self) -> object:
        return ("ethercat", self._channel)

    def subscribe(self, ident: int, callback: Callable[[bytes, float], None]) -> None:
        with self._shared.lock:
            self._shared.receivers.setdefault(ident, []).append(callback)

    def unsubscribe(self, ident: int, callback: Callable[[bytes, float], None]) -> None:
        with self._shared.lock:
            found = self._shared.receivers.get(ident, [])
            if callback in found:
                found.remove(callback)

    def send(self, ident: int, data: bytes) -> None:
        """The outputs of slave ``ident - 200h`` for the next cycle."""
        position = ident - 0x200 - 1
        if 0 <= position < self._shared.slaves:
            self._shared.outputs[position] = bytes(data)

    def send_rtr(self, ident: int, length: int) -> None:
        """EtherCAT has no remote frames: the inputs come with every cycle."""

    def send_sync(self, counter: int | None = None) -> None:
        """One process data cycle of the line; each subscribed slave's inputs handed on."""
        shared = self._shared
        with shared.lock:
            if not shared.mapped:
                return
            master = shared.master
            slaves = master.slaves
            for position, data in shared.outputs.items():
                out = slaves[position].output
                if len(out):
                    slaves[position].output = data[: len(out)].ljust(len(out), b"\x00")
            master.send_processdata()
            wkc = int(master.receive_processdata(PROCESS_DATA_TIMEOUT_US))
            if wkc < int(master.expected_wkc):
                self.missed += 1
                return
            now = time.monotonic()
            inputs = [
                (callbacks, bytes(slaves[ident - 0x180 - 1].input))
                for ident, callbacks in shared.receivers.items()
                if callbacks and 0 <= ident - 0x180 - 1 < len(slaves)
            ]
        for callbacks, data in inputs:
            for cb in list(callbacks):
                cb(data, now)
