"""The PROFINET side of a simulated PROFIdrive drive: PNIO-CM record access over UDP.

:class:`ProfinetDevice` answers connectionless DCE/RPC on a UDP socket as a PROFINET IO
device's context manager does (:mod:`servodesk.domain.pnio`): ``Connect`` with a supervisor
AR with device access, ``Write`` / ``Read`` of records, ``Release``; with :meth:`ProfinetDevice.
serve_io` also an IO controller's AR, its ``Control`` PrmEnd and RT frames on a network
interface (sim/profinet_io.py). Two records are served:

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
number, a client's resend) or a delayed duplicate of an earlier one (an older sequence number)
with the response it sent before, without carrying it out again (for the last
:data:`RESEND_CACHE` client activities). It takes requests in fragments and sends long
responses in fragments (C706 CL-RPC), and answers an unknown operation or interface with a
DCE/RPC reject.

It is as strict as a device stack where servodesk's tests depend on it (issue 47,
docs/profinet.md "Conformance"): a Release needs the AR's SessionKey; another station cannot
take over a live ARUUID; the ARBlockReq's version, ARType, ARProperties, UDP RT port, station
name and activity factor are checked; unknown blocks are refused; I&M1-4, which I&M0
advertises, are served; P922 is read-only, a subindex on a simple parameter is 04h, arrays
are read in one request with No. of elements > 1, the identifier's bit 9 marks read-only
parameters, and P11572 reads 0 while it activates and 1 when done (004 §20.8.14.1).

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

Over 700 lines: one PNIO-CM context manager (Connect, Read, Write, Release, the AR and its
session key, PROFIdrive parameter requests), every handler checking the same AR state as the
spec's state machine does.
"""

from __future__ import annotations

import dataclasses
import logging
import time
import uuid
from dataclasses import dataclass, field

from servodesk.domain import pnio
from servodesk.domain import profidrive as pd
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.dcp import check_name_of_station
from servodesk.domain.profile import ObjectSpec, ObjectType
from servodesk.errors import LinkError, ValidationError
from servodesk.sim.engine import SimAbort, SimulatedDrive
from servodesk.sim.profinet_dcp import DcpResponder, DcpStation, interface_mac
from servodesk.sim.profinet_io import IoDevice, Refused
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
    # 08000024h "no data available" has no PROFIdrive number of its own; it is not the
    # operating state (11h): 14h "value impermissible" (every LECSN-T parameter holds a
    # value, so the twin does not answer it for a parameter of the manual).
    0x08000024: 0x14,
    0x06010001: 0xFF,  # write-only
}


#: ARProperties bits a supervisor AR with device access may set: State (0-2), Supervisor
#: takeover allowed (3), ParametrizationServer (4), DeviceAccess (8), CompanionAR (9-10),
#: AcknowledgeCompanionAR (11), StartupMode (30), PullModuleAlarmAllowed (31); the rest
#: are reserved and 0 (IEC 61158-6-10 ARProperties).
AR_PROPERTIES_KNOWN = 0xC0000F1F
#: ARProperties.State: 001b = Active, the only value a connect may give.
AR_STATE_ACTIVE = 0x1
#: PROFIdrive identifier bit 9: the parameter is read-only (PROFIdrive V4.1, parameter
#: description, element "identifier").
ID_READ_ONLY = 0x0200
#: P922 (telegram selection): read-only over PROFIdrive, set by the IO controller's
#: configuration (004 §20.4.3.1: access R).
P922 = 0x039A
#: ARType of an IO controller's AR, the Control operation and its PNIOStatus ErrorCode.
AR_TYPE_IOCAR = 0x0001
OP_CONTROL = 4
ERROR_CODE_CONTROL = 0xDD


@dataclass(slots=True)
class _Ar:
    session_key: int
    #: Seconds without a record read or write after which the device drops the AR.
    timeout_s: float
    #: time.monotonic() of the AR's last connect, read or write.
    last: float
    #: The parameter response waiting to be read from 0xB02E.
    pending: bytes | None = None
    #: Who set it up (CMInitiatorMacAdd, CMInitiatorStationName): another station may
    #: not take it over by reusing its ARUUID.
    initiator: tuple[bytes, str] = (bytes(6), "")


@dataclass(slots=True)
class _Cache:
    """The last response sent to one client activity (for its resends)."""

    seqnum: int
    #: The response's datagrams (several when it went in fragments).
    datagrams: tuple[bytes, ...]


@dataclass(slots=True)
class _State:
    ars: dict[uuid.UUID, _Ar] = field(default_factory=dict)
    answered: dict[uuid.UUID, _Cache] = field(default_factory=dict)
    #: Calls whose request fragments are still coming in, by (activity, sequence number).
    fragments: dict[tuple[uuid.UUID, int], pnio.Reassembly] = field(default_factory=dict)


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
        #: I&M1-4 (004 §20.4.4: IM supported 30 = 001Eh, I&M1-4), RAM-kept, blank at first.
        self._im_records: dict[int, bytes] = {k: b" " * n for k, n in pnio.IM_LENGTHS.items()}
        #: P11572 (parameter activation): when the last 1EA5h was written (004 §20.8.14.1).
        self._activation_started: float | None = None
        #: DCE/RPC rejects sent (unknown interface or operation).
        self.rejects = 0
        #: Longest response body sent in one datagram; a longer one goes in fragments
        #: (C706 §12.5.3.2; PNIO limits a fragment to the UDP payload of one frame).
        self.max_fragment_body = pnio.MAX_DATAGRAM - pnio.RPC_HEADER_LEN
        #: The IO device for an IO controller's AR and its RT frames (:meth:`serve_io`).
        self.io: IoDevice | None = None

    # Cyclic IO -------------------------------------------------------------------------

    def serve_io(self, ifname: str) -> IoDevice:
        """Take an IO controller's AR and exchange its RT frames on ``ifname`` (the device
        end of a veth pair; sim/profinet_io.py). Without it an IO AR is refused (ARType)."""
        if self.io is None:
            self.io = IoDevice(self.drive, ifname).start()
        return self.io

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
            busy=lambda: self.ars > 0 or (self.io is not None and self.io.ar is not None),
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
        if self.io is not None:
            self.io.drop()
        if mode == 8:
            self.drive.factory_reset()
        else:
            self.drive.reset_node()

    def stop(self) -> None:
        if self.io is not None:
            self.io.stop()
            self.io = None
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
        """The (first) response datagram to one request; None for a datagram that is
        dropped. :meth:`answers` gives every fragment of a long answer."""
        out = self.answers(frame)
        return out[0] if out else None

    def answers(self, frame: bytes) -> list[bytes]:
        """The datagrams that answer one request datagram: the response (in fragments when
        it is longer than :attr:`max_fragment_body`), a fragment acknowledgement, a reject,
        or nothing."""
        try:
            req = pnio.parse_rpc(frame)
        except pnio.PnioFrameError as exc:
            log.debug("PNIO datagram dropped: %s", exc)
            return []
        if req.ptype != pnio.PTYPE_REQUEST:
            return []  # a client's fack of our reply fragments, ping, ...: nothing to do
        cached = self._state.answered.get(req.activity)
        if cached is not None and (
            cached.seqnum == req.seqnum or _older(req.seqnum, cached.seqnum)
        ):
            # A resend, or a delayed duplicate of an earlier call on this activity: the last
            # response, never the call once more (C706 ch. 10: a server carries out the
            # calls of one activity once each, in sequence-number order).
            self.resends += 1
            return list(cached.datagrams)
        if req.flags1 & pnio.FLAG_FRAG:
            whole = self._reassemble(req)
            if whole is None:
                if req.flags1 & pnio.FLAG_NOFACK:
                    return []
                # C706 §12.5.3.6: a fragment without "no fack" is acknowledged.
                return [pnio.build_rpc(pnio.fack(req))]
            req = whole
        if req.interface != pnio.DEVICE_INTERFACE or req.opnum not in _OPS:
            # An interface the server does not export, or an operation beyond the
            # interface's: a DCE/RPC reject (C706 §12.5.3.7 / nca_s_unk_if,
            # nca_s_op_rng_error), as every RPC runtime answers, not a PNIO response.
            self.rejects += 1
            code = (
                pnio.NCA_UNKNOWN_INTERFACE
                if req.interface != pnio.DEVICE_INTERFACE
                else pnio.NCA_OP_RANGE_ERROR
            )
            return [
                pnio.build_rpc(
                    pnio.RpcPacket(
                        ptype=pnio.PTYPE_REJECT,
                        opnum=req.opnum,
                        object_uuid=req.object_uuid,
                        interface=req.interface,
                        activity=req.activity,
                        seqnum=req.seqnum,
                        body=code.to_bytes(4, "little" if req.little else "big"),
                        flags1=pnio.FLAG_LASTFRAG | pnio.FLAG_NOFACK,
                        little=req.little,
                    )
                )
            ]
        self._expire()
        status, args_max, blocks = self._call(req)
        body = pnio.response_body(status, blocks, args_max, little=req.little)
        response = pnio.RpcPacket(
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
        datagrams = tuple(
            pnio.build_rpc(f) for f in pnio.fragment(response, self.max_fragment_body)
        )
        answered = self._state.answered
        answered.pop(req.activity, None)  # to the end: the oldest activity goes first
        answered[req.activity] = _Cache(req.seqnum, datagrams)
        while len(answered) > RESEND_CACHE:
            del answered[next(iter(answered))]
        return list(datagrams)

    def _reassemble(self, frag: pnio.RpcPacket) -> pnio.RpcPacket | None:
        """The whole request once every fragment of its call is in; None before."""
        key = (frag.activity, frag.seqnum)
        pending = self._state.fragments
        if key not in pending:
            while len(pending) >= RESEND_CACHE:
                del pending[next(iter(pending))]
            pending[key] = pnio.Reassembly()
        body = pending[key].add(frag)
        if body is None:
            return None
        del pending[key]
        return dataclasses.replace(
            frag, body=body, flags1=frag.flags1 & ~pnio.FLAG_FRAG | pnio.FLAG_LASTFRAG, fragnum=0
        )

    def _call(self, req: pnio.RpcPacket) -> tuple[int, int, bytes]:
        """(PNIOStatus, ArgsMaximum, the response blocks) of one operation."""
        err = {
            pnio.OP_CONNECT: pnio.ERROR_CODE_CONNECT,
            pnio.OP_RELEASE: pnio.ERROR_CODE_RELEASE,
            pnio.OP_READ: pnio.ERROR_CODE_READ,
            pnio.OP_WRITE: pnio.ERROR_CODE_WRITE,
            OP_CONTROL: ERROR_CODE_CONTROL,
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
            if req.opnum == OP_CONTROL:
                return 0, args_max, self._control(args)
            return self._read(args, args_max)
        except Refused as exc:
            return pnio.pnio_status(err, *exc.codes), args_max, b""
        except pnio.PnioFrameError:
            return pnio.pnio_status(err, pnio.DECODE_PNIO, pnio.CMRPC, 0x01), args_max, b""
        except _Refused as exc:
            return pnio.pnio_status(err, *exc.codes), args_max, exc.blocks

    def _connect(self, args: bytes) -> bytes:
        blocks = pnio.split_blocks(args)
        if any(t not in pnio.CONNECT_BLOCKS for t, _ in blocks):
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x01)  # unknown blocks
        ar_reqs = [c for t, c in blocks if t == pnio.BLOCK_AR_REQ]
        if len(ar_reqs) != 1:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x03)  # wrong block count
        field = pnio.AR_FIELD
        for t, high, low in pnio.block_versions(args):
            if t == pnio.BLOCK_AR_REQ and high != 1:
                raise _Refused(pnio.DECODE_PNIO, 0x01, field["version_high"])
            if t == pnio.BLOCK_AR_REQ and low != 0:
                raise _Refused(pnio.DECODE_PNIO, 0x01, field["version_low"])
        ar = pnio.parse_ar_block_req(ar_reqs[0])
        if ar.ar_type == AR_TYPE_IOCAR and self.io is not None:
            # An IO controller's AR: the IO device checks its blocks (sim/profinet_io.py).
            self._check_station(ar)
            return self.io.connect(ar, blocks, self.peer)
        # Only a supervisor AR with device access: no IO controller, expected submodules or
        # cyclic data come with it (the twin has no IO data to exchange; docs/profinet.md).
        if ar.ar_type != pnio.AR_TYPE_SUPERVISOR:
            raise _Refused(pnio.DECODE_PNIO, 0x01, field["ar_type"])  # faulty ARBlockReq
        if len(blocks) != 1:
            # IOCR, alarm CR or expected submodule blocks have no place in an AR with
            # device access.
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x01)
        if (
            ar.properties & ~AR_PROPERTIES_KNOWN
            or ar.properties & 0x7 != AR_STATE_ACTIVE
            or not ar.properties & pnio.AR_PROPERTIES_DEVICE_ACCESS & 0x100
        ):
            raise _Refused(pnio.DECODE_PNIO, 0x01, field["properties"])
        self._check_station(ar)
        initiator = (ar.initiator_mac, ar.station_name)
        live = self._state.ars.get(ar.ar_uuid)
        if live is not None and live.initiator != initiator:
            # The ARUUID of a live AR from another station: no takeover (the CM keys an AR
            # by its ARUUID and its initiator; IEC 61158-6-10 CMDEV).
            raise _Refused(pnio.DECODE_PNIO, 0x01, field["ar_uuid"])
        if live is None and len(self._state.ars) >= MAX_ARS:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x04)  # no AR resources
        self._state.ars[ar.ar_uuid] = _Ar(
            ar.session_key,
            timeout_s=0.1 * ar.timeout_factor,
            last=time.monotonic(),
            initiator=initiator,
        )
        return pnio.ar_block_res(ar.ar_type, ar.ar_uuid, ar.session_key, self.mac)

    def _check_station(self, ar: pnio.ArRequest) -> None:
        """The ARBlockReq's fields every AR type shares: UDP RT port, station name, activity
        time-out factor (IEC 61158-6-10 ARBlockReq)."""
        field = pnio.AR_FIELD
        if ar.udp_rt_port != 0x8892:
            raise _Refused(pnio.DECODE_PNIO, 0x01, field["udp_rt_port"])
        if not 1 <= len(ar.station_name) <= 240:
            raise _Refused(pnio.DECODE_PNIO, 0x01, field["name_length"])
        try:
            check_name_of_station(ar.station_name)
        except ValidationError:
            raise _Refused(pnio.DECODE_PNIO, 0x01, field["station_name"]) from None
        low, high = ACTIVITY_FACTOR_RANGE
        if not low <= ar.timeout_factor <= high:
            raise _Refused(pnio.DECODE_PNIO, 0x01, FIELD_ACTIVITY_FACTOR)  # faulty ARBlockReq

    def _control(self, args: bytes) -> bytes:
        """Control (opnum 4): an IO controller's PrmEnd for its IO AR."""
        if self.io is None:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x05)  # no IO AR: AR UUID unknown
        return self.io.control(args)

    def _release(self, args: bytes) -> bytes:
        ar_uuid, key, _command = pnio.parse_release_block(
            pnio.one_block(args, pnio.BLOCK_RELEASE_REQ)
        )
        if self.io is not None:
            done = self.io.release(ar_uuid, key)
            if done is not None:
                return done
        ar = self._state.ars.get(ar_uuid)
        if ar is None:
            raise _Refused(pnio.DECODE_PNIO, pnio.CMRPC, 0x05)  # AR UUID unknown
        if key != ar.session_key:
            # Only the AR's own initiator ends it (IEC 61158-6-10: the SessionKey of the
            # release block must be the AR's).
            raise _Refused(
                pnio.DECODE_PNIO, pnio.CODE1_RELEASE_BLOCK, pnio.RELEASE_FIELD_SESSION_KEY
            )
        del self._state.ars[ar_uuid]
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
        im = _im_number(where.index)
        if im is not None:
            if where.subslot != 1 or where.slot not in (0, 1):
                raise _Refused(pnio.DECODE_PNIORW, 0xB2, 0, answer())
            try:
                content = pnio.one_block(record, pnio.BLOCK_IM[im])
            except pnio.PnioFrameError:
                raise _Refused(pnio.DECODE_PNIORW, 0xB8, 0, answer()) from None
            if len(content) != pnio.IM_LENGTHS[im]:
                raise _Refused(pnio.DECODE_PNIORW, 0xB1, 0, answer())
            self._im_records[im] = content
            return 0, args_max, answer()
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

        im = _im_number(where.index)
        if where.index == pnio.INDEX_IM0 and where.subslot == 1 and where.slot in (0, 1):
            data = self.im0(where.slot)
        elif im is not None and where.subslot == 1 and where.slot in (0, 1):
            data = pnio.block(pnio.BLOCK_IM[im], self._im_records[im])
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
        if entry.object_type is ObjectType.VAR:
            if sub != 0:
                # 004 §20.4.2 04h "no array": a subindex on a parameter without subindexes.
                raise _ParameterError(0x04)
            coe_sub = 0
        else:
            coe_sub = sub if pnu < pd.COE_FROM else sub + 1
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
        entry = self.drive.profile.entries.get(address.pnu)
        if address.elements != 1 and entry is not None and entry.object_type is not ObjectType.VAR:
            return self._elements_of(address)
        if address.elements != 1:
            return self._block(address)
        if address.pnu == self._activation_index and self._activation_started is not None:
            return self._activation_state()
        where, data_type = self._object(address)
        try:
            raw = self.drive.read_bytes(where.index, where.subindex)
        except SimAbort as exc:
            raise _ParameterError(ERROR_FOR_ABORT.get(exc.code, 0x14)) from None
        value = pd.from_coe(pd.FORMAT_OF.get(data_type, pd.FMT_OCTET_STRING), raw)
        if value.count > 255 or len(value.data) > pd.MAX_BYTES - 6:
            raise _ParameterError(0x15)  # response too long: read it in blocks
        return value

    def _elements_of(self, address: pd.ParameterAddress) -> pd.Values:
        """``elements`` consecutive elements of an array from PNU subindex ``subindex``, in
        one value block (PROFIdrive: No. of elements > 1 reads a part of an array; P964 x5,
        P975 x8)."""
        fmt: int | None = None
        data = b""
        for i in range(address.elements):
            one = pd.ParameterAddress(address.pnu, address.subindex + i)
            where, data_type = self._object(one)
            f = pd.FORMAT_OF.get(data_type, pd.FMT_OCTET_STRING)
            if f in pd.BYTE_STRINGS or (fmt is not None and f != fmt):
                raise _ParameterError(0x16)  # not one format: no such address
            fmt = f
            try:
                data += pd.from_coe(f, self.drive.read_bytes(where.index, where.subindex)).data
            except SimAbort as exc:
                raise _ParameterError(ERROR_FOR_ABORT.get(exc.code, 0x14)) from None
        assert fmt is not None
        if len(data) > pd.MAX_BYTES - 6:
            raise _ParameterError(0x15)
        return pd.Values(fmt, address.elements, data)

    @property
    def _activation_index(self) -> int | None:
        q = self.drive.profile.quirk("parameter_activation", None)
        return int(q["index"]) if isinstance(q, dict) and "index" in q else None

    def _activation_state(self) -> pd.Values:
        """P11572 after 1EA5h was written: 0 while the drive activates the parameters
        (about 100 ms), then 1 (004 §20.8.14.1)."""
        q = self.drive.profile.quirk("parameter_activation", {}) or {}
        started = self._activation_started
        assert started is not None
        busy = time.monotonic() - started < float(q.get("duration_ms", 100)) / 1000.0
        value = int(q.get("busy_value", 0)) if busy else int(q.get("done_value", 1))
        return pd.Values(pd.FMT_UINT16, 1, value.to_bytes(2, "big"))

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
        if address.pnu == P922:
            # 004 §20.4.3.1: P922 is R; the telegram comes from the IO controller's
            # configuration (GSDML), never from a parameter write.
            raise _ParameterError(0x01)
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
        if where.index == self._activation_index and int.from_bytes(values.data, "big") == 0x1EA5:
            self._activation_started = time.monotonic()

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
            ident = fmt | (pd.ID_ARRAY if array else 0)
            if not any(sp.access.writable for sp in specs) or entry.index == P922:
                ident |= ID_READ_ONLY
            return pd.Values(pd.FMT_UINT16, 1, ident.to_bytes(2))
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


#: The PNIO-CM operations the device interface exports (IEC 61158-6-10: Connect, Release,
#: Read, Write, Control; Control (4) carries an IO controller's PrmEnd).
_OPS = frozenset({pnio.OP_CONNECT, pnio.OP_RELEASE, pnio.OP_READ, pnio.OP_WRITE, 4})


def _older(seqnum: int, last: int) -> bool:
    """``seqnum`` comes before ``last`` (32-bit sequence numbers that wrap)."""
    return 0 < (last - seqnum) & 0xFFFFFFFF < 0x80000000


def _im_number(index: int) -> int | None:
    """1-4 for the records of I&M1-4, None for any other index."""
    for n, i in pnio.INDEX_IM.items():
        if i == index:
            return n
    return None


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
