"""A drive session: one connected drive (or axis), its link, profile, state and events.

The API sees sessions only. A session validates every access against its profile before it
reaches the link, polls the drive's CiA 402 state for live updates, and turns link events
(EMCY, NMT, link loss) into messages for the WebSocket hub.

Over 700 lines: :class:`Session` is the one gate every object access passes (profile checks,
protection, the state poll, link events); its parts read and write the same per-drive state
under one lock.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import contextvars
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CONTROLWORD,
    ENCODER_INCREMENTS,
    ENCODER_REVOLUTIONS,
    ERROR_CODE,
    MODE,
    MODE_DISPLAY,
    POSITION,
    STATUSWORD,
    VELOCITY,
)
from servodesk.domain.datatypes import DataType, Value, codec
from servodesk.domain.encoder_units import (
    counts_per_rev_from,
    rescaled,
)
from servodesk.domain.profile import DeviceProfile, ErrorEntry
from servodesk.domain.values import ObjectValue, describe, encode_write
from servodesk.errors import (
    ConflictError,
    DriveStateError,
    LinkError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.links.base import DriveIdentity, DriveLink, LinkEvent
from servodesk.services.events import AuditSink, EventHub

if TYPE_CHECKING:
    from servodesk.services.cyclic import CyclicExchange

log = logging.getLogger(__name__)

#: EMCY messages kept per session for the Alarms page (a bounded log).
EMCY_LOG_SIZE = 200

HEARTBEAT_TIME = ObjectAddress(0x1017)
COMMANDS: dict[str, cia402.Command] = {c.value: c for c in cia402.Command}
#: Targets that make an enabled drive move by themselves (target velocity, target torque).
_MOTION_TARGETS = (ObjectAddress(0x60FF), ObjectAddress(0x6071))

#: What a motion borrows: each setting it writes (persisted, not process data), with its raw
#: value before the first such write (None: unreadable) and whether it was already written
#: since the last store. Set by services/motion/ around a motion's own writes (a context
#: variable: only that task's writes are borrowed, not a user's write beside it).
Borrowed = dict[ObjectAddress, tuple[bytes | None, bool]]
BORROW: contextvars.ContextVar[Borrowed | None] = contextvars.ContextVar(
    "servodesk_borrow", default=None
)
#: Commands that are always sent: stopping must never be refused.
_ALWAYS = {cia402.Command.QUICK_STOP, cia402.Command.DISABLE_VOLTAGE}
#: Where a single command leads, to suggest the step that is missing.
_COMMAND_TARGET = {
    cia402.Command.SHUTDOWN: cia402.State.READY_TO_SWITCH_ON,
    cia402.Command.SWITCH_ON: cia402.State.SWITCHED_ON,
    cia402.Command.SWITCH_ON_ENABLE: cia402.State.OPERATION_ENABLED,
    cia402.Command.ENABLE_OPERATION: cia402.State.OPERATION_ENABLED,
    cia402.Command.DISABLE_OPERATION: cia402.State.SWITCHED_ON,
}
GOALS: dict[str, cia402.State] = {
    "enable": cia402.State.OPERATION_ENABLED,
    "disable": cia402.State.SWITCH_ON_DISABLED,
}


def set_audit_sink(hub: EventHub, sink: AuditSink | None) -> None:
    """Record the writes of every session on ``hub`` with ``sink`` (None: stop)."""
    hub.audit = sink


def error_info(e: ErrorEntry) -> dict[str, Any]:
    return {
        "table": e.table,
        "code": e.code,
        "code_hex": f"0x{e.code:04X}" if e.code <= 0xFFFF else f"0x{e.code:08X}",
        "display": e.display,
        "name": e.name,
        "kind": e.kind,
        "cause": e.cause,
        "remedy": e.remedy,
        "section": e.section,
    }


@dataclass(frozen=True, slots=True)
class DriveState:
    state: str
    statusword: int
    statusword_hex: str
    bits: list[dict[str, object]]
    mode: int | None
    mode_name: str | None
    position: int | None
    velocity: int | None
    position_unit: str | None
    velocity_unit: str | None
    position_eng: float | None
    velocity_eng: float | None
    position_raw_unit: str | None
    velocity_raw_unit: str | None
    error_code: int | None
    error: dict[str, Any] | None
    nmt_state: str
    time: float

    def key(self) -> tuple[Any, ...]:
        return (
            self.statusword,
            self.mode,
            self.position,
            self.velocity,
            self.error_code,
            self.nmt_state,
        )


class Session:
    def __init__(
        self,
        sid: str,
        link: DriveLink,
        profile: DeviceProfile,
        hub: EventHub,
        *,
        identity: DriveIdentity,
        simulated: bool = False,
        note: str | None = None,
        poll_hz: float = 20.0,
    ) -> None:
        self.id = sid
        self.link = link
        self.profile = profile
        self.hub = hub
        self.identity = identity
        self.simulated = simulated
        self.note = note
        self.poll_hz = poll_hz
        self.connected = True
        self.last_state: DriveState | None = None
        self._last_controlword_at = 0.0
        self._poll_task: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._failures = 0
        #: Objects written through servodesk since the last store: they differ from the
        #: drive's non-volatile copy (changes made by other tools are not seen).
        self.dirty: set[ObjectAddress] = set()
        self._heartbeat_ms = 0
        self._heartbeat_lost = False
        #: The last EMCY messages received in this session (services/alarms.py), oldest first.
        self.emcy_log: collections.deque[dict[str, Any]] = collections.deque(maxlen=EMCY_LOG_SIZE)
        #: Called with every polled DriveState (services/homing.py reports progress from it).
        self.state_listeners: list[Callable[[DriveState], None]] = []
        #: Poll at least this often (Hz) whatever the watchers: the 3D viewer raises it while
        #: it has clients (services/viewer.py); 0: no floor.
        self.min_poll_hz = 0.0
        #: The cyclic process data exchange while it runs (services/pdo.py, cyclic.py).
        self.cyclic: CyclicExchange | None = None
        #: The encoder the increment scales are for (domain/encoder_units.py): the drive's
        #: 608Fh once ``start`` has read it, else the profile's simulation setting.
        self.counts_per_rev = float(profile.simulation.counts_per_rev)
        #: The encoder the catalog profile's scales are for (``counts_per_rev`` before 608Fh).
        self.profile_counts_per_rev = self.counts_per_rev
        self.counts_per_rev_source = "profile"

    # Lifecycle ----------------------------------------------------------------------------

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self.link.add_event_callback(self._on_link_event)
        self._heartbeat_ms = await self._heartbeat_period()
        await self._adopt_encoder()
        with contextlib.suppress(ServodeskError):
            self.last_state = await self.drive_state()
        self._poll_task = asyncio.create_task(self._poll(), name=f"poll {self.id}")

    async def close(self) -> None:
        if self.cyclic is not None:
            self.cyclic.stop()
            self.cyclic = None
        if self._poll_task is not None:
            self._poll_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._poll_task
            self._poll_task = None
        self.link.remove_event_callback(self._on_link_event)
        await self.link.close()
        self.connected = False
        self.hub.publish(
            {"type": "link", "session": self.id, "event": "closed", "message": "session closed"},
            session=self.id,
        )

    async def _heartbeat_period(self) -> int:
        """The drive's producer heartbeat time (1017h), 0 when it has none or sends none."""
        if self.profile.spec(HEARTBEAT_TIME) is None:
            return 0
        try:
            return int.from_bytes((await self.link.read(HEARTBEAT_TIME))[:2], "little")
        except ServodeskError:
            return 0

    @property
    def units_rescaled(self) -> bool:
        """``profile`` is the catalog's with its increment units rescaled to the drive's
        encoder; the frontend then loads GET /sessions/{sid}/profile, not GET /profiles/{id}."""
        return self.counts_per_rev != self.profile_counts_per_rev

    async def _adopt_encoder(self) -> None:
        """Rescale the profile's increment units to the drive's encoder (608Fh).

        The profile's deg and rpm scales are written for its own encoder; a drive on another
        motor (or a twin on a plant file) reports its resolution in 608Fh, CiA 402-2 §6.9.4,
        and the session then shows that axis's degrees. A drive that does not answer, or
        answers 0 (smartris: "not usable", 001 Table 3-2), keeps the profile's scales.
        """
        try:
            # None: the profile has no such object (no 608Fh:02 means 1 revolution).
            inc = await self._read_int(ENCODER_INCREMENTS, DataType.UNSIGNED32)
            revs = await self._read_int(ENCODER_REVOLUTIONS, DataType.UNSIGNED32)
        except ServodeskError as exc:
            # Not fatal, as for 1017h: a drive that does not give it keeps the profile's units
            # (a bus that is really gone shows in the first state poll).
            log.info("%s: 608Fh not read (%s); the profile's scales stay", self.id, exc)
            return
        cpr = counts_per_rev_from(inc, 1 if revs is None else revs) if inc is not None else None
        if cpr is None:
            return
        self.counts_per_rev_source = "608Fh"
        if cpr != self.counts_per_rev:
            log.info(
                "%s: encoder %g counts/rev (608Fh), profile %s assumes %d: rescaling",
                self.id,
                cpr,
                self.profile.id,
                self.profile.simulation.counts_per_rev,
            )
            self.profile = rescaled(self.profile, cpr)
            self.counts_per_rev = cpr

    def _check_heartbeat(self) -> None:
        # CiA 301 §7.2.8.3.2.2: a consumer expects each heartbeat within its period; allow
        # 2.5 periods before calling it lost (bus load and scheduling jitter).
        age = self.link.heartbeat_age()
        if not self._heartbeat_ms or age is None:
            return
        late = age > 2.5 * self._heartbeat_ms / 1000.0
        if late and not self._heartbeat_lost:
            self._heartbeat_lost = True
            self.hub.publish(
                {
                    "type": "link",
                    "session": self.id,
                    "event": "heartbeat_lost",
                    "message": f"no heartbeat for {age * 1000:.0f} ms "
                    f"(1017h = {self._heartbeat_ms} ms)",
                },
                session=self.id,
            )
        elif not late and self._heartbeat_lost:
            self._heartbeat_lost = False
            self.hub.publish(
                {
                    "type": "link",
                    "session": self.id,
                    "event": "heartbeat_restored",
                    "message": "heartbeats arrive again",
                },
                session=self.id,
            )

    def info(self) -> dict[str, Any]:
        p = self.link.params
        return {
            "id": self.id,
            "node_id": p.node_id,
            "interface": p.interface,
            "channel": p.channel,
            "bitrate": p.bitrate,
            "profile_id": self.profile.id,
            "profile_name": self.profile.name,
            "fieldbus": self.profile.fieldbus,
            "link": self.link.fieldbus,
            # PROFINET: the application relations the session holds with the drive.
            "ar": getattr(self.link, "ar_in_use", None),
            "simulated": self.simulated,
            "note": self.note,
            "identity": asdict(self.identity),
            "connected": self.connected,
            "state": self.last_state.state if self.last_state else cia402.State.UNKNOWN.value,
            "nmt_state": self.last_state.nmt_state if self.last_state else "unknown",
            "dirty": [str(a) for a in sorted(self.dirty)],
            "encoder": {
                "counts_per_rev": self.counts_per_rev,
                "source": self.counts_per_rev_source,
                "rescaled": self.units_rescaled,
            },
        }

    # Objects -----------------------------------------------------------------------------

    async def read_object(self, address: ObjectAddress) -> ObjectValue:
        raw = await self.link.read(address)
        return describe(address, self.profile.spec(address), raw)

    async def write_object(
        self,
        address: ObjectAddress,
        value: Value | None = None,
        raw_hex: str | None = None,
        client: str | None = None,
        *,
        audited: bool = True,
    ) -> ObjectValue:
        """Write one object and read it back (the answer is the drive's value).

        ``audited`` False: the caller records the write in the audit log itself, with the old
        value it already holds (a restore: from the backup it took before writing,
        services/restore.py), so this write costs no audit read of its own."""
        spec = self.profile.spec(address)
        data = encode_write(address, spec, value, raw_hex)
        audit = self.hub.audit if audited else None
        old: bytes | None = None
        setting = spec is None or (spec.persist and not spec.process)
        # The mode of operation is the motion's command, read back in 6061h (CiA 402-2
        # §6.2.4), not a setting it borrows: the homing status reads it after the run.
        borrow = BORROW.get() if setting and address != MODE else None
        if borrow is not None and address not in borrow:
            # A motion's own setting (6081h profile velocity for a jog, 6098h for homing):
            # it is given back when the motion ends (issue "Motion safety" item 6), so it
            # is not a change the next "Save to EEPROM" would store behind the user's back.
            with contextlib.suppress(ObjectAccessError):
                old = await self.link.read(address)
            borrow[address] = (old, address in self.dirty)
        elif audit is not None and (spec is None or (spec.access.readable and not spec.process)):
            # The audit log records a parameter's value before the write (DESIGN: who, what,
            # old, new). Process objects (controlword, targets) skip the read: it would delay
            # every motion command, a halt included, by one SDO round trip.
            with contextlib.suppress(ObjectAccessError):
                old = await self.link.read(address)
        if address == CONTROLWORD:
            await self._space_controlword()
        await self.write_raw(address, data)
        if audit is not None:
            audit(self, address, old, data, client or "unknown")
        if address == CONTROLWORD:
            self._last_controlword_at = time.monotonic()
        if address == HEARTBEAT_TIME:
            self._heartbeat_ms = int.from_bytes(data[:2], "little")
        log.info("write %s %s = %s on %s", address, spec.name if spec else "?", data.hex(), self.id)
        if setting and borrow is None:
            self.dirty.add(address)
        if spec is not None and not spec.access.readable:
            return describe(address, spec, data)
        return await self.read_object(address)

    async def write_raw(self, address: ObjectAddress, data: bytes) -> None:
        """Write encoded bytes: by SDO, or through the RPDO output image when it carries them.

        An object that travels in an RPDO servodesk produces cannot be written by SDO: the
        next RPDO (applied at SYNC) would overwrite it. Its value goes into the output image
        instead, and the call returns once the drive has had it for two cycles.
        """
        cyclic = self.cyclic
        if cyclic is not None and cyclic.outputs and cyclic.carries(address):
            await cyclic.write_through(address, data)
        else:
            await self.link.write(address, data)

    async def read_many(self, addresses: list[ObjectAddress]) -> list[ObjectValue | ServodeskError]:
        """Read several objects; a failure is returned in its place, the rest go on. The link
        reads them (the PROFINET link packs up to 39 in one request); a link error (the bus is
        gone) ends the reads: the remaining ones would only time out too."""
        out: list[ObjectValue | ServodeskError] = []
        for a, raw in zip(addresses, await self.link.read_many(addresses), strict=True):
            if isinstance(raw, ServodeskError):
                out.append(raw)
                continue
            try:
                out.append(describe(a, self.profile.spec(a), raw))
            except ServodeskError as exc:
                out.append(exc)
        return out

    # Non-volatile memory ---------------------------------------------------------------------

    def _procedure(self, quirk: str, index: int, signature: int) -> tuple[ObjectAddress, int]:
        """The object and value of a store/restore: the profile's quirk, else CiA 301."""
        q = self.profile.quirk(quirk)
        if isinstance(q, dict) and "index" in q:
            return ObjectAddress(int(q["index"]), int(q.get("subindex", 1))), int(q["value"])
        address = ObjectAddress(index, 1)
        if self.profile.spec(address) is None:
            raise DriveStateError(
                f"profile {self.profile.id} has no {index:04X}h:01 and no {quirk} procedure",
                hint="see the family's manual for how it saves or resets parameters",
            )
        return address, signature

    async def store(self) -> dict[str, Any]:
        """Store the parameters in non-volatile memory (CiA 301 §7.5.2.13: 1010h <- "save")."""
        address, value = self._procedure("store_parameters", 0x1010, 0x65766173)
        expected = float(self.profile.quirk("store_parameters_duration_s", 0) or 0)
        q = self.profile.quirk("store_parameters")
        if isinstance(q, dict) and q.get("duration_s"):
            expected = float(q["duration_s"])
        dirty = len(self.dirty)
        t0 = time.monotonic()
        self._progress("store", 0.0, f"saving parameters ({address} <- 0x{value:08X})")
        # Some drives answer the SDO only when the save is done: allow the whole duration.
        # The drive's watchdog as the drive had it, not as servodesk armed it (links/base.py).
        async with self.link.watchdog_paused():
            await self.link.write(
                address, value.to_bytes(4, "little"), timeout=max(2.0, expected * 2)
            )
            # CiA 301: reading the store object gives 0 while it saves (HIWIN 000 §3.1 too).
            while True:
                try:
                    busy = (await self.link.read(address, timeout=1.0))[:1] == b"\x00"
                except ServodeskError:
                    busy = False
                elapsed = time.monotonic() - t0
                if not busy or elapsed > max(30.0, expected * 3):
                    break
                self._progress(
                    "store",
                    min(0.95, elapsed / expected) if expected else 0.5,
                    f"saving... {elapsed:.0f} s",
                )
                await asyncio.sleep(0.2)
        self.dirty.clear()
        duration = time.monotonic() - t0
        self._progress("store", 1.0, f"saved in {duration:.1f} s")
        self.hub.publish({"type": "sessions_changed"})
        return {
            "stored": dirty,
            "duration_s": round(duration, 3),
            "procedure": f"{address} <- 0x{value:08X}",
        }

    async def restore_defaults(self, reset: bool) -> dict[str, Any]:
        """Restore the default parameters (CiA 301 §7.5.2.14: 1011h <- "load")."""
        address, value = self._procedure("restore_defaults", 0x1011, 0x64616F6C)
        if reset and not self.link.sends_nmt:
            # Refused before the defaults are loaded: half of it would leave the drive with
            # defaults that apply at a reset nobody sends.
            raise ConflictError(
                f"the {self.link.fieldbus} link sends no NMT reset; nothing was restored",
                hint="restore without the reset, then reset the drive from its network's "
                "manager (or power-cycle it)",
            )
        await self.link.write(address, value.to_bytes(4, "little"), timeout=10.0)
        self.dirty.clear()
        if reset:
            # CiA 301: restored defaults apply after the next reset of the node.
            await self.link.nmt("reset")
            message = "defaults restored; the drive was reset and now uses them"
        else:
            message = "defaults restored; they apply after the next reset of the drive"
        self.hub.publish({"type": "sessions_changed"})
        return {"message": message}

    def _progress(self, operation: str, fraction: float, message: str) -> None:
        self.hub.publish(
            {
                "type": "progress",
                "session": self.id,
                "operation": operation,
                "fraction": round(fraction, 3),
                "message": message,
            },
            session=self.id,
        )

    async def _read_int(self, address: ObjectAddress, default_type: DataType) -> int | None:
        spec = self.profile.spec(address)
        if spec is None and self.profile.variables:
            return None
        raw = await self.link.read(address)
        v = codec(spec.data_type if spec else default_type).decode(raw)
        return int(v) if isinstance(v, int | bool) else None

    # CiA 402 state -------------------------------------------------------------------------

    async def _state_values(self) -> list[int | None]:
        """Statusword, mode display, position, velocity and error code. A statusword that
        cannot be read raises; the others are None then. A link that reads several objects in
        one request (PROFINET) reads them in one."""
        wanted = [
            (STATUSWORD, DataType.UNSIGNED16),
            (MODE_DISPLAY, DataType.INTEGER8),
            (POSITION, DataType.INTEGER32),
            (VELOCITY, DataType.INTEGER32),
            (ERROR_CODE, DataType.UNSIGNED16),
        ]
        if not getattr(self.link, "reads_many_at_once", False):
            sw = await self._read_int(*wanted[0])
            return [sw, *[await self._opt(a, dt) for a, dt in wanted[1:]]]
        # As _read_int: an object the profile lacks is not asked for.
        asked = [(a, dt) for a, dt in wanted if self.profile.spec(a) or not self.profile.variables]
        raws = dict(zip(asked, await self.link.read_many([a for a, _ in asked]), strict=True))
        out: list[int | None] = []
        for a, dt in wanted:
            raw = raws.get((a, dt))
            if isinstance(raw, ServodeskError):
                if a == STATUSWORD:
                    raise raw
                raw = None
            spec = self.profile.spec(a)
            v = codec(spec.data_type if spec else dt).decode(raw) if raw is not None else None
            out.append(int(v) if isinstance(v, int | bool) else None)
        return out

    async def drive_state(self) -> DriveState:
        sw, mode, pos, vel, err = await self._state_values()
        if sw is None:
            raise DriveStateError(
                f"profile {self.profile.id} has no statusword (6041h)",
                hint="this drive is not a CiA 402 axis",
            )
        state = cia402.decode_state(sw)
        error = None
        if err:
            entry = self.profile.error("error_code", err) or self.profile.error("emcy", err)
            error = (
                error_info(entry)
                if entry
                else {
                    "table": "error_code",
                    "code": err,
                    "code_hex": f"0x{err:04X}",
                    "display": None,
                    "name": "Unknown error code",
                    "kind": "fault",
                    "cause": None,
                    "remedy": None,
                    "section": None,
                }
            )
        pspec, vspec = self.profile.spec(POSITION), self.profile.spec(VELOCITY)
        return DriveState(
            state=state.value,
            statusword=sw,
            statusword_hex=f"0x{sw:04X}",
            bits=cia402.decode_statusword(sw, mode),
            mode=mode,
            mode_name=cia402.mode_name(mode) if mode is not None else None,
            position=pos,
            velocity=vel,
            position_unit=pspec.unit if pspec else None,
            velocity_unit=vspec.unit if vspec else None,
            position_eng=pos * pspec.scale if pspec and pos is not None and pspec.unit else None,
            velocity_eng=vel * vspec.scale if vspec and vel is not None and vspec.unit else None,
            position_raw_unit=pspec.raw_unit if pspec else None,
            velocity_raw_unit=vspec.raw_unit if vspec else None,
            error_code=err,
            error=error,
            nmt_state=await self.link.network_state(),
            time=time.time(),
        )

    async def _opt(self, address: ObjectAddress, dt: DataType) -> int | None:
        try:
            return await self._read_int(address, dt)
        except ServodeskError as exc:
            if isinstance(exc, LinkError):
                raise
            return None

    async def command(self, name: str) -> DriveState:
        """Run a state command or walk to a goal state (``enable``/``disable``)."""
        if name in GOALS:
            if GOALS[name] is cia402.State.OPERATION_ENABLED:
                await self._zero_targets()
            await self._walk(GOALS[name])
        elif name in COMMANDS:
            command = COMMANDS[name]
            if command not in _ALWAYS:
                await self._check_applies(command)
            await self._send(command)
            await asyncio.sleep(0.02)
        else:
            raise ValidationError(
                f"unknown state command {name!r}",
                field="command",
                hint=f"use one of {', '.join([*COMMANDS, *GOALS])}",
            )
        st = await self.drive_state()
        self._publish_state(st)
        return st

    async def _zero_targets(self) -> None:
        """Servo on must never start motion: clear velocity and torque targets first.

        In profile velocity or torque mode (CiA 402-2 §6.6, §6.7) the drive follows 60FFh /
        6071h as soon as it is enabled, so a target left over from an earlier jog would move
        the axis at once. Only done when the drive is not enabled yet.
        """
        sw = await self._read_int(STATUSWORD, DataType.UNSIGNED16)
        if cia402.decode_state(sw or 0) is cia402.State.OPERATION_ENABLED:
            return
        for address in _MOTION_TARGETS:
            spec = self.profile.spec(address)
            if spec is not None and spec.access.writable:
                with contextlib.suppress(ObjectAccessError):
                    await self.write_raw(address, bytes(spec.bits // 8))

    async def _check_applies(self, command: cia402.Command) -> None:
        """Refuse a command that has no transition from the present state (CiA 402-2 §6.2)."""
        sw = await self._read_int(STATUSWORD, DataType.UNSIGNED16)
        state = cia402.decode_state(sw or 0)
        # Would the drive react to these controlword bits? (The device's own table.)
        if cia402.device_transition(state, cia402.command_word(command), previous=0) is not None:
            return
        target = _COMMAND_TARGET.get(command)
        hint = None
        if target is not None:
            try:
                path = cia402.command_path(state, target)
                hint = f"send {path[0].value} first" if path else None
            except ValueError:
                hint = None
        if command is cia402.Command.FAULT_RESET:
            hint = "there is no fault to reset"
        raise DriveStateError(
            f"{command.value} does nothing in {state.value}", hint=hint or "see the state diagram"
        )

    async def _send(self, command: cia402.Command) -> None:
        if command is cia402.Command.FAULT_RESET:
            # CiA 402-2 §6.2.1: fault reset acts on the rising edge of bit 7.
            await self._write_controlword(0x0000)
        await self._write_controlword(cia402.command_word(command))

    async def _write_controlword(self, word: int) -> None:
        await self._space_controlword()
        await self.write_raw(CONTROLWORD, word.to_bytes(2, "little"))
        self._last_controlword_at = time.monotonic()

    async def _space_controlword(self) -> None:
        # Some drives ignore controlword changes that come too fast (quirk from the profile).
        gap_ms = self.profile.quirk("controlword_min_interval_ms", 0) or 0
        wait = self._last_controlword_at + gap_ms / 1000.0 - time.monotonic()
        if wait > 0:
            await asyncio.sleep(wait)

    async def _walk(self, target: cia402.State) -> None:
        for _ in range(8):
            sw = await self._read_int(STATUSWORD, DataType.UNSIGNED16)
            state = cia402.decode_state(sw or 0)
            if state == target:
                return
            try:
                path = cia402.command_path(state, target)
            except ValueError as exc:
                raise DriveStateError(str(exc)) from exc
            await self._send(path[0])
            if not await self._wait_change(state, timeout=1.0):
                raise DriveStateError(
                    f"the drive stayed in {state.value} after {path[0].value}",
                    hint="check the drive's enable inputs, safe torque off and error code",
                )
        raise DriveStateError(f"could not reach {target.value}")

    async def _wait_change(self, old: cia402.State, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            sw = await self._read_int(STATUSWORD, DataType.UNSIGNED16)
            if cia402.decode_state(sw or 0) != old:
                return True
            await asyncio.sleep(0.005)
        return False

    # Live updates ---------------------------------------------------------------------------

    def _publish_state(self, st: DriveState) -> None:
        self.last_state = st
        self.hub.publish({"type": "state", "session": self.id, **asdict(st)}, session=self.id)

    async def _poll(self) -> None:
        last_sent = 0.0
        while True:
            hz = self.poll_hz if self.hub.watchers(self.id) else 1.0
            await asyncio.sleep(1.0 / max(hz, self.min_poll_hz))
            self._check_heartbeat()
            try:
                st = await self.drive_state()
            except LinkError as exc:
                self._failures += 1
                if self._failures == 3 and self.connected:
                    self.connected = False
                    self.hub.publish(
                        {
                            "type": "link",
                            "session": self.id,
                            "event": "lost",
                            "message": exc.message,
                        },
                        session=self.id,
                    )
                    self.hub.publish({"type": "sessions_changed"})
                continue
            except ServodeskError:
                continue
            if not self.connected:
                self.connected = True
                self.hub.publish(
                    {
                        "type": "link",
                        "session": self.id,
                        "event": "restored",
                        "message": "the drive answers again",
                    },
                    session=self.id,
                )
                self.hub.publish({"type": "sessions_changed"})
            self._failures = 0
            for listener in list(self.state_listeners):
                listener(st)
            changed = self.last_state is None or st.key() != self.last_state.key()
            if changed or time.monotonic() - last_sent > 1.0:
                if self.last_state is None or st.state != self.last_state.state:
                    self.hub.publish({"type": "sessions_changed"})
                self._publish_state(st)
                last_sent = time.monotonic()

    def _on_link_event(self, ev: LinkEvent) -> None:
        # Called on a bus thread: hand over to the event loop.
        if self._loop is None:
            return
        self._loop.call_soon_threadsafe(self._handle_event, ev)

    def _handle_event(self, ev: LinkEvent) -> None:
        if ev.kind == "emcy":
            code = int(ev.data.get("code", 0))
            entry = self.profile.error("emcy", code) or self.profile.error("error_code", code)
            msg: dict[str, Any] = {
                "type": "emcy",
                "session": self.id,
                "code": code,
                "code_hex": f"0x{code:04X}",
                "register": ev.data.get("register", 0),
                "data": ev.data.get("data", ""),
                "time": ev.time,
                "name": entry.name
                if entry
                else ("Error reset / no error" if code == 0 else "Unknown error code"),
                "cause": entry.cause if entry else None,
                "remedy": entry.remedy if entry else None,
            }
            self.emcy_log.append(msg)
            self.hub.publish(msg, session=self.id)
        elif ev.kind == "nmt":
            self.hub.publish(
                {"type": "nmt", "session": self.id, "state": ev.data.get("state"), "time": ev.time},
                session=self.id,
            )
