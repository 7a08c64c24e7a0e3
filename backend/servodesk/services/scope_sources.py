"""Where the live scope's samples come from (docs/scope.md "Sources"): the cyclic PDOs
(:class:`PdoSource`, stamped in the exchange's thread), SDO polling (:class:`SdoSource`) and
the drive's state for the trigger (:class:`StateWatch`). The drive-side recorder is
scope_recorder.py."""

from __future__ import annotations

import asyncio
import collections
import contextlib
import logging
import time
from typing import TYPE_CHECKING

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import Value, codec
from servodesk.errors import (
    LinkError,
    ServodeskError,
)
from servodesk.links.base import LinkEvent

if TYPE_CHECKING:
    from servodesk.services.cyclic import CyclicExchange, SampleListener
    from servodesk.services.session import Session

from servodesk.services.scope_channels import (
    CLOCK_TOLERANCE_S,
    STATE_POLL_HZ,
    STATUSWORD,
    SampleBuffer,
    ScopeChannel,
    as_number,
)

log = logging.getLogger(__name__)


def tpdo_addresses(session: Session) -> set[ObjectAddress]:
    """Objects the session's running cyclic exchange receives in its active TPDOs."""
    ex = session.cyclic
    if ex is None or not ex.running:
        return set()
    return {a for ch in ex.tx for a in ch.addresses}


# Sources -----------------------------------------------------------------------------------


class PdoSource:
    """The cyclic exchange's TPDOs of one session, for that session's ``pdo`` channels.

    Its listener runs in the exchange's thread, inside the bus cycle (on EtherCAT the line's
    one cycle thread, for every slave and cycle): it only stamps the frame and queues it
    (one deque append). :meth:`flush`, called by the scope's producer on the event loop,
    puts the queued frames' values into the channels' buffers, one column per channel
    (docs/scope.md "EtherCAT and PROFINET cyclic channels": 15 µs a frame in the cycle
    thread before, with 8 channels, against 1-2 µs now).
    """

    def __init__(self, session: Session, channels: list[ScopeChannel]) -> None:
        self.session = session
        self.channels = channels
        self.exchange: CyclicExchange | None = None
        # Buffers by address (two channels may show one object, e.g. with other scales).
        self._index: dict[ObjectAddress, list[SampleBuffer]] = {}
        for ch in channels:
            self._index.setdefault(ch.address, []).append(ch.buffer)
        #: Frames taken in the exchange's thread, not yet in the buffers: (time, the TPDO's
        #: addresses, its values).
        self._pending: collections.deque[tuple[float, list[ObjectAddress], tuple[Value, ...]]]
        self._pending = collections.deque()
        # The exchange hands over the same address list with every frame of a TPDO (kept
        # alive by it): its columns for these channels are found once per list, by identity
        # (the list kept with them, so that a freed list's id never maps another's columns).
        self._columns: dict[
            int, tuple[list[ObjectAddress], list[tuple[int, list[SampleBuffer]]]]
        ] = {}
        self._listener = self._make_listener()

    def _make_listener(self) -> SampleListener:
        pending = self._pending
        tolerance = CLOCK_TOLERANCE_S

        def on_sample(
            timestamp: float, addresses: list[ObjectAddress], values: tuple[Value, ...]
        ) -> None:
            # The frame's bus timestamp is the sample's time when it is on the backend's
            # clock (python-can's virtual and UDP buses, socketcan); an adapter counting
            # from its own epoch, and the EtherCAT and PROFINET IO threads (monotonic
            # clock), get the reception time instead.
            now = time.time()
            pending.append(
                (timestamp if abs(now - timestamp) < tolerance else now, addresses, values)
            )

        return on_sample

    def _columns_of(self, addresses: list[ObjectAddress]) -> list[tuple[int, list[SampleBuffer]]]:
        known = self._columns.get(id(addresses))
        if known is not None and known[0] is addresses:
            return known[1]
        cols = [(i, self._index[a]) for i, a in enumerate(addresses) if a in self._index]
        self._columns[id(addresses)] = (addresses, cols)
        return cols

    def flush(self) -> None:
        """Move the queued frames into the channels' buffers (the producer, event loop)."""
        pending = self._pending
        n = len(pending)
        if not n:
            return
        # Frames of one TPDO together, in the order they came (one source per channel).
        groups: dict[int, tuple[list[ObjectAddress], list[float], list[tuple[Value, ...]]]] = {}
        for _ in range(n):
            t, addresses, values = pending.popleft()
            g = groups.get(id(addresses))
            if g is None:
                g = groups[id(addresses)] = (addresses, [], [])
            g[1].append(t)
            g[2].append(values)
        for addresses, times, rows in groups.values():
            for col, bufs in self._columns_of(addresses):
                if isinstance(rows[0][col], str | bytes):
                    continue  # Not a number: nothing to plot (a mapped object's type is fixed).
                column = [float(row[col]) for row in rows]
                for buf in bufs:
                    buf.add_many(times, column)

    def attach(self) -> bool:
        """Listen to the session's present exchange; False when cyclic data does not run."""
        ex = self.session.cyclic
        if ex is self.exchange and ex is not None and ex.running:
            return True
        self.detach()
        if ex is None or not ex.running:
            return False
        self.flush()
        self._columns.clear()  # A new exchange has its own address lists.
        self._listener = self._make_listener()
        ex.add_listener(self._listener)
        self.exchange = ex
        return True

    def detach(self) -> None:
        ex = self.exchange
        if ex is not None:
            ex.remove_listener(self._listener)
        self.exchange = None

    def check(self) -> None:
        """Follow a restart of cyclic data; mark the channels when it stopped."""
        ok = self.attach()
        mapped = tpdo_addresses(self.session) if ok else set()
        for ch in self.channels:
            if not ok:
                ch.error = "cyclic data stopped: start it on the PDO page (no samples meanwhile)"
            elif ch.address not in mapped:
                ch.error = f"{ch.address} is no longer in an active TPDO"
            elif ch.error is not None and ch.error.startswith(("cyclic", "0x")):
                ch.error = None


class SdoSource:
    """One polling task per session: its ``sdo`` channels read in turn."""

    def __init__(self, session: Session, channels: list[ScopeChannel]) -> None:
        self.session = session
        self.channels = channels
        self.task: asyncio.Task[None] | None = None

    def start(self) -> None:
        self.task = asyncio.get_running_loop().create_task(
            self._run(), name=f"scope sdo {self.session.id}"
        )

    async def stop(self) -> None:
        if self.task is not None:
            self.task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.task
            self.task = None

    async def _run(self) -> None:
        link = self.session.link
        decoders = [codec(ch.spec.data_type).decode for ch in self.channels]
        due = [0.0] * len(self.channels)
        periods = [
            1.0 / ch.config.rate_hz if ch.config.rate_hz > 0 else 0.0 for ch in self.channels
        ]
        # A link that reads several objects in one request (PROFINET: one PROFIdrive request
        # of up to 39 parameters) samples the due channels together, at one time stamp;
        # the others read them in turn, each stamped when its answer arrived.
        together = bool(getattr(link, "reads_many_at_once", False))

        def sampled(i: int, raw: bytes | ServodeskError, t: float) -> None:
            ch = self.channels[i]
            if isinstance(raw, ServodeskError):
                ch.error = raw.message
                due[i] = time.monotonic() + 1.0
                return
            v = as_number(decoders[i](raw))
            if v is not None:
                ch.buffer.add(t, v)
                ch.error = None
            if periods[i]:
                # Keep the requested rhythm; after a stall start again from now.
                due[i] = max(due[i] + periods[i], time.monotonic() - periods[i])

        while True:
            now = time.monotonic()
            ready = [i for i in range(len(self.channels)) if due[i] <= now]
            waited = not ready
            try:
                if together and ready:
                    raws = await link.read_many([self.channels[i].address for i in ready])
                    t = time.time()
                    for i, got in zip(ready, raws, strict=True):
                        sampled(i, got, t)
                else:
                    for i in ready:
                        one: bytes | ServodeskError
                        try:
                            one = await link.read(self.channels[i].address)
                        except LinkError:
                            raise
                        except ServodeskError as exc:
                            one = exc
                        # The sample's time: when its answer arrived.
                        sampled(i, one, time.time())
            except LinkError as exc:
                for i in ready:
                    self.channels[i].error = exc.message
                await asyncio.sleep(0.2)  # The bus is gone or busy: do not spin.
                continue
            if waited:
                wait = min(due) - time.monotonic()
                await asyncio.sleep(max(wait, 0.0005))
            else:
                # Let the session's own poll and other requests have the link in between.
                await asyncio.sleep(0)


class StateWatch:
    """The CiA 402 state of the trigger channel's session, for state and fault triggers.

    Its own statusword poll (one SDO read per period, far less than the session's full
    state poll) gives each change the time its answer arrived; EMCY messages (CiA 301
    §7.2.7) count as faults at the time the link received them.
    """

    def __init__(self, session: Session, kind: str, events: collections.deque[float]) -> None:
        self.session = session
        self.kind = kind
        self.events = events
        self.task: asyncio.Task[None] | None = None
        self.state: str | None = None

    def start(self) -> None:
        self.task = asyncio.get_running_loop().create_task(
            self._run(), name=f"scope state {self.session.id}"
        )
        if self.kind == "fault":
            self.session.link.add_event_callback(self._on_event)

    async def stop(self) -> None:
        self.session.link.remove_event_callback(self._on_event)
        if self.task is not None:
            self.task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.task
            self.task = None

    def _on_event(self, ev: LinkEvent) -> None:
        # Bus thread. An EMCY with error code 0000h is "error reset / no error", not a fault.
        if ev.kind == "emcy" and int(ev.data.get("code", 0)):
            self.events.append(ev.time)

    async def _run(self) -> None:
        link = self.session.link
        period = 1.0 / STATE_POLL_HZ
        while True:
            try:
                raw = await link.read(STATUSWORD)
            except ServodeskError:
                await asyncio.sleep(0.1)
                continue
            t = time.time()
            state = cia402.decode_state(int.from_bytes(raw[:2], "little")).value
            prev, self.state = self.state, state
            changed = prev is not None and state != prev
            if changed and (self.kind == "state" or state == cia402.State.FAULT.value):
                self.events.append(t)
            await asyncio.sleep(period)
