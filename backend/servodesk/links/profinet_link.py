"""PROFINET object access: PROFIdrive parameter access over PNIO-CM record read / write.

Where the drive is: ``interface`` ``profinet``, ``channel`` ``host`` or ``host:port`` (the
device's IP address; port 34964, the PNIO-CM RPC port, by default), ``node_id`` the drive
object's DO-ID (1 on the LECSN-T, P975.7, 004 §20.4.3.7).

Opening the link sets up a supervisor AR with device access (``Connect``); closing it ends
the AR (``Release``). Each object access is one PROFIdrive parameter request written to
record 0xB02E of slot 1 / subslot 1 and its response read back (004 §20.4.1); objects are
parameters by the PNU rule of 004 §20.1.5 (:mod:`servodesk.domain.profidrive`). Values come
back big-endian with their format and are handed on in CoE byte order, like every link's.

What the link learns from the device, once per parameter: whether it is an array (the
identifier's bit 14, description element 1), which decides what CoE sub 0 means (the value
of a simple parameter, the number of entries of an array: description element 2), and the
format of each element it reads, which a change request must name.

Cyclic data (the telegram, 004 §20.1.2) runs in a second AR, servodesk's IO controller AR
(links/profinet_io.py), set up when the PDO page starts cyclic data (``nmt("start")``) and
ended when it stops; a drive whose IO AR is the PLC's refuses it. PROFINET has no NMT
otherwise: the drive's communication state belongs to its IO controller.

The AR is an IO supervisor AR with device access (ARType 0006h, DeviceAccess): the
LEC-S-NP's Anybus CompactCom 40 takes IO supervisors next to the PLC's IO AR, and such an AR
needs no expected submodules from the GSD file (docs/profinet.md "Which AR"). Its
CMInitiatorMacAdd is the MAC of the host's NIC that reaches the device; the RPC object UUID
carries the device's vendor and device ID (``extra`` vendor_id / device_id, from DCP; the
vendor from I&M0 once it is read). A call longer than one datagram goes in CL-RPC fragments
and a fragmented answer is put together again.

A request without an answer is sent once more with the same sequence number, which a
device answers from its last response without carrying the call out twice. An AR the device
no longer knows (it was restarted) is set up again once.

Over 700 lines: one link, the contract's hooks for PNIO-CM (the AR's Connect and Release, record
read and write) and the PROFIdrive parameter requests over them, which share the AR and what it
learnt per parameter.
"""

from __future__ import annotations

import asyncio
import dataclasses
import errno
import socket
import struct
import time
import uuid
from collections.abc import Awaitable, Callable, Sequence
from typing import Any, TypeVar

from servodesk.domain import pnio
from servodesk.domain import profidrive as pd
from servodesk.domain.address import ObjectAddress
from servodesk.errors import (
    ConflictError,
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.links.base import DriveIdentity, DriveLink, LinkParams
from servodesk.links.profinet_io import (
    AR_IO,
    AR_SUPERVISOR,
    PERIODS_MS,
    IoController,
    ProfinetCyclic,
    check_nic,
    reduction_ratio,
)

#: The interface name of this link (the transport: PNIO-CM connectionless RPC on UDP).
INTERFACE = "profinet"
#: Sends of one RPC call before it times out (the first and one resend).
SENDS = 2
#: Where the PROFIdrive drive object's parameter access record is.
DRIVE_SLOT = 1
DRIVE_SUBSLOT = 1
#: The station name servodesk gives as the AR's initiator.
INITIATOR_NAME = "servodesk"
#: The AR's CMInitiatorActivityTimeoutFactor (x 100 ms): a device drops a supervisor AR
#: after this long without a record read or write (IEC 61158-6-10 CMSM). An open session
#: polls the statusword at 20 Hz, so its AR lives as long as it does; one whose servodesk
#: died without a Release stops blocking the drive's DCP changes 10 s later. An AR that
#: timed out while idle is set up again by the next access (``_with_ar``).
ACTIVITY_TIMEOUT_FACTOR = 100
#: Bytes per block of a string longer than one response: 4 + 2 + 232 = 238 of 240 bytes.
BLOCK_BYTES = 232
#: How long to wait for a parameter response that is not ready yet (PNIORW B5h), per poll.
NOT_READY_POLL_S = 0.002

_AR_UNKNOWN = (pnio.DECODE_PNIO, pnio.CMRPC, 0x05)
#: ioctls for a network interface's IPv4 address and MAC (linux/sockios.h).
_SIOCGIFADDR = 0x8915
_SIOCGIFHWADDR = 0x8927
#: The initiator's own object UUID (made once: a UUID from text is costly).
_INITIATOR_OBJECT = pnio.object_uuid(0, 0)
T = TypeVar("T")


def interface_mac_for(local_ip: str) -> bytes:
    """The MAC of the network interface that holds ``local_ip`` (the address the host sends
    to the device from); six zero bytes for loopback or where none holds it. The ARBlockReq's
    CMInitiatorMacAdd is the initiator's own MAC (IEC 61158-6-10 ARBlockReq)."""
    import fcntl

    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for _index, name in socket.if_nameindex():
            req = struct.pack("256s", name.encode()[:15])
            try:
                addr = fcntl.ioctl(probe.fileno(), _SIOCGIFADDR, req)
            except OSError:
                continue  # no IPv4 address on it
            if socket.inet_ntoa(addr[20:24]) != local_ip:
                continue
            try:
                hw = fcntl.ioctl(probe.fileno(), _SIOCGIFHWADDR, req)
            except OSError:
                return bytes(6)
            return bytes(hw[18:24])
    finally:
        probe.close()
    return bytes(6)


class _ArLost(Exception):
    """The device no longer knows the AR (restarted, or it timed the AR out)."""


class ProfinetLink(DriveLink):
    """One PROFIdrive drive object of a PROFINET IO device, reached by record access."""

    fieldbus = "profinet"
    sends_nmt = False
    #: :meth:`read_many` reads several objects in one request (the scope samples together).
    reads_many_at_once = True
    #: Why servodesk does not write the process data mapping here (services/pdo.py).
    mapping_owner = (
        "the telegram and its mapping are chosen in the IO controller's configuration tool "
        "with the GSD file (004 §20.1.1); a supervisor does not write them. Edit and export "
        "the layout here for that tool"
    )
    #: Why the telegram's cyclic data is not servodesk's here (links/cyclic.py
    #: ``no_cyclic_reason``) when no network interface carries RT frames to the drive.
    no_io_nic = (
        "servodesk reaches this drive as an IO supervisor (an IO supervisor AR with device "
        "access, ARType 0006h) for its parameters; its telegram is exchanged with an IO "
        "controller set up from the GSD file (004 §20.1.1), and servodesk is one only where a "
        "network interface carries its RT frames to the drive"
    )

    #: Cyclic data always carries outputs: an IO controller sends the setpoint telegram every
    #: cycle (services/pdo.py starts it from the drive's present values).
    cyclic_outputs_always = True
    #: Send clock 1 ms (SendClockFactor 32) x the reduction ratios servodesk offers.
    cyclic_periods_ms = PERIODS_MS
    #: The telegram is the expected submodule of servodesk's IO AR (:meth:`prepare_io`).
    sets_up_telegram = True

    def __init__(self, params: LinkParams) -> None:
        if params.interface != INTERFACE:
            raise ValidationError(
                f"interface {params.interface!r} does not carry PROFINET",
                field="interface",
                hint=f"use interface {INTERFACE} with channel host or host:port",
            )
        if not 1 <= params.node_id <= 255:
            raise ValidationError(
                f"node id {params.node_id} is no PROFIdrive DO-ID (1..255)",
                field="node_id",
                hint="the node id of a PROFINET drive is its drive object's DO-ID: 1 on the "
                "LECSN-T (P975.7)",
            )
        self.host, self.port = pnio.parse_channel(params.channel)
        super().__init__(params)
        self._sock: socket.socket | None = None
        self._activity = uuid.uuid4()
        self._seqnum = 0
        self._ar_uuid = uuid.uuid4()
        self._session_key = 0
        self._record_seq = 0
        self._reference = 0
        self._server_boot = 0
        #: The object UUID of the device instance (DEA00000-6C97-11D1-8271-IIII-DDDD-VVVV,
        #: IEC 61158-6-10): its vendor and device ID, given by the caller from DCP Identify
        #: (``extra`` vendor_id / device_id) or, for the vendor, learnt from I&M0.
        self.vendor_id = int(params.extra.get("vendor_id", 0))
        self.device_id = int(params.extra.get("device_id", 0))
        self._object_uuid = pnio.object_uuid(self.vendor_id, self.device_id)
        #: The initiator MAC sent in the ARBlockReq: the host NIC's that reaches the device.
        self.initiator_mac = bytes(6)
        #: Longest request body in one datagram (a longer one goes in fragments), and
        #: whether request fragments ask for fragment acknowledgements.
        self.max_fragment_body = pnio.MAX_DATAGRAM - pnio.RPC_HEADER_LEN
        self.fragment_acks = False
        self._reply = pnio.Reassembly()
        #: Learnt from the device: PNU -> is an array; (PNU, PNU subindex) -> format.
        self._arrays: dict[int, bool] = {}
        self._formats: dict[tuple[int, int], int] = {}
        #: Answers dropped (another call's, or no PNIO response) and ARs set up again.
        self.stale = 0
        self.reconnects = 0
        #: The IO controller AR of cyclic data (links/profinet_io.py), while it runs, and
        #: what the next one is set up for (:meth:`prepare_io`).
        self.io: IoController | None = None
        self._io_plan: tuple[int, int, int, float] | None = None
        self._io_first = b""
        self._io_running: tuple[int, int, int, float] | None = None

    @property
    def no_cyclic(self) -> str | None:
        """Why there is no cyclic data on this link; None when there can be."""
        try:
            check_nic(self.params.extra.get("nic"), self.host)
        except ServodeskError as exc:
            return f"{self.no_io_nic}: {exc.message}" + (f" ({exc.hint})" if exc.hint else "")
        return None

    @property
    def ar_in_use(self) -> str:
        """The ARs this session has with the drive, in words (API: the session's ``ar``)."""
        if self.io is not None:
            return f"{AR_SUPERVISOR} and {AR_IO}"
        return AR_SUPERVISOR

    def prepare_io(
        self,
        telegram: int | None,
        rx: int,
        tx: int,
        period: float,
        outputs: bool,
        first: bytes = b"",
    ) -> None:
        """What the next IO AR carries: the drive's telegram (P922) and the lengths of its
        setpoint (``rx``) and actual-value (``tx``) telegrams, at ``period``, its first
        outputs ``first`` (services/pdo.py)."""
        if not outputs:
            raise ConflictError(
                "cyclic data over PROFINET runs with outputs on",
                hint="an IO controller sends the drive its setpoint telegram every cycle; turn "
                "outputs on (the output image starts from the drive's present values)",
            )
        if telegram is None or not rx or not tx:
            raise ConflictError(
                "the drive names no telegram with setpoint and actual values (P922)",
                hint="select telegram 1, 100, 102 or 103 in the drive",
            )
        reduction_ratio(period)  # a cycle servodesk does not offer: refused before the AR
        self._io_plan = (telegram, rx, tx, period)
        self._io_first = first

    def cyclic_transport(self) -> ProfinetCyclic:
        return ProfinetCyclic(self)

    # Hooks -------------------------------------------------------------------------

    def _open(self) -> None:
        try:
            infos = socket.getaddrinfo(self.host, self.port, socket.AF_INET, socket.SOCK_DGRAM)
        except OSError as exc:
            raise LinkError(
                f"cannot resolve {self.host!r}: {exc}", hint="check the device's IP address"
            ) from exc
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.connect(infos[0][4])
            sock.settimeout(self.params.timeout)
            self.initiator_mac = interface_mac_for(sock.getsockname()[0])
            self._sock = sock
            self._connect_blocking()
            sock.setblocking(False)
        except BaseException:
            self._sock = None
            sock.close()
            raise

    def _close(self) -> None:
        self._end_io()
        sock, self._sock = self._sock, None
        if sock is None:
            return
        try:
            # End the AR, so the device's AR resources are free for the next client.
            sock.settimeout(min(0.3, self.params.timeout))
            args = pnio.release_block(
                pnio.BLOCK_RELEASE_REQ, self._ar_uuid, self._session_key, pnio.CONTROL_RELEASE
            )
            self._call_blocking(sock, pnio.OP_RELEASE, args)
        except (OSError, ServodeskError, pnio.PnioFrameError):
            pass  # Best effort: the device may be gone; its AR times out by itself.
        finally:
            sock.close()

    async def _aread(self, address: ObjectAddress) -> bytes:
        return await self._with_ar(self._read_object, address)

    async def _awrite(self, address: ObjectAddress, data: bytes) -> None:
        await self._with_ar(self._write_object, address, data)

    async def identity(self) -> DriveIdentity:
        """The I&M0 name plate (manufacturer, order ID, serial, revisions, 004 §20.4.4)."""
        try:
            im = await self._acall(self._with_ar, self._read_im0)
        except (ObjectAccessError, NotFoundError):
            # No I&M0 where servodesk looks (slot 0, subslot 1): the profile is then found
            # from P964 (the profile's vendor_id_object), or chosen by the user.
            return DriveIdentity()
        serial = im.serial.strip()
        if self.vendor_id == 0 and im.vendor_id:
            # The vendor ID of the object UUID from the name plate, from now on.
            self.vendor_id = im.vendor_id
            self._object_uuid = pnio.object_uuid(self.vendor_id, self.device_id)
        return DriveIdentity(
            vendor_id=im.vendor_id,
            serial=int(serial) if serial.isdigit() else None,
            device_name=im.order_id or None,
            hardware_version=str(im.hardware_revision),
            software_version=im.software_version,
        )

    async def read_many(self, addresses: Sequence[ObjectAddress]) -> list[bytes | ServodeskError]:
        """Several objects in as few parameter requests as fit 240 bytes (39 parameters; an
        object whose shape is not known yet takes three)."""
        out: list[bytes | ServodeskError] = []
        chunk: list[ObjectAddress] = []
        size = 0
        for a in [*addresses, None]:
            n = len(self._plan(a)) if a is not None else 0
            if chunk and (a is None or size + n > pd.MAX_PARAMETERS):
                try:
                    out += await self._acall(self._with_ar, self._read_batch, chunk)
                except LinkError:
                    raise  # As ObjectAccess.read_many: the rest would time out too.
                except ServodeskError as exc:
                    out += [exc] * len(chunk)
                chunk, size = [], 0
            if a is not None:
                chunk.append(a)
                size += n
        return out

    def _nmt(self, command: str) -> None:
        """PROFINET has no NMT: "start" sets up servodesk's IO controller AR and its cycle
        (the exchange's OPERATIONAL), "preop" / "stop" end it; the rest, and those without
        an IO AR, are refused as before."""
        if command == "start":
            self._start_io()
            return
        if command in ("preop", "stop") and self.io is not None:
            self._end_io()
            return
        raise ConflictError(
            f"servodesk sends no NMT command ({command}) over PROFINET",
            hint="PROFINET has no NMT; the drive's communication state belongs to its IO "
            "controller (004 §20.1.1)",
        )

    def _start_io(self) -> None:
        plan = self._io_plan
        if plan is None:
            raise ConflictError(
                "no telegram planned for the IO AR", hint="start cyclic data from the PDO page"
            )
        running = self.io
        if running is not None and self._io_running == plan and running.health.state == "ok":
            # Cyclic data started again with the same telegram and cycle: the AR stays (a
            # Release would take the drive to Switch on disabled, 004 §20.5.2).
            running.set_outputs(self._io_first.ljust(plan[1], b"\0")[: plan[1]])
            return
        self._end_io()
        telegram, rx, tx, period = plan
        controller = IoController(
            self.host,
            self.port,
            check_nic(self.params.extra.get("nic"), self.host),
            object_uuid=self._object_uuid,
            telegram=telegram,
            rx_bytes=rx,
            tx_bytes=tx,
            cycle_s=period,
            timeout=self.params.timeout,
        )
        controller.set_outputs(self._io_first.ljust(rx, b"\0")[:rx])
        controller.connect()
        self.io = controller
        self._io_running = plan

    def _end_io(self) -> None:
        controller, self.io = self.io, None
        if controller is not None:
            controller.close()

    def _network_state(self) -> str:
        """ "operational" while servodesk's IO AR exchanges the telegram."""
        return "operational" if self.io is not None else "unknown"

    # Objects as parameters -------------------------------------------------------------

    def _plan(self, address: ObjectAddress) -> list[pd.ParameterAddress]:
        """The parameters one object's read asks for."""
        index, sub = address.index, address.subindex
        if pd.needs_shape(index, sub) and index not in self._arrays:
            # The identifier (array or not), the number of elements and the value of PNU
            # subindex 0: what CoE sub 0 is follows from the first.
            return [
                pd.ParameterAddress(index, pd.DESC_ID, pd.ATTR_DESCRIPTION),
                pd.ParameterAddress(index, pd.DESC_ELEMENTS, pd.ATTR_DESCRIPTION),
                pd.ParameterAddress(index, 0),
            ]
        return [pd.parameter_for(index, sub, array=self._arrays.get(index, False))]

    async def _read_object(self, address: ObjectAddress) -> bytes:
        (result,) = await self._read_batch([address])
        if isinstance(result, ServodeskError):
            raise result
        return result

    async def _read_blocks(self, address: ObjectAddress) -> bytes:
        """A string longer than one response (error 15h), read block by block: subindex =
        block number, number of elements = block size, until a block comes back short
        (servodesk's convention, which the twin's recorder data uses; docs/profinet.md)."""
        out = bytearray()
        for block in range(0x10000):
            target = pd.ParameterAddress(address.index, block, pd.ATTR_VALUE, BLOCK_BYTES)
            resp = await self._parameters(pd.REQUEST_READ, [target])
            v = resp.values[0]
            if v.error is not None:
                raise self._refusal(v.error, address, "read")
            out += v.data
            if v.count < BLOCK_BYTES:
                break
        return bytes(out)

    async def _read_batch(self, addresses: list[ObjectAddress]) -> list[bytes | ServodeskError]:
        plans = [self._plan(a) for a in addresses]
        resp = await self._parameters(pd.REQUEST_READ, [p for plan in plans for p in plan])
        if len(addresses) > 1 and resp.negative and all(v.error == 0x15 for v in resp.values):
            # Too long for one response (strings): one by one.
            return [await self._read_one(a) for a in addresses]
        out: list[bytes | ServodeskError] = []
        pos = 0
        for a, plan in zip(addresses, plans, strict=True):
            values = resp.values[pos : pos + len(plan)]
            pos += len(plan)
            try:
                out.append(self._decode(a, plan, values))
            except ServodeskError as exc:
                out.append(exc if not _too_long(exc) else await self._read_one_in_blocks(a))
        return out

    async def _read_one_in_blocks(self, address: ObjectAddress) -> bytes | ServodeskError:
        try:
            return await self._read_blocks(address)
        except ServodeskError as exc:
            return exc

    def _decode(
        self, address: ObjectAddress, plan: list[pd.ParameterAddress], values: Sequence[pd.Values]
    ) -> bytes:
        if len(plan) == 1:
            return self._coe(address, plan[0], values[0])
        ident = values[0]
        if ident.error is not None:
            self._arrays[address.index] = False  # No such parameter: read it as one.
            raise self._refusal(ident.error, address, "read")
        array = self._learn(address.index, ident)
        target = pd.parameter_for(address.index, address.subindex, array=array)
        return self._coe(address, target, values[1] if array else values[2])

    async def _read_one(self, address: ObjectAddress) -> bytes | ServodeskError:
        try:
            return await self._read_object(address)
        except ServodeskError as exc:
            return exc

    async def _write_object(self, address: ObjectAddress, data: bytes) -> None:
        index, sub = address.index, address.subindex
        if pd.needs_shape(index, sub) and index not in self._arrays:
            await self._read_shape(address)
        target = pd.parameter_for(index, sub, array=self._arrays.get(index, False))
        if target.attribute == pd.ATTR_DESCRIPTION:
            # CoE sub 0 of an array: its number of elements, a description element that
            # PROFIdrive does not let a client change (error 07h).
            raise self._refusal(0x07, address, "write")
        fmt = self._formats.get((target.pnu, target.subindex))
        if fmt is None:
            fmt = await self._learn_format(address, target)
        try:
            values = pd.from_coe(fmt, data)
        except ValueError:
            raise ValidationError(
                f"write {address}: {len(data)} bytes are no value of the parameter's format "
                f"{fmt:02X}h (P{target.pnu}.{target.subindex})",
                field="value",
                hint="give a value of the object's data type",
            ) from None
        resp = await self._parameters(pd.REQUEST_CHANGE, [target], [values])
        if resp.negative:
            number = resp.values[0].error if resp.values else None
            raise self._refusal(0x14 if number is None else number, address, "write")

    async def _read_shape(self, address: ObjectAddress) -> None:
        resp = await self._parameters(
            pd.REQUEST_READ, [pd.ParameterAddress(address.index, pd.DESC_ID, pd.ATTR_DESCRIPTION)]
        )
        ident = resp.values[0]
        if ident.error is not None:
            raise self._refusal(ident.error, address, "write")
        self._learn(address.index, ident)

    async def _learn_format(self, address: ObjectAddress, target: pd.ParameterAddress) -> int:
        """The element's format: from a read of it, or (a write-only parameter) from the
        identifier's data type."""
        resp = await self._parameters(
            pd.REQUEST_READ,
            [target, pd.ParameterAddress(target.pnu, pd.DESC_ID, pd.ATTR_DESCRIPTION)],
        )
        value, ident = resp.values
        if value.error is None:
            fmt = value.format
        elif ident.error is None:
            fmt = int.from_bytes(ident.data[:2], "big") & 0xFF
        else:
            raise self._refusal(ident.error, address, "write")
        self._formats[(target.pnu, target.subindex)] = fmt
        return fmt

    def _learn(self, index: int, ident: pd.Values) -> bool:
        array = bool(int.from_bytes(ident.data[:2], "big") & pd.ID_ARRAY)
        self._arrays[index] = array
        return array

    def _coe(self, address: ObjectAddress, target: pd.ParameterAddress, v: pd.Values) -> bytes:
        if v.error is not None:
            raise self._refusal(v.error, address, "read")
        if target.attribute == pd.ATTR_DESCRIPTION:
            # The number of elements, as CoE sub 0 holds it (UNSIGNED8).
            n = int.from_bytes(v.data[:2], "big")
            return bytes((min(n, 255),))
        if v.format not in pd.FORMAT_SIZES or v.format in (pd.FMT_ZERO, pd.FMT_ERROR):
            raise LinkError(
                f"read {address}: the drive answered format {v.format:02X}h",
                hint="the device may not implement PROFIdrive parameter access as servodesk "
                "expects (docs/profinet.md)",
            )
        self._formats[(target.pnu, target.subindex)] = v.format
        return pd.to_coe(v)

    def _refusal(self, number: int, address: ObjectAddress, op: str) -> ObjectAccessError:
        meaning = pd.error_text(number)
        return ObjectAccessError(
            f"{op} {address} refused by the drive: {meaning} (PROFIdrive error {number:02X}h)",
            code=number,
            meaning=meaning,
            protocol="profidrive",
            address=str(address),
            hint=_HINTS.get(number),
        )

    # Parameter requests over record 0xB02E -----------------------------------------------

    async def _parameters(
        self,
        request_id: int,
        addresses: Sequence[pd.ParameterAddress],
        values: Sequence[pd.Values] = (),
    ) -> pd.Response:
        self._reference = reference = self._reference % 255 + 1
        request = pd.build_request(
            pd.Request(reference, request_id, self.params.node_id, tuple(addresses), tuple(values))
        )
        await self._record(pnio.OP_WRITE, pnio.INDEX_PARAMETER_ACCESS, request)
        deadline = time.monotonic() + self.request_timeout
        while True:
            try:
                data = await self._record(pnio.OP_READ, pnio.INDEX_PARAMETER_ACCESS, pd.MAX_BYTES)
                break
            except _NotReady:
                # PROFIdrive: the drive has not finished the request; read again.
                if time.monotonic() > deadline:
                    raise LinkTimeoutError(
                        f"the drive at {self.host} has no parameter response after "
                        f"{self.request_timeout:g} s"
                    ) from None
                await asyncio.sleep(NOT_READY_POLL_S)
        try:
            resp = pd.parse_response(data)
        except pd.ProfidriveFrameError as exc:
            raise LinkError(
                f"the drive's parameter response is malformed: {exc}",
                hint="the device may not implement PROFIdrive parameter access (docs/profinet.md)",
            ) from exc
        if resp.reference != reference:
            raise LinkError(
                f"the drive answered request {resp.reference}, not {reference}",
                hint="another supervisor may use the drive's parameter access channel (it has "
                "one, 004 §20.1.2)",
            )
        if resp.response_id & ~pd.NEGATIVE != request_id:
            raise LinkError(f"the drive answered response ID {resp.response_id:02X}h")
        if resp.negative and resp.values and all(v.error == 0x19 for v in resp.values):
            raise NotFoundError(
                f"the drive at {self.host} has no drive object {self.params.node_id} "
                f"(PROFIdrive error 19h)",
                hint="the node id is the DO-ID: 1 on the LECSN-T (P975.7)",
            )
        if resp.count != len(addresses) or (
            len(resp.values) != len(addresses) and (resp.negative or request_id == pd.REQUEST_READ)
        ):
            raise LinkError(
                f"the drive answered {resp.count} parameters for {len(addresses)}",
                hint="the device may not implement PROFIdrive parameter access (docs/profinet.md)",
            )
        return resp

    async def _read_im0(self) -> pnio.Im0:
        data = await self._record(pnio.OP_READ, pnio.INDEX_IM0, 256, slot=0)
        try:
            return pnio.parse_im0(data)
        except pnio.PnioFrameError as exc:
            raise ObjectAccessError(
                f"the device's I&M0 is malformed: {exc}",
                code=0,
                meaning="I&M0 malformed",
                protocol="pnio",
            ) from exc

    async def _record(
        self, op: int, index: int, data_or_length: bytes | int, *, slot: int = DRIVE_SLOT
    ) -> bytes:
        """Write a record (bytes) or read one (the most bytes to take); the record read."""
        self._record_seq = (self._record_seq + 1) & 0xFFFF
        where = pnio.RecordAddress(slot, DRIVE_SUBSLOT, index)
        if isinstance(data_or_length, bytes):
            head = pnio.RecordHeader(self._record_seq, self._ar_uuid, where, len(data_or_length))
            args = pnio.record_request(pnio.BLOCK_WRITE_REQ, head) + data_or_length
            expected = pnio.BLOCK_WRITE_RES
        else:
            head = pnio.RecordHeader(self._record_seq, self._ar_uuid, where, data_or_length)
            args = pnio.record_request(pnio.BLOCK_READ_REQ, head)
            expected = pnio.BLOCK_READ_RES
        status, blocks = await self._rpc(op, args)
        if status:
            code1, code2 = (status >> 8) & 0xFF, status & 0xFF
            decode = (status >> 16) & 0xFF
            if (decode, code1, code2) == _AR_UNKNOWN:
                raise _ArLost
            if decode == pnio.DECODE_PNIORW and code1 == 0xB5:
                raise _NotReady
            text = pnio.status_text(status)
            if decode == pnio.DECODE_PNIORW and code1 in (0xB0, 0xB2):
                raise NotFoundError(
                    f"the device at {self.host} has no record {index:04X}h at slot {slot} "
                    f"subslot {DRIVE_SUBSLOT} ({text})",
                    hint="the device may not be a PROFIdrive drive (docs/profinet.md)",
                )
            raise ObjectAccessError(
                f"the device refused the {text} (PNIOStatus {status:08X}h)",
                code=status,
                meaning=text,
                protocol="pnio",
            )
        try:
            _head, record = pnio.parse_record_header(blocks, expected)
        except pnio.PnioFrameError as exc:
            raise LinkError(f"the device's record response is malformed: {exc}") from exc
        return record

    async def _with_ar(self, fn: Callable[..., Awaitable[T]], *args: Any) -> T:
        """``fn(*args)``; where the device no longer knows the AR, set one up again and
        try once more (a parameter request is a whole write and read, so nothing of it was
        carried out twice)."""
        try:
            return await fn(*args)
        except _ArLost:
            await self._reconnect()
        try:
            return await fn(*args)
        except _ArLost:
            raise LinkError(
                f"the device at {self.host} dropped servodesk's AR again just after it was set up",
                hint="another client may take the device's ARs; check the IO controller",
            ) from None

    # RPC -------------------------------------------------------------------------------

    def _packet(self, opnum: int, args: bytes, args_max: int) -> list[bytes]:
        """The request's datagrams: one, or fragments of at most :attr:`max_fragment_body`
        body bytes (C706 §12.5.3.2), with "no fack" unless :attr:`fragment_acks`."""
        self._reply = pnio.Reassembly()
        body = pnio.request_body(args, args_max)
        flags = pnio.FLAG_IDEMPOTENT
        if len(body) > self.max_fragment_body and not self.fragment_acks:
            flags |= pnio.FLAG_NOFACK
        packet = pnio.RpcPacket(
            ptype=pnio.PTYPE_REQUEST,
            opnum=opnum,
            object_uuid=self._object_uuid,
            interface=pnio.DEVICE_INTERFACE,
            activity=self._activity,
            seqnum=self._seqnum,
            body=body,
            server_boot=self._server_boot,
            flags1=flags,
        )
        return [pnio.build_rpc(f) for f in pnio.fragment(packet, self.max_fragment_body)]

    def _match(self, frame: bytes) -> tuple[int, bytes] | None:
        """(PNIOStatus, blocks) of the response to the call in progress; None for a datagram
        that is not it."""
        try:
            packet = pnio.parse_rpc(frame)
        except pnio.PnioFrameError:
            self.stale += 1
            return None
        if packet.activity != self._activity or packet.seqnum != self._seqnum:
            self.stale += 1
            return None
        if packet.ptype in (pnio.PTYPE_FAULT, pnio.PTYPE_REJECT):
            raise LinkError(
                f"the device at {self.host} rejected the RPC call "
                f"(status {packet.body[:4].hex() or 'none'})",
                hint="the device may not be a PROFINET IO device, or not accept a supervisor "
                "AR (docs/profinet.md)",
            )
        if packet.ptype != pnio.PTYPE_RESPONSE:
            self.stale += 1  # working / no-call / fack: the answer is still to come
            return None
        self._server_boot = packet.server_boot
        if packet.flags1 & pnio.FLAG_FRAG:
            # One fragment of a long answer (C706 §12.5.3.2): the whole once all are in.
            body = self._reply.add(packet)
            if body is None:
                return None
            packet = dataclasses.replace(packet, body=body)
        try:
            return pnio.parse_response_body(packet.body, little=packet.little)
        except pnio.PnioFrameError as exc:
            raise LinkError(f"the device's RPC response is malformed: {exc}") from exc

    async def _rpc(self, opnum: int, args: bytes) -> tuple[int, bytes]:
        sock = self._sock
        if sock is None:
            raise LinkError("the PROFINET socket is closed", hint="open the session again")
        loop = asyncio.get_running_loop()
        timeout = self.request_timeout
        self._seqnum = (self._seqnum + 1) & 0xFFFFFFFF
        datagrams = self._packet(opnum, args, pnio.MAX_DATAGRAM)
        for _ in range(SENDS):
            try:
                for datagram in datagrams:
                    await loop.sock_sendall(sock, datagram)
                # asyncio.timeout, not wait_for: no task per request.
                async with asyncio.timeout(timeout):
                    while True:
                        got = self._match(await loop.sock_recv(sock, 65535))
                        if got is not None:
                            return got
            except TimeoutError:
                continue
            except ConnectionRefusedError as exc:
                raise self._nobody(exc) from exc
        raise LinkTimeoutError(
            f"no PNIO answer from {self.host}:{self.port} within {timeout:g} s ({SENDS} sends)"
        )

    def _call_blocking(self, sock: socket.socket, opnum: int, args: bytes) -> tuple[int, bytes]:
        self._seqnum = (self._seqnum + 1) & 0xFFFFFFFF
        datagrams = self._packet(opnum, args, pnio.MAX_DATAGRAM)
        for _ in range(SENDS):
            try:
                for datagram in datagrams:
                    sock.send(datagram)
                deadline = time.monotonic() + (sock.gettimeout() or 1.0)
                while True:
                    sock.settimeout(max(0.001, deadline - time.monotonic()))
                    got = self._match(sock.recv(65535))
                    if got is not None:
                        return got
            except TimeoutError:
                continue
            except ConnectionRefusedError as exc:
                raise self._nobody(exc) from exc
        raise NotFoundError(
            f"no PROFINET device answers at udp {self.host}:{self.port} "
            f"(no answer to {SENDS} connect requests)",
            hint="check the device's IP address and that it is powered and on this network",
        )

    def _nobody(self, exc: OSError) -> NotFoundError:
        return NotFoundError(
            f"nothing answers PNIO-CM at udp {self.host}:{self.port} "
            f"({errno.errorcode.get(exc.errno or 0, exc)})",
            hint="check the device's IP address and port (34964), and that it is powered",
        )

    def _connect_blocking(self) -> None:
        """Set up the supervisor AR (blocking; in the worker thread that opens the link)."""
        sock = self._sock
        assert sock is not None
        status, blocks = self._call_blocking(sock, pnio.OP_CONNECT, self._new_ar())
        self._check_connect(status, blocks)

    def _new_ar(self) -> bytes:
        """The connect request of a new supervisor AR (a new ARUUID and session key)."""
        self._ar_uuid = uuid.uuid4()
        self._session_key = (self._session_key + 1) & 0xFFFF
        return pnio.ar_block_req(
            pnio.ArRequest(
                ar_uuid=self._ar_uuid,
                session_key=self._session_key,
                initiator_mac=self.initiator_mac,
                # CMInitiatorObjectUUID names the initiator (servodesk), which has no
                # PI vendor or device ID of its own: instance 1 of 0000/0000.
                initiator_object=_INITIATOR_OBJECT,
                station_name=INITIATOR_NAME,
                timeout_factor=ACTIVITY_TIMEOUT_FACTOR,
            )
        )

    def _check_connect(self, status: int, blocks: bytes) -> None:
        if status:
            raise ConflictError(
                f"the device at {self.host} refused the supervisor AR: "
                f"{pnio.status_text(status)} (PNIOStatus {status:08X}h)",
                hint="the device may allow no further AR now; close other supervisors' "
                "sessions, or check that it accepts a supervisor AR with device access",
            )
        try:
            ar_uuid, _key = pnio.parse_ar_block_res(pnio.one_block(blocks, pnio.BLOCK_AR_RES))
        except pnio.PnioFrameError as exc:
            raise LinkError(f"the device's connect response is malformed: {exc}") from exc
        if ar_uuid != self._ar_uuid:
            raise LinkError("the device answered the connect for another AR")

    async def _reconnect(self) -> None:
        self.reconnects += 1
        status, blocks = await self._rpc(pnio.OP_CONNECT, self._new_ar())
        self._check_connect(status, blocks)


def _too_long(exc: ServodeskError) -> bool:
    """PROFIdrive error 15h: the value does not fit one response (read it in blocks)."""
    return isinstance(exc, ObjectAccessError) and exc.protocol == "profidrive" and exc.code == 0x15


class _NotReady(Exception):
    """PNIORW B5h on reading 0xB02E: the parameter response is not there yet."""


#: What a user can do about the common PROFIdrive errors.
_HINTS: dict[int, str] = {
    0x00: "the drive has no such parameter; check the index against the profile (P980 lists "
    "the drive's parameters)",
    0x01: "the parameter is read-only",
    0x02: "the value is outside the parameter's range",
    0x03: "check the subindex: PNU subindex = CoE subindex - 1 (004 §20.1.5)",
    0x04: "the parameter has no subindexes; use subindex 0",
    0x05: "the value's data type does not match the parameter's",
    0x07: "the number of entries of an array cannot be changed over PROFIdrive",
    0x11: "the drive refuses this in its present state (e.g. servo on, or the master in RUN)",
    0xFF: "the parameter is write-only; it cannot be read back",
}
