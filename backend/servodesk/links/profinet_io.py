"""PROFINET cyclic data: servodesk as the drive's IO controller, and the
:class:`~servodesk.links.cyclic.CyclicTransport` the PDO exchange runs on.

:class:`IoController` sets up an IO controller AR (ARType IOCARSingle) next to the link's
supervisor AR: one ``Connect`` with the ARBlockReq, the input and output IOCRBlockReq of the
drive's telegram, the AlarmCRBlockReq and the ExpectedSubmoduleBlockReq (domain/pnio_io.py),
``Control`` PrmEnd, then it serves the device's ApplicationReady call on the socket it
connected from (the device calls its controller back over DCE/RPC; IEC 61158-6-10). Its
thread, not the event loop, then sends the output frame (RT_CLASS_1, Ethertype 8892h, the
output IOCR's FrameID) every SendClockFactor x ReductionRatio x 31.25 µs on an AF_PACKET
socket of the NIC, and receives the input frames between two sends.

Its watchdog: inputs that have not come for WatchdogFactor cycles are stale and the link
state is "link lost" (the exchange then puts a quick stop into the output image, as on
EtherCAT); so is a NIC without carrier (the cable out at servodesk's end). Once the carrier
is back, or at once after a watchdog loss, the same thread sets the IO AR up again by
itself (:meth:`IoController._recover`: Release of the old AR, Connect with the next session
key, PrmEnd, ApplicationReady); the link is "recovering" until the first valid input frame,
then "ok", and the inputs show the drive's own state (a device whose data hold timer ended
the AR is in Switch on disabled or Fault, 004 §20.5.2). The outputs carry what the exchange
holds: the quick stop put in at the loss, until the person in control commands again.

An input frame whose DataStatus is not "valid, run, primary, no problem" or whose IOPS is
bad counts as a data-status error and is not handed on. Frames lost are counted from the
gaps in the input frames' cycle counter.

A device whose IO AR is another controller's (the PLC's) refuses the connect; the error says
so and servodesk never takes the AR over.
"""

from __future__ import annotations

import contextlib
import logging
import math
import socket
import threading
import time
import uuid
from dataclasses import dataclass, field
from typing import Any, Protocol

from servodesk import nic
from servodesk.domain import pnio
from servodesk.domain import pnio_io as io
from servodesk.errors import (
    ConflictError,
    LinkError,
    LinkTimeoutError,
    ServodeskError,
    ValidationError,
)
from servodesk.links.cyclic import CyclicTransport, FrameCallback
from servodesk.realtime import raise_priority

log = logging.getLogger(__name__)

#: The send clock servodesk asks for: 32 x 31.25 µs = 1 ms (the shortest the twin takes).
SEND_CLOCK_FACTOR = 32
#: Reduction ratios (RT_CLASS_1: powers of two) servodesk offers: cycles of 1-16 ms.
REDUCTION_RATIOS = (1, 2, 4, 8, 16)
#: The cycles those make, in ms (the PDO page offers these and no other).
PERIODS_MS = tuple(io.cycle_s(SEND_CLOCK_FACTOR, r) * 1000 for r in REDUCTION_RATIOS)
#: The watchdog time servodesk asks for, at least [s]: its cycle runs on a thread of a
#: general-purpose OS, whose delays reach tens of milliseconds under load; a watchdog of 3
#: cycles (a PLC's usual) would fire on them: 100 ms fired once in a test run on 2 cores at
#: load 10 (tests/profinet/test_cyclic.py).
WATCHDOG_MIN_S = 0.2
#: How long the device has to call ApplicationReady after PrmEnd [s].
APPLICATION_READY_S = 3.0
#: While the link is lost, the pause between two tries to set the IO AR up again [s].
RECONNECT_EVERY_S = 0.5
#: A loss is held this long at least before the first try [s]: the exchange's SYNC thread
#: (one look per cycle, 16 ms at most) must see "link lost" to put its quick stop in first.
RECONNECT_AFTER_S = 0.05
#: The RPC time-out of a try [s]: short, so that stopping cyclic data never waits long.
RECONNECT_RPC_S = 0.3
#: How often the cycle thread reads the NIC's carrier [s] (as the EtherCAT line does).
CARRIER_EVERY_S = 0.02
#: The output and input IOCRs' references and the FrameIDs servodesk proposes.
OUTPUT_REF, INPUT_REF = 1, 2
OUTPUT_FRAME_ID, INPUT_FRAME_ID = 0x8000, 0x8001

OK = "ok"
LOST = "link lost"
STARTING = "recovering"


@dataclass
class IoHealth:
    """The cycles as the controller sees them (the keys of links/ethercat_health.py's view,
    which the PDO page and API show, plus the AR, the data-status errors and the cycle)."""

    state: str = STARTING
    reason: str | None = "waiting for the first input frame"
    cycles: int = 0
    received: int = 0
    lost: int = 0
    data_status_errors: int = 0
    losses: int = 0
    last_good: float = 0.0
    last_counter: int | None = None
    #: Send times of the output frames (the last ones): the cycle achieved.
    intervals: list[float] = field(default_factory=list)
    #: The NIC's carrier (/sys/class/net/<nic>/carrier; None where it cannot be read).
    carrier: bool | None = None
    #: When the AR was (set up) again: the watchdog counts from here until a valid input.
    fresh: float = 0.0
    lost_at: float = 0.0
    #: Why the link was lost (kept in ``reason`` while the AR is set up again).
    cause: str = ""
    carrier_lost_at: float = 0.0
    #: When the next try to set the AR up again may start (while the link is lost).
    retry_at: float = 0.0
    #: ARs set up again after a loss, and the last one's time from the loss to running.
    recoveries: int = 0
    last_recovery_s: float | None = None

    @property
    def stale(self) -> bool:
        return self.state != OK


def reduction_ratio(cycle_s: float) -> int:
    """The ReductionRatio of a cycle at servodesk's send clock; ValidationError for a cycle
    it does not offer."""
    ratio = round(cycle_s / io.cycle_s(SEND_CLOCK_FACTOR, 1))
    if ratio not in REDUCTION_RATIOS or abs(io.cycle_s(SEND_CLOCK_FACTOR, ratio) - cycle_s) > 1e-9:
        raise ValidationError(
            f"a PROFINET IO cycle of {cycle_s * 1000:g} ms is not one servodesk offers",
            field="sync_period_ms",
            hint="use 1, 2, 4, 8 or 16 ms (SendClockFactor 32 = 1 ms x reduction ratio)",
        )
    return ratio


class IoController:
    """One IO controller AR to one PROFINET IO device (see the module docstring)."""

    def __init__(
        self,
        host: str,
        port: int,
        nic_name: str,
        *,
        object_uuid: uuid.UUID,
        telegram: int,
        rx_bytes: int,
        tx_bytes: int,
        cycle_s: float,
        timeout: float = 1.0,
        station_name: str = "servodesk",
    ) -> None:
        ratio = reduction_ratio(cycle_s)
        self.host, self.port = host, port
        self.nic = nic_name
        self.object_uuid = object_uuid
        self.telegram = telegram
        self.timeout = timeout
        self.station_name = station_name
        self.reduction_ratio = ratio
        self.cycle = io.cycle_s(SEND_CLOCK_FACTOR, ratio)
        self.watchdog_factor = max(3, math.ceil(WATCHDOG_MIN_S / self.cycle))
        self.submodules = io.drive_submodules(telegram, rx_bytes, tx_bytes)
        self.in_layout, self.out_layout = io.layouts(self.submodules)
        self.ar_uuid = uuid.uuid4()
        self.session_key = 1
        self._activity = uuid.uuid4()
        self._seqnum = 0
        self._rpc: socket.socket | None = None
        self._raw: socket.socket | None = None
        self.mac = bytes(6)
        self.device_mac = bytes(6)
        self.out_frame_id = OUTPUT_FRAME_ID
        self.in_frame_id = INPUT_FRAME_ID
        self._outputs = bytes(rx_bytes)
        self._running = False  # DataStatus "run" once the device's application is ready
        #: Set once :meth:`connect` is done: from then on the cycle thread owns the RPC
        #: socket for setting the AR up again (before, connect's wait for ApplicationReady).
        self._up = False
        self.application_ready = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._counter = 0
        self._next_t = 0.0
        self._last_send = 0.0
        self._receivers: list[FrameCallback] = []
        self._lock = threading.Lock()
        self.health = IoHealth()

    # Setting up and ending the AR -------------------------------------------------------

    def connect(self) -> None:
        """Connect, PrmEnd, ApplicationReady, and the cycle running (blocking)."""
        nic.require(self.nic, hint="give the network interface that reaches the drive")
        self.mac = _mac_of(self.nic)
        connected = False
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.connect((self.host, self.port))
            local = sock.getsockname()[0]
            sock.close()
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            # The device calls its controller back where the connect came from; a PLC's
            # RPC port is 34964, which servodesk takes where it is free.
            try:
                sock.bind((local, pnio.RPC_PORT))
            except OSError:
                sock.bind((local, 0))
            # Not connected: the device's ApplicationReady comes from another port of its.
            self._rpc = sock
            status, blocks = self._call(pnio.OP_CONNECT, self._connect_blocks())
            self._check_connect(status, blocks)
            connected = True
            self._raw = nic.open_raw(
                self.nic,
                io.ETHERTYPE,
                what="PROFINET RT",
                permission_hint="cyclic PROFINET data sends raw Ethernet frames: run as root "
                "or give the Python binary CAP_NET_RAW",
            )
            self._raw.settimeout(self.cycle)
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="servodesk-pnio-rt", daemon=True)
            self._thread.start()
            args = io.control_block(
                io.BLOCK_PRM_END_REQ, self.ar_uuid, self.session_key, io.CONTROL_PRM_END
            )
            status, blocks = self._call(io.OP_CONTROL, args)
            if status:
                raise ConflictError(
                    f"the device at {self.host} refused PrmEnd: {pnio.status_text(status)}"
                )
            deadline = time.monotonic() + APPLICATION_READY_S
            while not self.application_ready.is_set():
                if time.monotonic() > deadline:
                    raise LinkTimeoutError(
                        f"the device at {self.host} did not call ApplicationReady within "
                        f"{APPLICATION_READY_S:g} s of PrmEnd",
                        hint="the device cannot reach servodesk's RPC port (a firewall?)",
                    )
                self._serve_once(0.05)
            self._running = True
            self._up = True
        except BaseException:
            self.close(release=connected)  # a refused connect left no AR to release
            raise

    def close(self, *, release: bool = True) -> None:
        """Stop the cycle and end the AR (Release; best effort: the device's watchdog ends
        it as well)."""
        self._stop.set()
        t, self._thread = self._thread, None
        if t is not None and t is not threading.current_thread():
            t.join(2.0)
        raw, self._raw = self._raw, None
        if raw is not None:
            raw.close()
        sock = self._rpc
        if sock is not None and release:
            with contextlib.suppress(OSError, LinkError, pnio.PnioFrameError):
                args = pnio.release_block(
                    pnio.BLOCK_RELEASE_REQ, self.ar_uuid, self.session_key, pnio.CONTROL_RELEASE
                )
                self._call(pnio.OP_RELEASE, args, sends=1, timeout=0.3)
        self._rpc = None
        if sock is not None:
            sock.close()

    def _connect_blocks(self) -> bytes:
        ar = pnio.ar_block_req(
            pnio.ArRequest(
                ar_uuid=self.ar_uuid,
                session_key=self.session_key,
                initiator_mac=self.mac,
                initiator_object=pnio.object_uuid(0, 0),
                station_name=self.station_name,
                ar_type=io.AR_TYPE_IOCAR,
                properties=io.AR_PROPERTIES_IOCAR,
                timeout_factor=100,
            )
        )

        def iocr(kind: int, ref: int, fid: int, layout: io.FrameLayout) -> bytes:
            return io.iocr_block_req(
                io.Iocr(kind, ref, fid, layout, SEND_CLOCK_FACTOR, self.reduction_ratio,
                        self.watchdog_factor, self.watchdog_factor)
            )  # fmt: skip

        return (
            ar
            + iocr(io.IOCR_INPUT, INPUT_REF, INPUT_FRAME_ID, self.in_layout)
            + iocr(io.IOCR_OUTPUT, OUTPUT_REF, OUTPUT_FRAME_ID, self.out_layout)
            + io.alarm_cr_block_req()
            + io.expected_submodule_block_req(self.submodules)
        )

    def _check_connect(self, status: int, blocks: bytes) -> None:
        if status:
            code1, code2 = (status >> 8) & 0xFF, status & 0xFF
            if code1 == pnio.CMRPC and code2 == io.CMRPC_NO_AR_RESOURCES:
                raise ConflictError(
                    f"the drive at {self.host} refused servodesk's IO controller AR: another IO "
                    f"controller (the PLC) holds its IO data (PNIOStatus {status:08X}h, "
                    "no AR resources)",
                    hint="servodesk does not take a drive's IO AR over: stop the PLC's "
                    "connection to the drive (its configuration or STOP with the AR released) "
                    "to run cyclic data from servodesk, or keep to parameter access",
                )
            raise ConflictError(
                f"the drive at {self.host} refused servodesk's IO controller AR: "
                f"{_connect_text(status)} (PNIOStatus {status:08X}h)",
                hint="check that the drive's telegram is one it offers and the cycle one it "
                "takes (docs/profinet.md, cyclic data)",
            )
        try:
            parts = dict(pnio.split_blocks(blocks))
            if io.BLOCK_MODULE_DIFF in parts:
                raise ConflictError(
                    f"the drive at {self.host} has other submodules than servodesk expects "
                    f"(ModuleDiffBlock): telegram {self.telegram}",
                    hint="check the drive's telegram (P922) and its GSD file",
                )
            ar_uuid, _key = pnio.parse_ar_block_res(parts[pnio.BLOCK_AR_RES])
            self.device_mac = parts[pnio.BLOCK_AR_RES][20:26]
            for t, content in pnio.split_blocks(blocks):
                if t == io.BLOCK_IOCR_RES:
                    kind, _ref, fid = io.parse_iocr_block_res(content)
                    if kind == io.IOCR_INPUT:
                        self.in_frame_id = fid
                    elif kind == io.IOCR_OUTPUT:
                        self.out_frame_id = fid
        except (KeyError, pnio.PnioFrameError) as exc:
            raise LinkError(f"the device's IO connect response is malformed: {exc}") from exc
        if ar_uuid != self.ar_uuid:
            raise LinkError("the device answered the IO connect for another AR")

    # RPC: calls to the device, and the device's ApplicationReady -----------------------

    def _call(
        self, opnum: int, args: bytes, *, sends: int = 2, timeout: float | None = None
    ) -> tuple[int, bytes]:
        sock = self._rpc
        assert sock is not None
        self._seqnum += 1
        packet = pnio.RpcPacket(
            ptype=pnio.PTYPE_REQUEST,
            opnum=opnum,
            object_uuid=self.object_uuid,
            interface=pnio.DEVICE_INTERFACE,
            activity=self._activity,
            seqnum=self._seqnum,
            body=pnio.request_body(args, pnio.MAX_DATAGRAM),
        )
        datagram = pnio.build_rpc(packet)
        wait = timeout if timeout is not None else self.timeout
        for _ in range(sends):
            sock.sendto(datagram, (self.host, self.port))
            deadline = time.monotonic() + wait
            while (left := deadline - time.monotonic()) > 0:
                got = self._serve_once(left)
                if got is not None and got.activity == self._activity:
                    if got.seqnum != self._seqnum:
                        continue
                    if got.ptype != pnio.PTYPE_RESPONSE:
                        raise LinkError(f"the device rejected the RPC call (ptype {got.ptype})")
                    return pnio.parse_response_body(got.body, little=got.little)
        raise LinkTimeoutError(f"no PNIO answer from {self.host}:{self.port} to opnum {opnum}")

    def _serve_once(self, wait: float) -> pnio.RpcPacket | None:
        """One datagram: a response is returned; the device's ApplicationReady request is
        answered (Done) and sets :attr:`application_ready`."""
        sock = self._rpc
        assert sock is not None
        sock.settimeout(max(0.001, wait))
        try:
            frame, peer = sock.recvfrom(65535)
        except TimeoutError:
            return None
        except ConnectionRefusedError as exc:
            raise LinkError(f"nothing answers PNIO-CM at udp {self.host}:{self.port}") from exc
        try:
            packet = pnio.parse_rpc(frame)
        except pnio.PnioFrameError:
            return None
        if packet.ptype != pnio.PTYPE_REQUEST:
            return packet
        status = 0
        reply = b""
        try:
            args_max, args = pnio.parse_request_body(packet.body, little=packet.little)
            ar_uuid, key, command = io.parse_control_block(
                pnio.one_block(args, io.BLOCK_APP_READY_REQ)
            )
            ok = (
                packet.interface == io.CONTROLLER_INTERFACE
                and packet.opnum == io.OP_CONTROL
                and ar_uuid == self.ar_uuid
                and key == self.session_key
                and command & io.CONTROL_APPLICATION_READY
            )
            if ok:
                reply = io.control_block(io.BLOCK_APP_READY_RES, ar_uuid, key, pnio.CONTROL_DONE)
                self.application_ready.set()
            else:
                status = pnio.pnio_status(0xDD, pnio.DECODE_PNIO, io.CODE1_CONTROL, 0)
        except pnio.PnioFrameError:
            args_max = 0
            status = pnio.pnio_status(0xDD, pnio.DECODE_PNIO, pnio.CMRPC, 0x01)
        answer = pnio.RpcPacket(
            ptype=pnio.PTYPE_RESPONSE,
            opnum=packet.opnum,
            object_uuid=packet.object_uuid,
            interface=packet.interface,
            activity=packet.activity,
            seqnum=packet.seqnum,
            body=pnio.response_body(status, reply, args_max, little=packet.little),
            flags1=pnio.FLAG_LASTFRAG | pnio.FLAG_NOFACK,
            little=packet.little,
        )
        with contextlib.suppress(OSError):
            sock.sendto(pnio.build_rpc(answer), peer)
        return None

    # The cycle ---------------------------------------------------------------------------

    def set_outputs(self, data: bytes) -> None:
        self._outputs = bytes(data)

    def subscribe(self, callback: FrameCallback) -> None:
        with self._lock:
            self._receivers = [*self._receivers, callback]

    def unsubscribe(self, callback: FrameCallback) -> None:
        with self._lock:
            self._receivers = [c for c in self._receivers if c is not callback]

    def _run(self) -> None:
        # Inputs missing for the watchdog time end the AR on both sides: this thread must
        # not wait behind a busy machine's other work (servodesk/realtime.py). It sleeps in
        # recv until its next send.
        raise_priority("PROFINET IO controller")
        raw = self._raw
        assert raw is not None
        h = self.health
        self._counter = 0
        self._next_t = time.perf_counter()
        self._last_send = 0.0
        h.fresh = time.monotonic()
        next_carrier = 0.0
        while not self._stop.is_set():
            self._send_due()
            raw.settimeout(max(0.0002, self._next_t - time.perf_counter()))
            try:
                frame = raw.recv(1600)
            except TimeoutError:
                frame = b""
            except OSError:
                if self._stop.is_set():
                    return
                frame = b""
            t = time.monotonic()
            if frame:
                self._input(frame, t)
            if t >= next_carrier:
                next_carrier = t + CARRIER_EVERY_S
                self._carrier(t)
            self._watch(t)
            if self._up and h.state == LOST and h.carrier is not False and t >= h.retry_at:
                self._recover()

    def _send_due(self) -> None:
        """The output frame, when its cycle has come."""
        raw = self._raw
        now = time.perf_counter()
        if raw is None or now < self._next_t:
            return
        h = self.health
        data = io.pack_c_sdu(
            self.out_layout, {io.TELEGRAM: self._outputs}, io.IOXS_GOOD, io.IOXS_GOOD
        )
        status = io.DATA_STATUS_OK if self._running else io.DATA_STATUS_OK & ~io.DS_RUN
        frame = io.build_rt(
            io.RtFrame(self.device_mac, self.mac, self.out_frame_id, data, self._counter, status)
        )
        try:
            raw.send(frame)
        except OSError as exc:
            h.reason = f"the NIC {self.nic} does not send: {exc}"
        if self._last_send:
            h.intervals.append(now - self._last_send)
            if len(h.intervals) > 4096:
                del h.intervals[:2048]
        self._last_send = now
        h.cycles += 1
        self._counter = (self._counter + round(self.cycle / io.CLOCK_UNIT_S)) & 0xFFFF
        self._next_t += self.cycle
        if self._next_t < now - 20 * self.cycle:
            self._next_t = now + self.cycle  # far behind (a stalled machine): resume

    def _watch(self, t: float) -> None:
        """The controller's watchdog: no valid input for WatchdogFactor cycles (3 times
        that before the first one after a (re)connect) is a lost link."""
        h = self.health
        watchdog = self.watchdog_factor * self.cycle
        since = t - max(h.last_good, h.fresh)
        limit = watchdog if h.last_good > h.fresh else 3 * watchdog
        if since > limit and h.state != LOST:
            self._lose(
                t,
                f"no valid input frame for {since * 1000:.0f} ms (watchdog "
                f"{self.watchdog_factor} x {self.cycle * 1000:g} ms)",
            )

    def _carrier(self, t: float) -> None:
        """The NIC's carrier: 0 is a lost link at once (a cable out at servodesk's end);
        when it returns after longer than the device's data hold time, the device has ended
        the AR, and it is set up again without waiting for its inputs."""
        h = self.health
        try:
            with open(f"/sys/class/net/{self.nic}/carrier") as f:
                carrier: bool | None = f.read().strip() == "1"
        except OSError:  # EINVAL while the interface is down, or no such file
            carrier = None if h.carrier is None else False
        was, h.carrier = h.carrier, carrier
        if carrier is False and was is not False:
            h.carrier_lost_at = t
            self._lose(t, f"no carrier on the network interface {self.nic} (cable out?)")
        elif carrier and was is False:
            down = t - h.carrier_lost_at
            hold = self.watchdog_factor * self.cycle
            h.retry_at = max(h.lost_at + RECONNECT_AFTER_S, t if down > hold else t + hold)

    def _lose(self, t: float, reason: str) -> None:
        h = self.health
        if h.state == LOST:
            return
        h.state, h.reason, h.cause = LOST, reason, reason
        h.losses += 1
        h.lost_at = t
        h.retry_at = t + RECONNECT_AFTER_S
        log.warning("PROFINET IO %s: link lost: %s", self.host, reason)

    def _recover(self) -> None:
        """Set the IO AR up again after a loss (called by the cycle thread while the link is
        lost and the NIC has its carrier): Release of the old AR (the device may still hold
        it), Connect with the next session key, PrmEnd, ApplicationReady. The state stays
        "link lost" until the device called ApplicationReady, then "recovering" until its
        first valid input frame; a try that fails is tried again RECONNECT_EVERY_S later.
        Nothing here touches the outputs: they carry the quick stop the exchange put in at
        the loss (services/cyclic.py ``hold_on_link_loss``)."""
        h = self.health
        self._running = False  # DataStatus STOP until the new AR is in data exchange
        h.reason = f"{h.cause}; setting the IO AR up again (Connect, PrmEnd, ApplicationReady)"
        try:
            with contextlib.suppress(LinkError, pnio.PnioFrameError):
                args = pnio.release_block(
                    pnio.BLOCK_RELEASE_REQ, self.ar_uuid, self.session_key, pnio.CONTROL_RELEASE
                )
                self._call(pnio.OP_RELEASE, args, sends=1, timeout=RECONNECT_RPC_S)
            self.session_key = self.session_key % 0xFFFF + 1
            self.application_ready.clear()
            status, blocks = self._call(
                pnio.OP_CONNECT, self._connect_blocks(), timeout=RECONNECT_RPC_S
            )
            self._check_connect(status, blocks)
            args = io.control_block(
                io.BLOCK_PRM_END_REQ, self.ar_uuid, self.session_key, io.CONTROL_PRM_END
            )
            status, _blocks = self._call(io.OP_CONTROL, args, timeout=RECONNECT_RPC_S)
            if status:
                raise ConflictError(f"the device refused PrmEnd: {pnio.status_text(status)}")
            deadline = time.monotonic() + APPLICATION_READY_S
            while not self.application_ready.is_set():
                if self._stop.is_set():
                    return
                if time.monotonic() > deadline:
                    raise LinkTimeoutError("the device did not call ApplicationReady")
                self._send_due()
                self._serve_once(min(0.01, max(0.0002, self._next_t - time.perf_counter())))
        except (ServodeskError, OSError, pnio.PnioFrameError) as exc:
            text = exc.message if isinstance(exc, ServodeskError) else str(exc)
            h.reason = f"{h.cause}; the IO AR could not be set up again: {text}"
            h.retry_at = time.monotonic() + RECONNECT_EVERY_S
            log.info("PROFINET IO %s: %s", self.host, h.reason)
            return
        self._running = True
        h.last_counter = None  # the new AR's cycle counter starts anew
        h.fresh = time.monotonic()
        h.state = STARTING
        h.reason = f"{h.cause}; the IO AR is set up again: waiting for its first input frame"
        h.recoveries += 1
        log.info("PROFINET IO %s: IO AR set up again (session key %d)", self.host, self.session_key)

    def _input(self, frame: bytes, t: float) -> None:
        f = io.parse_rt(frame, self.in_layout.length)
        if f is None or f.frame_id != self.in_frame_id or f.src != self.device_mac:
            return
        h = self.health
        h.received += 1
        if h.last_counter is not None:
            step = round(self.cycle / io.CLOCK_UNIT_S)
            gap = ((f.cycle_counter - h.last_counter) & 0xFFFF) // step
            if gap > 1:
                h.lost += gap - 1
        h.last_counter = f.cycle_counter
        off, n = self.in_layout.offset(*io.TELEGRAM)
        iops = f.data[off + n]
        ok = f.data_status & io.DATA_STATUS_OK == io.DATA_STATUS_OK and iops == io.IOXS_GOOD
        if not ok:
            h.data_status_errors += 1
            return
        h.last_good = t
        if h.state != OK:
            if h.lost_at:
                h.last_recovery_s = t - h.lost_at
                log.info("PROFINET IO %s: running %.3f s after the loss", self.host, t - h.lost_at)
            h.state, h.reason = OK, None
            h.lost_at = 0.0
        data = f.data[off : off + n]
        for cb in self._receivers:
            cb(data, t)

    def view(self) -> dict[str, Any]:
        h = self.health
        now = time.monotonic()
        return {
            "state": h.state,
            "reason": h.reason,
            "stale": h.stale,
            "cycles": h.cycles,
            "wkc_errors": 0,
            "missing_frames": h.lost,
            "last_wkc": None,
            "expected_wkc": 0,
            "carrier": h.carrier,
            "losses": h.losses,
            "since_good_s": round(now - h.last_good, 3) if h.last_good else None,
            "slaves": [],
            "ar": AR_IO,
            "data_status_errors": h.data_status_errors,
            "frames_received": h.received,
            "cycle_ms": round(self.cycle * 1000, 3),
            "watchdog_ms": round(self.watchdog_factor * self.cycle * 1000, 3),
        }


#: How the session names the ARs it uses (the API and the PDO page show it).
AR_SUPERVISOR = "IO supervisor AR with device access (ARType 0006h)"
AR_IO = "IO controller AR (ARType 0001h, IOCARSingle) for cyclic data"


def _connect_text(status: int) -> str:
    code1, code2 = (status >> 8) & 0xFF, status & 0xFF
    block = {
        0x01: "ARBlockReq",
        io.CODE1_IOCR: "IOCRBlockReq",
        io.CODE1_EXPECTED_SUBMODULE: "ExpectedSubmoduleBlockReq",
        io.CODE1_ALARM_CR: "AlarmCRBlockReq",
    }.get(code1)
    if block is None:
        return pnio.status_text(status)
    names = {v: k for k, v in (io.IOCR_FIELD if code1 == io.CODE1_IOCR else
                               io.EXPECTED_FIELD if code1 == io.CODE1_EXPECTED_SUBMODULE else
                               pnio.AR_FIELD).items()}  # fmt: skip
    return f"faulty {block}, field {code2} ({names.get(code2, '?')})"


def _mac_of(name: str) -> bytes:
    try:
        with open(f"/sys/class/net/{name}/address") as f:
            return bytes.fromhex(f.read().strip().replace(":", ""))
    except OSError as exc:
        raise LinkError(f"no MAC address for network interface {name!r}: {exc}") from exc


class _HasIo(Protocol):
    host: str
    port: int
    io: IoController | None


class ProfinetCyclic(CyclicTransport):
    """The PDO exchange's view of the link's IO controller AR: RxPDO (200h + DO-ID) is the
    setpoint telegram, sent with every cycle of the controller's thread; TxPDO (180h +
    DO-ID) the actual-value telegram of each valid input frame. "SYNC" has nothing to send:
    the cycle runs on the controller's own clock. The AR is set up after the transport is
    made (the exchange's "start"), so each call looks it up."""

    def __init__(self, link: _HasIo) -> None:
        self.link = link
        self._rx = 0x200 + int(getattr(getattr(link, "params", None), "node_id", 1))
        self._tx = self._rx - 0x80

    @property
    def bus_key(self) -> object:
        return ("profinet", self.link.host, self.link.port)

    def subscribe(self, ident: int, callback: FrameCallback) -> None:
        if ident == self._tx and self.link.io is not None:
            self.link.io.subscribe(callback)

    def unsubscribe(self, ident: int, callback: FrameCallback) -> None:
        if self.link.io is not None:
            self.link.io.unsubscribe(callback)

    def send(self, ident: int, data: bytes) -> None:
        if ident == self._rx and self.link.io is not None:
            self.link.io.set_outputs(data)

    def send_rtr(self, ident: int, length: int) -> None:
        """PROFINET has no remote frames: the inputs come every cycle."""

    def send_sync(self, counter: int | None = None) -> None:
        """Nothing: the controller's thread sends the outputs at its own cycle."""

    def health(self) -> dict[str, Any] | None:
        return self.link.io.view() if self.link.io is not None else None

    def link_state(self) -> str | None:
        return self.link.io.health.state if self.link.io is not None else None


def check_nic(name: str | None, host: str) -> str:
    """The NIC RT frames go on: ``name`` (the session's ``extra`` ``nic``), else the one that
    holds the address the host reaches the device from; LinkError on loopback."""
    if name:
        return nic.check_name(
            name, field="nic", hint="the network interface that reaches the drive"
        )
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect((host, pnio.RPC_PORT))
        local = probe.getsockname()[0]
    finally:
        probe.close()
    import fcntl
    import struct

    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for _index, ifname in socket.if_nameindex():
            req = struct.pack("256s", ifname.encode()[:15])
            try:
                addr = fcntl.ioctl(probe.fileno(), 0x8915, req)
            except OSError:
                continue
            if socket.inet_ntoa(addr[20:24]) == local and ifname != "lo":
                return ifname
    finally:
        probe.close()
    raise LinkError(
        f"the drive at {host} is reached over loopback: there is no Ethernet interface for "
        "PROFINET RT frames",
        hint="open the session with extra nic (the network interface that reaches the drive)",
    )
