"""Simulated EtherCAT slaves on a network interface: CoE object access to SimulatedDrives.

A line of slaves answers real EtherCAT frames on one interface (the slave end of a veth pair,
:mod:`servodesk.sim.veth`): each slave is an ESC (:class:`~servodesk.sim.esc.EscSlave`:
registers, SII EEPROM built from the drive's identity 1018h and device name 1008h, AL states
INIT to OPERATIONAL, the mailbox on SM0 / SM1, process data on SM2 / SM3 through the FMMUs)
whose CoE requests a :class:`CoeServer` answers from the drive: SDO upload and download,
expedited, normal and segmented, and SDO abort with the drive's CiA 301 abort code. Its
process data is the drive's :class:`ProcessDataServer`: the RxPDO assigned in 1C12h taken
from SM2 in OPERATIONAL, the TxPDO assigned in 1C13h put into SM3 from SAFE-OPERATIONAL on
(HIWIN 000 §2.8), each exchange answered with the inputs of the next. No distributed clocks;
BOOTSTRAP is refused with an AL status code (docs/ethercat.md).

Two ways to run a line:

- :class:`EthercatSlaveSim`: the ESCs in a thread of this process. Simple and inspectable
  (tests look at the slaves' registers), but SOEM in the *same* process holds the GIL while
  it waits in its state calls (``read_state``, ``write_state``, ``state_check``), so those
  get no answer.
- :class:`EthercatSlaveProcess`: the ESCs in a process of their own, the CoE servers (the
  drives) here; the ESC answers SOEM's register reads at once whatever this process holds, and
  a mailbox answer comes when the drive has given it, as a slave's firmware does.
  :class:`~servodesk.sim.bus.SimulatedBus` uses it.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import socket
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence
from dataclasses import replace
from multiprocessing.connection import Connection
from pathlib import Path

import servodesk
from servodesk.domain import ethercat as ec
from servodesk.domain.ethercat import AlState
from servodesk.errors import LinkError
from servodesk.sim import coe_info, esc
from servodesk.sim.engine import SimAbort, SimulatedDrive
from servodesk.sim.esc import EscBehaviour, EscLine, EscSlave
from servodesk.sim.esi_twin import TwinOptions
from servodesk.sim.pdo import PdoEngine

log = logging.getLogger(__name__)

#: Default mailbox offsets and sizes (SII words 18h-1Bh): SM0 at 1000h, SM1 after it.
MAILBOX_START = 0x1000
MAILBOX_SIZE = 128
#: How long the ESC process may take to start (a new interpreter imports servodesk).
START_TIMEOUT = 30.0


def sii_from_drive(
    drive: SimulatedDrive, mailbox_size: int, options: TwinOptions | None = None
) -> ec.SiiInfo:
    """The SII identity of a drive: what its 1018h and 1008h read (0 / the profile name
    where the drive has none). With ``options`` (a twin from an ESI) the mailbox and process
    data SyncManagers are where the profile's ``Sm`` elements put them (ETG.2000
    DeviceType/Sm: MBoxOut, MBoxIn, Outputs, Inputs), the identity the option's where given,
    and complete access claimed where the option says so."""
    info = _sii_from_objects(drive, mailbox_size)
    if options is None:
        return info
    update: dict[str, object] = {}
    for sm in drive.profile.pdo.sync_managers:
        kind = sm.kind.lower()
        if kind in ("mboxout", "mboxin") and sm.start_address is not None:
            size = sm.default_size or mailbox_size
            if 32 <= size <= 1024:
                update["mailbox_out" if kind == "mboxout" else "mailbox_in"] = (
                    sm.start_address,
                    size,
                )
        elif kind in ("outputs", "inputs") and sm.start_address is not None:
            update["outputs_start" if kind == "outputs" else "inputs_start"] = sm.start_address
    if options.sii_identity is not None:
        vendor, product, revision = options.sii_identity
        update.update(vendor_id=vendor, product_code=product, revision=revision)
    details = ec.COE_DETAILS_SDO
    if options.claims_complete_access:
        details |= ec.COE_DETAILS_COMPLETE_ACCESS
    if options.sdo_info:
        details |= ec.COE_DETAILS_SDO_INFO
    update["coe_details"] = details
    return replace(info, **update)  # type: ignore[arg-type]


def _sii_from_objects(drive: SimulatedDrive, mailbox_size: int) -> ec.SiiInfo:

    def u32(index: int, sub: int) -> int:
        try:
            return int.from_bytes(drive.read_bytes(index, sub)[:4], "little")
        except SimAbort:
            return 0

    try:
        name = drive.read_bytes(0x1008, 0).decode("ascii", "replace").rstrip("\x00")
    except SimAbort:
        name = drive.profile.name
    return ec.SiiInfo(
        vendor_id=u32(0x1018, 1),
        product_code=u32(0x1018, 2),
        revision=u32(0x1018, 3),
        serial=u32(0x1018, 4),
        name=name,
        mailbox_out=(MAILBOX_START, mailbox_size),
        mailbox_in=(MAILBOX_START + mailbox_size, mailbox_size),
        # The SYNC0 cycles the profile says the drive takes (HIWIN 000 §2.5, 1C32h:02 range).
        dc_cycle_ns=drive.profile.dc_cycles_ns(),
    )


class CoeServer:
    """The CoE SDO server of one drive (ETG.1000.6 §5.6.2): what the slave's firmware does
    with the mailbox requests its ESC takes."""

    def __init__(
        self, drive: SimulatedDrive, mailbox_in: int, options: TwinOptions | None = None
    ) -> None:
        self.drive = drive
        self.options = options or TwinOptions()
        #: SM1's length: what one answer can carry.
        self.mailbox_in = mailbox_in
        #: A segmented download in progress: index, sub, size, bytes so far, next toggle.
        self._download: tuple[int, int, int, bytearray, int] | None = None
        #: A segmented upload in progress: index, sub, bytes left, next toggle.
        self._upload: tuple[int, int, bytes, int] | None = None

    def reset(self) -> None:
        """The mailbox was reset: a transfer in progress ends."""
        self._download = self._upload = None

    def answers(self, data: bytes) -> list[bytes]:
        """The answers (CoE header on) to a CoE request: one for an SDO (none after an abort
        from the master), one or more (fragments) for SDO Information, which the ESC passes
        on only where the SII offers it (option ``sdo_info``; ETG.1000.6 §5.6.3)."""
        if len(data) >= 2 and int.from_bytes(data[:2], "little") >> 12 == ec.CoeService.SDO_INFO:
            # What one answer may carry: SM1 less the mailbox header (6 bytes) and the CoE
            # and SDO Information headers.
            room = self.mailbox_in - 6 - coe_info.INFO_HEADER
            return coe_info.answers(self.drive.profile, data, room)
        answer = self.handle(data)
        return [] if answer is None else [answer]

    def handle(self, data: bytes) -> bytes | None:
        """The answer (CoE header on) to a CoE SDO request, or None when there is none."""
        answer = self._handle(data)
        if (
            answer is not None
            and self.options.abort_reserved_bits
            and len(answer) > 2
            and answer[2] == ec.SDO_ABORT
            and int.from_bytes(answer[:2], "little") >> 12 == ec.CoeService.SDO_REQUEST
        ):
            # Option: the reserved bits 0-4 of the abort's command byte set (CiA 301
            # §7.2.4.3.17 says 0), as some firmware sends them.
            answer = answer[:2] + bytes([ec.SDO_ABORT | 0x1F]) + answer[3:]
        return answer

    def _handle(self, data: bytes) -> bytes | None:
        if len(data) < 3:
            return None
        command = data[2]
        ccs = command >> 5
        if ccs == 0:  # Download segment
            return self._download_segment(data)
        if ccs == 3:  # Upload segment
            return self._upload_segment(command)
        if ccs == 4:  # Abort from the master: drop any transfer in progress.
            self._download = self._upload = None
            return None
        if len(data) < 2 + ec.SDO_HEADER:
            return ec.build_sdo(ec.sdo_abort(0, 0, 0x05040001))
        sdo = ec.parse_sdo(data)
        self._download = self._upload = None
        try:
            if command & ec.SDO_COMPLETE_ACCESS:
                # Complete access is not offered (SII General CoE details bit 5 clear).
                raise SimAbort(0x06010000, "complete access is not supported")
            if ccs == 1:
                return self._download_initiate(sdo)
            if ccs == 2:
                return self._upload_initiate(sdo)
            raise SimAbort(0x05040001)
        except SimAbort as exc:
            return ec.build_sdo(ec.sdo_abort(sdo.index, sdo.subindex, exc.code))
        except Exception:  # A simulation bug must not stop the slave: a general error.
            log.exception("SDO %04X:%02X failed", sdo.index, sdo.subindex)
            return ec.build_sdo(ec.sdo_abort(sdo.index, sdo.subindex, 0x08000000))

    def _response(self, command: int, index: int, sub: int, payload: bytes = b"") -> bytes:
        sdo = ec.Sdo(ec.CoeService.SDO_RESPONSE, command, index, sub, payload.ljust(4, b"\x00"))
        return ec.build_sdo(sdo)

    def _download_initiate(self, sdo: ec.Sdo) -> bytes:
        if sdo.command & 0x02:  # Expedited: the data is in the 4 bytes (n unused if s).
            n = 4 - ((sdo.command >> 2) & 0x03) if sdo.command & 0x01 else 4
            self.drive.write_bytes(sdo.index, sdo.subindex, sdo.payload[:n])
            return self._response(ec.SDO_DOWNLOAD_RESPONSE, sdo.index, sdo.subindex)
        if len(sdo.payload) < 4:
            raise SimAbort(0x05040001, "no complete size")
        size = int.from_bytes(sdo.payload[:4], "little")
        first = sdo.payload[4:]
        if len(first) >= size:
            self.drive.write_bytes(sdo.index, sdo.subindex, first[:size])
        else:
            self.drive.check_download(sdo.index, sdo.subindex)
            self._download = (sdo.index, sdo.subindex, size, bytearray(first), 0)
        return self._response(ec.SDO_DOWNLOAD_RESPONSE, sdo.index, sdo.subindex)

    def _download_segment(self, data: bytes) -> bytes | None:
        if self._download is None:
            return ec.build_sdo(ec.sdo_abort(0, 0, 0x05040001))
        index, sub, size, buf, toggle = self._download
        command = data[2]
        if command & ec.SDO_TOGGLE != toggle:
            self._download = None
            return ec.build_sdo(ec.sdo_abort(index, sub, 0x05030000))
        seg = data[3:]
        if len(seg) == ec.SEGMENT_MIN_DATA:  # Padded: bits 1-3 say how many are unused.
            seg = seg[: ec.SEGMENT_MIN_DATA - ((command >> 1) & 0x07)]
        buf += seg
        if not command & ec.SDO_LAST_SEGMENT:
            self._download = (index, sub, size, buf, toggle ^ ec.SDO_TOGGLE)
            return self._segment_ack(toggle)
        self._download = None
        try:
            if len(buf) != size:
                raise SimAbort(0x06070010, f"{len(buf)} bytes sent, {size} announced")
            self.drive.write_bytes(index, sub, bytes(buf))
        except SimAbort as exc:
            return ec.build_sdo(ec.sdo_abort(index, sub, exc.code))
        return self._segment_ack(toggle)

    @staticmethod
    def _segment_ack(toggle: int) -> bytes:
        head = (ec.CoeService.SDO_RESPONSE << 12).to_bytes(2, "little")
        return head + bytes([ec.SDO_DOWNLOAD_SEGMENT_RESPONSE | toggle]) + bytes(7)

    def _upload_initiate(self, sdo: ec.Sdo) -> bytes:
        value = self.drive.read_bytes(sdo.index, sdo.subindex)
        if len(value) <= 4:
            command = ec.SDO_UPLOAD_EXPEDITED | ((4 - len(value)) << 2)
            return self._response(command, sdo.index, sdo.subindex, value)
        l1 = self.mailbox_in
        room = l1 - ec.NORMAL_DATA_OFFSET
        size = len(value).to_bytes(4, "little")
        if len(value) > room:
            # Segmented: the first part in the initiate response, the rest on request.
            self._upload = (sdo.index, sdo.subindex, value[room:], 0)
            value = value[:room]
        return self._response(ec.SDO_UPLOAD_NORMAL, sdo.index, sdo.subindex, size + value)

    def _upload_segment(self, command: int) -> bytes:
        if self._upload is None:
            return ec.build_sdo(ec.sdo_abort(0, 0, 0x05040001))
        index, sub, rest, toggle = self._upload
        if command & ec.SDO_TOGGLE != toggle:
            self._upload = None
            return ec.build_sdo(ec.sdo_abort(index, sub, 0x05030000))
        l1 = self.mailbox_in
        room = l1 - ec.SEGMENT_DATA_OFFSET
        part, rest = rest[:room], rest[room:]
        last = not rest
        self._upload = None if last else (index, sub, rest, toggle ^ ec.SDO_TOGGLE)
        return ec.sdo_segment(toggle | (ec.SDO_LAST_SEGMENT if last else 0), part)


#: The drive's CiA 402 "NMT state" names for the AL states (its PDO mapping objects are
#: writable in "preop" only, HIWIN 000 §2.8.1).
_AL_TO_NMT = {
    AlState.INIT: "init",
    AlState.PREOP: "preop",
    AlState.SAFEOP: "safeop",
    AlState.OP: "operational",
}


class ProcessDataServer:
    """The process data of one drive behind its ESC: what the firmware does with SM2 and SM3.

    The drive's :class:`~servodesk.sim.pdo.PdoEngine` (kind ``ethercat``) knows the assigned
    PDOs and packs them; here each process data exchange applies the outputs (OPERATIONAL
    only) and samples the TxPDO for the next exchange, handed to ``push``."""

    def __init__(
        self,
        drive: SimulatedDrive,
        push: Callable[[bytes], None],
        mirror: Callable[[dict[int, bytes]], None] | None = None,
    ) -> None:
        self.drive = drive
        self._push = push
        self._mirror = mirror
        self._tx_id = 0x180 + drive.node_id
        self._rx_id = 0x200 + drive.node_id
        self.engine = PdoEngine(drive, self._send, lambda code: None)
        fault = drive.profile.quirk("sm_watchdog_fault")
        #: A firmware too slow to answer SOEM's PDO configuration reads inside
        #: ``config_map`` (its mirror in the ESC emptied, so they wait for this process,
        #: which pysoem's config_map holds): SOEM maps nothing for this slave while its
        #: SDOs, outside config_map, work. What servodesk must notice (issue 46).
        self.slow_firmware = False
        self._watchdog_fault: int | None = (
            int(fault, 0) if isinstance(fault, str) else fault if isinstance(fault, int) else None
        )
        drive.on_write(self._written)
        self._config = [
            (a.index, a.subindex)
            for a in drive.profile.variables
            if _pdo_config(a.index) and drive.has_object(a.index, a.subindex)
        ]
        self.mirror()

    def _written(self, index: int, sub: int, value: object) -> None:
        self.engine.on_object_written(index)
        if _pdo_config(index):
            self.mirror()

    def mirror(self) -> None:
        """Hand the PDO configuration objects to the ESC process (esc.cached_upload)."""
        if self._mirror is None:
            return
        cache: dict[int, bytes] = {}
        if self.slow_firmware:
            self._mirror(cache)
            return
        for index, sub in self._config:
            with contextlib.suppress(SimAbort):
                cache[index << 8 | sub] = self.drive.read_bytes(index, sub)
        self._mirror(cache)

    def _send(self, can_id: int, data: bytes, fd: bool, extended: bool) -> None:
        if can_id == self._tx_id:
            self._push(data)

    def state(self, al: int, code: int = 0) -> None:
        """The ESC's AL state changed: the drive's state, and whether PDOs are exchanged. A
        SyncManager watchdog (001Bh) is the fieldbus fault of the profile's
        ``sm_watchdog_fault`` quirk when the drive's power stage was on: the process data it
        moved by stopped (HIWIN: FF49h, AL.FB1)."""
        self.drive.nmt_state = _AL_TO_NMT.get(AlState(al & 0x0F), "preop")
        self.engine.set_operational(al & 0x0F in (AlState.SAFEOP, AlState.OP))
        if code == 0x001B and self._watchdog_fault is not None and self._powered():
            self.drive.raise_fault(self._watchdog_fault)
        if al & 0x0F in (AlState.SAFEOP, AlState.OP):
            self.cycle(None)  # SM3 holds valid inputs from the first exchange on.

    def sync(self, mode: int, cycle_ns: int) -> None:
        """The synchronisation the master configured, as the slave reports it (ETG.1020):
        1C32h / 1C33h :01 the mode (0 FreeRun, 2 DC SYNC0), :02 the SYNC0 cycle in DC mode,
        and in DC mode the interpolation time period 60C2h from that cycle (HIWIN 000 §3.2:
        "set from the communication cycle", 1 ms = 10 x 10^-4 s; 250 and 500 µs with index
        -5)."""
        drive = self.drive
        for index in (0x1C32, 0x1C33):
            if drive.has_object(index, 1):
                drive.set_status(index, 1, mode)
            if mode and drive.has_object(index, 2):
                drive.set_status(index, 2, cycle_ns)
        if mode and drive.has_object(0x60C2, 1) and drive.has_object(0x60C2, 2):
            value, index = interpolation_period(cycle_ns)
            drive.set_status(0x60C2, 1, value)
            drive.set_status(0x60C2, 2, index)

    def _powered(self) -> bool:
        # Statusword bits 0-2 (ready, switched on, operation enabled) all set: CiA 402
        # "Operation enabled" or a quick stop in progress; bit 3 clear (no fault yet).
        return self.drive.statusword & 0x0F == 0x07

    def cycle(self, outputs: bytes | None) -> None:
        """One process data exchange: apply ``outputs``, then sample the next inputs."""
        if outputs is not None:
            self.engine.on_frame(self._rx_id, outputs, False)
        self.engine.on_sync()
        self.engine.flush()


def interpolation_period(cycle_ns: int) -> tuple[int, int]:
    """60C2h :01 / :02 (value x 10^index s) for a communication cycle: HIWIN 000 §3.2's
    table (250 / 500 µs -> 25 / 50 with -5; 1 / 2 / 4 ms -> 10 / 20 / 40 with -4), and for the
    cycles it leaves out the first index that gives the cycle exactly in an UNSIGNED8 (1.25 ms
    -> 125 with -5), else the nearest at -4."""
    first = -5 if cycle_ns < 1_000_000 else -4
    for index in (first, -5, -6):
        unit = 10 ** (9 + index)
        if cycle_ns % unit == 0 and cycle_ns // unit <= 0xFF:
            return cycle_ns // unit, index
    return min(0xFF, round(cycle_ns / 100_000)), -4


def _pdo_config(index: int) -> bool:
    """1C00h (SM types), 1C10h-1C2Fh (PDO assignment), 1600h-17FFh / 1A00h-1BFFh (mapping)."""
    return index == 0x1C00 or 0x1C10 <= index <= 0x1C2F or 0x1600 <= index <= 0x1BFF


def _servers(drives: Sequence[SimulatedDrive], mailbox_size: int) -> list[CoeServer]:
    if not drives:
        raise ValueError("an EtherCAT line needs at least one slave")
    return [CoeServer(d, mailbox_size) for d in drives]


class EthercatSlaveSim:
    """Slaves in a line on ``ifname``, in a thread: ``start()`` opens the socket and serves."""

    def __init__(
        self, drives: Sequence[SimulatedDrive], ifname: str, *, mailbox_size: int = MAILBOX_SIZE
    ) -> None:
        self.ifname = ifname
        self.servers = _servers(drives, mailbox_size)
        n = len(self.servers)
        self.slaves = [
            EscSlave(sii_from_drive(s.drive, mailbox_size), last=i == n - 1)
            for i, s in enumerate(self.servers)
        ]
        self.process_data: list[ProcessDataServer] = []
        for slave, server in zip(self.slaves, self.servers, strict=True):
            slave.coe = _answer_now(slave, server)
            slave.on_reset = server.reset
            pd = ProcessDataServer(server.drive, slave.set_inputs)
            slave.on_cycle = pd.cycle
            slave.on_state = pd.state
            slave.on_sync = pd.sync
            self.process_data.append(pd)
        self.line = EscLine(self.slaves)
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    @property
    def drives(self) -> list[SimulatedDrive]:
        return [s.drive for s in self.servers]

    @property
    def frames(self) -> int:
        return self.line.frames

    @property
    def dropped(self) -> int:
        return self.line.dropped

    def process(self, frame: bytes) -> bytes | None:
        """The frame as it comes back from the end of the line (None: no EtherCAT)."""
        return self.line.process(frame)

    def start(self) -> EthercatSlaveSim:
        """Open the raw socket; LinkError when the interface is missing or not permitted."""
        self._sock = esc.open_socket(self.ifname)
        sock = self._sock
        self._thread = threading.Thread(
            target=self.line.serve,
            args=(sock, self.ifname, self._stop),
            name="ethercat-slave",
            daemon=True,
        )
        self._thread.start()
        log.info("EtherCAT slaves on %s: %d", self.ifname, len(self.slaves))
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> EthercatSlaveSim:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _answer_now(slave: EscSlave, server: CoeServer) -> Callable[[bytes], None]:
    def coe(data: bytes) -> None:
        for answer in server.answers(data):
            slave.answer(answer)

    return coe


class EthercatSlaveProcess:
    """Slaves in a line on ``ifname``: the ESCs in a process of their own (module doc), the
    drives' CoE servers here, in a thread that answers the process's mailbox requests."""

    def __init__(
        self,
        drives: Sequence[SimulatedDrive],
        ifname: str,
        *,
        mailbox_size: int = MAILBOX_SIZE,
        claims_complete_access: bool = False,
        options: TwinOptions | None = None,
    ) -> None:
        """``claims_complete_access``: the SII's CoE details claim SDO complete access,
        which the firmware refuses (abort 0601 0000h), as some real slaves do: SOEM's
        config_map tries it, gets the abort into its error list and falls back to plain
        reads, so pysoem raises ConfigMapError for a mapping that succeeded (issue 46).

        ``options`` (every slave of the line; a twin from an ESI, sim/esi_twin.py): the
        SII's SyncManagers from the profile's ``Sm`` elements, and what real slaves do
        differently (:class:`~servodesk.sim.esi_twin.TwinOptions`)."""
        self.ifname = ifname
        if options is not None and claims_complete_access:
            options = replace(options, claims_complete_access=True)
        self._siis = [sii_from_drive(d, mailbox_size, options) for d in drives]
        if not drives:
            raise ValueError("an EtherCAT line needs at least one slave")
        # The CoE server answers within SM1, whatever size the profile gave it.
        self.servers = [
            CoeServer(d, sii.mailbox_in[1], options)
            for d, sii in zip(drives, self._siis, strict=True)
        ]
        if claims_complete_access and options is None:
            details = ec.COE_DETAILS_SDO | ec.COE_DETAILS_COMPLETE_ACCESS
            self._siis = [replace(s, coe_details=details) for s in self._siis]
        self._behaviour = EscBehaviour(
            boot_delay_s=options.boot_delay_s if options is not None else 0.0,
            watchdog=options.watchdog if options is not None else True,
        )
        self.process_data = [
            ProcessDataServer(
                s.drive,
                functools.partial(self._push, "inputs", i),
                functools.partial(self._push, "od", i),
            )
            for i, s in enumerate(self.servers)
        ]
        self._proc: subprocess.Popen[bytes] | None = None
        self._pdi: Connection | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        #: CoE requests answered (tests and logs).
        self.requests = 0
        #: The serve thread and the drive thread (inputs) both send to the ESC process.
        self._send_lock = threading.Lock()

    @property
    def drives(self) -> list[SimulatedDrive]:
        return [s.drive for s in self.servers]

    def start(self) -> EthercatSlaveProcess:
        """Start the ESC process; LinkError when the interface is missing, not permitted, or
        the process does not start."""
        # Checked here first: a missing interface or permission is told as it is, not as a
        # process that ended.
        esc.open_socket(self.ifname).close()
        # A plain interpreter (not multiprocessing's spawn, which imports the caller's main
        # module again), connected by a socket pair; its errors go to this stderr.
        ours, theirs = socket.socketpair()
        env = dict(os.environ)
        package_root = str(Path(servodesk.__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
        code = f"from servodesk.sim.esc import child_main; child_main({theirs.fileno()})"
        proc = subprocess.Popen(
            [sys.executable, "-c", code], pass_fds=(theirs.fileno(),), env=env, close_fds=True
        )
        theirs.close()
        pdi = Connection(ours.detach())
        try:
            pdi.send((self.ifname, self._siis, [self._behaviour] * len(self._siis)))
            if not pdi.poll(START_TIMEOUT):
                raise LinkError(
                    f"the simulated EtherCAT slaves on {self.ifname!r} did not start within "
                    f"{START_TIMEOUT:g} s"
                )
            try:
                kind, message, hint = pdi.recv()
            except (EOFError, OSError):
                raise LinkError(
                    f"the simulated EtherCAT slaves' process on {self.ifname!r} ended as it "
                    f"started (exit code {proc.wait(5)})",
                    hint="its error output says why",
                ) from None
            if kind == "error":
                raise LinkError(str(message), hint=hint)
        except BaseException:
            pdi.close()
            _end(proc)
            raise
        self._proc, self._pdi = proc, pdi
        for pd in self.process_data:
            pd.mirror()  # Before the master's first config_map reads it.
        self._thread = threading.Thread(target=self._serve, name="ethercat-coe", daemon=True)
        self._thread.start()
        log.info(
            "EtherCAT slaves on %s: %d (ESC process %s)", self.ifname, len(self.servers), proc.pid
        )
        return self

    def _serve(self) -> None:
        pdi = self._pdi
        assert pdi is not None
        while not self._stop.is_set():
            try:
                if not pdi.poll(0.05):
                    continue
                kind, index, data = pdi.recv()
            except (EOFError, OSError):
                if not self._stop.is_set():
                    log.warning("the EtherCAT ESC process on %s ended", self.ifname)
                return
            server = self.servers[index]
            if kind == "reset":
                server.reset()
                continue
            if kind == "cycle":
                self.process_data[index].cycle(data)
                continue
            if kind == "state":
                state, code = data
                self.process_data[index].state(int(state), int(code))
                continue
            if kind == "sync":
                mode, cycle = data
                self.process_data[index].sync(int(mode), int(cycle))
                continue
            # Answered outside the send lock: a write of a PDO configuration object mirrors
            # it to the ESC process (_push), which takes the lock itself.
            answers = server.answers(data) or [None]
            self.requests += 1
            try:
                with self._send_lock:
                    for answer in answers:
                        pdi.send(("coe", index, answer))
            except OSError:
                return

    def _push(self, kind: str, index: int, data: object) -> None:
        pdi = getattr(self, "_pdi", None)  # None until started
        if pdi is None:
            return
        with self._send_lock, contextlib.suppress(OSError):
            pdi.send((kind, index, data))

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
            self._thread = None
        if self._pdi is not None:
            self._pdi.close()  # The ESC process ends on the closed connection.
            self._pdi = None
        if self._proc is not None:
            _end(self._proc)
            self._proc = None

    def __enter__(self) -> EthercatSlaveProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _end(proc: subprocess.Popen[bytes]) -> None:
    """Wait for the ESC process to end on its closed connection; terminate it if it does not."""
    try:
        proc.wait(5)
    except subprocess.TimeoutExpired:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
