"""The CANopen device side of a simulated drive: a python-canopen ``LocalNode``.

:class:`SimCanopenDevice` serves one :class:`~servodesk.sim.engine.SimulatedDrive` on a
``canopen.Network``: its SDO server answers from the drive's object store with the CiA 301
abort codes the drive raises, its NMT slave follows NMT commands and produces boot-up and
heartbeat messages, and the drive's faults go out as EMCY frames.

CiA 301 behaviour implemented here (beyond python-canopen's ``LocalNode``):

- A segmented download is refused at its initiation when the object does not exist or is not
  writable (python-canopen would only check after the last segment).
- SDO block upload (CiA 301 §7.2.4.3.9-§7.2.4.3.12, frames from
  :mod:`servodesk.domain.sdo_block`; python-canopen's server answers a block initiate with a
  normal upload): with CRC, the size indicated, sub-blocks of the client's blksize, the
  segments after the acknowledged ackseq sent again; objects of at most the client's pst bytes
  (pst non-zero) switch to the normal upload. Strict: a command other than the one the
  transfer expects, a blksize outside 1..127 or an ackseq beyond the sub-block aborts
  (0504 0001h, 0504 0002h, 0504 0003h) and ends the transfer. ``drop_segments`` /
  ``late_segments`` (the n-th segment frame of a transfer, from 1) lose a segment or send it
  after the next, as a bus could, for the client's tests.
- In NMT STOPPED the node answers no SDO and sends no EMCY (CiA 301 §7.3.2.2.1 table 35);
  heartbeat and NMT keep working.
- Reset node reloads the stored parameters and restarts the drive; reset communication
  reloads the 1000h-1FFFh parameters; both send a boot-up message and enter PRE-OPERATIONAL.
- A heartbeat consumer (1016h:01, :mod:`servodesk.sim.heartbeat_consumer`) watches the
  producer it names once its first heartbeat arrived and reacts per 6007h when it lapses.
- The heartbeat starts at boot when 1017h is non-zero, restarts on every write of 1017h, and
  carries the NMT state byte (0x7F pre-operational, 0x05 operational, 0x04 stopped).
- Process data (:mod:`servodesk.sim.pdo`): SYNC, RPDOs and RTRs reach the drive's
  :class:`~servodesk.sim.pdo.PdoEngine` through a listener on the network's notifier (canopen's
  own listener drops remote frames), only in OPERATIONAL; the engine is rebuilt when a PDO
  object (14xxh-1Bxxh, 1C12h/1C13h, 1005h, P922) is written and after a reset.
"""

from __future__ import annotations

import contextlib
import logging
import struct
from typing import Any

import can
from canopen import LocalNode
from canopen.nmt import COMMAND_TO_STATE, NmtSlave
from canopen.sdo.constants import EXPEDITED, REQUEST_DOWNLOAD, SDO_STRUCT
from canopen.sdo.exceptions import SdoAbortedError
from canopen.sdo.server import SdoServer

from servodesk.domain import sdo_block
from servodesk.domain.datatypes import Value
from servodesk.domain.sdo import SdoProtocolError
from servodesk.sim.engine import K_HEARTBEAT, SimAbort, SimulatedDrive
from servodesk.sim.heartbeat_consumer import HEARTBEAT_EVENT, HeartbeatConsumer
from servodesk.sim.od_build import build_object_dictionary
from servodesk.sim.pdo import PdoEngine

log = logging.getLogger(__name__)

NMT_BOOTUP = 0x00
NMT_STOPPED = 0x04
NMT_OPERATIONAL = 0x05
NMT_PRE_OPERATIONAL = 0x7F
_NMT_NAMES = {NMT_BOOTUP: "init", NMT_STOPPED: "stopped", NMT_OPERATIONAL: "op"}


class _BlockUpload:
    """A block upload in progress: the data, what the client acknowledged, what is due."""

    def __init__(self, data: bytes, blksize: int, crc: bool) -> None:
        self.data = data
        self.blksize = blksize
        self.crc = crc
        #: Bytes the client acknowledged (the next sub-block starts there).
        self.pos = 0
        #: Segments in the sub-block last sent (an ackseq beyond it is refused).
        self.sent = 0
        #: The command the client must send next: start, ack, end response.
        self.expect = sdo_block.CS_START
        #: Segment frames sent in this transfer (for drop_segments / late_segments).
        self.frames = 0
        #: The sub-block last sent holds the last segment (c set).
        self.ends = False


class _SdoServer(SdoServer):
    def __init__(self, rx_cobid: int, tx_cobid: int, node: Any) -> None:
        super().__init__(rx_cobid, tx_cobid, node)
        self._block: _BlockUpload | None = None
        #: Fault injection (tests): segment frames of a transfer, counted from 1, that are
        #: not sent (lost on the bus) or sent after the next one (out of order).
        self.drop_segments: set[int] = set()
        self.late_segments: set[int] = set()
        #: Block upload initiates served (not switched), for tests and benchmarks.
        self.block_uploads = 0

    def on_request(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self._node.nmt_state_byte == NMT_STOPPED:
            return
        if self._block is not None:
            self._block_step(bytes(data))
            return
        super().on_request(can_id, data, timestamp)

    # Block upload (CiA 301 §7.2.4.3.9-§7.2.4.3.12) ---------------------------------------

    def block_upload(self, data: bytearray) -> None:
        """An initiate block upload request (ccs 5) with no block transfer in progress."""
        frame = bytes(data)
        self._index, self._subindex = struct.unpack_from("<HB", frame, 1)
        if sdo_block.client_cs(frame) != sdo_block.CS_INITIATE:
            # A start, ack or end with no transfer: not valid now (§7.2.4.3.17).
            self.abort(0x05040001)
            return
        try:
            req = sdo_block.parse_initiate_request(frame)
        except SdoProtocolError as exc:
            self.abort(exc.abort_code)
            return
        value = self._node.get_data(req.index, req.subindex, check_readable=True)
        if req.pst and len(value) <= req.pst:
            # §7.2.4.3.9: at most pst bytes, the server may switch to the normal upload.
            self.init_upload(data)
            return
        self.block_uploads += 1
        # This server does CRC. It says so (sc) when the client asked for it (cc): the CRC is
        # used only when both do, and the end frame's CRC field is 0 otherwise; python-canopen
        # 2.4.1's client checks the CRC whenever sc is set, asked for or not.
        self._block = _BlockUpload(bytes(value), req.blksize, req.crc)
        self.send_response(
            sdo_block.initiate_response(req.index, req.subindex, len(value), crc=req.crc)
        )

    def _block_step(self, frame: bytes) -> None:
        block = self._block
        assert block is not None
        if frame[0] == 0x80:  # The client aborts (§7.2.4.3.17): the transfer ends, unanswered.
            self._block = None
            return
        cs = sdo_block.client_cs(frame)
        if cs != block.expect:
            self._block = None
            self.abort(0x05040001)
            return
        if cs == sdo_block.CS_END:
            self._block = None  # Done; the end response is not answered.
            return
        if cs == sdo_block.CS_ACK:
            try:
                ackseq, blksize = sdo_block.parse_ack(frame)
            except SdoProtocolError as exc:
                self._block = None
                self.abort(exc.abort_code)
                return
            if ackseq > block.sent:
                self._block = None
                self.abort(sdo_block.ABORT_SEQNO)
                return
            block.pos = min(len(block.data), block.pos + 7 * ackseq)
            block.blksize = blksize
            if block.ends and ackseq == block.sent:
                # Every segment acknowledged, the c segment among them: the end (§7.2.4.3.13),
                # with the bytes of the last segment that carry no data and the CRC.
                n = len(block.data)
                unused = 7 - (n - 7 * ((n - 1) // 7)) if n else 7
                crc = sdo_block.crc16(block.data) if block.crc else 0
                block.expect = sdo_block.CS_END
                self.send_response(sdo_block.end(unused, crc))
                return
        self._send_sub_block(block)

    def _send_sub_block(self, block: _BlockUpload) -> None:
        """Segments from the acknowledged position: blksize of them, or up to the last."""
        data, pos = block.data, block.pos
        frames: list[bytes] = []
        seqno = 0
        while seqno < block.blksize:
            seqno += 1
            chunk = data[pos : pos + 7]
            pos += 7
            last = pos >= len(data)
            frames.append(sdo_block.segment(seqno, chunk, last))
            if last:
                break
        block.ends = frames[-1][0] & 0x80 != 0
        block.sent = len(frames)
        block.expect = sdo_block.CS_ACK
        late: bytes | None = None
        for f in frames:
            block.frames += 1
            if block.frames in self.drop_segments:
                continue
            if block.frames in self.late_segments:
                late = f
                continue
            self.send_response(f)
            if late is not None:
                self.send_response(late)
                late = None
        if late is not None:
            self.send_response(late)

    def init_download(self, request: bytearray) -> None:
        command, index, subindex = SDO_STRUCT.unpack_from(request)
        if command & 0xE0 == REQUEST_DOWNLOAD and not command & EXPEDITED:
            self._index = index
            self._subindex = subindex
            self._node.check_download(index, subindex)
        super().init_download(request)


class _NmtSlave(NmtSlave):
    def on_command(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if len(data) < 2:
            return
        cmd, node_id = struct.unpack_from("BB", data)
        if node_id not in (0, self.id):
            return
        device: SimCanopenDevice = self._local_node
        if cmd == 0x81:
            device.reset_node()
        elif cmd == 0x82:
            device.reset_communication()
        elif cmd in (0x01, 0x02, 0x80):
            device.set_nmt_state(COMMAND_TO_STATE[cmd])

    def on_write(self, index: int, data: bytes, **kwargs: Any) -> None:
        """Unused: the device restarts the heartbeat itself after a write of 1017h."""


class _FrameListener(can.Listener):
    """Every frame of the bus, remote frames included, to the process-data engine and the
    heartbeat consumer."""

    def __init__(self, engine: PdoEngine, consumer: HeartbeatConsumer) -> None:
        self._engine = engine
        self._consumer = consumer

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame:
            return
        if not msg.is_remote_frame:
            self._consumer.on_frame(msg.arbitration_id)
        try:
            self._engine.on_frame(msg.arbitration_id, msg.data, msg.is_remote_frame)
        except Exception:  # An exception here would stop the notifier thread (and SDO).
            log.exception("process data frame 0x%03X not handled", msg.arbitration_id)

    def stop(self) -> None:
        """Nothing to release."""


class SimCanopenDevice(LocalNode):
    """A simulated drive as a CANopen node (attach with ``network.add_node(device)``)."""

    def __init__(self, drive: SimulatedDrive) -> None:
        super().__init__(drive.node_id, build_object_dictionary(drive.profile, drive.node_id))
        self.drive = drive
        self.node_id = node_id = drive.node_id
        self.sdo: _SdoServer = _SdoServer(0x600 + node_id, 0x580 + node_id, self)
        self.nmt = _NmtSlave(node_id, self)
        self._write_callbacks = []  # LocalNode's NmtSlave hook is replaced by _on_drive_write.
        #: The drive's process data (``pdo`` is python-canopen's own, unused PDO object).
        self.pdo_engine = PdoEngine(drive, self._send_frame, self._send_pdo_emcy)
        self.heartbeat_consumer = HeartbeatConsumer(self._heartbeat_event)
        self._listener = _FrameListener(self.pdo_engine, self.heartbeat_consumer)
        self._configure_consumer()
        self._notifier: Any = None
        drive.on_emcy(self._on_emcy)
        drive.on_write(self._on_drive_write)

    def associate_network(self, network: Any) -> None:
        super().associate_network(network)
        notifier = getattr(network, "notifier", None)
        if notifier is None:
            log.warning("node %d: the network has no notifier; no process data", self.node_id)
            return
        notifier.add_listener(self._listener)
        self._notifier = notifier

    def remove_network(self) -> None:
        if self._notifier is not None:
            with contextlib.suppress(ValueError):  # Already gone with the notifier.
                self._notifier.remove_listener(self._listener)
            self._notifier = None
        super().remove_network()

    # SDO access goes to the drive's object store --------------------------------------

    def get_data(self, index: int, subindex: int, check_readable: bool = False) -> bytes:
        try:
            return self.drive.read_bytes(index, subindex)
        except SimAbort as exc:
            raise SdoAbortedError(exc.code) from None

    def set_data(
        self, index: int, subindex: int, data: bytes, check_writable: bool = False
    ) -> None:
        try:
            self.drive.write_bytes(index, subindex, bytes(data))
        except SimAbort as exc:
            raise SdoAbortedError(exc.code) from None

    def check_download(self, index: int, subindex: int) -> None:
        try:
            self.drive.check_download(index, subindex)
        except SimAbort as exc:
            raise SdoAbortedError(exc.code) from None

    # NMT --------------------------------------------------------------------------------

    @property
    def nmt_state_byte(self) -> int:
        state: int = self.nmt._state
        return state

    def boot(self) -> None:
        """Initialisation finished: boot-up message, PRE-OPERATIONAL, heartbeat per 1017h."""
        self.nmt._state = NMT_BOOTUP
        self.drive.nmt_state = "init"
        self.pdo_engine.set_operational(False)
        self.pdo_engine.configure()  # The reset reloaded the PDO parameters.
        self.network.send_message(0x700 + self.node_id, bytes([NMT_BOOTUP]))
        self.set_nmt_state(NMT_PRE_OPERATIONAL)
        self._restart_heartbeat()

    def set_nmt_state(self, state: int) -> None:
        self.nmt._state = state
        self.drive.nmt_state = _NMT_NAMES.get(state, "preop")
        # CiA 301 §7.3.2.2.1 table 35: PDOs only in OPERATIONAL.
        self.pdo_engine.set_operational(state == NMT_OPERATIONAL)
        self.nmt.update_heartbeat()

    def reset_node(self) -> None:
        self.nmt.stop_heartbeat()
        self.drive.reset_node()
        self._configure_consumer()
        self.boot()

    def reset_communication(self) -> None:
        self.nmt.stop_heartbeat()
        self.drive.reset_communication()
        self._configure_consumer()
        self.boot()

    def shutdown(self) -> None:
        """Stop the heartbeat and leave the network."""
        self.nmt.stop_heartbeat()
        self.heartbeat_consumer.close()
        self.remove_network()

    # Heartbeat consumer (CiA 301 §7.2.8.3.2.2) ------------------------------------------

    def _configure_consumer(self) -> None:
        if self.drive.has_object(0x1016, 1):
            entry = self.drive.read(0x1016, 1)
            self.heartbeat_consumer.configure(entry if isinstance(entry, int) else 0)

    def _heartbeat_event(self, producer: int) -> None:
        """The producer's heartbeat lapsed: EMCY 8130h and the reaction 6007h asks for."""
        option = self.drive.read(0x6007) if self.drive.has_object(0x6007) else 1
        log.warning(
            "node %d: the heartbeat of node %d lapsed (6007h = %s)", self.node_id, producer, option
        )
        if option == 1:
            self.drive.raise_fault(HEARTBEAT_EVENT)  # 603Fh, 1003h and the EMCY.
            return
        self._on_emcy(HEARTBEAT_EVENT, 0x11, bytes(5))  # Generic + communication error.
        if option in (2, 3):
            # As the commands would (CiA 402-2 table 28): disable voltage, or quick stop.
            self.drive.write(0x6040, 0, 0x0000 if option == 2 else 0x0002)

    def _restart_heartbeat(self) -> None:
        period = 0
        if self.drive.has_object(0x1017):
            value = self.drive.read(0x1017)
            period = value if isinstance(value, int) else 0
        if period > 0:
            self.nmt.start_heartbeat(period)
        else:
            self.nmt.stop_heartbeat()

    def _on_drive_write(self, index: int, subindex: int, value: Value) -> None:
        if index << 8 | subindex == K_HEARTBEAT:
            self._restart_heartbeat()
        if index == 0x1016 and subindex == 1 and isinstance(value, int):
            self.heartbeat_consumer.configure(value)
        self.pdo_engine.on_object_written(index)

    # Process data -------------------------------------------------------------------------

    def _send_frame(self, can_id: int, data: bytes, fd: bool, extended: bool) -> None:
        if not self.has_network():
            return
        network = self.network
        bus = network.bus
        if bus is None:
            return
        msg = can.Message(arbitration_id=can_id, data=data, is_extended_id=extended, is_fd=fd)
        try:
            with network.send_lock:
                bus.send(msg)
        except Exception:  # The bus may be gone while shutting down.
            log.debug("PDO 0x%03X not sent", can_id, exc_info=True)

    def _send_pdo_emcy(self, code: int) -> None:
        # Error register 11h: generic + communication error (smartris 001 §10-3 example).
        self._on_emcy(code, 0x11, bytes(5))

    # EMCY -------------------------------------------------------------------------------

    def _on_emcy(self, code: int, register: int, data: bytes) -> None:
        if not self.has_network() or self.nmt_state_byte == NMT_STOPPED:
            return
        try:
            self.emcy.send(code, register, data)
        except Exception:  # The bus may be gone while shutting down.
            log.debug("EMCY 0x%04X not sent", code, exc_info=True)
