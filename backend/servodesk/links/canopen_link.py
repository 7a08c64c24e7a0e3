"""CANopen link: a canopen ``RemoteNode`` on any python-can interface.

One canopen ``Network`` (one python-can bus and its notifier thread) is shared by every link
on the same interface and channel, reference-counted, because most adapters can be opened
only once. canopen handles NMT, heartbeat, EMCY and the bus scan; object access uses
servodesk's asyncio SDO client (expedited, segmented and block upload, frames from
:mod:`servodesk.domain.sdo` and :mod:`servodesk.domain.sdo_block`), because awaiting the
answer on the event loop is as fast as a plain blocking canopen loop while a thread hand-over
per request costs 40 %. Abort codes become :class:`ObjectAccessError` with the CiA 301 text.

Over 700 lines: the shared canopen network (one python-can bus per channel, reference-counted,
with servodesk's heartbeat) and the link over it share the bus's lifetime; the SDO protocol
itself is in domain/sdo.py and domain/sdo_block.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import os
import sys
import threading
import time
from collections import deque
from collections.abc import AsyncIterator, Callable
from typing import Any

import can
import canopen

from servodesk.domain import sdo, sdo_block
from servodesk.domain.address import ObjectAddress
from servodesk.domain.sdo_abort import abort_error
from servodesk.errors import (
    LinkClosedError,
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.links.base import (
    QUICK_STOP_WORD,
    DriveIdentity,
    DriveLink,
    LinkParams,
    TrafficView,
    object_identity,
)
from servodesk.links.can_traffic import BusTraffic

log = logging.getLogger(__name__)

# canopen's NMT state names, by the commands of DriveLink.nmt().
_NMT_COMMANDS = {
    "start": "OPERATIONAL",
    "stop": "STOPPED",
    "preop": "PRE-OPERATIONAL",
    "reset": "RESET",
    "reset_comm": "RESET COMMUNICATION",
}
_NMT_STATE_NAMES = {
    "OPERATIONAL": "operational",
    "PRE-OPERATIONAL": "preop",
    "STOPPED": "stopped",
    "INITIALISING": "initialising",
}


class _SharedNetwork:
    """A canopen Network with a reference count."""

    def __init__(self, network: canopen.Network, traffic: BusTraffic) -> None:
        self.network = network
        self.traffic = traffic
        self.users = 0
        #: servodesk's own heartbeat (COB-ID 700h + MASTER_NODE_ID) and how many links use it.
        self.heartbeat: Any = None
        self.heartbeat_users = 0


class NetworkPool:
    """Opens each (interface, channel) once and shares it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._nets: dict[tuple[str, str], _SharedNetwork] = {}

    def acquire(self, params: LinkParams) -> canopen.Network:
        key = params.bus_key()
        with self._lock:
            shared = self._nets.get(key)
            if shared is None:
                if params.interface not in can.interfaces.VALID_INTERFACES:
                    known = ", ".join(sorted(can.interfaces.VALID_INTERFACES))
                    raise ValidationError(
                        f"unknown CAN interface {params.interface!r}",
                        field="interface",
                        hint=f"python-can interfaces: {known}",
                    )
                network = canopen.Network()
                # Disconnecting waits for the notifier's receive to time out (canopen's default
                # 1 s made every session close take a second); a busy bus is not affected.
                network.NOTIFIER_CYCLE = 0.05
                kwargs: dict[str, Any] = {"interface": params.interface, "channel": params.channel}
                if params.bitrate:
                    kwargs["bitrate"] = params.bitrate
                kwargs.update(params.extra)
                try:
                    network.connect(**kwargs)
                except Exception as exc:  # python-can raises many types per backend.
                    raise NotFoundError(
                        f"cannot open CAN interface {params.interface!r} channel "
                        f"{params.channel!r}: {exc}",
                        hint="check the interface name, channel and that the adapter is present",
                    ) from exc
                # The status bar's counts (links/can_traffic.py): the frames the notifier
                # already receives, no traffic of its own.
                traffic = BusTraffic(params.interface, params.bitrate)
                if network.notifier is not None:
                    network.notifier.add_listener(traffic)
                shared = _SharedNetwork(network, traffic)
                self._nets[key] = shared
            shared.users += 1
            return shared.network

    def start_heartbeat(self, params: LinkParams) -> None:
        """servodesk produces a heartbeat on this bus (CiA 301 §7.2.8.3.2.2: NMT state
        operational, 05h) for the drives whose consumer (1016h) it arms. python-can sends it
        periodically on its own (a kernel task on SocketCAN, a thread elsewhere): it goes on
        while the process lives, whatever its event loop does, and ends with it."""
        with self._lock:
            shared = self._nets[params.bus_key()]
            if shared.heartbeat is None:
                msg = can.Message(
                    arbitration_id=0x700 + MASTER_NODE_ID, data=[0x05], is_extended_id=False
                )
                bus = shared.network.bus
                if bus is None:
                    raise LinkError("the CAN bus is not connected")
                shared.heartbeat = bus.send_periodic(msg, HEARTBEAT_PERIOD_S)
            shared.heartbeat_users += 1

    def stop_heartbeat(self, params: LinkParams) -> None:
        with self._lock:
            shared = self._nets.get(params.bus_key())
            if shared is None or shared.heartbeat is None:
                return
            shared.heartbeat_users -= 1
            if shared.heartbeat_users <= 0:
                shared.heartbeat.stop()
                shared.heartbeat, shared.heartbeat_users = None, 0

    def traffic(self, params: LinkParams) -> TrafficView | None:
        """What the bus of ``params`` carries (None: not open)."""
        with self._lock:
            shared = self._nets.get(params.bus_key())
        if shared is None:
            return None
        return shared.traffic.view(shared.network.bus)

    def producing(self, params: LinkParams) -> bool:
        with self._lock:
            shared = self._nets.get(params.bus_key())
            return shared is not None and shared.heartbeat is not None

    def release(self, params: LinkParams) -> None:
        key = params.bus_key()
        with self._lock:
            shared = self._nets.get(key)
            if shared is None:
                return
            shared.users -= 1
            if shared.users <= 0:
                del self._nets[key]
                if shared.heartbeat is not None:
                    shared.heartbeat.stop()
                try:
                    shared.network.disconnect()
                except Exception:  # Closing a dead adapter must not mask the caller's error.
                    log.exception("disconnecting %s", key)


pool = NetworkPool()


#: servodesk's node id as a heartbeat producer (CiA 301 allows 1-127; the top one, where
#: commissioning masters usually sit, keeps the drives' range free). The bus scan does not
#: list it while servodesk produces on that bus.
MASTER_NODE_ID = 0x7F
HEARTBEAT_PERIOD_S = 0.1
#: The drives' consumer time: ten periods. A drive-side backup for a dead PC (servodesk's own
#: dead-man stops a lost client within 250 ms), so it must never fire while servodesk lives:
#: at 400 ms a twin on a loaded 2-core machine saw a lapse and quick-stopped a tuning.
CONSUMER_TIME_MS = 1000
CONSUMER = ObjectAddress(0x1016, 1)

#: Longest upload accepted (a DOMAIN could be larger; servodesk does not read those).
_MAX_SEGMENTED = 1 << 20
#: Block upload (CiA 301 §7.2.4.3.9-§7.2.4.3.12, docs/scope.md "Block upload"): used for
#: :meth:`CanopenLink.read_large` (the drive-side recorder's data) and for any object whose
#: segmented upload announced more than this many bytes (DOMAIN and string objects, learnt
#: per link on their first read). It is also the request's pst: a server may answer an object
#: of at most this size with the normal upload (§7.2.4.3.9). Round trips: segmented
#: 1 + ceil(n / 7), block 3 + ceil(n / 889) (initiate, one per sub-block of 127 segments,
#: end); block wins from 15 bytes, and 32 keeps the short strings (1008h-100Ah on most
#: drives) on the protocol every server has.
BLOCK_THRESHOLD = 32
#: Segments per sub-block asked for: the most (127 x 7 = 889 bytes per acknowledgement).
BLOCK_SIZE = 127
#: Aborts of a block initiate after which the same object is read by segmented upload: the
#: server does not do block transfers (0504 0001h, the one certain refusal), or refuses this
#: one (block size, memory, access, a general error). Any other abort is the object's own
#: answer (no such object, write-only, ...) and is raised as it is.
_BLOCK_REFUSALS = frozenset({0x05040001, 0x05040002, 0x05040005, 0x06010000, 0x08000000})
#: The abort code of a block upload the link ends itself (cancelled): general error.
_ABORT_GENERAL = 0x08000000
#: Time-outs in a row, with nothing received in between, after which a block upload gives up.
_BLOCK_SILENCES = 3
#: Heartbeats read this soon after an NMT command may predate it (see _on_heartbeat).
HEARTBEAT_STALE_S = 0.05
#: The scs bits of a download's answer (CiA 301 §7.2.4.3.3: initiate download response,
#: scs = 3).
DOWNLOAD_ANSWER = 0x60


class _Doorbell:
    """Hands SDO answers from the bus thread to the event loop through an eventfd it watches.

    ``call_soon_threadsafe`` wakes the loop through its self-pipe, which costs a handle per
    answer and, on the loop side, two reads of which one raises: with answers looped back
    at once, a read cost 24 us of CPU that way and 20.5 us this way. Here the bus thread
    queues the frame and bumps an eventfd; the loop reads it once and delivers. Linux only
    (``attach`` returns None elsewhere and on loops without ``add_reader``).
    """

    _ONE = (1).to_bytes(8, sys.byteorder)

    def __init__(
        self, loop: asyncio.AbstractEventLoop, fd: int, deliver: Callable[[bytes], None]
    ) -> None:
        self._loop = loop
        self._fd = fd
        self._deliver = deliver
        self._frames: deque[bytes] = deque()
        # Held while writing and while closing, so the bus thread never writes to a closed
        # (and possibly reused) descriptor.
        self._lock = threading.Lock()

    @classmethod
    def attach(
        cls, loop: asyncio.AbstractEventLoop, deliver: Callable[[bytes], None]
    ) -> _Doorbell | None:
        if sys.platform != "linux":
            return None
        fd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
        bell = cls(loop, fd, deliver)
        try:
            loop.add_reader(fd, bell._ring)
        except NotImplementedError:  # A loop without readers (Windows' proactor).
            os.close(fd)
            return None
        return bell

    def post(self, frame: bytes) -> None:
        """From the bus thread."""
        self._frames.append(frame)
        with self._lock:
            if self._fd >= 0:
                with contextlib.suppress(BlockingIOError):  # Counter full: a wake is due.
                    os.write(self._fd, self._ONE)

    def _ring(self) -> None:
        with contextlib.suppress(OSError):  # Nothing to read, or closed since scheduled.
            os.read(self._fd, 8)
        frames = self._frames
        while frames:
            self._deliver(frames.popleft())

    def close(self) -> None:
        """On the loop's thread (or after the loop has closed)."""
        with self._lock:
            fd, self._fd = self._fd, -1
            if fd < 0:
                return
            self._loop.remove_reader(fd)  # A no-op on a closed loop.
            os.close(fd)


def _closed_while_waiting() -> LinkClosedError:
    """The link was closed (the session ended) while a transfer waited for the drive."""
    return LinkClosedError(
        "the link was closed while a request waited for the drive's answer",
        hint="open the session again",
    )


class CanopenLink(DriveLink):
    """A CiA 301 node on a CAN bus, accessed as an SDO client."""

    fieldbus = "canopen"

    def __init__(self, params: LinkParams) -> None:
        if not 1 <= params.node_id <= 127:
            raise ValidationError(
                f"node id {params.node_id} is outside 1..127",
                field="node_id",
                hint="CANopen node ids are 1 to 127",
            )
        super().__init__(params)
        self._network: canopen.Network | None = None
        self._node: canopen.RemoteNode | None = None
        self._waiter: asyncio.Future[bytes] | None = None
        #: Answers that arrived while the waiter already held one the request has not yet
        #: looked at (a stale answer ahead of the real one, both in one doorbell ring).
        self._unread: deque[bytes] = deque()
        #: Answers still owed to initiate requests that ended without theirs (cancelled on
        #: the bus, or timed out): (multiplexor, answer kind, loop time it is no longer
        #: expected). See :meth:`_pay`.
        self._owed: list[tuple[bytes, int, float]] = []
        self._doorbell: _Doorbell | None = None
        self._watchdog: asyncio.Handle | None = None
        #: When the armed watchdog fires (loop time). Kept here, not read from the handle:
        #: uvloop's call_at of a time already past returns a plain Handle, without when().
        self._watchdog_at = 0.0
        self._deadline = 0.0
        self.last_heartbeat: float | None = None
        self.nmt_state: str = "unknown"
        #: The drive's 1016h:01 before servodesk armed it (None: not armed).
        self._watchdog_original: bytes | None = None
        self._watchdog_text: str | None = None
        #: When servodesk last commanded an NMT state (monotonic), see _on_heartbeat.
        self._nmt_commanded_at = -math.inf
        #: Block upload for large reads (False: segmented only, e.g. a benchmark's baseline).
        self.block_upload = True
        #: The node refused a block upload and served the segmented one (asked once per link).
        self.block_refused = False
        #: Objects whose upload was longer than BLOCK_THRESHOLD: read by block upload.
        self._large: set[ObjectAddress] = set()
        #: SDO frames this link sent and received (requests, answers, block segments), for
        #: the bus load a benchmark reports.
        self.sdo_frames_tx = 0
        self.sdo_frames_rx = 0
        #: Block segments dropped (out of order, or after a gap) and sent again by the server;
        #: sub-blocks ended by the response time-out (their tail lost).
        self.block_resent = 0
        self.block_timeouts = 0

    # Hooks -------------------------------------------------------------------------

    def _open(self) -> None:
        network = pool.acquire(self.params)
        try:
            node = canopen.RemoteNode(self.params.node_id, canopen.ObjectDictionary())
            node.sdo.RESPONSE_TIMEOUT = self.params.timeout
            if self.params.node_id in network:
                raise LinkError(
                    f"node {self.params.node_id} on {self.params.channel} is already open",
                    hint="close the other session first",
                )
            network.add_node(node)
            # servodesk's own SDO client answers on this COB-ID; canopen's would queue every
            # answer forever, so it is taken off the subscription.
            network.unsubscribe(0x580 + self.params.node_id, node.sdo.on_response)
            network.subscribe(0x580 + self.params.node_id, self._on_sdo_frame)
        except Exception:
            pool.release(self.params)
            raise
        node.nmt.add_heartbeat_callback(self._on_heartbeat)
        node.emcy.add_callback(self._on_emcy)
        self._network, self._node = network, node

    def _close(self) -> None:
        network, node = self._network, self._node
        self._network = self._node = None
        if self._watchdog_original is not None:
            # Closed while armed (the session's close writes the entry back first): the
            # heartbeat it asked for ends with it.
            self._watchdog_original = self._watchdog_text = None
            pool.stop_heartbeat(self.params)
        if network is not None and node is not None:
            network.unsubscribe(0x580 + self.params.node_id, self._on_sdo_frame)
            # Give canopen back its own subscription so that remove_network() can drop it.
            network.subscribe(0x580 + self.params.node_id, node.sdo.on_response)
            node.remove_network()
            network.pop(node.id, None)
            pool.release(self.params)

    @property
    def network(self) -> canopen.Network:
        """The canopen Network this link's node is on (for PDO and SYNC work).

        It is shared with every other link on the same interface and channel, so callers
        must not disconnect it; the link's own SDO answers are not routed through canopen.
        """
        network = self._network
        if network is None:
            raise LinkError("the CANopen link is not open")
        return network

    def _require(self) -> canopen.RemoteNode:
        if self._node is None:
            raise LinkError("the CANopen link is not open")
        return self._node

    # SDO client (CiA 301 §7.2.4): frames from servodesk.domain.sdo, sent from the event
    # loop; the answer comes back from canopen's bus thread through a future. Awaiting the
    # answer on the loop avoids two thread hand-overs per request (bench/bench_sdo.py).

    def _on_sdo_frame(self, can_id: int, data: bytearray, timestamp: float) -> None:
        doorbell = self._doorbell
        if doorbell is not None:
            doorbell.post(bytes(data))
            return
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._deliver, bytes(data))

    def _deliver(self, frame: bytes) -> None:
        self.sdo_frames_rx += 1
        waiter = self._waiter
        if waiter is None:
            # No request in flight: a late answer to one that timed out or was cancelled,
            # dropped; it no longer stands in for the next request's answer.
            self._pay(frame)
            return
        if not waiter.done():
            waiter.set_result(frame)
        else:
            # The waiter holds an answer _transact has not looked at yet; if that one is
            # stale, this may be the real one, so it is kept for the request, not dropped.
            self._unread.append(frame)

    def _arm(self, loop: asyncio.AbstractEventLoop) -> None:
        """The response time-out of the answer now awaited (see :meth:`_on_watchdog`)."""
        deadline = self._deadline = loop.time() + self.request_timeout
        dog = self._watchdog
        if dog is None or self._watchdog_at > deadline:
            if dog is not None:
                dog.cancel()
            self._watchdog_at = deadline
            self._watchdog = loop.call_at(deadline, self._on_watchdog)

    def _on_watchdog(self) -> None:
        """The response time-out: one timer per link, moved only when it fires too early.

        A timer per request (call_later, heap push, cancel, heap clean-up) cost about 7 us,
        a third of the loop side of an SDO read. Requests only move ``_deadline`` forward, so
        this timer fires about once per time-out and re-arms for the request in flight; a
        request with a shorter time-out than the armed one re-arms it earlier.
        """
        dog, self._watchdog = self._watchdog, None
        waiter, loop = self._waiter, self._loop
        if dog is None or waiter is None or waiter.done() or loop is None:
            return
        if self._deadline <= self._watchdog_at:
            waiter.set_exception(TimeoutError())
        else:
            self._watchdog_at = self._deadline
            self._watchdog = loop.call_at(self._deadline, self._on_watchdog)

    def _owe(self, request: bytes, kind: int) -> None:
        """An initiate ``request`` on the bus ended without its answer (``kind``: the scs bits
        of the answer it waits for); the answer may still come, for up to a time-out."""
        loop = self._loop
        if loop is not None:
            self._owed.append((request[1:4], kind, loop.time() + self.request_timeout))

    def _pay(self, frame: bytes) -> bool:
        """Whether ``frame`` is the late answer owed to an earlier request (:meth:`_owe`); the
        debt is then settled.

        CiA 301 SDO frames carry no transaction id: the answer to a cancelled write of 6060h
        and the answer to the next write of 6060h look alike, and the first would be taken
        for the second, whose refusal (an abort) then went unseen. A server answers in order,
        so the owed answer comes first. Debts lapse after a time-out: where the request never
        reached the drive (the usual cause of a time-out), the next request of the same object
        loses its answer once and waits out one time-out before its retry, rather than take
        a stale one."""
        if not self._owed or len(frame) < 4:
            return False
        loop = self._loop
        now = loop.time() if loop is not None else math.inf
        self._owed = [d for d in self._owed if d[2] > now]
        kind = frame[0] & 0xE0
        for i, (mux, owed_kind, _until) in enumerate(self._owed):
            # An abort (scs 4) answers either kind of request (CiA 301 §7.2.4.3.17).
            if mux == frame[1:4] and kind in (owed_kind, 0x80):
                del self._owed[i]
                return True
        return False

    def stop_frame(self) -> Callable[[], None] | None:
        """An expedited SDO download of 6040h:00 = 0002h (quick stop) straight onto the bus.

        canopen's Network.send_message holds the network's send lock, so it is safe from the
        dead-man's thread beside the loop's own requests. The drive answers it like any
        download; that answer is owed (:meth:`_owe`), so it is not taken for the answer of
        the loop's next write of 6040h (CiA 301 SDO has no transaction id)."""
        network, loop = self._network, self._loop
        if network is None or loop is None:
            return None
        cob_id = 0x600 + self.params.node_id
        frame = sdo.initiate_download(0x6040, 0, QUICK_STOP_WORD.to_bytes(2, "little"))

        def send() -> None:
            network.send_message(cob_id, frame)
            if not loop.is_closed():
                loop.call_soon_threadsafe(self._owe, frame, DOWNLOAD_ANSWER)

        return send

    # The drive's own watchdog: its heartbeat consumer on servodesk's heartbeat --------------

    async def arm_watchdog(self) -> str | None:
        """Make the drive watch servodesk's heartbeat (1016h:01, CiA 301 §7.5.2.17), so that a
        dead PC stops the axis by the drive's abort connection option code 6007h. None where
        the drive has no consumer entry (an SDO abort). The entry it had is kept and written
        back by :meth:`disarm_watchdog` (and around a store, :meth:`watchdog_paused`)."""
        if self._watchdog_original is not None:
            return self._watchdog_text
        try:
            original = await self.read(CONSUMER)
        except ObjectAccessError:
            return None
        pool.start_heartbeat(self.params)
        entry = (MASTER_NODE_ID << 16) | CONSUMER_TIME_MS
        try:
            await self.write(CONSUMER, entry.to_bytes(4, "little"))
        except ServodeskError:
            pool.stop_heartbeat(self.params)
            raise
        self._watchdog_original = original
        self._watchdog_text = (
            f"CiA 301 heartbeat consumer 1016h:01 = {entry:08X}h: the drive watches "
            f"servodesk's heartbeat (node {MASTER_NODE_ID}, every "
            f"{HEARTBEAT_PERIOD_S * 1000:.0f} ms) and reacts per 6007h when it lapses for "
            f"{CONSUMER_TIME_MS} ms"
        )
        return self._watchdog_text

    async def disarm_watchdog(self) -> None:
        original, self._watchdog_original = self._watchdog_original, None
        self._watchdog_text = None
        if original is None:
            return
        try:
            await self.write(CONSUMER, original)
        finally:
            pool.stop_heartbeat(self.params)

    @property
    def watchdog(self) -> str | None:
        return self._watchdog_text

    @contextlib.asynccontextmanager
    async def watchdog_paused(self) -> AsyncIterator[None]:
        """The drive's own entry back in place for a store: servodesk's arming is not to be
        saved in the drive's non-volatile memory (it would fault without servodesk)."""
        original = self._watchdog_original
        if original is None:
            yield
            return
        armed = await self.read(CONSUMER)
        await self.write(CONSUMER, original)
        try:
            yield
        finally:
            await self.write(CONSUMER, armed)

    def _abandon(self) -> None:
        """End the request in flight now: the link is closing, no answer will be awaited."""
        dog, self._watchdog = self._watchdog, None
        if dog is not None:
            dog.cancel()
        waiter = self._waiter
        if waiter is not None and not waiter.done():
            waiter.set_exception(
                LinkClosedError(
                    "the link was closed while a request waited for the drive's answer",
                    hint="open the session again",
                )
            )

    async def open(self) -> None:
        await super().open()
        # No await from here on: no request can start before the doorbell is in place.
        self._doorbell = _Doorbell.attach(asyncio.get_running_loop(), self._deliver)

    async def close(self) -> None:
        loop, doorbell = self._loop, self._doorbell
        here = loop is None or loop.is_closed() or asyncio.get_running_loop() is loop
        if not self.closed and loop is not None and not loop.is_closed():
            if here:
                self._abandon()
            else:
                loop.call_soon_threadsafe(self._abandon)
        await super().close()
        # After the unsubscription in _close: the bus thread no longer posts (a post already
        # under way finds the doorbell closed).
        self._doorbell = None
        if doorbell is not None:
            if here:
                doorbell.close()
            else:
                assert loop is not None
                loop.call_soon_threadsafe(doorbell.close)

    async def _transact(self, request: bytes, address: ObjectAddress) -> bytes:
        network, loop = self._network, self._loop
        if network is None or loop is None:
            raise LinkError("the CANopen link is not open")
        cob_id = 0x600 + self.params.node_id
        ccs = request[0] & 0xE0
        # ccs 1 / 2 / 5: initiate download / upload / block upload (cs 0 is the only block
        # upload request sent through here).
        initiate = ccs in (0x20, 0x40, 0xA0)
        # Their answers: scs 3 (download), 2 (upload), 6 (block upload, or 2 where the server
        # switches protocol, §7.2.4.3.9), or an abort (CiA 301 §7.2.4.3).
        answer_scs: tuple[int, ...] = (
            (0x60, 0x80) if ccs == 0x20 else (0xC0, 0x40, 0x80) if ccs == 0xA0 else (0x40, 0x80)
        )
        # CiA 301 leaves retries to the client; like canopen, send once more on silence.
        for attempt in range(2):
            waiter: asyncio.Future[bytes] = loop.create_future()
            self._waiter = waiter
            self._arm(loop)
            sent = False
            try:
                try:
                    self.sdo_frames_tx += 1
                    network.send_message(cob_id, request)
                except (can.CanError, RuntimeError) as exc:
                    # python-can's send failures (a full transmit queue, a bus that is off)
                    # and canopen's "not connected" are not OSErrors, so they are mapped here.
                    raise LinkError(
                        f"{address}: the SDO request could not be sent: {exc}",
                        hint="check the CAN adapter, and that the bus is not in bus-off",
                    ) from exc
                sent = True
                answer = await waiter
                # An initiate request's answer (and any abort) echoes the multiplexor
                # (CiA 301 §7.2.4.3). One for another object, or of another kind (an upload's
                # answer to a download of the same object), is the late answer to a request
                # that already timed out or was cancelled: drop it and keep waiting. So is one
                # that matches but is still owed to such a request of the same object (_pay).
                while (
                    initiate
                    and len(answer) >= 4
                    and (
                        self._pay(answer)
                        or answer[1:4] != request[1:4]
                        or answer[0] & 0xE0 not in answer_scs
                    )
                ):
                    log.debug(
                        "node %d: dropped a stale SDO answer %s", self.params.node_id, answer.hex()
                    )
                    if self._unread:
                        answer = self._unread.popleft()
                        continue
                    waiter = loop.create_future()
                    self._waiter = waiter
                    answer = await waiter
                if initiate and attempt == 1:
                    # Answered on the retry: the drive may have been slow rather than deaf,
                    # and this may be the late answer to the first send, the retry's still
                    # to come. Taken by the next request of the same object, it would stand
                    # in for that one's answer (a write's refusal unseen). Owed, it is dropped
                    # when it comes; where the first send was lost, the next such request
                    # within a time-out waits one out before its own retry instead.
                    self._owe(request, answer_scs[0])
                return answer
            except asyncio.CancelledError:
                # Cancelled on the bus (a motion's monitor ended by a dead-man stop): its
                # answer is still to come, unless it is already here, unread.
                held = [*self._unread]
                if waiter.done() and not waiter.cancelled() and waiter.exception() is None:
                    held.append(waiter.result())
                if (
                    initiate
                    and sent
                    and not any(a[1:4] == request[1:4] and a[0] & 0xE0 in answer_scs for a in held)
                ):
                    self._owe(request, answer_scs[0])
                raise
            except TimeoutError:
                if self._network is None:
                    raise _closed_while_waiting() from None
                if attempt == 0:
                    continue
                with contextlib.suppress(Exception):
                    network.send_message(
                        cob_id, sdo.abort(address.index, address.subindex, sdo.ABORT_TIMEOUT)
                    )
                if initiate:
                    self._owe(request, answer_scs[0])
                raise LinkTimeoutError(
                    f"{address}: no SDO response from node {self.params.node_id} within "
                    f"{self.request_timeout:g} s",
                    hint="check the node id, bitrate, cabling and that the drive is powered",
                ) from None
            finally:
                self._waiter = None
                self._unread.clear()
        raise AssertionError("unreachable")

    async def read_large(self, address: ObjectAddress, *, timeout: float | None = None) -> bytes:
        """Read an object expected to be large (a recording, a DOMAIN) by SDO block upload,
        or by segmented upload where the node refuses block transfers (docs/scope.md)."""
        return await self._acall(self._aread_large, address, timeout=timeout)

    async def _aread(self, address: ObjectAddress) -> bytes:
        if address in self._large and self.block_upload and not self.block_refused:
            return await self._aread_large(address)
        return await self._aread_normal(address)

    async def _aread_normal(self, address: ObjectAddress) -> bytes:
        """Expedited or segmented upload (CiA 301 §7.2.4.3.6-§7.2.4.3.7)."""
        idx, sub = address.index, address.subindex
        try:
            request = sdo.initiate_upload(idx, sub)
            answer = await self._transact(request, address)
            # The usual answer, expedited with its size (CiA 301 §7.2.4.3.6: scs 2, e = s = 1)
            # for the multiplexor asked for, is taken without the full parser below.
            if len(answer) == 8 and answer[0] & 0xE3 == 0x43 and answer[1:4] == request[1:4]:
                return answer[4 : 8 - (answer[0] >> 2 & 0x03)]
            start = sdo.parse_initiate_upload(answer, idx, sub)
            if start.data is not None:
                return start.data
            if start.size is not None and start.size > BLOCK_THRESHOLD:
                self._large.add(address)  # Block upload from its next read on.
            return await self._segments(start, address)
        except sdo.SdoAbort as exc:
            raise abort_error(exc.code, address, "read") from exc
        except sdo.SdoProtocolError as exc:
            raise self._protocol_error(exc, address) from exc

    async def _segments(self, start: sdo.UploadStart, address: ObjectAddress) -> bytes:
        """The segments of an upload the server started (CiA 301 §7.2.4.3.7)."""
        idx, sub = address.index, address.subindex
        out, toggle = bytearray(), 0
        while True:
            seg = sdo.parse_upload_segment(
                await self._transact(sdo.upload_segment(toggle), address), toggle, idx, sub
            )
            out += seg.data
            if seg.last:
                break
            toggle ^= 1
            if len(out) > _MAX_SEGMENTED:
                raise sdo.SdoProtocolError("upload longer than servodesk accepts")
        if start.size is not None and len(out) != start.size:
            raise sdo.SdoProtocolError(f"announced {start.size} bytes, sent {len(out)}")
        return bytes(out)

    async def _aread_large(self, address: ObjectAddress) -> bytes:
        if not self.block_upload or self.block_refused:
            return await self._aread_normal(address)
        idx, sub = address.index, address.subindex
        try:
            request = sdo_block.initiate_upload(idx, sub, BLOCK_SIZE, BLOCK_THRESHOLD)
            try:
                answer = await self._transact(request, address)
                start = sdo_block.parse_initiate_response(answer, idx, sub)
            except sdo.SdoAbort as exc:
                if exc.code not in _BLOCK_REFUSALS:
                    raise
                return await self._after_refusal(exc.code, address)
            if isinstance(start, sdo.UploadStart):
                # The server switched to the normal upload (§7.2.4.3.9): small enough, or a
                # server without block transfers that says so this way (python-canopen's).
                if start.data is not None:
                    return start.data
                return await self._segments(start, address)
            return await self._blocks(start, address)
        except sdo.SdoAbort as exc:
            raise abort_error(exc.code, address, "read") from exc
        except sdo.SdoProtocolError as exc:
            raise self._protocol_error(exc, address) from exc

    async def _after_refusal(self, code: int, address: ObjectAddress) -> bytes:
        """The block initiate was aborted with ``code``: read by segmented upload, and
        remember that the node refuses block transfers once the segmented read shows that
        the object itself was readable (0504 0001h says so on its own)."""
        try:
            data = await self._aread_normal(address)
        finally:
            if code == sdo.ABORT_COMMAND:
                self.block_refused = True
        if not self.block_refused:
            log.info(
                "node %d refuses SDO block upload (abort 0x%08X): segmented from now on",
                self.params.node_id,
                code,
            )
        self.block_refused = True
        return data

    async def _blocks(self, start: sdo_block.BlockStart, address: ObjectAddress) -> bytes:
        """The sub-blocks of a block upload, acknowledged, and its end (§7.2.4.3.10-13).

        A sub-block whose tail is lost ends by the response time-out: the acknowledgement
        names the last segment received in order and the server sends the rest again
        (:class:`~servodesk.domain.sdo_block.BlockReceiver`)."""
        network, loop = self._network, self._loop
        if network is None or loop is None:
            raise LinkError("the CANopen link is not open")
        idx, sub = address.index, address.subindex
        cob_id = 0x600 + self.params.node_id
        rx = sdo_block.BlockReceiver(idx, sub, BLOCK_SIZE, _MAX_SEGMENTED)

        def send(frame: bytes) -> None:
            self.sdo_frames_tx += 1
            try:
                network.send_message(cob_id, frame)
            except (can.CanError, RuntimeError) as exc:
                raise LinkError(
                    f"{address}: the SDO request could not be sent: {exc}",
                    hint="check the CAN adapter, and that the bus is not in bus-off",
                ) from exc

        try:
            send(sdo_block.START)
            heard, silences = False, 0
            while True:
                try:
                    frame = await self._next_frame(loop)
                except TimeoutError:
                    silences += 1
                    self.block_timeouts += 1
                    if self._network is None or silences >= _BLOCK_SILENCES:
                        raise
                    # Nothing since the start: it may be lost, send it again. Else the end
                    # of the sub-block is: acknowledge what came in order (§7.2.4.3.12).
                    send(rx.ack() if heard else sdo_block.START)
                    continue
                heard, silences = True, 0
                dropped = rx.dropped
                over = rx.segment(frame)
                self.block_resent += rx.dropped - dropped
                if over:
                    send(rx.ack())
                    if rx.complete:
                        break
            end = sdo_block.parse_end(await self._next_frame(loop), idx, sub)
            data = rx.finish(end, start.crc, start.size)
            send(sdo_block.END_RESPONSE)
            return data
        except asyncio.CancelledError:
            # Cancelled on the bus (the scope stopped): the server is still in the transfer
            # and would take the link's next request for a wrong block command. Abort it
            # (CiA 301 §7.2.4.3.17: either side may, at any time).
            with contextlib.suppress(Exception):
                network.send_message(cob_id, sdo.abort(idx, sub, _ABORT_GENERAL))
            raise
        except TimeoutError:
            if self._network is None:
                raise _closed_while_waiting() from None
            with contextlib.suppress(Exception):
                network.send_message(cob_id, sdo.abort(idx, sub, sdo.ABORT_TIMEOUT))
            raise LinkTimeoutError(
                f"{address}: the block upload from node {self.params.node_id} stopped: no "
                f"segment within {self.request_timeout:g} s",
                hint="check the bus load and cabling; a drive may limit block transfers",
            ) from None
        finally:
            self._waiter = None
            self._unread.clear()

    async def _next_frame(self, loop: asyncio.AbstractEventLoop) -> bytes:
        """The next SDO frame from the node, within the response time-out.

        The waiter stays in place once resolved, so frames that arrive before the next call
        queue in ``_unread`` (:meth:`_deliver`) instead of being dropped."""
        if self._unread:
            return self._unread.popleft()
        waiter: asyncio.Future[bytes] = loop.create_future()
        self._waiter = waiter
        self._arm(loop)
        return await waiter

    async def _awrite(self, address: ObjectAddress, data: bytes) -> None:
        idx, sub = address.index, address.subindex
        try:
            sdo.parse_initiate_download(
                await self._transact(sdo.initiate_download(idx, sub, data), address), idx, sub
            )
            if 0 < len(data) <= 4:
                return
            toggle = 0
            for pos in range(0, max(len(data), 1), 7):
                chunk = data[pos : pos + 7]
                last = pos + 7 >= len(data)
                answer = await self._transact(sdo.download_segment(toggle, chunk, last), address)
                sdo.parse_download_segment(answer, toggle, idx, sub)
                toggle ^= 1
        except sdo.SdoAbort as exc:
            raise abort_error(exc.code, address, "write") from exc
        except sdo.SdoProtocolError as exc:
            raise self._protocol_error(exc, address) from exc

    def _protocol_error(self, exc: sdo.SdoProtocolError, address: ObjectAddress) -> LinkError:
        if self._network is not None:
            with contextlib.suppress(Exception):
                self._network.send_message(
                    0x600 + self.params.node_id,
                    sdo.abort(address.index, address.subindex, exc.abort_code),
                )
        return LinkError(
            f"{address}: the drive's SDO answer does not follow CiA 301: {exc}",
            hint="another master may be talking to this node, or the node id is shared",
        )

    async def identity(self) -> DriveIdentity:
        return await object_identity(self)

    def _nmt(self, command: str) -> None:
        node = self._require()
        state = _NMT_COMMANDS.get(command)
        if state is None:
            raise ValidationError(
                f"unknown NMT command {command!r}", hint=f"use one of {', '.join(_NMT_COMMANDS)}"
            )
        node.nmt.state = state
        # CiA 301 NMT commands are not confirmed; without a heartbeat the state servodesk last
        # commanded is the best knowledge (a heartbeat, when the drive sends one, corrects it).
        # After a reset the node boots into PRE-OPERATIONAL (CiA 301 §7.3.2.1).
        commanded = {"start": "operational", "stop": "stopped"}.get(command, "preop")
        self._nmt_commanded_at = time.monotonic()
        if commanded != self.nmt_state:
            self.nmt_state = commanded
            self._emit("nmt", state=commanded)

    def bus_traffic(self) -> TrafficView | None:
        return pool.traffic(self.params) if not self.closed else None

    def _network_state(self) -> str:
        return self.nmt_state

    def heartbeat_age(self) -> float | None:
        if self.last_heartbeat is None:
            return None
        return time.monotonic() - self.last_heartbeat

    # Bus-thread callbacks ------------------------------------------------------------------

    def _on_heartbeat(self, state: int) -> None:
        now = time.monotonic()
        self.last_heartbeat = now
        name = {0x00: "bootup", 0x04: "stopped", 0x05: "operational", 0x7F: "preop"}.get(
            state & 0x7F, f"0x{state:02X}"
        )
        # A heartbeat the drive sent just before our NMT command can be read just after it:
        # it would undo the commanded state until the next heartbeat, and a cyclic start in
        # that window would believe the node already OPERATIONAL. A boot-up is always news.
        if name == "bootup":
            self.resets_seen += 1
        if name != "bootup" and now - self._nmt_commanded_at < HEARTBEAT_STALE_S:
            return
        if name != self.nmt_state:
            self.nmt_state = name
            self._emit("nmt", state=name)

    def _on_emcy(self, err: Any) -> None:
        self._emit(
            "emcy", code=int(err.code), register=int(err.register), data=bytes(err.data).hex()
        )


def scan(params: LinkParams, timeout: float = 0.5) -> list[int]:
    """Node ids that answer on the bus (SDO upload of 1000h to every node, CiA 301)."""
    network = pool.acquire(params)
    try:
        network.scanner.reset()
        network.scanner.search()
        time.sleep(timeout)
        own = {MASTER_NODE_ID} if pool.producing(params) else set()
        return sorted(set(network.scanner.nodes) - own)
    finally:
        pool.release(params)
