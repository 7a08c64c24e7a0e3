"""CC-Link IE TSN object access over SLMP (4E binary frames on UDP): the CTMM04x's transient
transmission (003 §4-2).

Where the station is: ``interface`` ``slmp``, ``channel`` ``host:port`` (the port of a unit
is not in manual 003; MR-J4-GF answers SLMP on UDP 5010, the default), ``node_id`` the axis
+ 1 (1 = X, 2 = Y, 3 = Z, 4 = U), sent as the request-destination multidrop station no.
Objects are read and written with 4020h SDO Upload / SDO Download (:mod:`servodesk.domain.slmp`).

What this link does not do, and why:

- Cyclic process data: a CC-Link IE TSN station exchanges it with its manager only, in the
  network's time slots (003 §3-3); a PC on the network reaches the station's objects by
  SLMP. Motion from servodesk writes the control word and set-points as objects, which a
  station under a running manager overwrites from its cyclic data (docs/slmp.md).
- NMT: 003 §3-3 names the SLMP command "NMT State Download" but gives no code, and a PC must
  not change the state of a station its manager runs. The state reads "unknown".

Each request carries a new serial no.; an answer with another serial (a late answer to a
request that timed out) is dropped. A request without an answer is sent once more, with a
new serial: an SDO download of one value twice leaves the value the same.
"""

from __future__ import annotations

import asyncio
import errno
import socket
from collections.abc import Callable

from servodesk.domain import slmp
from servodesk.domain.address import ObjectAddress
from servodesk.domain.sdo_abort import abort_error
from servodesk.errors import (
    ConflictError,
    LinkError,
    LinkTimeoutError,
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

#: The interface name of this link (the transport: SLMP 4E binary frames on UDP).
INTERFACE = "slmp"
#: Axes of one station: node id 1..4 -> multidrop no. 0..3 (003 §4-2).
AXES = 4
#: The end code of a request to a network, station or multidrop no. that does not exist.
END_NO_DESTINATION = 0xCF10
#: Sends of one request before it times out (the first and one retry).
SENDS = 2


class SlmpLink(DriveLink):
    """One axis of a CC-Link IE TSN station, reached by SLMP over UDP."""

    fieldbus = "cclink-ie-tsn"
    sends_nmt = False
    #: Why there is no cyclic process data here (links/cyclic.py ``transport_for``).
    no_cyclic = (
        "a CC-Link IE TSN station exchanges cyclic data with its manager only, in the "
        "network's time slots (003 §3-3); servodesk reads and writes its objects by SLMP"
    )

    def __init__(self, params: LinkParams) -> None:
        if params.interface != INTERFACE:
            raise ValidationError(
                f"interface {params.interface!r} does not carry SLMP",
                field="interface",
                hint=f"use interface {INTERFACE} with channel host:port",
            )
        if not 1 <= params.node_id <= AXES:
            # A station has four axes at most: node 5 and up is no device there (404).
            raise NotFoundError(
                f"node id {params.node_id} is no axis of an SLMP station",
                hint="SLMP node ids are the axis + 1: 1 = X, 2 = Y, 3 = Z, 4 = U (003 §4-2)",
            )
        self.host, self.port = slmp.parse_channel(params.channel)
        super().__init__(params)
        self.route = slmp.Route(multidrop=params.node_id - 1)
        self._sock: socket.socket | None = None
        self._serial = 0
        #: Answers dropped because their serial was not the request's (late answers).
        self.stale = 0

    # Hooks -------------------------------------------------------------------------

    def _open(self) -> None:
        try:
            infos = socket.getaddrinfo(self.host, self.port, socket.AF_INET, socket.SOCK_DGRAM)
        except OSError as exc:
            raise LinkError(
                f"cannot resolve {self.host!r}: {exc}", hint="check the station's address"
            ) from exc
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.connect(infos[0][4])
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            raise LinkError(
                f"cannot reach {self.host}:{self.port}: {exc}", hint="check the station's address"
            ) from exc
        self._sock = sock

    def _close(self) -> None:
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()

    async def _aread(self, address: ObjectAddress) -> bytes:
        data = slmp.upload_data(address.index, address.subindex)
        answer = await self._request(slmp.SUB_UPLOAD, data, address, "read")
        return self._object(answer, address, with_value=True)

    async def _awrite(self, address: ObjectAddress, data: bytes) -> None:
        if len(data) > slmp.MAX_OBJECT_BYTES:
            raise ValidationError(
                f"{address}: {len(data)} bytes do not fit one SLMP request "
                f"(at most {slmp.MAX_OBJECT_BYTES})",
                field="value",
                hint="servodesk sends no SLMP block transfers",
            )
        body = slmp.download_data(address.index, address.subindex, data)
        answer = await self._request(slmp.SUB_DOWNLOAD, body, address, "write")
        self._object(answer, address, with_value=False)

    async def identity(self) -> DriveIdentity:
        return await object_identity(self)

    def stop_frame(self) -> Callable[[], None] | None:
        """An SLMP SDO download of 6040h:00 = 0002h (quick stop) from a socket of its own.

        Its own socket, so that its answer never reaches the loop's requests (their serials
        are the loop's; 003 §4-4 answers to the sender's port). Blocking sendto from the
        dead-man's thread; the answer is not awaited."""
        if self._sock is None:
            return None
        target = (self.host, self.port)
        frame = slmp.build_request(
            0xFFFF,
            self.route,
            slmp.CMD_OBJECT,
            slmp.SUB_DOWNLOAD,
            slmp.download_data(0x6040, 0, QUICK_STOP_WORD.to_bytes(2, "little")),
            timer=4,
        )

        def send() -> None:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
                sock.sendto(frame, target)

        return send

    # Requests ------------------------------------------------------------------------

    async def _request(
        self, subcommand: int, data: bytes, address: ObjectAddress, op: str
    ) -> slmp.Response:
        sock = self._sock
        if sock is None:
            raise LinkError("the SLMP socket is closed", hint="open the session again")
        loop = asyncio.get_running_loop()
        timeout = self.request_timeout
        timer = max(1, min(0xFFFF, round(timeout / 0.25)))
        for _ in range(SENDS):
            self._serial = serial = (self._serial + 1) & 0xFFFF
            frame = slmp.build_request(
                serial, self.route, slmp.CMD_OBJECT, subcommand, data, timer=timer
            )
            try:
                await loop.sock_sendall(sock, frame)
                # asyncio.timeout, not wait_for: no task per request (bench/bench_slmp.py).
                async with asyncio.timeout(timeout):
                    answer = await self._answer(sock, serial)
            except TimeoutError:
                continue
            except ConnectionRefusedError as exc:
                raise NotFoundError(
                    f"{op} {address}: nothing answers SLMP at udp {self.host}:{self.port} "
                    f"({errno.errorcode.get(exc.errno or 0, exc)})",
                    hint="check the station's address and port, and that it is powered",
                ) from exc
            if answer.end_code == END_NO_DESTINATION:
                raise NotFoundError(
                    f"{op} {address}: the station at {self.host}:{self.port} has no axis "
                    f"{'XYZU'[self.route.multidrop]} (end code {answer.end_code:04X}h: "
                    f"{slmp.end_code_text(answer.end_code)})",
                    hint="check the node id: the axis + 1 (1 = X, 2 = Y, 3 = Z, 4 = U)",
                )
            if answer.end_code != 0:
                raise self._refusal(answer, address, op)
            return answer
        raise LinkTimeoutError(
            f"{op} {address}: no SLMP answer from {self.host}:{self.port} axis "
            f"{'XYZU'[self.route.multidrop]} within {timeout:g} s ({SENDS} sends)"
        )

    async def _answer(self, sock: socket.socket, serial: int) -> slmp.Response:
        """The response with ``serial``; others (late answers) and frames that are no 4E
        response are dropped."""
        loop = asyncio.get_running_loop()
        while True:
            frame = await loop.sock_recv(sock, slmp.MAX_FRAME)
            try:
                answer = slmp.parse_response(frame)
            except slmp.SlmpFrameError:
                self.stale += 1
                continue
            if answer.serial != serial:
                self.stale += 1
                continue
            return answer

    def _refusal(self, answer: slmp.Response, address: ObjectAddress, op: str) -> Exception:
        abort = slmp.refused_abort_code(answer.data)
        if abort is not None:
            return abort_error(abort, address, op)
        meaning = slmp.end_code_text(answer.end_code)
        return ObjectAccessError(
            f"{op} {address} refused by the station: {meaning} (end code {answer.end_code:04X}h)",
            code=answer.end_code,
            meaning=meaning,
            protocol="slmp",
            address=str(address),
            hint="the station's own manual lists its end codes",
        )

    def _object(self, answer: slmp.Response, address: ObjectAddress, *, with_value: bool) -> bytes:
        try:
            obj = slmp.parse_object_data(answer.data, with_value=with_value)
        except slmp.SlmpFrameError as exc:
            raise LinkError(
                f"{address}: the station's answer is malformed: {exc}",
                hint="the station may not implement the 4020h object access servodesk uses",
            ) from exc
        if (obj.index, obj.subindex) != (address.index, address.subindex):
            raise LinkError(
                f"{address}: the station answered for {obj.index:04X}h:{obj.subindex:02X}h",
                hint="another client may share this station's serial numbers",
            )
        return obj.data

    def _nmt(self, command: str) -> None:
        raise ConflictError(
            f"servodesk sends no NMT command ({command}) over SLMP",
            hint="the station's NMT state belongs to its CC-Link IE TSN manager (003 §3-3); "
            "change it there",
        )

    def _network_state(self) -> str:
        return "unknown"
