"""The IO device side of a simulated PROFIdrive drive: an IO controller's AR, its RT frames
and their watchdog (docs/profinet.md "Cyclic data").

:class:`IoDevice` takes the IO controller AR a :class:`~servodesk.sim.profinet_device.
ProfinetDevice` hands it (ARType IOCARSingle) and checks its blocks as a device stack does
(IEC 61158-6-10 ConnectReq; domain/pnio_io.py): one IO AR at a time (a second is refused
with CMRPC "no AR resources" while one is live), an input and an output IOCR of RT_CLASS_1
at SendClockFactor 32 (1 ms) with a ReductionRatio of 1-16, the alarm CR, and the expected
submodules of a PROFIdrive drive (access point, drive object, the telegram submodule whose
ident is a telegram of the profile) with the telegram's lengths. The telegram the controller
configures becomes the drive's P922 (the controller's configuration chooses it, 004
§20.1.1). After PrmEnd it calls the controller's ApplicationReady back over DCE/RPC; from then
on the drive's PdoEngine (sim/pdo.py, kind ``telegram``) takes the output frames' setpoint
telegram as its RxPDO and gives the actual-value telegram for each input frame.

Its thread sends the input frame every cycle on the interface (a veth end) and reads the
output frames. Outputs that have not come for DataHoldFactor cycles end the AR (the device's
data hold timer, IEC 61158-6-10): the communication is then IDLE, in which the LECSN-T's
state is always Switch on disabled (004 §20.5.2); the twin gets there by a quick stop (its
quick stop option code 2: decelerate with 6085h, then Switch on disabled, 004 §20.8.10).
"""

from __future__ import annotations

import itertools
import logging
import socket
import threading
import time
import uuid
from dataclasses import dataclass

from servodesk.domain import pnio
from servodesk.domain import pnio_io as io
from servodesk.nic import open_raw, require
from servodesk.realtime import raise_priority
from servodesk.sim.engine import SimAbort, SimulatedDrive
from servodesk.sim.pdo import PdoEngine
from servodesk.sim.profinet_dcp import interface_mac

log = logging.getLogger(__name__)

#: The send clock the twin takes (1 ms) and its reduction ratios (1-16 ms cycles).
SEND_CLOCK_FACTOR = 32
REDUCTION_RATIOS = (1, 2, 4, 8, 16)
#: Largest WatchdogFactor / DataHoldFactor (IEC 61158-6-10: 1-7680).
MAX_FACTOR = 0x1E00
#: The controlword of a quick stop (CiA 402-2 §6.2.1, 004 §20.5.2).
QUICK_STOP = 0x0002
P922 = 0x039A


class Refused(Exception):
    """A connect or control refused with (ErrorDecode, ErrorCode1, ErrorCode2)."""

    def __init__(self, code1: int, code2: int, decode: int = pnio.DECODE_PNIO) -> None:
        super().__init__(f"PNIO {decode:02X}h {code1:02X}h {code2:02X}h")
        self.codes = (decode, code1, code2)


@dataclass
class IoAr:
    ar_uuid: uuid.UUID
    session_key: int
    controller_mac: bytes
    controller_object: uuid.UUID
    #: Where the controller's RPC is (the address and port its connect came from).
    peer: tuple[str, int]
    cycle: float
    data_hold: int
    in_frame_id: int
    out_frame_id: int
    in_layout: io.FrameLayout
    out_layout: io.FrameLayout
    #: Until data exchange the CM supervises the initiator's activity instead (the
    #: ARBlockReq's CMInitiatorActivityTimeoutFactor x 100 ms; IEC 61158-6-10 CMSM).
    activity_timeout: float = 10.0
    created: float = 0.0
    #: Data exchange: after the controller acknowledged ApplicationReady.
    exchanging: bool = False
    last_rx: float = 0.0
    counter: int = 0


class IoDevice:
    """The IO device of one simulated drive on ``ifname`` (see the module docstring)."""

    def __init__(self, drive: SimulatedDrive, ifname: str) -> None:
        require(ifname, hint="the device end of a veth pair (sim/veth.py) must exist")
        self.drive = drive
        self.ifname = ifname
        self.mac = interface_mac(ifname)
        self.ar: IoAr | None = None
        self._inputs = b""
        self._tx_id = 0x180 + drive.node_id
        self._rx_id = 0x200 + drive.node_id
        self.engine = PdoEngine(drive, self._send, lambda code: None)
        drive.on_write(lambda index, _sub, _value: self.engine.on_object_written(index))
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        #: ARs ended by the watchdog, output frames taken, input frames sent (tests, bench).
        self.aborts = 0
        self.outputs_received = 0
        self.inputs_sent = 0
        #: Output frames whose DataStatus or IOPS said the data is not valid.
        self.data_status_errors = 0

    # Lifecycle -------------------------------------------------------------------------

    def start(self) -> IoDevice:
        self._sock = open_raw(
            self.ifname,
            io.ETHERTYPE,
            what="PROFINET RT",
            permission_hint="PROFINET RT frames are raw Ethernet: run as root or give CAP_NET_RAW",
        )
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="pnio-io-device", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None
        self._end("the device stopped", stop_drive=False)

    # Connect, control, release -----------------------------------------------------------

    def connect(
        self, ar: pnio.ArRequest, blocks: list[tuple[int, bytes]], peer: tuple[str, int]
    ) -> bytes:
        """The response blocks to an IO controller's connect; :class:`Refused` when it is
        not one this device takes."""
        with self._lock:
            if self.ar is not None:
                # One IO AR: the device's IO data belongs to the controller that has it.
                raise Refused(pnio.CMRPC, io.CMRPC_NO_AR_RESOURCES)
            if ar.properties & 0x7 != 1 or ar.properties & 0x100:
                raise Refused(0x01, pnio.AR_FIELD["properties"])  # State, DeviceAccess
            iocrs = [io.parse_iocr_block_req(c) for t, c in blocks if t == io.BLOCK_IOCR_REQ]
            alarms = [c for t, c in blocks if t == io.BLOCK_ALARM_CR_REQ]
            expected = [c for t, c in blocks if t == io.BLOCK_EXPECTED_SUBMODULE_REQ]
            kinds = sorted(r.iocr_type for r in iocrs)
            if kinds != [io.IOCR_INPUT, io.IOCR_OUTPUT] or len(alarms) != 1 or not expected:
                raise Refused(pnio.CMRPC, 0x01)  # missing or unexpected blocks
            subs = [s for c in expected for s in io.parse_expected_submodule_block_req(c)]
            self._check_submodules(subs)
            cycle = 0.0
            for r in iocrs:
                cycle = self._check_iocr(r, subs)
            alarm_type, alarm_lt, alarm_ref = io.parse_alarm_cr_block_req(alarms[0])
            if alarm_type != 1:
                raise Refused(io.CODE1_ALARM_CR, 4)
            if alarm_lt != io.ETHERTYPE:
                raise Refused(io.CODE1_ALARM_CR, 5)
            r_in = next(r for r in iocrs if r.iocr_type == io.IOCR_INPUT)
            r_out = next(r for r in iocrs if r.iocr_type == io.IOCR_OUTPUT)
            by = {(s.slot, s.subslot): s for s in subs}

            def layout(r: io.Iocr, inputs: bool) -> io.FrameLayout:
                data = tuple(
                    (s, ss, off, by[(s, ss)].inputs if inputs else by[(s, ss)].outputs)
                    for s, ss, off, _n in r.layout.data
                )
                return io.FrameLayout(data, r.layout.iocs, r.layout.length)

            self.ar = IoAr(
                ar_uuid=ar.ar_uuid,
                session_key=ar.session_key,
                controller_mac=ar.initiator_mac,
                controller_object=ar.initiator_object,
                peer=peer,
                cycle=cycle,
                data_hold=r_out.data_hold_factor,
                in_frame_id=r_in.frame_id,
                out_frame_id=r_out.frame_id,
                in_layout=layout(r_in, True),
                out_layout=layout(r_out, False),
                activity_timeout=0.1 * ar.timeout_factor,
                created=time.monotonic(),
            )
        log.info("IO AR %s from %s: %.0f ms cycle", ar.ar_uuid, peer, cycle * 1000)
        return (
            pnio.ar_block_res(ar.ar_type, ar.ar_uuid, ar.session_key, self.mac)
            + io.iocr_block_res(io.IOCR_INPUT, r_in.reference, r_in.frame_id)
            + io.iocr_block_res(io.IOCR_OUTPUT, r_out.reference, r_out.frame_id)
            + io.alarm_cr_block_res(alarm_ref)
        )

    def _check_submodules(self, subs: list[io.Submodule]) -> None:
        field = io.EXPECTED_FIELD
        code1 = io.CODE1_EXPECTED_SUBMODULE
        places = {(s.slot, s.subslot): s for s in subs}
        if set(places) != {io.DAP, io.MAP, io.TELEGRAM} or len(places) != len(subs):
            raise Refused(code1, field["submodule_ident"])  # not this device's submodules
        dap, mapp, tel = places[io.DAP], places[io.MAP], places[io.TELEGRAM]
        if dap.module_ident != io.DAP_MODULE_IDENT or mapp.module_ident != io.DRIVE_MODULE_IDENT:
            raise Refused(code1, field["module_ident"])
        if dap.ident != io.DAP_SUBMODULE_IDENT or mapp.ident != io.MAP_SUBMODULE_IDENT:
            raise Refused(code1, field["submodule_ident"])
        if dap.kind or mapp.kind or tel.kind != 3:
            raise Refused(code1, field["data_length"])
        telegram = self.drive.profile.pdo.telegram(tel.ident)
        if telegram is None:
            raise Refused(code1, field["submodule_ident"])  # no such telegram
        # The controller's configuration chooses the telegram (004 §20.1.1): P922 follows.
        try:
            if self.drive.read(P922) != tel.ident:
                self.drive.write(P922, 0, tel.ident)
        except SimAbort:
            raise Refused(code1, field["submodule_ident"]) from None
        rx, tx = self.lengths()
        if (tel.outputs, tel.inputs) != (rx, tx):
            raise Refused(code1, field["data_length"])

    def lengths(self) -> tuple[int, int]:
        """The setpoint and actual-value telegrams' bytes of the drive's configuration."""
        rx = self.engine.frame_bytes("rx")
        tx = self.engine.frame_bytes("tx")
        return rx, tx

    def _check_iocr(self, r: io.Iocr, subs: list[io.Submodule]) -> float:
        f = io.IOCR_FIELD
        c = io.CODE1_IOCR
        if r.lt != io.ETHERTYPE:
            raise Refused(c, f["lt"])
        if r.properties & 0xF != io.RT_CLASS_1 or r.properties & ~0xF:
            raise Refused(c, f["properties"])
        if not io.frame_ident_ok(r.frame_id):
            raise Refused(c, f["frame_id"])
        if r.send_clock_factor != SEND_CLOCK_FACTOR:
            raise Refused(c, f["send_clock"])
        if r.reduction_ratio not in REDUCTION_RATIOS:
            raise Refused(c, f["reduction_ratio"])
        if not 1 <= r.watchdog_factor <= MAX_FACTOR:
            raise Refused(c, f["watchdog"])
        if not r.watchdog_factor <= r.data_hold_factor <= MAX_FACTOR:
            raise Refused(c, f["data_hold"])
        inputs = r.iocr_type == io.IOCR_INPUT
        with_inputs = [s for s in subs if s.kind in (0, 1, 3)]  # data objects of the input CR
        with_outputs = [s for s in subs if s.kind in (2, 3)]
        mine, other = (with_inputs, with_outputs) if inputs else (with_outputs, with_inputs)
        objects = {(s, ss): off for s, ss, off, _n in r.layout.data}
        iocs = {(s, ss): off for s, ss, off in r.layout.iocs}
        if set(objects) != {(s.slot, s.subslot) for s in mine} or set(iocs) != {
            (s.slot, s.subslot) for s in other
        }:
            raise Refused(c, f["apis"])  # not the expected submodules' data and IOCS
        used = [
            (objects[(s.slot, s.subslot)],
             objects[(s.slot, s.subslot)] + (s.inputs if inputs else s.outputs) + 1)
            for s in mine
        ] + [(off, off + 1) for off in iocs.values()]  # fmt: skip
        used.sort()
        if any(b0 < a1 for (_a0, a1), (b0, _b1) in itertools.pairwise(used)):
            raise Refused(c, f["apis"])  # overlapping data
        need = max((end for _s, end in used), default=0)
        if not max(io.MIN_DATA_LENGTH, need) <= r.layout.length <= 1440:
            raise Refused(c, f["data_length"])
        return io.cycle_s(r.send_clock_factor, r.reduction_ratio)

    def control(self, args: bytes) -> bytes:
        """PrmEnd (IODControlReq 0110h): Done, then ApplicationReady to the controller."""
        ar_uuid, key, command = io.parse_control_block(pnio.one_block(args, io.BLOCK_PRM_END_REQ))
        ar = self.ar
        if ar is None or ar.ar_uuid != ar_uuid:
            raise Refused(pnio.CMRPC, 0x05)  # AR UUID unknown
        if key != ar.session_key:
            raise Refused(io.CODE1_CONTROL, 5)
        if not command & io.CONTROL_PRM_END:
            raise Refused(io.CODE1_CONTROL, 8)
        threading.Thread(
            target=self._application_ready, args=(ar,), name="pnio-app-ready", daemon=True
        ).start()
        return io.control_block(io.BLOCK_PRM_END_RES, ar_uuid, key, pnio.CONTROL_DONE)

    def release(self, ar_uuid: uuid.UUID, key: int) -> bytes | None:
        """The response to a Release of the IO AR; None when ``ar_uuid`` is not it."""
        ar = self.ar
        if ar is None or ar.ar_uuid != ar_uuid:
            return None
        if key != ar.session_key:
            raise Refused(pnio.CODE1_RELEASE_BLOCK, pnio.RELEASE_FIELD_SESSION_KEY)
        self._end("released by its controller", stop_drive=True)
        return pnio.release_block(pnio.BLOCK_RELEASE_RES, ar_uuid, key, pnio.CONTROL_DONE)

    def drop(self) -> None:
        """The AR ends without a word to the controller (the device was reset)."""
        self._end("the device was reset", stop_drive=False)

    def _application_ready(self, ar: IoAr) -> None:
        """Call the controller's ApplicationReady (IEC 61158-6-10: CControl) and, once it
        answers Done, exchange data."""
        body = pnio.request_body(
            io.control_block(
                io.BLOCK_APP_READY_REQ, ar.ar_uuid, ar.session_key, io.CONTROL_APPLICATION_READY
            ),
            pnio.MAX_DATAGRAM,
        )
        packet = pnio.RpcPacket(
            ptype=pnio.PTYPE_REQUEST,
            opnum=io.OP_CONTROL,
            object_uuid=ar.controller_object,
            interface=io.CONTROLLER_INTERFACE,
            activity=uuid.uuid4(),
            seqnum=0,
            body=body,
        )
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.settimeout(0.5)
            for _ in range(4):
                if self.ar is not ar:
                    return
                sock.sendto(pnio.build_rpc(packet), ar.peer)
                try:
                    frame = sock.recv(65535)
                    reply = pnio.parse_rpc(frame)
                    status, _blocks = pnio.parse_response_body(reply.body, little=reply.little)
                except (TimeoutError, OSError, pnio.PnioFrameError):
                    continue
                if reply.ptype != pnio.PTYPE_RESPONSE or reply.activity != packet.activity:
                    continue
                if status:
                    log.info("ApplicationReady refused: %s", pnio.status_text(status))
                    return
                with self._lock:
                    if self.ar is ar:
                        ar.exchanging = True
                        ar.last_rx = time.monotonic()
                        self.drive.nmt_state = "operational"
                        self.engine.set_operational(True)
                log.info("IO AR %s in data exchange", ar.ar_uuid)
                return
        log.info("the controller did not answer ApplicationReady: IO AR ended")
        self._end("no answer to ApplicationReady", stop_drive=False)

    def _end(self, why: str, *, stop_drive: bool) -> None:
        with self._lock:
            ar, self.ar = self.ar, None
            if ar is None:
                return
            self.engine.set_operational(False)
            self.drive.nmt_state = "preop"
        log.info("IO AR %s ended: %s", ar.ar_uuid, why)
        if stop_drive and ar.exchanging:
            # Communication IDLE: Switch on disabled (004 §20.5.2), reached by a quick stop.
            try:
                self.drive.write(0x6040, 0, QUICK_STOP)
            except SimAbort:
                log.debug("quick stop refused", exc_info=True)

    # RT frames ---------------------------------------------------------------------------

    def _send(self, can_id: int, data: bytes, fd: bool, extended: bool) -> None:
        if can_id == self._tx_id:
            self._inputs = data

    def _run(self) -> None:
        # As a device's stack: its data hold must not expire because the host was busy
        # (servodesk/realtime.py); the thread sleeps in recv between frames.
        raise_priority("PROFINET IO device (twin)")
        sock = self._sock
        assert sock is not None
        next_t = time.perf_counter()
        while not self._stop.is_set():
            ar = self.ar
            if ar is None:
                sock.settimeout(0.05)
                self._receive(sock, None)
                next_t = time.perf_counter()
                continue
            now = time.perf_counter()
            if now >= next_t:
                self._cycle(sock, ar)
                next_t += ar.cycle
                if next_t < now - 20 * ar.cycle:
                    next_t = now + ar.cycle
            sock.settimeout(max(0.0002, next_t - time.perf_counter()))
            self._receive(sock, ar)
            if not ar.exchanging and time.monotonic() - ar.created > ar.activity_timeout:
                self._end("no data exchange within the activity time-out", stop_drive=False)
            elif ar.exchanging and time.monotonic() - ar.last_rx > ar.data_hold * ar.cycle:
                self.aborts += 1
                self._end(
                    f"no output frame for {ar.data_hold} x {ar.cycle * 1000:g} ms (data hold)",
                    stop_drive=True,
                )

    def _cycle(self, sock: socket.socket, ar: IoAr) -> None:
        if ar.exchanging:
            self.engine.on_sync()
            self.engine.flush()
        data = io.pack_c_sdu(ar.in_layout, {io.TELEGRAM: self._inputs}, io.IOXS_GOOD, io.IOXS_GOOD)
        frame = io.build_rt(
            io.RtFrame(ar.controller_mac, self.mac, ar.in_frame_id, data, ar.counter,
                       io.DATA_STATUS_OK)
        )  # fmt: skip
        ar.counter = (ar.counter + round(ar.cycle / io.CLOCK_UNIT_S)) & 0xFFFF
        try:
            sock.send(frame)
            self.inputs_sent += 1
        except OSError:
            log.debug("input frame not sent", exc_info=True)

    def _receive(self, sock: socket.socket, ar: IoAr | None) -> None:
        try:
            frame, addr = sock.recvfrom(1600)
        except (TimeoutError, OSError):
            return
        if addr[2] == socket.PACKET_OUTGOING or ar is None:
            return
        f = io.parse_rt(frame, ar.out_layout.length)
        if f is None or f.frame_id != ar.out_frame_id or f.dst != self.mac:
            return
        off, n = ar.out_layout.offset(*io.TELEGRAM)
        if (
            f.data[off + n] != io.IOXS_GOOD
            or f.data_status & io.DATA_STATUS_OK != io.DATA_STATUS_OK
        ):
            # Not valid, or the controller in STOP: the watchdog is served, the data not used.
            if f.data_status & io.DS_VALID:
                ar.last_rx = time.monotonic()
            if f.data_status & io.DS_RUN or f.data[off + n] != io.IOXS_GOOD:
                self.data_status_errors += 1
            return
        ar.last_rx = time.monotonic()
        self.outputs_received += 1
        if ar.exchanging:
            self.engine.on_frame(self._rx_id, f.data[off : off + n], False)
