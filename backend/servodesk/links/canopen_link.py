"""CANopen link: a canopen ``RemoteNode`` on any python-can interface.

One canopen ``Network`` (one python-can bus and its notifier thread) is shared by every link
on the same interface and channel, reference-counted, because most adapters can be opened
only once. canopen handles NMT, heartbeat, EMCY and the bus scan; object access uses
servodesk's asyncio SDO client (expedited and segmented, frames from
:mod:`servodesk.domain.sdo`), because awaiting the answer on the event loop is as fast as a
plain blocking canopen loop while a thread hand-over per request costs 40 %. Abort codes
become :class:`ObjectAccessError` with the CiA 301 text.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from typing import Any

import can
import canopen

from servodesk.domain import sdo
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


#: Longest segmented upload accepted (a DOMAIN could be larger; servodesk does not read those).
_MAX_SEGMENTED = 1 << 20


def _expire(waiter: asyncio.Future[bytes]) -> None:
    if not waiter.done():
        waiter.set_exception(TimeoutError())


def _abort_error(code: int, address: ObjectAddress, op: str) -> ObjectAccessError:
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
        self._waiter: asyncio.Future[bytes] | None = None
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
            # servodesk's own SDO client answers on this COB-ID; canopen's would queue every
            # answer forever, so it is taken off the subscription.
            network.unsubscribe(0x580 + self.params.node_id, node.sdo.on_response)
            network.subscribe(0x580 + self.params.node_id, self._on_sdo_frame)
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
            network.unsubscribe(0x580 + self.params.node_id, self._on_sdo_frame)
            # Give canopen back its own subscription so that remove_network() can drop it.
            network.subscribe(0x580 + self.params.node_id, node.sdo.on_response)
            node.remove_network()
            network.pop(node.id, None)
            pool.release(self.params)

    def _require(self) -> canopen.RemoteNode:
        if self._node is None:
            raise LinkError("the CANopen link is not open")
        return self._node

    # SDO client (CiA 301 §7.2.4): frames from servodesk.domain.sdo, sent from the event
    # loop; the answer comes back from canopen's bus thread through a future. Awaiting the
    # answer on the loop avoids two thread hand-overs per request (bench/bench_sdo.py).

    def _on_sdo_frame(self, can_id: int, data: bytearray, timestamp: float) -> None:
        loop, frame = self._loop, bytes(data)
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._deliver, frame)

    def _deliver(self, frame: bytes) -> None:
        waiter = self._waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(frame)
        # Otherwise a late answer to a request that already timed out: dropped.

    async def _transact(self, request: bytes, address: ObjectAddress) -> bytes:
        network = self._network
        if network is None or self._loop is None:
            raise LinkError("the CANopen link is not open")
        node_id = self.params.node_id
        # CiA 301 leaves retries to the client; like canopen, send once more on silence.
        for attempt in range(2):
            waiter: asyncio.Future[bytes] = self._loop.create_future()
            self._waiter = waiter
            # A plain timer on the future: lighter than asyncio.timeout()'s task cancellation,
            # which showed in the per-request cost (bench/bench_sdo.py).
            timer = self._loop.call_later(self.request_timeout, _expire, waiter)
            try:
                network.send_message(0x600 + node_id, request)
                return await waiter
            except TimeoutError:
                if attempt == 0:
                    continue
                with contextlib.suppress(Exception):
                    network.send_message(
                        0x600 + node_id,
                        sdo.abort(address.index, address.subindex, sdo.ABORT_TIMEOUT),
                    )
                raise LinkTimeoutError(
                    f"{address}: no SDO response from node {node_id} within "
                    f"{self.request_timeout:g} s",
                    hint="check the node id, bitrate, cabling and that the drive is powered",
                ) from None
            finally:
                timer.cancel()
                self._waiter = None
        raise AssertionError("unreachable")

    async def _aread(self, address: ObjectAddress) -> bytes:
        idx, sub = address.index, address.subindex
        try:
            start = sdo.parse_initiate_upload(
                await self._transact(sdo.initiate_upload(idx, sub), address), idx, sub
            )
            if start.data is not None:
                return start.data
            out, toggle = bytearray(), 0
            while True:
                seg = sdo.parse_upload_segment(
                    await self._transact(sdo.upload_segment(toggle), address), toggle, idx, sub
                )
                out += seg.data
                if seg.last:
                    break
                toggle ^= 1
                if len(out) > _MAX_SEGMENTED:
                    raise sdo.SdoProtocolError("upload longer than servodesk accepts")
            if start.size is not None and len(out) != start.size:
                raise sdo.SdoProtocolError(f"announced {start.size} bytes, sent {len(out)}")
            return bytes(out)
        except sdo.SdoAbort as exc:
            raise _abort_error(exc.code, address, "read") from exc
        except sdo.SdoProtocolError as exc:
            raise self._protocol_error(exc, address) from exc

    async def _awrite(self, address: ObjectAddress, data: bytes) -> None:
        idx, sub = address.index, address.subindex
        try:
            sdo.parse_initiate_download(
                await self._transact(sdo.initiate_download(idx, sub, data), address), idx, sub
            )
            if 0 < len(data) <= 4:
                return
            toggle = 0
            for pos in range(0, max(len(data), 1), 7):
                chunk = data[pos : pos + 7]
                last = pos + 7 >= len(data)
                answer = await self._transact(sdo.download_segment(toggle, chunk, last), address)
                sdo.parse_download_segment(answer, toggle, idx, sub)
                toggle ^= 1
        except sdo.SdoAbort as exc:
            raise _abort_error(exc.code, address, "write") from exc
        except sdo.SdoProtocolError as exc:
            raise self._protocol_error(exc, address) from exc

    def _protocol_error(self, exc: sdo.SdoProtocolError, address: ObjectAddress) -> LinkError:
        if self._network is not None:
            with contextlib.suppress(Exception):
                self._network.send_message(
                    0x600 + self.params.node_id,
                    sdo.abort(address.index, address.subindex, exc.abort_code),
                )
        return LinkError(
            f"{address}: the drive's SDO answer does not follow CiA 301: {exc}",
            hint="another master may be talking to this node, or the node id is shared",
        )

    async def identity(self) -> Identity:
        async def u32(index: int, sub: int) -> int | None:
            try:
                return int.from_bytes((await self.read(ObjectAddress(index, sub)))[:4], "little")
            except ObjectAccessError:
                return None

        async def text(index: int) -> str | None:
            try:
                v = codec(DataType.VISIBLE_STRING).decode(await self.read(ObjectAddress(index)))
                return str(v)
            except ObjectAccessError:
                return None

        return Identity(
            vendor_id=await u32(0x1018, 1),
            product_code=await u32(0x1018, 2),
            revision=await u32(0x1018, 3),
            serial=await u32(0x1018, 4),
            device_name=await text(0x1008),
            hardware_version=await text(0x1009),
            software_version=await text(0x100A),
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

    def heartbeat_age(self) -> float | None:
        if self.last_heartbeat is None:
            return None
        return time.monotonic() - self.last_heartbeat

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
