"""EtherCAT object access over CoE (CANopen over EtherCAT), with pysoem (SOEM) as the master.

Where the drive is: ``interface`` ``ethercat``, ``channel`` the network interface the line
is plugged into (``eth1``, or the master end of a veth pair for the simulated slave),
``node_id`` the slave's position in the line + 1 (1 = the first slave after the master).
Objects are read and written with CoE SDO upload / download (ETG.1000.6 §5.6.2), which SOEM
does expedited, normal or segmented as the size needs.

Opening a link opens the interface with SOEM and runs ``config_init``: every slave of the
line is found, given its configured station address (1001h, 1002h, ...), its SII is read and
its mailbox SyncManagers programmed, and PRE-OPERATIONAL is requested, where CoE works. Links
to several slaves on one interface share one SOEM master (one per interface: a second
``config_init`` would reset the line under the first), and their requests take turns.

Cyclic process data (links/ethercat_cyclic.py): ``start`` (the PDO page's cyclic data)
maps the line's process data with SOEM's ``config_map`` (the PDO assignment 1C12h / 1C13h and
mapping read over CoE, SM2 / SM3 and the FMMUs programmed), checks what it mapped against
each slave's PDO assignment, requests SAFE-OP, confirms that the exchange comes back with the
expected working counter, then requests OP; every cycle is then one LRW of the line's process
data image, each accounted for in the line's health (links/ethercat_health.py: working
counter errors, missing frames, the link lost and recovered). SOEM's error list is emptied
around each SDO and each mapping (:func:`drain_errors`).

What this link does not do (docs/ethercat.md):

- Distributed clocks: the cycle is SOEM's free run, paced by servodesk's cycle thread.
- NMT: EtherCAT has none; ``preop`` and ``stop`` (INIT) and ``start`` (OP) are AL state
  requests (AL control 0120h), which the slave may refuse with an AL status code: the refusal
  is a ConflictError carrying it. ``reset`` and ``reset_comm`` are refused.

pysoem holds the GIL in its state calls (``read_state``, ``write_state``, ``state_check``);
only ``config_init`` and the SDO services release it. A slave answered by Python code in this
same process while it waits cannot answer those calls: the simulated line therefore runs its
ESCs in a process of their own (:class:`~servodesk.sim.ethercat_slave.EthercatSlaveProcess`,
what ``SimulatedBus`` uses); with the thread front-end (``EthercatSlaveSim``, tests) the
state reads "unknown" and a state request times out.

Over 700 lines: the SOEM master shared by the links of one interface (:class:`_Master`, its
thread and its turns) and the link over it; the process-data exchange is already its own module
(links/ethercat_cyclic.py).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.ethercat import (
    MBXERR_SERVICE_NOT_SUPPORTED,
    MBXERR_UNSUPPORTED_PROTOCOL,
    OdEntryInfo,
    OdObjectInfo,
)
from servodesk.domain.sdo_abort import abort_error
from servodesk.errors import (
    ConflictError,
    LinkError,
    LinkTimeoutError,
    LinkUnavailableError,
    NotFoundError,
    ObjectAccessError,
    ValidationError,
)
from servodesk.links.base import (
    QUICK_STOP_WORD,
    DriveIdentity,
    DriveLink,
    LinkParams,
    object_identity,
)
from servodesk.links.ethercat_health import LOST, RECOVERING, LineHealth
from servodesk.nic import check_name, require

log = logging.getLogger(__name__)

try:
    import pysoem
except ImportError as exc:  # pragma: no cover - pysoem is a dependency
    raise LinkUnavailableError(
        f"pysoem is not installed: {exc}", hint="install servodesk with its dependencies"
    ) from exc

#: The interface name of this link.
INTERFACE = "ethercat"
#: AL states (ETG.1000.6 §6.4.1, AL status bits 0-3) by name, and back.
AL_STATES = {0x01: "init", 0x02: "preop", 0x03: "boot", 0x04: "safeop", 0x08: "op"}
AL_PREOP, AL_SAFEOP, AL_OP = 0x02, 0x04, 0x08
#: How long one process data exchange waits for its frame to come back (µs).
PROCESS_DATA_TIMEOUT_US = 2000
#: The AL state each command of DriveLink.nmt requests ("safeop": inputs only, see
#: EthercatLink.inputs_only_command).
NMT_AL_STATES = {"preop": 0x02, "stop": 0x01, "safeop": 0x04, "start": 0x08}
#: Largest object servodesk reads in one SDO upload (pysoem's buffer).
READ_BUFFER = 4096
#: The process data watchdog servodesk switches on where a slave has it off: the ESC's
#: usual default (2498 x 40 ns divider = 100 us, 1000 of them).
SM_WATCHDOG_MS = 100.0
#: Exchanges after SAFE-OP within which one must come back with the expected working
#: counter before cyclic data is said to run.
CONFIRM_CYCLES = 10
#: How long a state request waits for the slave to get there (µs, SOEM's unit).
STATE_TIMEOUT_US = 500_000
#: How long a read AL state is reported before it is read again (s): the session polls the
#: state with every status, and pysoem's read holds the GIL while it waits (module doc), up to
#: its time-out (about 17 ms) when nobody answers.
STATE_MAX_AGE = 1.0
#: How long the dead-man's stop waits for a request in flight on the line (s): longer than
#: one SDO's time-out at the default 0.5 s, short enough that a line stuck in a call does
#: not hold the stop back for long (it then logs and the loop's stop follows).
STOP_LOCK_S = 0.6


#: Mailbox error codes that say a slave has no SDO Information (ETG.1000.4 §5.6: 2
#: unsupported protocol, 4 service not supported).
MBX_REFUSALS = (MBXERR_UNSUPPORTED_PROTOCOL, MBXERR_SERVICE_NOT_SUPPORTED)
#: How often one object's SDO Information is asked for before the read fails.
OD_TRIES = 2
#: Emptying the slave's out mailbox (:func:`_flush_mailbox`): at most this many polls,
#: stopping after this many empty ones in a row, this far apart (s).
FLUSH_MAX_POLLS = 20
FLUSH_EMPTY_POLLS = 3
FLUSH_POLL_S = 0.005


@dataclass
class _Master:
    """One SOEM master on one interface, shared by the links to its slaves."""

    master: Any
    slaves: int
    lock: threading.Lock = field(default_factory=threading.Lock)
    users: int = 0
    #: config_map has run and no PDO assignment or mapping was written since: the slaves'
    #: input / output images and FMMUs stand.
    mapped: bool = False
    #: config_map has run on this configuration of the line (config_init) before.
    was_mapped: bool = False
    #: The cyclic transports' receivers, by identifier (180h + node: that slave's inputs).
    receivers: dict[int, list[Callable[[bytes, float], None]]] = field(default_factory=dict)
    #: Outputs to send, by slave position (0-based).
    outputs: dict[int, bytes] = field(default_factory=dict)
    #: config_dc has run (the slaves' clocks set and their delays measured).
    dc: bool = False
    #: The AL state each slave (by position) was last brought to by a state request (SAFE-OP
    #: for cyclic inputs only, OP with outputs): what the cycle thread brings it back to
    #: after a link loss. A slave without one is in SAFE-OP after config_map.
    target_states: dict[int, int] = field(default_factory=dict)
    #: The cycles' bookkeeping (links/ethercat_health.py).
    health: LineHealth = field(default_factory=lambda: LineHealth(""))


_masters: dict[str, _Master] = {}
_masters_lock = threading.Lock()


def _open_master(channel: str) -> _Master:
    """The shared master of ``channel``, opened and configured the first time."""
    with _masters_lock:
        shared = _masters.get(channel)
        if shared is None:
            shared = _Master(*_configure(channel))
            shared.health.nic = channel
            _masters[channel] = shared
        shared.users += 1
        return shared


def _release_master(channel: str, shared: _Master) -> None:
    with _masters_lock:
        shared.users -= 1
        if shared.users <= 0 and _masters.get(channel) is shared:
            del _masters[channel]
            with shared.lock:
                shared.master.close()


def hold_line(channel: str) -> tuple[int, Callable[[], None]]:
    """How many slaves the line on ``channel`` has (SOEM's ``config_init``, or the count of
    the master the open links share), and the call that lets the master go again: the line
    stays configured in between, so that the slaves' links opened meanwhile (a scan reading
    their identities) do not configure it once each."""
    shared = _open_master(channel)
    return shared.slaves, lambda: _release_master(channel, shared)


def _configure(channel: str) -> tuple[Any, int]:
    check_name(
        channel,
        field="channel",
        hint="give the interface the EtherCAT line is plugged into, e.g. eth1",
    )
    require(channel, hint="the EtherCAT line's NIC is the channel")
    master = pysoem.Master()
    # The SDO calls release the GIL, so a slave simulated in this process can answer.
    master.always_release_gil = True
    try:
        master.open(channel)
    except ConnectionError as exc:
        raise LinkError(
            f"cannot open {channel!r} for EtherCAT: {exc}",
            hint="SOEM sends raw Ethernet frames: run as root or give CAP_NET_RAW",
        ) from exc
    try:
        found = int(master.config_init(release_gil=True))
    except Exception as exc:
        master.close()
        raise LinkError(f"EtherCAT configuration on {channel!r} failed: {exc}") from exc
    if found <= 0:
        master.close()
        raise NotFoundError(
            f"no EtherCAT slave answers on {channel!r}",
            hint="check the cable to the first slave's IN port and that the drive is powered",
        )
    return master, found


def soem_error_text(err: object) -> str:
    """One entry of SOEM's error list (pysoem's SdoError / MailboxError / PacketError) in
    words, naming the slave (SOEM counts slaves from 1, as servodesk's node ids)."""
    where = f"slave {getattr(err, 'slave_pos', '?')}"
    if isinstance(err, pysoem.SdoError):
        return (
            f"{where}: SDO abort 0x{int(err.abort_code):08X} on "
            f"{int(err.index):04X}h:{int(err.subindex):02X} ({err.desc})"
        )
    if isinstance(err, pysoem.MailboxError):
        return f"{where}: mailbox error {int(err.error_code)} ({err.desc})"
    if isinstance(err, pysoem.PacketError):
        return f"{where}: mailbox packet error {int(err.error_code)}"
    return f"{type(err).__name__}: {err}"


def drain_errors(master: Any, before: str) -> list[str]:
    """Empty SOEM's error list (``ecx_poperror`` until empty) and say what it held.

    SOEM keeps one error list per master; pysoem's SDO calls raise on the first entry they
    pop, whoever left it there (an SDO Information request of the detection, an emergency,
    the complete-access read of a slave that claims it), and its ``config_map`` raises
    ConfigMapError for any entry at all, even where the mapping succeeded (issue 46). Each
    operation therefore starts from an empty list, and what was left is logged, not raised.
    """
    return [soem_error_text(e) for e in pop_errors(master, before)]


def pop_errors(master: Any, before: str) -> list[Any]:
    """:func:`drain_errors`, giving pysoem's entries themselves (logged the same way)."""
    collect = getattr(master, "_collect_mailbox_errors", None)
    if collect is None:  # pragma: no cover - pysoem 1.1.13 has it
        return []
    try:
        errors = list(collect())
    except Exception as exc:  # pragma: no cover - a closed master
        log.debug("SOEM's error list cannot be read: %s", exc)
        return []
    if errors:
        texts = "; ".join(soem_error_text(e) for e in errors)
        log.info("SOEM's error list before %s held: %s", before, texts)
    return errors


def _text(raw: object) -> str:
    """A name of SDO Information (VISIBLE_STRING: pysoem gives bytes)."""
    text = raw.decode("latin-1", "replace") if isinstance(raw, bytes) else str(raw or "")
    return text.strip("\x00 ")


def _flush_mailbox(master: Any, slave: Any) -> int:
    """Read and drop what the slave's out mailbox (SM1) still holds: a late answer there
    would be taken by the next mailbox request as its own (SOEM matches no request ids;
    ETG.1000.4 §5.6). Polled until :data:`FLUSH_EMPTY_POLLS` polls in a row found nothing
    (an answer may come a moment after an empty poll); how many were dropped."""
    dropped = empty = 0
    for _ in range(FLUSH_MAX_POLLS):
        # pysoem's mbx_receive raises the first entry of SOEM's error list, whoever left it.
        drain_errors(master, "emptying the mailbox")
        try:
            got = int(slave.mbx_receive())
        except Exception as exc:  # An emergency (pysoem raises it): dropped too, and said.
            log.info("emptying the mailbox: %s", exc)
            got = 1
        if got > 0:
            dropped, empty = dropped + 1, 0
            continue
        empty += 1
        if empty >= FLUSH_EMPTY_POLLS:
            break
        time.sleep(FLUSH_POLL_S)
    if dropped:
        log.info("dropped %d mailbox answer(s) nobody asked for", dropped)
    return dropped


def _od_object(obj: Any) -> OdObjectInfo:
    """One of pysoem's ``slave.od`` objects as plain data, its descriptions read now (pysoem
    reads an object's entries when they are asked for). SOEM's ``ecx_readOE`` fills sub-index
    0 to the object's max sub-index, and leaves zero where the slave refused one (a gap)."""
    code = int(obj.object_code)
    name = _text(obj.name)
    if code == 7:  # VAR: the object's own description is sub-index 0's.
        entries: tuple[OdEntryInfo, ...] = (
            OdEntryInfo(0, name, int(obj.data_type), int(obj.bit_length), int(obj.obj_access)),
        )
    else:
        entries = tuple(
            OdEntryInfo(sub, _text(e.name), int(e.data_type), int(e.bit_length), int(e.obj_access))
            for sub, e in enumerate(obj.entries)
            if int(e.data_type) or int(e.bit_length)
        )
    return OdObjectInfo(int(obj.index), name, code, int(obj.data_type), entries)


def _pdo_configuration(index: int) -> bool:
    """The PDO assignment (1C10h-1C2Fh) and mapping (1600h-17FFh, 1A00h-1BFFh) objects,
    whose change changes the process data images (ETG.1020)."""
    return 0x1C10 <= index <= 0x1C2F or 0x1600 <= index <= 0x1BFF


class EthercatLink(DriveLink):
    """One slave of an EtherCAT line, its objects reached by CoE SDO through SOEM."""

    fieldbus = "ethercat"
    #: ``config_init`` reads every slave's SII over the line, some seconds on a long one.
    OPEN_TIMEOUT = 15.0
    #: No NMT reset (EtherCAT has none): a restore of the defaults with a reset is refused
    #: before anything is restored (services/session.py), not left half done.
    sends_nmt = False
    #: The state for cyclic data with the outputs off (services/pdo.py start_cyclic):
    #: SAFE-OP, where the slave sends its inputs and ignores the output image (ETG.1000.6
    #: §6.4.1). In OP an EtherCAT slave takes the outputs of every cycle, and an output image
    #: nobody fills would command controlword 0.
    inputs_only_command = "safeop"
    #: How cyclic data may be synchronised (:meth:`configure_sync`): FreeRun, the slave's own
    #: cycle, or DC, its SYNC0 event from the distributed clocks (ETG.1020; HIWIN 000 §2.5).
    sync_modes = ("freerun", "dc")

    def __init__(self, params: LinkParams) -> None:
        if params.interface != INTERFACE:
            raise ValidationError(
                f"interface {params.interface!r} does not carry EtherCAT",
                field="interface",
                hint=f"use interface {INTERFACE} with the network interface as channel",
            )
        if params.node_id < 1:
            raise ValidationError(
                f"node id {params.node_id} is no slave position",
                field="node_id",
                hint="EtherCAT node ids are the slave's position in the line + 1",
            )
        super().__init__(params)
        self._shared: _Master | None = None
        self._slave: Any = None
        self._state: tuple[float, str] | None = None
        #: The synchronisation the next SAFE-OP request configures, and the one in force:
        #: (mode, SYNC0 cycle in ns).
        self._sync: tuple[str, int] = ("freerun", 0)
        self._applied: tuple[str, int] = ("freerun", 0)
        #: The process data watchdog time before servodesk switched it on (None: untouched).
        self._watchdog_original: float | None = None
        self._watchdog_text: str | None = None

    # The drive's own watchdog: the SyncManager (process data) watchdog ---------------------

    async def arm_watchdog(self) -> str | None:
        """The ESC's process data watchdog (registers 0400h divider, 0420h time; ETG.1000.4
        and HIWIN 000 §2.10 table 2.10.1: error 001Bh, OP -> SAFE-OP and the drive's fault
        reaction): a master that stops sending process data stops the drive. servodesk
        switches it on (100 ms) where the slave has it off, and says it acts only while
        cyclic process data runs in OP."""
        return await self._call(self._arm_watchdog)

    def _arm_watchdog(self) -> str | None:
        shared, slave = self._master()
        with shared.lock:
            try:
                ms = float(slave.get_watchdog("processdata"))
                if ms <= 0:
                    slave.set_watchdog("processdata", SM_WATCHDOG_MS)
                    self._watchdog_original = ms
                    ms = float(slave.get_watchdog("processdata"))
            except Exception as exc:  # SOEM's register access: no answer from the ESC.
                raise LinkError(f"the ESC's watchdog registers cannot be read: {exc}") from exc
        if ms <= 0:
            return None
        self._watchdog_text = (
            f"EtherCAT SyncManager watchdog {ms:g} ms (ESC 0420h): without servodesk's process "
            "data the drive goes to SAFE-OP with error 001Bh and its fault reaction; it acts "
            "only while cyclic process data runs (OP)"
        )
        return self._watchdog_text

    async def disarm_watchdog(self) -> None:
        original, self._watchdog_original = self._watchdog_original, None
        self._watchdog_text = None
        if original is not None:
            await self._call(self._set_watchdog, original)

    def _set_watchdog(self, ms: float) -> None:
        shared, slave = self._master()
        with shared.lock:
            slave.set_watchdog("processdata", ms)

    @property
    def watchdog(self) -> str | None:
        return self._watchdog_text

    # The dead-man's stop, beside the event loop ------------------------------------------

    def stop_frame(self) -> Callable[[], None] | None:
        """A CoE SDO download of 6040h:00 = 0002h (quick stop, CiA 402-2 §6.2.1 table 28)
        from the dead-man's thread, under the line's lock.

        SOEM keeps one mailbox exchange per slave, so every access takes ``shared.lock``; the
        loop's own SDOs hold it only from their executor threads, never while the loop waits,
        so a held event loop does not hold it. The thread waits at most
        :data:`STOP_LOCK_S` for a request in flight (a running SDO ends within its time-out)
        and then sends; pysoem's SDO services release the GIL while they wait for the slave.
        While cyclic process data carries 6040h, the next cycle's outputs command the drive
        again: the orderly stop the loop sends next goes through the cyclic exchange."""
        if self._shared is None or self._slave is None:
            return None
        shared, slave = self._shared, self._slave
        word = QUICK_STOP_WORD.to_bytes(2, "little")

        def send() -> None:
            if not shared.lock.acquire(timeout=STOP_LOCK_S):
                log.warning("dead-man stop: the EtherCAT line stayed busy %.1f s", STOP_LOCK_S)
                return
            try:
                slave.sdo_write(0x6040, 0, word, release_gil=True)
            except Exception as exc:  # The loop's orderly stop follows and reports.
                log.warning("dead-man stop: the quick stop SDO failed: %s", exc)
            finally:
                shared.lock.release()

        return send

    def configure_sync(self, mode: str, period_s: float) -> None:
        """Synchronise the slave's process data by ``mode`` ("freerun" or "dc", SYNC0 every
        ``period_s``) from its next transition to SAFE-OP; a slave already in SAFE-OP or OP
        with another synchronisation goes back to PRE-OP first (the DC registers are set in
        PRE-OP, ETG.1020). The slave checks the cycle (AL status 0035h)."""
        if mode not in self.sync_modes:
            raise ValidationError(
                f"EtherCAT has no synchronisation {mode!r}",
                field="sync",
                hint="use freerun or dc",
            )
        self._sync = (mode, round(period_s * 1e9) if mode == "dc" else 0)

    # Hooks -------------------------------------------------------------------------

    def _open(self) -> None:
        shared = _open_master(self.params.channel)
        if self.params.node_id > shared.slaves:
            _release_master(self.params.channel, shared)
            raise NotFoundError(
                f"no EtherCAT slave at position {self.params.node_id} on "
                f"{self.params.channel!r} ({shared.slaves} found)",
                hint="the node id is the slave's position in the line + 1",
            )
        self._shared = shared
        self._slave = shared.master.slaves[self.params.node_id - 1]

    def _close(self) -> None:
        shared, self._shared, self._slave = self._shared, None, None
        if shared is not None:
            _release_master(self.params.channel, shared)

    def line(self) -> _Master:
        """The state this link shares with the other links of its line: the SOEM master, the
        lock every access takes, and the cyclic transport's receivers and outputs
        (links/ethercat_cyclic.py drives one process data cycle of the whole line with it).
        LinkError when the link is closed."""
        shared, _ = self._master()
        return shared

    def _master(self) -> tuple[_Master, Any]:
        if self._shared is None or self._slave is None:
            raise LinkError("the EtherCAT link is closed", hint="open the session again")
        return self._shared, self._slave

    def _read(self, address: ObjectAddress) -> bytes:
        shared, slave = self._master()
        with shared.lock:
            shared.master.sdo_read_timeout = self._timeout_us()
            drain_errors(shared.master, f"reading {address}")
            try:
                data = slave.sdo_read(
                    address.index, address.subindex, READ_BUFFER, release_gil=True
                )
            except Exception as exc:
                # pysoem raised on the first entry: the rest would trip the next call.
                drain_errors(shared.master, f"the rest of the failed read of {address}")
                raise self._failed(exc, address, "read") from exc
        return bytes(data)

    def _write(self, address: ObjectAddress, data: bytes) -> None:
        shared, slave = self._master()
        with shared.lock:
            shared.master.sdo_write_timeout = self._timeout_us()
            drain_errors(shared.master, f"writing {address}")
            try:
                slave.sdo_write(address.index, address.subindex, bytes(data), release_gil=True)
            except Exception as exc:
                drain_errors(shared.master, f"the rest of the failed write of {address}")
                raise self._failed(exc, address, "write") from exc
            if _pdo_configuration(address.index):
                shared.mapped = False  # The images change: config_map again before SAFE-OP.

    def _timeout_us(self) -> int:
        return max(1000, round(self.request_timeout * 1e6))

    def _failed(self, exc: Exception, address: ObjectAddress, op: str) -> Exception:
        if isinstance(exc, pysoem.SdoError):
            return abort_error(int(exc.abort_code), address, op)
        where = f"slave {self.params.node_id} on {self.params.channel!r}"
        if isinstance(exc, pysoem.WkcError):
            return LinkTimeoutError(
                f"{op} {address}: no CoE answer from {where} within "
                f"{self.request_timeout:g} s (working counter {getattr(exc, 'wkc', '?')})"
            )
        if isinstance(exc, pysoem.PacketError) and int(getattr(exc, "error_code", 0)) == 1:
            # SOEM's ecx_SDOread / ecx_SDOwrite take an abort only when its command byte is
            # exactly 80h; one with the reserved bits 0-4 set (CiA 301 §7.2.4.3.17 says 0,
            # some firmware sends 1s) is its packet error 1 "unexpected frame", and the
            # abort code is lost with the frame.
            return ObjectAccessError(
                f"{op} {address}: {where} refused it with a frame SOEM does not take as an SDO "
                "response or abort (unexpected frame: e.g. an SDO abort with reserved bits "
                "set); its abort code is not known",
                code=0,
                meaning="abort code unknown: the answer was no valid SDO abort",
                address=str(address),
                hint="the object may not exist or not allow this access; the object "
                "dictionary page or the drive's ESI says which",
            )
        if isinstance(exc, (pysoem.MailboxError, pysoem.PacketError)):
            return LinkError(
                f"{op} {address}: the mailbox exchange with {where} failed: {exc}",
                hint="the slave answered something other than a CoE SDO response",
            )
        if type(exc).__module__.startswith("pysoem"):
            # Any other SOEM failure (an interface no longer open, ...) is the link's.
            return LinkError(f"{op} {address} on {where}: {type(exc).__name__}: {exc}")
        return exc

    async def identity(self) -> DriveIdentity:
        """CoE 1018h/1008h-100Ah, completed from the SII (the slave's EEPROM, read by SOEM's
        config_init: vendor id, product code, revision at words 8-13, the device name from
        the SII strings; ETG.1000.6 §5.4, ETG.2010). A slave without 1008h, or one that
        aborts 1018h:03, is still identified; where CoE gives a value, CoE wins."""
        ident = await object_identity(self)
        vendor, product, revision, name = self._sii_identity()
        return replace(
            ident,
            vendor_id=ident.vendor_id if ident.vendor_id is not None else vendor,
            product_code=ident.product_code if ident.product_code is not None else product,
            revision=ident.revision if ident.revision is not None else revision,
            device_name=ident.device_name or name,
        )

    async def object_list(self) -> tuple[OdObjectInfo, ...] | None:
        """The slave's object dictionary as its CoE SDO Information service describes it
        (ETG.1000.6 §5.6.3: Get OD List of all objects, then each one's Object Description
        and its sub-indices' Entry Descriptions; SOEM's ``ecx_readODlist``,
        ``ecx_readODdescription``, ``ecx_readOE`` through pysoem's ``slave.od``), or None
        where the slave does not offer the service (an SDO Info Error or a mailbox error:
        SDO Information is optional, CoE details bit 1 of the SII)."""
        return await self._call(self._object_list)

    def _object_list(self) -> tuple[OdObjectInfo, ...] | None:
        shared, slave = self._master()
        where = f"slave {self.params.node_id} on {self.params.channel!r}"
        with shared.lock:
            drain_errors(shared.master, "reading the SDO Information")
            try:
                listed = self._listed(shared, slave, where)
                if listed is None:
                    return None
                return tuple(self._described(shared, slave, o, where) for o in listed)
            finally:
                _flush_mailbox(shared.master, slave)
                # An entry the slave refused leaves its SDO Info Error in SOEM's list: it
                # would trip the next SDO (:func:`drain_errors`).
                drain_errors(shared.master, "the end of the SDO Information read")

    def _listed(self, shared: _Master, slave: Any, where: str) -> list[Any] | None:
        """The object list (Get OD List, pysoem's ``slave.od``), asked twice: a slave without
        the service refuses both (SDO Info Error or mailbox error "service not supported",
        ETG.1000.6 §5.6.3), one whose answer was lost (:meth:`_described`) answers the second."""
        for attempt in range(OD_TRIES):
            try:
                return list(slave.od)
            except (pysoem.SdoInfoError, pysoem.MailboxError, pysoem.PacketError) as exc:
                errors = pop_errors(shared.master, "the SDO Information's object list")
                _flush_mailbox(shared.master, slave)
                refused = any(
                    isinstance(e, pysoem.MailboxError) and int(e.error_code) in MBX_REFUSALS
                    for e in errors
                )
                if refused or attempt + 1 == OD_TRIES:
                    # SOEM waits out its mailbox time-out (700 ms) after a mailbox error:
                    # a slave that says it has no such service is not asked again.
                    log.info("%s: no SDO Information (%s)", where, exc)
                    return None
            except pysoem.WkcError as exc:
                raise LinkTimeoutError(
                    f"SDO Information of {where}: no answer (working counter "
                    f"{getattr(exc, 'wkc', '?')})"
                ) from exc
        return None

    def _described(self, shared: _Master, slave: Any, obj: Any, where: str) -> OdObjectInfo:
        """One object's descriptions, asked again once after an answer SOEM did not take
        (pysoem's SdoInfoError "read failed"). Seen on 2026-12-07 with the ESI twin of the
        Ingenia file (546 objects) at a load of 6-9 on 2 cores: in 2 of 4 plain pysoem reads
        of its dictionary, and once through this link before it emptied the mailbox; each
        time the slave's out mailbox still held an answer that the following SDOs took for
        their own (SOEM: unexpected frame, mailbox errors). The mailbox is emptied before
        asking again (:func:`_flush_mailbox`)."""
        for attempt in range(OD_TRIES):
            try:
                return _od_object(obj)
            except (pysoem.SdoInfoError, pysoem.MailboxError, pysoem.PacketError) as exc:
                texts = drain_errors(shared.master, f"SDO Information of {int(obj.index):04X}h")
                dropped = _flush_mailbox(shared.master, slave)
                log.info(
                    "%s: SDO Information of %04Xh failed (%s; %d stale answers dropped)",
                    where,
                    int(obj.index),
                    exc,
                    dropped,
                )
                if attempt + 1 == OD_TRIES:
                    raise LinkError(
                        f"SDO Information of {int(obj.index):04X}h from {where} failed "
                        f"{OD_TRIES} times: {exc}" + (f" ({'; '.join(texts)})" if texts else ""),
                        hint="the drive's generic EtherCAT profile is used; import its ESI "
                        "for its own objects",
                    ) from exc
        raise AssertionError("unreachable")  # pragma: no cover

    def _sii_identity(self) -> tuple[int | None, int | None, int | None, str | None]:
        """(vendor, product code, revision, name) as SOEM cached them from the SII."""
        _, slave = self._master()

        def num(attr: str) -> int | None:
            v = getattr(slave, attr, None)
            return int(v) if isinstance(v, int) else None

        raw = getattr(slave, "name", None)
        name = raw.decode("latin-1", "replace") if isinstance(raw, bytes) else raw
        return num("man"), num("id"), num("rev"), (name or "").strip() or None

    def _network_state(self) -> str:
        """The slave's AL state (AL status 0130h) as SOEM reads it: init, preop, boot,
        safeop, op; "unknown" when the slave does not answer."""
        shared, slave = self._master()
        if shared.health.state in (LOST, RECOVERING) and any(shared.receivers.values()):
            # Cyclic data runs and its cycles see no answer (links/ethercat_health.py): the
            # state is not known, and a read would only wait for its time-out holding the
            # GIL (module doc).
            self._state = None
            return "unknown"
        now = time.monotonic()
        if self._state is not None and now - self._state[0] < STATE_MAX_AGE:
            return self._state[1]
        with shared.lock:
            shared.master.read_state()
            name = AL_STATES.get(int(slave.state) & 0x0F, "unknown")
        self._state = (now, name)
        return name

    def _map_process_data(self, shared: _Master, slave: Any) -> None:
        """Before OP (ETG.1000.6 §6.4.1): the synchronisation asked (:meth:`configure_sync`),
        the process data mapped (SOEM's config_map reads the PDO assignment over CoE and
        programs SM2 / SM3 and the FMMUs) and checked, SAFE-OP, and a few exchanges that must
        come back with the expected working counter, so that the slave has valid outputs
        when OP is requested and "running" means frames on the wire (issue 46)."""
        with shared.lock:
            shared.master.read_state()
            if (
                shared.mapped
                and int(slave.state) & 0x0F in (AL_SAFEOP, AL_OP)
                and self._applied == self._sync
            ):
                return
            if int(slave.state) & 0x0F in (AL_SAFEOP, AL_OP):
                # Another synchronisation (its registers are written in PRE-OP), or a line
                # left in SAFE-OP by a mapping that failed: back to PRE-OP, map again.
                slave.state = AL_PREOP
                slave.write_state()
                slave.state_check(AL_PREOP, STATE_TIMEOUT_US)
            if not shared.mapped and shared.was_mapped:
                # SOEM maps a line once per configuration: each config_map takes the next
                # free FMMUs of every slave (ecx_config_map_group, FMMUunused), and a third or
                # fourth mapping finds none and maps nothing (working counter 0). A new
                # mapping therefore starts from a new configuration of the line (INIT, the SII
                # read again, PRE-OP), which also resets SOEM's distributed clocks.
                self._reconfigure(shared)
            # The DC registers first: SOEM's config_map requests SAFE-OP itself, where the
            # slave checks its synchronisation.
            self._set_sync(shared, slave)
            if not shared.mapped:
                self._map_and_check(shared)
            slave.state = AL_SAFEOP
            slave.write_state()
            reached = int(slave.state_check(AL_SAFEOP, STATE_TIMEOUT_US)) & 0x0F
            if reached != AL_SAFEOP:
                code = int(slave.al_status)
                # Acknowledged, so that the next request is not blocked by the indication.
                slave.state = AL_PREOP | 0x10
                slave.write_state()
                mode, cycle = self._sync
                hint = (
                    f"the drive does not take a SYNC0 cycle of {cycle / 1e6:g} ms: choose "
                    "another period, or FreeRun"
                    if mode == "dc" and code in (0x0030, 0x0035)
                    else "check the PDO assignment (1C12h / 1C13h) on the PDO page"
                )
                raise ConflictError(
                    f"the EtherCAT slave refused SAFE-OP: AL status code 0x{code:04X} "
                    f"{pysoem.al_status_code_to_string(code)}",
                    hint=hint,
                )
            self._applied = self._sync
            self._confirm_exchange(shared)

    def _expected_sizes(self, shared: _Master) -> dict[int, tuple[int, int]]:
        """Each slave's output and input bytes as its PDO assignment says (1C12h / 1C13h,
        the assigned PDOs' entries, ETG.1020 / CiA 301 §7.4.8: bits 0-7 of an entry are its
        length), read over CoE; a slave whose assignment cannot be read (no CoE, fixed PDOs
        from the SII) is left out and checked by the working counter alone."""
        out: dict[int, tuple[int, int]] = {}
        for position, s in enumerate(shared.master.slaves):

            def u(index: int, sub: int, size: int, s: Any = s) -> int:
                drain_errors(shared.master, "reading the PDO assignment")
                data = bytes(s.sdo_read(index, sub, 8, release_gil=True))
                return int.from_bytes(data[:size], "little")

            sizes: list[int] = []
            try:
                for assign in (0x1C12, 0x1C13):
                    bits = 0
                    for n in range(1, u(assign, 0, 1) + 1):
                        pdo = u(assign, n, 2)
                        for e in range(1, u(pdo, 0, 1) + 1):
                            bits += u(pdo, e, 4) & 0xFF
                    sizes.append((bits + 7) // 8)
            except Exception as exc:  # No CoE PDO assignment: the SII's PDOs, unchecked.
                drain_errors(shared.master, "the rest of the PDO assignment read")
                log.debug("slave %d: PDO assignment not readable: %s", position + 1, exc)
                continue
            out[position] = (sizes[0], sizes[1])
        return out

    def _map_and_check(self, shared: _Master) -> None:
        """SOEM's config_map, then what it really mapped checked against each slave's PDO
        assignment: a ConfigMapError (SOEM's error list was not empty) is no failure when the
        mapping is right, and no exception is no success when it is not. A failed mapping
        leaves the line unmapped, in PRE-OP, so that the next start maps it again."""
        master = shared.master
        expected = self._expected_sizes(shared)
        drain_errors(master, "config_map")
        soem_errors: list[str] = []
        try:
            master.config_map()
        except pysoem.ConfigMapError as exc:
            soem_errors = [soem_error_text(e) for e in exc.error_list]
        except Exception as exc:
            shared.mapped = False
            raise LinkError(
                f"mapping the process data of {self.params.channel!r} failed: {exc}"
            ) from exc
        soem_errors += drain_errors(master, "the end of config_map")
        # config_map used the FMMUs of this configuration: a new mapping starts from a new one.
        shared.was_mapped = True
        problems: list[str] = []
        for position, s in enumerate(master.slaves):
            got = (len(s.output), len(s.input))
            want = expected.get(position)
            if want is not None and got != want:
                problems.append(
                    f"slave {position + 1} has {got[0]} output / {got[1]} input bytes mapped "
                    f"where its PDO assignment (1C12h / 1C13h) has {want[0]} / {want[1]}"
                )
        mapped_bytes = sum(len(s.output) + len(s.input) for s in master.slaves)
        if mapped_bytes and int(master.expected_wkc) <= 0:
            problems.append("SOEM expects no working counter for the mapped image")
        if soem_errors:
            log.warning(
                "config_map on %s reported (%s): %s",
                self.params.channel,
                "the mapping is nevertheless complete" if not problems else "and it is not",
                "; ".join(soem_errors),
            )
        if problems:
            shared.mapped = False
            # SOEM requested SAFE-OP with this mapping: back to PRE-OP, where the line says
            # what it is (no process data), rather than SAFE-OP with a wrong image.
            master.state = AL_PREOP
            master.write_state()
            master.state_check(AL_PREOP, STATE_TIMEOUT_US)
            why = "; ".join(problems + soem_errors)
            raise LinkError(
                f"the process data of {self.params.channel!r} were not mapped as assigned: {why}",
                hint="check the PDO assignment on the PDO page, then start cyclic data "
                "again (it maps the line again)",
            )
        shared.mapped = True
        shared.health.expected_wkc = int(master.expected_wkc)

    def _confirm_exchange(self, shared: _Master) -> None:
        """Exchange process data until one LRW comes back with SOEM's expected working
        counter (ETG.1000.4 §5.4.3), at most :data:`CONFIRM_CYCLES`; otherwise the line is
        marked unmapped and the error names the slaves that do not take part and why."""
        master = shared.master
        expected = int(master.expected_wkc)
        got = -1
        for _ in range(CONFIRM_CYCLES):
            master.send_processdata()
            got = int(master.receive_processdata(PROCESS_DATA_TIMEOUT_US))
            if got == expected:
                return
        shared.mapped = False
        why = (
            "no frame came back"
            if got < 0
            else f"the frames came back with working counter {got} of {expected}"
        )
        raise LinkError(
            f"process data on {self.params.channel!r}: {why} in {CONFIRM_CYCLES} cycles "
            f"({self._culprits(shared)})",
            hint="check the cable and the slaves' state on the Network page; starting cyclic "
            "data again maps the line again",
        )

    def _culprits(self, shared: _Master) -> str:
        """The slaves not in SAFE-OP / OP, or with their error indication, and their AL
        status codes: who does not take part in the exchange (SOEM's ``ecx_readstate``)."""
        master = shared.master
        try:
            master.read_state()
        except Exception as exc:
            return f"the slaves' states cannot be read: {exc}"
        found = []
        for position, s in enumerate(master.slaves):
            state = int(s.state)
            if state & 0x0F not in (AL_SAFEOP, AL_OP) or state & 0x10:
                code = int(s.al_status)
                found.append(
                    f"slave {position + 1} in {AL_STATES.get(state & 0x0F, 'no state')}"
                    + (
                        f", AL status code 0x{code:04X} {pysoem.al_status_code_to_string(code)}"
                        if code
                        else ""
                    )
                )
        return "; ".join(found) or "every slave is in SAFE-OP or OP"

    def _reconfigure(self, shared: _Master) -> None:
        """SOEM's config_init again (the line's slaves back to INIT, then PRE-OP)."""
        try:
            found = int(shared.master.config_init(release_gil=True))
        except Exception as exc:
            raise LinkError(f"configuring {self.params.channel!r} again failed: {exc}") from exc
        if found < self.params.node_id:
            raise NotFoundError(
                f"slave {self.params.node_id} is no longer on {self.params.channel!r} "
                f"({found} found)",
                hint="check the line's cabling and that the drive is powered",
            )
        shared.slaves = found
        shared.dc = False
        shared.was_mapped = False
        self._applied = ("freerun", 0)

    def _set_sync(self, shared: _Master, slave: Any) -> None:
        """The DC registers for the synchronisation asked (SOEM's ``ecx_configdc`` once per
        line: system time offsets and propagation delays; ``ecx_dcsync0``: the SYNC0 start
        time and cycle, activation 0981h), or SYNC0 off for FreeRun."""
        mode, cycle = self._sync
        if mode == "dc":
            if not shared.dc:
                if not shared.master.config_dc():
                    raise ConflictError(
                        f"no slave on {self.params.channel!r} has distributed clocks",
                        hint="start cyclic data in FreeRun",
                    )
                shared.dc = True
            slave.dc_sync(True, cycle)
        elif shared.dc:
            slave.dc_sync(False, 0)

    def _nmt(self, command: str) -> None:
        target = NMT_AL_STATES.get(command)
        if target is None:
            raise ConflictError(
                f"EtherCAT has no NMT command {command!r}",
                hint="EtherCAT drives change state by AL control requests: "
                "preop, stop (INIT), safeop and start (OP)",
            )
        shared, slave = self._master()
        self._state = None
        with shared.lock:
            shared.master.read_state()
            now = int(slave.state)
            if now & 0x10:
                # An error indication (e.g. 001Bh, the SyncManager watchdog) blocks every
                # request until it is acknowledged (ETG.1000.6 §6.4.1, AL control bit 4): the
                # user asking for a state is that acknowledgement (HIWIN 000 §3.2.1 step 2).
                slave.state = (now & 0x0F) | 0x10
                slave.write_state()
        if target in (AL_SAFEOP, AL_OP):
            self._map_process_data(shared, slave)
        with shared.lock:
            slave.state = target
            slave.write_state()
            reached = int(slave.state_check(target, STATE_TIMEOUT_US)) & 0x0F
            if reached == target:
                shared.target_states[self.params.node_id - 1] = target
                return
            code = int(slave.al_status)
            now = int(slave.state)
            if code:
                # Acknowledge the refusal, so the slave's error indication does not block
                # the next request (ETG.1000.6 §6.4.1, AL control bit 4).
                slave.state = (now & 0x0F) | 0x10
                slave.write_state()
        name = AL_STATES[target].upper()
        if code:
            raise ConflictError(
                f"the EtherCAT slave refused {name} ({command}): AL status code "
                f"0x{code:04X} {pysoem.al_status_code_to_string(code)}",
                hint="it stays in " + AL_STATES.get(now & 0x0F, "its state").upper(),
            )
        raise LinkTimeoutError(
            f"the EtherCAT slave did not reach {name} ({command}) within "
            f"{STATE_TIMEOUT_US / 1e6:g} s"
        )
