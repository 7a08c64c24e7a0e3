"""The PROFINET side of a simulated PROFIdrive drive: PNIO-CM record access over UDP.

:class:`ProfinetDevice` answers connectionless DCE/RPC on a UDP socket as a PROFINET IO
device's context manager does (:mod:`servodesk.domain.pnio`): ``Connect`` with a supervisor
AR with device access, ``Write`` / ``Read`` of records, ``Release``. Two records are served:

- 0xB02E on slot 1, subslot 1 (the PROFIdrive drive object, I&M0 profile ID 3A00h): a
  parameter request written there is carried out on the spot, and its response is read back
  from the same index (PROFIdrive base mode parameter access, 004 §20.4.1;
  :mod:`servodesk.domain.profidrive`);
- 0xAFF0 (I&M0) on slot 0 and slot 1, from the profile's ``im0`` quirk (004 §20.4.4).

The parameters are the :class:`~servodesk.sim.engine.SimulatedDrive`'s objects, as on the
CANopen front-end, reached by the PNU rule of 004 §20.1.5 (PNU = CoE index, array element
PNU subindex = CoE subindex - 1). A refusal is answered with the PROFIdrive error number of
004 §20.4.2 that matches the drive's reason.

Like a device's RPC server, it answers a repeated request (the same activity and sequence
number, a client's resend) with the response it sent before, without carrying it out twice
(for the last :data:`RESEND_CACHE` client activities).

:meth:`ProfinetDevice.serve_dcp` also answers DCP on a network interface
(sim/profinet_dcp.py): a station name or IP address set there is the device's, and the
PNIO-CM server moves to the new address (with ``manage_addresses``, the twin gives the
interface that address first); a reset to factory leaves it without an address until one is
set (004 §20.4.5).

An AR whose client falls silent is dropped: the device's CM supervises the initiator's
activity (the ARBlockReq's CMInitiatorActivityTimeoutFactor x 100 ms, restarted by every
record read and write) until the AR exchanges IO data, which a supervisor AR with device access
never does (IEC 61158-6-10 CMSM; so p-net's ``pf_cmsm.c``). A client that died without a
Release thus stops blocking DCP name and address changes once that time has passed.
"""

from __future__ import annotations

import logging
import time
import uuid
from dataclasses import dataclass, field

from servodesk.domain import pnio
from servodesk.domain import profidrive as pd
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import ObjectSpec, ObjectType
from servodesk.errors import LinkError
from servodesk.sim.engine import SimAbort, SimulatedDrive
from servodesk.sim.profinet_dcp import DcpResponder, DcpStation, interface_mac
from servodesk.sim.udp_server import UdpServer
from servodesk.sim.veth import add_address, delete_address

log = logging.getLogger(__name__)

#: Client activities whose last response is kept for a resend.
RESEND_CACHE = 64
#: Where the PROFIdrive drive object is (the parameter access record's slot and subslot).
DRIVE_SLOT = 1
DRIVE_SUBSLOT = 1
#: The drive object's DO-ID (P975.7 = 1, 004 §20.4.3.7).
DO_ID = 1
#: Supervisor ARs one device keeps at a time.
MAX_ARS = 4
#: The CMInitiatorActivityTimeoutFactor an ARBlockReq may give (x 100 ms: 0.1-100 s).
ACTIVITY_FACTOR_RANGE = (1, 1000)
#: Field number of CMInitiatorActivityTimeoutFactor in the ARBlockReq (PNIO ErrorCode2 of a
#: connect refused for it).
FIELD_ACTIVITY_FACTOR = 0x0A

#: The PROFIdrive error number a PROFIdrive device answers for each reason the drive model
#: gives (its CiA 301 abort code).
ERROR_FOR_ABORT: dict[int, int] = {
    0x06020000: 0x00,  # no such object: impermissible parameter number
    0x06010002: 0x01,  # read-only
    0x06090030: 0x02,  # value range
    0x06090031: 0x02,
    0x06090032: 0x02,
    0x06090036: 0x02,
    0x06090011: 0x03,  # no such subindex
    0x06070010: 0x05,  # data type / length
    0x06070012: 0x05,
    0x06070013: 0x05,
    0x08000020: 0x11,  # not in the present state
    0x08000021: 0x11,
    0x08000022: 0x11,
    0x08000024: 0x11,
    0x06010001: 0xFF,  # write-only
}


@dataclass(slots=True)
class _Ar:
    session_key: int
    #: Seconds without a record read or write after which the device drops the AR.
    timeout_s: float
    #: time.monotonic() of the AR's last connect, read or write.
    last: float
    #: The parameter response waiting to be read from 0xB02E.
    pending: bytes | None = None


@dataclass(slots=True)
class _Cache:
    """The last response sent to one client activity (for its resends)."""

    seqnum: int
    datagram: bytes


@dataclass(slots=True)
class _State:
    ars: dict[uuid.UUID, _Ar] = field(default_factory=dict)
    answered: dict[uuid.UUID, _Cache] = field(default_factory=dict)


class ProfinetDevice(UdpServer):
    """A UDP PNIO-CM server for one drive; ``start()`` binds, ``channel`` tells where."""

    name = "pnio-device"

    def __init__(
        self,
        drive: SimulatedDrive,
        host: str = "127.0.0.1",
        port: int = 0,
        *,
        serial: str | None = None,
    ) -> None:
        super().__init__(host, port)
        self.drive = drive
        self._state = _State()
        self.mac = bytes.fromhex("020000") + drive.node_id.to_bytes(3, "big")
        im = drive.profile.quirk("im0", {}) or {}
        self._im = im
        self.serial = serial or str(drive.profile.simulation.serial_number or drive.node_id)
        #: Resends answered from the cache.
        self.resends = 0
        dcp_id = drive.profile.quirk("dcp", {}) or {}
        self.station = DcpStation(
            vendor_id=int(dcp_id.get("vendor_id", 0)),
            device_id=int(dcp_id.get("device_id", 0)),
            type_of_station=str(dcp_id.get("type_of_station", drive.profile.name)),
            name_of_station=str(dcp_id.get("station_name", "")),
        )
        self._dcp: DcpResponder | None = None
        self._dcp_ifname: str | None = None
        self._addresses: list[str] = []  # given to the DCP interface by this twin
        self._parked_port: int | None = None  # the port while the device has no address

    # DCP -------------------------------------------------------------------------------

    def serve_dcp(self, ifname: str, *, manage_addresses: bool = False) -> DcpResponder:
        """Answer DCP on ``ifname`` (the device end of a veth pair, or a NIC) with the
        interface's MAC. The station's IP is where PNIO-CM is served. With
        ``manage_addresses`` an address set by DCP is first given to ``ifname`` (/32), so that
        the host reaches the twin there; otherwise it must be one of the host's already."""
        if self._sock is not None:
            self.station.ip = self.address[0]
            self.station.netmask = "255.255.255.0" if self.station.ip != "0.0.0.0" else "0.0.0.0"
        self._dcp_ifname = ifname if manage_addresses else None
        responder = DcpResponder(
            self.station,
            interface_mac(ifname),
            busy=lambda: self.ars > 0,
            on_ip=self._take_ip,
            on_factory=self._factory,
        )
        self._dcp = responder.start(ifname)
        return responder

    @property
    def dcp_mac(self) -> bytes | None:
        """The MAC this device answers DCP with (None: no DCP)."""
        return self._dcp.mac if self._dcp is not None else None

    @property
    def port(self) -> int | None:
        """The UDP port of its PNIO-CM server (kept while it has no address)."""
        return self.address[1] if self._sock is not None else self._parked_port

    def _take_ip(self, ip: str) -> bool:
        """Serve PNIO-CM at ``ip`` from now on (0.0.0.0: nowhere); False when the address
        cannot be taken."""
        if ip == "0.0.0.0":
            if self._sock is not None:
                self._parked_port = self.address[1]
                super().stop()
                self._stop.clear()
            return True
        if self._dcp_ifname is not None and ip not in self._addresses:
            try:
                add_address(self._dcp_ifname, ip)
            except LinkError as exc:
                if "File exists" not in exc.message:  # already the host's
                    log.info("DCP address %s not taken: %s", ip, exc.message)
                    return False
            else:
                self._addresses.append(ip)
        if self._sock is None and self._parked_port is not None:
            self._host, self._port = ip, self._parked_port
            try:
                self.start()
            except OSError:
                return False
            self._parked_port = None
            return True
        return self.rebind(ip)

    def _factory(self, mode: int) -> None:
        """Reset to factory (004 §20.4.5): mode 8 also forgets every stored parameter; both
        reset the drive like a power cycle."""
        self._state.ars.clear()
        if mode == 8:
            self.drive.factory_reset()
        else:
            self.drive.reset_node()

    def stop(self) -> None:
        if self._dcp is not None:
            self._dcp.stop()
            self._dcp = None
        super().stop()
        if self._dcp_ifname is not None:
            for ip in self._addresses:
                try:
                    delete_address(self._dcp_ifname, ip)
                except LinkError:
                    log.debug("address %s not removed", ip, exc_info=True)
        self._addresses.clear()

    @property
    def cached_activities(self) -> int:
        """Client activities whose last response is kept for a resend (at most
        :data:`RESEND_CACHE`)."""
        return len(self._state.answered)

    @property
    def ars(self) -> int:
        """Application relations open now."""
        self._expire()
        return len(self._state.ars)

    def _expire(self) -> None:
        """Drop the ARs whose initiator has been silent for its activity time-out."""
        now = time.monotonic()
        ars = self._state.ars
        for key in [k for k, ar in ars.items() if now - ar.last > ar.timeout_s]:
            log.info("AR %s timed out (no record access for %.1f s)", key, ars[key].timeout_s)
            del ars[key]

    # RPC -------------------------------------------------------------------------------

    def answer(self, frame: bytes) -> bytes | None:
        """The response datagram to one request; None for a datagram that is dropped."""
        try:
            req = pnio.parse_rpc(frame)
        except pnio.PnioFrameError as exc:
            log.debug("PNIO datagram dropped: %s", exc)
            return None
        if req.ptype != pnio.PTYPE_REQUEST or req.interface != pnio.DEVICE_INTERFACE:
            return None
        cached = self._state.answered.get(req.activity)
        if cached is not None and cached.seqnum == req.seqnum:
            self.resends += 1
            return cached.datagram
        self._expire()
        status, args_max, blocks = self._call(req)
        body = pnio.response_body(status, blocks, args_max, little=req.little)
        datagram = pnio.build_rpc(
            pnio.RpcPacket(
                ptype=pnio.PTYPE_RESPONSE,
                opnum=req.opnum,
                object_uuid=req.object_uuid,
                interface=req.interface,
                activity=req.activity,
                seqnum=req.seqnum,
                body=body,
                flags1=pnio.FLAG_LASTFRAG | pnio.FLAG_NOFACK,
                little=req.little,
            )
        )
        answered = self._state.answered
        answered.pop(req.activity, None)  # to the end: the oldest activity goes first
        answered[req.activity] = _Cache(req.seqnum, datagram)
        while len(answered) > RESEND_CACHE:
            del answered[next(iter(answered))]
        return datagram

    def _call(self, req: pnio.RpcPacket) -> tuple[int, int, bytes]:
        """(PNIOStatus, ArgsMaximum, the response blocks) of one operation."""
        err = {
            pnio.OP_CONNECT: pnio.ERROR_CODE_CONNECT,
            pnio.OP_RELEASE: pnio.ERROR_CODE_RELEASE,
            pnio.OP_READ: pnio.ERROR_CODE_READ,
            pnio.OP_WRITE: pnio.ERROR_CODE_WRITE,
        }.get(req.opnum)
        if err is None:
            return pnio.pnio_status(0xDD, pnio.DECODE_PNIO, pnio.CMRPC, 0x01), 0, b""
        try:
            args_max, args = pnio.parse_request_body(req.body, little=req.little)
        except pnio.PnioFrameError:
            return pnio.pnio_status(err, pnio.DECODE_PNIO, pnio.CMRPC, 0x00), 0, b""
        try:
            if req.opnum == pnio.OP_CONNECT:
                return 0, args_max, self._connect(args)
            if req.opnum == pnio.OP_RELEASE:
                return 0, args_max, self._release(args)
            if req.opnum == pnio.OP_WRITE:
                return self._write(args, args_max)
            return self._read(args, args_max)
        except pnio.PnioFrameError:
            return pnio.pnio_status(err, pnio.DECODE_PNIO, pnio.CMRPC, 0x01), args_max, b""
        except _Refused as exc:
            return pnio.pnio_status(err, *exc.codes), args_max, exc.blocks

    def _connect(self, args: bytes) -> bytes:
        blocks = pnio.split_blocks(args)
        ar_reqs = [c for t, c in blocks if t == pnio.BLOCK_AR_REQ]
        if len(ar_reqs) != 1:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x03)  # wrong block count
        ar = pnio.parse_ar_block_req(ar_reqs[0])
        # Only a supervisor AR with device access: no IO controller, expected submodules or
        # cyclic data come with it (the twin has no IO data to exchange; docs/profinet.md).
        if ar.ar_type != pnio.AR_TYPE_SUPERVISOR or not ar.properties & 0x100:
            raise _Refused(pnio.DECODE_PNIO, 0x01, 0x04)  # faulty ARBlockReq: ARType
        low, high = ACTIVITY_FACTOR_RANGE
        if not low <= ar.timeout_factor <= high:
            raise _Refused(pnio.DECODE_PNIO, 0x01, FIELD_ACTIVITY_FACTOR)  # faulty ARBlockReq
        if ar.ar_uuid not in self._state.ars and len(self._state.ars) >= MAX_ARS:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x04)  # no AR resources
        self._state.ars[ar.ar_uuid] = _Ar(
            ar.session_key, timeout_s=0.1 * ar.timeout_factor, last=time.monotonic()
        )
        return pnio.ar_block_res(ar.ar_type, ar.ar_uuid, ar.session_key, self.mac)

    def _release(self, args: bytes) -> bytes:
        ar_uuid, key, _command = pnio.parse_release_block(
            pnio.one_block(args, pnio.BLOCK_RELEASE_REQ)
        )
        if self._state.ars.pop(ar_uuid, None) is None:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x05)  # AR UUID unknown
        return pnio.release_block(pnio.BLOCK_RELEASE_RES, ar_uuid, key, pnio.CONTROL_DONE)

    def _write(self, args: bytes, args_max: int) -> tuple[int, int, bytes]:
        head, record = pnio.parse_record_header(args, pnio.BLOCK_WRITE_REQ)
        ar = self._ar(head)
        where = head.where

        def answer(status: int = 0) -> bytes:
            return pnio.record_response(
                pnio.BLOCK_WRITE_RES,
                pnio.RecordHeader(head.seq, head.ar_uuid, where, len(record), status=status),
            )

        if where.index == pnio.INDEX_IM0:
            raise _Refused(pnio.DECODE_PNIORW, 0xB6, 0, answer())  # I&M0 is read-only
        if where.index != pnio.INDEX_PARAMETER_ACCESS:
            raise _Refused(pnio.DECODE_PNIORW, 0xB0, 0, answer())
        if (where.slot, where.subslot) != (DRIVE_SLOT, DRIVE_SUBSLOT):
            raise _Refused(pnio.DECODE_PNIORW, 0xB2, 0, answer())
        if len(record) > pd.MAX_BYTES:
            raise _Refused(pnio.DECODE_PNIORW, 0xB1, 0, answer())
        try:
            request = pd.parse_request(record)
        except pd.ProfidriveFrameError:
            raise _Refused(pnio.DECODE_PNIORW, 0xB8, 0, answer()) from None
        ar.pending = self.parameters(request)
        return 0, args_max, answer()

    def _read(self, args: bytes, args_max: int) -> tuple[int, int, bytes]:
        head, _ = pnio.parse_record_header(args, pnio.BLOCK_READ_REQ)
        ar = self._ar(head)
        where = head.where

        def answer(data: bytes = b"") -> bytes:
            h = pnio.RecordHeader(head.seq, head.ar_uuid, where, len(data))
            return pnio.record_response(pnio.BLOCK_READ_RES, h) + data

        if where.index == pnio.INDEX_IM0 and where.subslot == 1 and where.slot in (0, 1):
            data = self.im0(where.slot)
        elif where.index != pnio.INDEX_PARAMETER_ACCESS:
            raise _Refused(pnio.DECODE_PNIORW, 0xB0, 0, answer())
        elif (where.slot, where.subslot) != (DRIVE_SLOT, DRIVE_SUBSLOT):
            raise _Refused(pnio.DECODE_PNIORW, 0xB2, 0, answer())
        elif ar.pending is None:
            # PROFIdrive: a read of 0xB02E without a request written before it.
            raise _Refused(pnio.DECODE_PNIORW, 0xB5, 0, answer())
        else:
            data, ar.pending = ar.pending, None
        return 0, args_max, answer(data[: head.length])

    def _ar(self, head: pnio.RecordHeader) -> _Ar:
        ar = self._state.ars.get(head.ar_uuid)
        if ar is None:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x05)  # AR UUID unknown
        ar.last = time.monotonic()  # the initiator is active: its time-out starts again
        return ar

    def im0(self, slot: int) -> bytes:
        """The I&M0 record of slot 0 (the access point) or slot 1 (the drive object)."""
        im = self._im
        suffix = f"_slot{slot}"
        p = self.drive.profile
        vendor = int(im.get("manufacturer_id", p.identity.vendor_id or 0))
        firmware = self._firmware()
        revision = int(im.get("im_revision", 0x0101))
        return pnio.im0_block(
            pnio.Im0(
                vendor_id=vendor,
                order_id=str(im.get("order_id", p.name)),
                serial=self.serial,
                hardware_revision=1,
                software_revision=("V", firmware // 100, firmware % 100, 0),
                profile_id=int(im.get("profile_id" + suffix, 0)),
                profile_type=int(im.get("profile_specific_type" + suffix, 0)),
                version=(revision >> 8, revision & 0xFF),
                supported=int(im.get("im_supported", 0)),
            )
        )

    def _firmware(self) -> int:
        """P964.2, the drive's firmware version (110 = V1.10), or 100 where it reads none."""
        try:
            return int.from_bytes(self.drive.read_bytes(0x03C4, 2), "little") or 100
        except SimAbort:
            return 100

    # PROFIdrive parameters -------------------------------------------------------------

    def parameters(self, request: pd.Request) -> bytes:
        """The parameter response to one request (004 §20.4.1)."""
        n = len(request.addresses)
        change = request.request_id == pd.REQUEST_CHANGE
        if request.request_id not in (pd.REQUEST_READ, pd.REQUEST_CHANGE):
            return pd.build_response(
                pd.Response(
                    request.reference,
                    request.request_id | pd.NEGATIVE,
                    request.axis,
                    n,
                    tuple(pd.error_values(0x21) for _ in range(n)),
                )
            )
        results: list[pd.Values] = []
        for i, address in enumerate(request.addresses):
            if request.axis != DO_ID:
                results.append(pd.error_values(0x19))
                continue
            try:
                if change:
                    self._change(address, request.values[i])
                    results.append(pd.Values(pd.FMT_ZERO, 0))
                else:
                    results.append(self._value(address))
            except _ParameterError as exc:
                results.append(pd.error_values(exc.number))
        failed = any(v.format == pd.FMT_ERROR for v in results)
        rid = request.request_id | (pd.NEGATIVE if failed else 0)
        values = tuple(results) if failed or not change else ()
        out = pd.build_response(pd.Response(request.reference, rid, request.axis, n, values))
        if len(out) > pd.MAX_BYTES:
            errors = tuple(pd.error_values(0x15) for _ in range(n))
            neg = request.request_id | pd.NEGATIVE
            out = pd.build_response(pd.Response(request.reference, neg, request.axis, n, errors))
        return out

    def _object(self, address: pd.ParameterAddress) -> tuple[ObjectAddress, DataType]:
        """The object a value address reaches and its data type (004 §20.1.5)."""
        pnu, sub = address.pnu, address.subindex
        entry = self.drive.profile.entries.get(pnu)
        if entry is None:
            raise _ParameterError(0x00)
        if pnu < pd.COE_FROM or entry.object_type is not ObjectType.VAR:
            coe_sub = sub if pnu < pd.COE_FROM else sub + 1
        elif sub != 0:
            raise _ParameterError(0x04)  # subindex access to a parameter without subindexes
        else:
            coe_sub = 0
        spec = self.drive.profile.spec(ObjectAddress(pnu, coe_sub))
        if spec is None or coe_sub > 255:
            raise _ParameterError(0x03)
        return ObjectAddress(pnu, coe_sub), spec.data_type

    def _value(self, address: pd.ParameterAddress) -> pd.Values:
        if address.attribute == pd.ATTR_DESCRIPTION:
            return self._description(address)
        if address.attribute == pd.ATTR_TEXT:
            raise _ParameterError(0x0F)
        if address.attribute != pd.ATTR_VALUE:
            raise _ParameterError(0x16)
        if address.elements != 1:
            return self._block(address)
        where, data_type = self._object(address)
        try:
            raw = self.drive.read_bytes(where.index, where.subindex)
        except SimAbort as exc:
            raise _ParameterError(ERROR_FOR_ABORT.get(exc.code, 0x14)) from None
        value = pd.from_coe(pd.FORMAT_OF.get(data_type, pd.FMT_OCTET_STRING), raw)
        if value.count > 255 or len(value.data) > pd.MAX_BYTES - 6:
            raise _ParameterError(0x15)  # response too long: read it in blocks
        return value

    def _block(self, address: pd.ParameterAddress) -> pd.Values:
        """Block ``subindex`` of ``elements`` bytes of a string longer than one response
        (servodesk's convention for the twin's recorder data, docs/profinet.md)."""
        entry = self.drive.profile.entries.get(address.pnu)
        if entry is None:
            raise _ParameterError(0x00)
        spec = self.drive.profile.spec(ObjectAddress(address.pnu, 0))
        strings = (DataType.VISIBLE_STRING, DataType.OCTET_STRING, DataType.DOMAIN)
        if entry.object_type is not ObjectType.VAR or spec is None or spec.data_type not in strings:
            raise _ParameterError(0x16)
        try:
            raw = self.drive.read_bytes(address.pnu, 0)
        except SimAbort as exc:
            raise _ParameterError(ERROR_FOR_ABORT.get(exc.code, 0x14)) from None
        start = address.subindex * address.elements
        if start > len(raw):
            raise _ParameterError(0x03)
        part = raw[start : start + address.elements]
        return pd.Values(pd.FORMAT_OF.get(spec.data_type, pd.FMT_OCTET_STRING), len(part), part)

    def _change(self, address: pd.ParameterAddress, values: pd.Values) -> None:
        if address.attribute == pd.ATTR_DESCRIPTION:
            raise _ParameterError(0x07)
        if address.attribute == pd.ATTR_TEXT:
            raise _ParameterError(0x20)
        if address.attribute != pd.ATTR_VALUE or address.elements != 1:
            raise _ParameterError(0x16)
        where, data_type = self._object(address)
        fmt = pd.FORMAT_OF.get(data_type, pd.FMT_OCTET_STRING)
        if values.format != fmt:
            raise _ParameterError(0x17 if values.format not in pd.FORMAT_SIZES else 0x05)
        if fmt not in pd.BYTE_STRINGS and values.count != 1:
            raise _ParameterError(0x18)
        try:
            self.drive.write_bytes(where.index, where.subindex, pd.to_coe(values))
        except SimAbort as exc:
            raise _ParameterError(ERROR_FOR_ABORT.get(exc.code, 0x14)) from None

    def _description(self, address: pd.ParameterAddress) -> pd.Values:
        """Description elements 1 (identifier) and 2 (number of array elements or string
        length); the others are not simulated (error 03h)."""
        entry = self.drive.profile.entries.get(address.pnu)
        if entry is None:
            raise _ParameterError(0x00)
        array = entry.object_type is not ObjectType.VAR
        specs = [s for s in entry.specs() if not (array and address.pnu >= pd.COE_FROM and
                                                   s.subindex == 0)]  # fmt: skip
        if not specs:
            raise _ParameterError(0x00)
        if address.subindex == pd.DESC_ID:
            fmt = pd.FORMAT_OF.get(specs[0].data_type, pd.FMT_OCTET_STRING)
            return pd.Values(pd.FMT_UINT16, 1, (fmt | (pd.ID_ARRAY if array else 0)).to_bytes(2))
        if address.subindex == pd.DESC_ELEMENTS:
            try:
                n = self._elements(address.pnu, array, specs)
            except SimAbort as exc:
                raise _ParameterError(ERROR_FOR_ABORT.get(exc.code, 0x14)) from None
            return pd.Values(pd.FMT_UINT16, 1, n.to_bytes(2))
        raise _ParameterError(0x03)

    def _elements(self, pnu: int, array: bool, specs: list[ObjectSpec]) -> int:
        """Description element 2: the number of array elements, or a string's length."""
        if array and pnu >= pd.COE_FROM and ObjectAddress(pnu, 0) in self.drive.profile.variables:
            # CoE sub 0, the number of entries in use (a mapping's may be fewer).
            return int.from_bytes(self.drive.read_bytes(pnu, 0), "little")
        if array:
            return len(specs)
        if specs[0].data_type in (DataType.VISIBLE_STRING, DataType.OCTET_STRING):
            return len(self.drive.read_bytes(pnu, 0))
        return 0


class _ParameterError(Exception):
    def __init__(self, number: int) -> None:
        super().__init__(f"PROFIdrive error {number:02X}h")
        self.number = number


class _Refused(Exception):
    """An operation refused with a PNIOStatus (ErrorDecode, ErrorCode1, ErrorCode2) and,
    for record access, the response header block that goes with it."""

    def __init__(self, decode: int, code1: int, code2: int, blocks: bytes = b"") -> None:
        super().__init__(f"PNIO {decode:02X}h {code1:02X}h {code2:02X}h")
        self.codes = (decode, code1, code2)
        self.blocks = blocks
