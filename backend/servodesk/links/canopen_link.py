"""CANopen link: a canopen ``RemoteNode`` on any python-can interface.

One canopen ``Network`` (one python-can bus and its notifier thread) is shared by every link
on the same interface and channel, reference-counted, because most adapters can be opened
only once. Object access goes through the node's SDO client (expedited or segmented, chosen
by canopen from the size); abort codes become :class:`ObjectAccessError` with the CiA 301
text.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

import can
import canopen
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.sdo_abort import ABORT_HINTS, abort_text
from servodesk.errors import (
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ValidationError,
)
from servodesk.links.base import DriveLink, Identity, LinkParams

log = logging.getLogger(__name__)

# canopen's NMT state names, by the commands of DriveLink.nmt().
_NMT_COMMANDS = {
    "start": "OPERATIONAL",
    "stop": "STOPPED",
    "preop": "PRE-OPERATIONAL",
    "reset": "RESET",
    "reset_comm": "RESET COMMUNICATION",
}
_NMT_STATE_NAMES = {
    "OPERATIONAL": "operational",
    "PRE-OPERATIONAL": "preop",
    "STOPPED": "stopped",
    "INITIALISING": "initialising",
}


class _SharedNetwork:
    """A canopen Network with a reference count."""

    def __init__(self, network: canopen.Network) -> None:
        self.network = network
        self.users = 0


class NetworkPool:
    """Opens each (interface, channel) once and shares it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._nets: dict[tuple[str, str], _SharedNetwork] = {}

    def acquire(self, params: LinkParams) -> canopen.Network:
        key = params.bus_key()
        with self._lock:
            shared = self._nets.get(key)
            if shared is None:
                if params.interface not in can.interfaces.VALID_INTERFACES:
                    known = ", ".join(sorted(can.interfaces.VALID_INTERFACES))
                    raise ValidationError(
                        f"unknown CAN interface {params.interface!r}",
                        field="interface",
                        hint=f"python-can interfaces: {known}",
                    )
                network = canopen.Network()
                kwargs: dict[str, Any] = {"interface": params.interface, "channel": params.channel}
                if params.bitrate:
                    kwargs["bitrate"] = params.bitrate
                kwargs.update(params.extra)
                try:
                    network.connect(**kwargs)
                except Exception as exc:  # python-can raises many types per backend.
                    raise NotFoundError(
                        f"cannot open CAN interface {params.interface!r} channel "
                        f"{params.channel!r}: {exc}",
                        hint="check the interface name, channel and that the adapter is present",
                    ) from exc
                shared = _SharedNetwork(network)
                self._nets[key] = shared
            shared.users += 1
            return shared.network

    def release(self, params: LinkParams) -> None:
        key = params.bus_key()
        with self._lock:
            shared = self._nets.get(key)
            if shared is None:
                return
            shared.users -= 1
            if shared.users <= 0:
                del self._nets[key]
                try:
                    shared.network.disconnect()
                except Exception:  # Closing a dead adapter must not mask the caller's error.
                    log.exception("disconnecting %s", key)


pool = NetworkPool()


def _sdo_error(exc: SdoAbortedError, address: ObjectAddress, op: str) -> ObjectAccessError:
    code = int(exc.code)
    meaning = abort_text(code)
    return ObjectAccessError(
        f"{op} {address} refused by the drive: {meaning} (0x{code:08X})",
        code=code,
        meaning=meaning,
        protocol="sdo",
        address=str(address),
        hint=ABORT_HINTS.get(code),
    )


class CanopenLink(DriveLink):
    """A CiA 301 node on a CAN bus, accessed as an SDO client."""

    fieldbus = "canopen"

    def __init__(self, params: LinkParams) -> None:
        if not 1 <= params.node_id <= 127:
            raise ValidationError(
                f"node id {params.node_id} is outside 1..127",
                field="node_id",
                hint="CANopen node ids are 1 to 127",
            )
        super().__init__(params)
        self._network: canopen.Network | None = None
        self._node: canopen.RemoteNode | None = None
        self.last_heartbeat: float | None = None
        self.nmt_state: str = "unknown"

    # Hooks -------------------------------------------------------------------------

    def _open(self) -> None:
        network = pool.acquire(self.params)
        try:
            node = canopen.RemoteNode(self.params.node_id, canopen.ObjectDictionary())
            node.sdo.RESPONSE_TIMEOUT = self.params.timeout
            if self.params.node_id in network:
                raise LinkError(
                    f"node {self.params.node_id} on {self.params.channel} is already open",
                    hint="close the other session first",
                )
            network.add_node(node)
        except Exception:
            pool.release(self.params)
            raise
        node.nmt.add_heartbeat_callback(self._on_heartbeat)
        node.emcy.add_callback(self._on_emcy)
        self._network, self._node = network, node

    def _close(self) -> None:
        network, node = self._network, self._node
        self._network = self._node = None
        if network is not None and node is not None:
            node.remove_network()
            network.pop(node.id, None)
            pool.release(self.params)

    def _require(self) -> canopen.RemoteNode:
        if self._node is None:
            raise LinkError("the CANopen link is not open")
        return self._node

    def _read(self, address: ObjectAddress) -> bytes:
        node = self._require()
        try:
            data: bytes = node.sdo.upload(address.index, address.subindex)
        except SdoAbortedError as exc:
            raise _sdo_error(exc, address, "read") from exc
        except SdoCommunicationError as exc:
            raise LinkTimeoutError(
                f"read {address}: no SDO response from node {node.id} ({exc})",
                hint="check the node id, bitrate, cabling and that the drive is powered",
            ) from exc
        return bytes(data)

    def _write(self, address: ObjectAddress, data: bytes) -> None:
        node = self._require()
        try:
            node.sdo.download(address.index, address.subindex, data)
        except SdoAbortedError as exc:
            raise _sdo_error(exc, address, "write") from exc
        except SdoCommunicationError as exc:
            raise LinkTimeoutError(
                f"write {address}: no SDO response from node {node.id} ({exc})",
                hint="check the node id, bitrate, cabling and that the drive is powered",
            ) from exc

    def _identity(self) -> Identity:
        def u32(index: int, sub: int) -> int | None:
            try:
                return int(codec(DataType.UNSIGNED32).decode(self._read(ObjectAddress(index, sub))))
            except ObjectAccessError:
                return None

        def text(index: int) -> str | None:
            try:
                v = codec(DataType.VISIBLE_STRING).decode(self._read(ObjectAddress(index, 0)))
                return str(v)
            except ObjectAccessError:
                return None

        return Identity(
            vendor_id=u32(0x1018, 1),
            product_code=u32(0x1018, 2),
            revision=u32(0x1018, 3),
            serial=u32(0x1018, 4),
            device_name=text(0x1008),
            hardware_version=text(0x1009),
            software_version=text(0x100A),
        )

    def _nmt(self, command: str) -> None:
        node = self._require()
        state = _NMT_COMMANDS.get(command)
        if state is None:
            raise ValidationError(
                f"unknown NMT command {command!r}", hint=f"use one of {', '.join(_NMT_COMMANDS)}"
            )
        node.nmt.state = state

    def _network_state(self) -> str:
        return self.nmt_state

    # Bus-thread callbacks ------------------------------------------------------------------

    def _on_heartbeat(self, state: int) -> None:
        self.last_heartbeat = time.monotonic()
        name = {0x00: "bootup", 0x04: "stopped", 0x05: "operational", 0x7F: "preop"}.get(
            state & 0x7F, f"0x{state:02X}"
        )
        if name != self.nmt_state:
            self.nmt_state = name
            self._emit("nmt", state=name)

    def _on_emcy(self, err: Any) -> None:
        self._emit(
            "emcy", code=int(err.code), register=int(err.register), data=bytes(err.data).hex()
        )


def scan(params: LinkParams, timeout: float = 0.5) -> list[int]:
    """Node ids that answer on the bus (SDO upload of 1000h to every node, CiA 301)."""
    network = pool.acquire(params)
    try:
        network.scanner.reset()
        network.scanner.search()
        time.sleep(timeout)
        return sorted(set(network.scanner.nodes))
    finally:
        pool.release(params)
