"""The link contract: object access and process data, whatever the fieldbus.

Public methods do the shared work once (serialising access to one device, timeouts,
logging, error mapping, running blocking library calls off the event loop); a fieldbus
implements the small ``_`` hooks, which are plain blocking functions run in a worker thread.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.ethercat import OdObjectInfo
from servodesk.errors import (
    LinkClosedError,
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ServodeskError,
)

log = logging.getLogger(__name__)
T = TypeVar("T")

#: Controlword quick stop (CiA 402-2 §6.2.1, table 28: 0xxx x01xb): what every link's
#: :meth:`DriveLink.stop_frame` writes to 6040h.
QUICK_STOP_WORD = 0x0002


@dataclass(frozen=True, slots=True)
class LinkParams:
    """Where a drive is: python-can style bus options plus the node."""

    interface: str = "virtual"
    channel: str = "servodesk"
    bitrate: int | None = None
    node_id: int = 1
    #: Per-request timeout in seconds (SDO response time-out).
    timeout: float = 1.0
    extra: dict[str, Any] = field(default_factory=dict)

    def bus_key(self) -> tuple[str, str]:
        return (self.interface, self.channel)


@dataclass(frozen=True, slots=True)
class DriveIdentity:
    """Identity object (1018h) and names (1008h-100Ah) or the fieldbus equivalent."""

    vendor_id: int | None = None
    product_code: int | None = None
    revision: int | None = None
    serial: int | None = None
    device_name: str | None = None
    hardware_version: str | None = None
    software_version: str | None = None


@dataclass(frozen=True, slots=True)
class LinkEvent:
    """Something the device or the link reported, fanned out to the session.

    ``kind``: "emcy" (code, register, data), "nmt" (state), "heartbeat_lost",
    "link_lost", "link_restored".
    """

    kind: str
    time: float
    data: dict[str, Any] = field(default_factory=dict)


EventCallback = Callable[[LinkEvent], None]


@dataclass(frozen=True, slots=True)
class TrafficView:
    """What a bus carries, as a link counted it (links/can_traffic.py); None: not known."""

    frames_per_s: float
    load_percent: float | None
    #: What the numbers count, or why there is no load, in words.
    load_basis: str
    error_frames: int | None
    bus_state: str | None


class _Turn:
    """First-come, first-served access to one device, taken without awaiting when it is free.

    ``asyncio.Lock`` costs two coroutines and a wake-up scan per request even when nobody
    waits, which showed in the SDO round trip (bench/bench_sdo.py). Here a free turn is taken
    by a plain call; a busy one is queued and handed over directly by :meth:`give`, so a
    newcomer never overtakes a waiting request.
    """

    __slots__ = ("_held", "_queue")

    def __init__(self) -> None:
        self._held = False
        self._queue: deque[asyncio.Future[None]] = deque()

    def try_take(self) -> bool:
        if self._held:
            return False
        self._held = True
        return True

    async def take(self) -> None:
        if self.try_take():
            return
        turn: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._queue.append(turn)
        try:
            await turn
        except asyncio.CancelledError:
            if turn.done() and not turn.cancelled():
                self.give()  # Handed over just before the cancel: pass it on.
            else:
                with contextlib.suppress(ValueError):
                    self._queue.remove(turn)
            raise

    def give(self) -> None:
        queue = self._queue
        while queue:
            turn = queue.popleft()
            if not turn.done():  # A cancelled waiter is skipped.
                turn.set_result(None)  # The turn stays held: it passes to that waiter.
                return
        self._held = False


async def object_identity(access: ObjectAccess) -> DriveIdentity:
    """The identity object (1018h:01-04) and names (1008h-100Ah) read as objects, for links
    that reach the device's object dictionary (CANopen SDO, SLMP 4020h); a missing entry is
    None."""

    async def u32(index: int, sub: int) -> int | None:
        try:
            return int.from_bytes((await access.read(ObjectAddress(index, sub)))[:4], "little")
        except ObjectAccessError:
            return None

    async def text(index: int) -> str | None:
        try:
            v = codec(DataType.VISIBLE_STRING).decode(await access.read(ObjectAddress(index)))
            return str(v)
        except ObjectAccessError:
            return None

    return DriveIdentity(
        vendor_id=await u32(0x1018, 1),
        product_code=await u32(0x1018, 2),
        revision=await u32(0x1018, 3),
        serial=await u32(0x1018, 4),
        device_name=await text(0x1008),
        hardware_version=await text(0x1009),
        software_version=await text(0x100A),
    )


class ObjectAccess(ABC):
    """Read and write object dictionary entries as raw bytes."""

    @abstractmethod
    async def read(self, address: ObjectAddress, *, timeout: float | None = None) -> bytes: ...

    @abstractmethod
    async def write(
        self, address: ObjectAddress, data: bytes, *, timeout: float | None = None
    ) -> None: ...

    async def read_large(self, address: ObjectAddress, *, timeout: float | None = None) -> bytes:
        """Read an object expected to be large (a recording, a DOMAIN). A fieldbus with a
        transfer made for bulk data overrides this (CANopen: SDO block upload, docs/scope.md
        "Block upload"); elsewhere it is the plain read."""
        return await self.read(address, timeout=timeout)

    async def read_many(self, addresses: Sequence[ObjectAddress]) -> list[bytes | ServodeskError]:
        """Read several objects; a refused one yields its error in its place and the rest go
        on. A link error (no answer, the bus is gone) ends the reads: the remaining ones
        would only time out too. A fieldbus that reads several objects in one request (the
        PROFINET link) overrides this."""
        out: list[bytes | ServodeskError] = []
        for a in addresses:
            try:
                out.append(await self.read(a))
            except LinkError:
                raise
            except ServodeskError as exc:
                out.append(exc)
        return out

    async def write_many(
        self, items: Sequence[tuple[ObjectAddress, bytes]]
    ) -> list[ServodeskError | None]:
        out: list[ServodeskError | None] = []
        for a, d in items:
            try:
                await self.write(a, d)
                out.append(None)
            except ServodeskError as exc:
                out.append(exc)
        return out


class DriveLink(ObjectAccess):
    """A connection to one drive (node / slave / axis) on a fieldbus.

    Subclasses implement ``_open``, ``_close`` and either the blocking ``_read``/``_write``
    hooks (run in a worker thread) or the async ``_aread``/``_awrite`` hooks (run on the
    event loop, for links whose library lets them await an answer without a thread). Where
    the fieldbus has them, ``_nmt``, ``_identity`` and ``_network_state`` too. Public
    methods take this link's turn (first come, first served), so no two requests to one
    device overlap (an SDO answer, for one, does not say which request it answers).
    """

    #: Registry name, e.g. "canopen".
    fieldbus: str = ""
    #: Whether :meth:`nmt` sends network-management commands on this link.
    sends_nmt: bool = True

    # What this fieldbus's cyclic data offers and needs (services/pdo.py reads them; the
    # exchange itself is the link's ``cyclic_transport``, links/cyclic.py).
    #: How cyclic data may be synchronised: "freerun" (the drive's own cycle) everywhere,
    #: "dc" where distributed clocks fire the drive's SYNC0 (EtherCAT).
    sync_modes: tuple[str, ...] = ("freerun",)
    #: The NMT command that starts cyclic data with the outputs off. CiA 301's "start"
    #: (TPDOs come, RPDOs are not sent); EtherCAT's SAFE-OP, where an OP slave takes the
    #: outputs of every cycle (ETG.1000.6 §6.4).
    inputs_only_command: str = "start"
    #: Cyclic data always carries outputs: a PROFINET IO controller sends its setpoint
    #: telegram every cycle (IEC 61158-6-10); "inputs only" is the present values sent back.
    cyclic_outputs_always: bool = False
    #: The only cycles the link offers, in ms (PROFINET: send clock x reduction ratio);
    #: None: any period in services/cyclic.py's MIN_PERIOD..MAX_PERIOD.
    cyclic_periods_ms: tuple[float, ...] | None = None
    #: The link sets the telegram of cyclic data up itself when it starts (PROFINET: the
    #: expected submodule of servodesk's IO AR, as an IO controller's configuration tool
    #: does, 004 §20.1.1): services/pdo.py then offers the choice and calls
    #: :meth:`prepare_io`. Elsewhere the drive's PDO mapping says what is exchanged.
    sets_up_telegram: bool = False
    #: Resets of the drive this link has seen (CANopen: its boot-up message, CiA 301
    #: §7.3.2.1); a restore compares it before and after its writes (services/restore.py).
    #: A link that cannot see a reset keeps 0.
    resets_seen: int = 0

    def __init__(self, params: LinkParams) -> None:
        self.params = params
        self._lock = threading.Lock()
        self._turn = _Turn()
        self._closed = True
        self._callbacks: list[EventCallback] = []
        self.requests = 0
        self.failures = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._timeout: float | None = None

    def prepare_io(
        self,
        telegram: int | None,
        rx: int,
        tx: int,
        period: float,
        outputs: bool,
        first: bytes = b"",
    ) -> None:
        """What the next cyclic exchange carries, on a link that ``sets_up_telegram``: the
        telegram, the setpoint (``rx``) and actual-value (``tx``) lengths in bytes, the
        cycle [s], and the first outputs. Nothing to set up elsewhere."""

    # Lifecycle ---------------------------------------------------------------------

    #: Longest time opening a bus may take: some drivers reach out (a socketcand host name,
    #: a USB scan) and would otherwise wait for their own, much longer time-outs.
    OPEN_TIMEOUT = 5.0

    async def open(self) -> None:
        self._loop = asyncio.get_running_loop()
        opening = asyncio.ensure_future(self._call(self._open, check_open=False))
        try:
            await asyncio.wait_for(asyncio.shield(opening), self.OPEN_TIMEOUT)
        except TimeoutError:
            # The open goes on in its worker thread (a thread cannot be stopped). Should it
            # still succeed, what it opened is closed again: a late success must not hold a
            # shared bus or EtherCAT master for a link nobody has.
            opening.add_done_callback(self._close_late_open)
            raise NotFoundError(
                f"{self.fieldbus} interface {self.params.interface!r} channel "
                f"{self.params.channel!r} did not open within {self.OPEN_TIMEOUT:g} s",
                hint="check that the adapter or host exists and is reachable",
            ) from None
        self._closed = False

    def _close_late_open(self, opening: asyncio.Future[None]) -> None:
        if opening.cancelled() or opening.exception() is not None:
            return
        threading.Thread(target=self._close_locked, name="link-late-close", daemon=True).start()

    async def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        await asyncio.to_thread(self._close_locked)

    def _close_locked(self) -> None:
        with self._lock:
            self._close()

    @property
    def closed(self) -> bool:
        return self._closed

    async def __aenter__(self) -> DriveLink:
        await self.open()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # Object access -------------------------------------------------------------------

    async def read(self, address: ObjectAddress, *, timeout: float | None = None) -> bytes:
        """Read one object; ``timeout`` overrides the link's response time-out for this call."""
        return await self._acall(self._aread, address, timeout=timeout)

    async def write(
        self, address: ObjectAddress, data: bytes, *, timeout: float | None = None
    ) -> None:
        """Write one object; ``timeout`` is for slow ones (a parameter save can take seconds)."""
        await self._acall(self._awrite, address, bytes(data), timeout=timeout)

    @property
    def request_timeout(self) -> float:
        """The response time-out of the request in progress."""
        return self._timeout if self._timeout is not None else self.params.timeout

    async def identity(self) -> DriveIdentity:
        """Identity of the device; a missing entry is None, not an error."""
        return await self._call(self._identity)

    async def nmt(self, command: str) -> None:
        """Send a network-management command: start, stop, preop, reset, reset_comm."""
        await self._call(self._nmt, command)

    async def network_state(self) -> str:
        return await self._call(self._network_state)

    def heartbeat_age(self) -> float | None:
        """Seconds since the device's last heartbeat, or None when none was seen."""
        return None

    def bus_traffic(self) -> TrafficView | None:
        """What the bus carries, from counts the link keeps anyway (links/can_traffic.py);
        None where this link counts none (the status bar says "not reported")."""
        return None

    async def object_list(self) -> tuple[OdObjectInfo, ...] | None:
        """The device's object dictionary as it describes it itself (EtherCAT's CoE SDO
        Information, ETG.1000.6 §5.6.3), or None where the device or this fieldbus offers no
        such service (services/manager.py then takes the fieldbus's generic profile)."""
        return None

    async def arm_watchdog(self) -> str | None:
        """Arm the drive's own watchdog on servodesk's sign of life, so that a dead PC stops
        the axis without servodesk; a sentence naming it for people, or None where this link
        arms none (then only servodesk's dead-man stops the axis)."""
        return None

    async def disarm_watchdog(self) -> None:
        """Put back what :meth:`arm_watchdog` changed."""

    @property
    def watchdog(self) -> str | None:
        """The sentence :meth:`arm_watchdog` returned while it is armed, else None."""
        return None

    @contextlib.asynccontextmanager
    async def watchdog_paused(self) -> AsyncIterator[None]:
        """The drive's own settings in place for a store (the arming must not be saved)."""
        yield

    def stop_frame(self) -> Callable[[], None] | None:
        """A function that puts a quick stop (controlword 6040h = 0002h, CiA 402-2 §6.2.1
        table 28) on the wire without the event loop, safe to call from any thread; None
        where this fieldbus has no such path (the stop then goes through the loop).

        The dead-man's thread (services/deadman.py) calls it when the heartbeats stop, so a
        held event loop does not delay the stop. It is fire-and-forget: the loop sends the
        orderly stop through the link afterwards and sees the drive's answer there."""
        return None

    # Events -----------------------------------------------------------------------------

    def add_event_callback(self, cb: EventCallback) -> None:
        """``cb`` is called from a bus thread; it must not block."""
        self._callbacks.append(cb)

    def remove_event_callback(self, cb: EventCallback) -> None:
        if cb in self._callbacks:
            self._callbacks.remove(cb)

    def _emit(self, kind: str, **data: Any) -> None:
        ev = LinkEvent(kind, time.time(), data)
        for cb in list(self._callbacks):
            try:
                cb(ev)
            except Exception:  # A subscriber's bug must not stop bus processing.
                log.exception("event callback failed for %s", kind)

    @contextlib.asynccontextmanager
    async def exclusive(self) -> AsyncIterator[None]:
        """Hold this link's turn: none of servodesk's requests (the session's status poll
        among them) goes to the device until the block ends. For another master that must
        talk to the same device meanwhile: an SDO server channel serves one client (CiA 301),
        and its answer does not say which request it answers."""
        await self._turn.take()
        try:
            yield
        finally:
            self._turn.give()

    # Shared machinery ----------------------------------------------------------------

    async def _call(self, fn: Callable[..., T], *args: Any, check_open: bool = True) -> T:
        if check_open and self._closed:
            raise LinkClosedError("the link is closed", hint="open the session again")
        # The turn queues callers fairly without holding threads; the thread lock guards
        # against callers from other loops or threads.
        turn = self._turn
        if not turn.try_take():
            await turn.take()
        try:
            return await asyncio.to_thread(self._locked, fn, *args)
        finally:
            turn.give()

    async def _acall(
        self, fn: Callable[..., Awaitable[T]], *args: Any, timeout: float | None = None
    ) -> T:
        """Run an async hook under the link's turn with the shared error mapping.

        This is every read and write, so it is written out flat: the turn is taken without
        an await when the link is idle, and the accounting of :meth:`_counted` is inline
        (the same :meth:`_failure`).
        """
        if self._closed:
            raise LinkClosedError("the link is closed", hint="open the session again")
        turn = self._turn
        if not turn.try_take():
            await turn.take()
        try:
            if self._closed:  # Closed while this request queued behind another.
                raise LinkClosedError("the link is closed", hint="open the session again")
            self._timeout = timeout  # Safe: requests to one link never overlap (the turn).
            self.requests += 1
            try:
                return await fn(*args)
            except Exception as exc:
                error = self._failure(exc)
                if error is exc:
                    raise
                raise error from exc
        finally:
            self._timeout = None
            turn.give()

    def _locked(self, fn: Callable[..., T], *args: Any) -> T:
        with self._lock, self._counted():
            return fn(*args)

    @contextlib.contextmanager
    def _counted(self) -> Iterator[None]:
        """Count a request and map library failures into the servodesk error tree."""
        self.requests += 1
        try:
            yield
        except Exception as exc:
            error = self._failure(exc)
            if error is exc:
                raise
            raise error from exc

    def _failure(self, exc: Exception) -> Exception:
        """Count a failed request; the error to raise, mapped into the servodesk tree.

        Servodesk errors pass as they are; a time-out or an OS error of the library becomes
        a link error; anything else (a bug) passes uncounted.
        """
        if isinstance(exc, ServodeskError):
            self.failures += 1
            return exc
        if isinstance(exc, TimeoutError):
            self.failures += 1
            return LinkTimeoutError(f"no answer from the device: {exc}")
        if isinstance(exc, OSError):
            self.failures += 1
            return LinkError(f"bus error: {exc}")
        return exc

    # Hooks ---------------------------------------------------------------------------

    @abstractmethod
    def _open(self) -> None: ...

    @abstractmethod
    def _close(self) -> None: ...

    async def _aread(self, address: ObjectAddress) -> bytes:
        return await asyncio.to_thread(self._locked_hook, self._read, address)

    async def _awrite(self, address: ObjectAddress, data: bytes) -> None:
        await asyncio.to_thread(self._locked_hook, self._write, address, data)

    def _locked_hook(self, fn: Callable[..., T], *args: Any) -> T:
        with self._lock:
            return fn(*args)

    def _read(self, address: ObjectAddress) -> bytes:
        raise NotImplementedError(f"{type(self).__name__} implements neither _read nor _aread")

    def _write(self, address: ObjectAddress, data: bytes) -> None:
        raise NotImplementedError(f"{type(self).__name__} implements neither _write nor _awrite")

    def _identity(self) -> DriveIdentity:
        return DriveIdentity()

    def _nmt(self, command: str) -> None:
        raise LinkError(f"{self.fieldbus} has no network management command {command!r}")

    def _network_state(self) -> str:
        return "unknown"
