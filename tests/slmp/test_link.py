"""The SLMP link against a simulated CC-Link IE TSN station over real UDP sockets.

What an engineer relies on when servodesk talks to a CTMM04x by SLMP: each axis's objects
read and write as over CANopen; a refusal names the CiA 301 abort or the SLMP end code; a
station that is not there, does not answer, answers late or answers garbage is reported as
such and never taken for another request's answer.
"""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Callable, Iterator

import pytest

from servodesk.domain import slmp
from servodesk.domain.address import ObjectAddress
from servodesk.errors import (
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ValidationError,
)
from servodesk.links.base import LinkParams
from servodesk.links.slmp_link import SlmpLink
from servodesk.sim.bus import SimulatedBus

STATUSWORD = ObjectAddress(0x6041)
TARGET = ObjectAddress(0x607A)


@pytest.fixture
def station() -> Iterator[SimulatedBus]:
    """A CTMM04x twin with axes X and Y on an SLMP station on a free loopback port."""
    with SimulatedBus.start(
        drives=[("ctmm04x", 1), ("ctmm04x", 2)], interface="slmp", channel="127.0.0.1:0"
    ) as bus:
        yield bus


def link(channel: str, node: int = 1, timeout: float = 0.3) -> SlmpLink:
    return SlmpLink(LinkParams(interface="slmp", channel=channel, node_id=node, timeout=timeout))


def run(coro: object) -> object:
    return asyncio.run(coro)  # type: ignore[arg-type]


def test_objects_of_each_axis_read_and_write(station: SimulatedBus) -> None:
    assert station.station is not None and station.network is None  # No CAN bus opened.
    x_drive, y_drive = station.drives

    async def go() -> None:
        async with link(station.station.channel, 1) as x, link(station.station.channel, 2) as y:
            ident = await x.identity()
            assert ident.device_name == "AECAT-AXIS4"
            assert ident.vendor_id == x_drive.read(0x1018, 1)
            await x.write(TARGET, (12345).to_bytes(4, "little", signed=True))
            await y.write(TARGET, (-777).to_bytes(4, "little", signed=True))
            assert int.from_bytes(await x.read(TARGET), "little", signed=True) == 12345
            assert int.from_bytes(await y.read(TARGET), "little", signed=True) == -777
            assert await x.read(STATUSWORD) == x_drive.read_bytes(0x6041, 0)
            assert await x.network_state() == "unknown"

    run(go())
    assert x_drive.read(0x607A) == 12345 and y_drive.read(0x607A) == -777


def test_refusals_name_the_abort_code_or_the_end_code(station: SimulatedBus) -> None:
    assert station.station is not None
    channel = station.station.channel

    async def go() -> None:
        async with link(channel, 1) as x:
            with pytest.raises(ObjectAccessError) as err:
                await x.read(ObjectAddress(0x5555))
            assert err.value.protocol == "sdo" and err.value.code == 0x06020000
            assert "0x5555:00 refused by the drive" in err.value.message
            with pytest.raises(ObjectAccessError) as err:
                await x.write(STATUSWORD, b"\x00\x00")  # Read-only.
            assert err.value.code == 0x06010002
            sent = station.station.answered if station.station else 0
            with pytest.raises(ValidationError, match="do not fit one SLMP request"):
                await x.write(ObjectAddress(0x1008), bytes(slmp.MAX_OBJECT_BYTES + 1))
            assert station.station is not None and station.station.answered == sent
        # Axis Z is not on this station: no device there (end code CF10h), not an abort.
        async with link(channel, 3) as z:
            with pytest.raises(NotFoundError, match="has no axis Z") as missing:
                await z.read(STATUSWORD)
            assert "end code CF10h" in missing.value.message
        # The session's NMT commands belong to the station's manager.
        async with link(channel, 1) as x:
            with pytest.raises(Exception, match="NMT") as nmt_err:
                await x.nmt("reset")
            assert "manager" in (getattr(nmt_err.value, "hint", "") or "")

    run(go())


def test_station_answers_other_commands_and_bad_data_with_end_codes(station: SimulatedBus) -> None:
    """And the link names an end code it has no meaning for as the station's refusal."""
    assert station.station is not None
    route = slmp.Route(multidrop=0)
    unknown = station.station.answer(slmp.build_request(5, route, 0x0401, 0x0000, b""))
    assert unknown is not None and slmp.parse_response(unknown).end_code == 0xC059
    bad = slmp.build_request(6, route, slmp.CMD_OBJECT, slmp.SUB_DOWNLOAD, b"\x7a\x60\x00")
    answer = station.station.answer(bad)
    assert answer is not None and slmp.parse_response(answer).end_code == 0xC061
    assert station.station.answer(b"GET / HTTP/1.1\r\n\r\n") is None  # Not SLMP: dropped.


def test_bad_addresses_are_refused_before_anything_is_sent() -> None:
    with pytest.raises(ValidationError, match="does not carry SLMP"):
        SlmpLink(LinkParams(interface="virtual", channel="127.0.0.1:5010", node_id=1))
    with pytest.raises(NotFoundError, match="no axis") as err:
        link("127.0.0.1:5010", node=5)
    assert "1 = X" in (err.value.hint or "")
    with pytest.raises(ValidationError, match="port"):
        link("127.0.0.1:http")


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_nothing_listening_is_not_found() -> None:
    port = _free_udp_port()

    async def go() -> None:
        async with link(f"127.0.0.1:{port}") as x:
            with pytest.raises(NotFoundError, match=f"nothing answers SLMP at udp .*:{port}"):
                await x.read(STATUSWORD)

    run(go())


class RawStation:
    """A UDP peer that answers each request with ``reply(request, n)`` (a list of frames)."""

    def __init__(self, reply: Callable[[slmp.Request, int], list[bytes]]) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.reply = reply
        self.requests: list[slmp.Request] = []
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    @property
    def channel(self) -> str:
        return f"127.0.0.1:{self.sock.getsockname()[1]}"

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                frame, peer = self.sock.recvfrom(4096)
            except TimeoutError:
                continue
            req = slmp.parse_request(frame)
            self.requests.append(req)
            for out in self.reply(req, len(self.requests)):
                self.sock.sendto(out, peer)

    def close(self) -> None:
        self._stop.set()
        self._t.join()
        self.sock.close()


def _value_answer(req: slmp.Request, value: bytes, serial: int | None = None) -> bytes:
    obj = slmp.parse_object_data(req.data, with_value=False)
    data = slmp.download_data(obj.index, obj.subindex, value)
    return slmp.build_response(req.serial if serial is None else serial, req.route, 0, data)


def test_a_silent_station_times_out_after_a_second_send_with_a_new_serial() -> None:
    raw = RawStation(lambda req, n: [])

    async def go() -> None:
        async with link(raw.channel, 2, timeout=0.1) as y:
            with pytest.raises(LinkTimeoutError, match=r"axis Y within 0.1 s \(2 sends\)"):
                await y.read(STATUSWORD)

    try:
        run(go())
    finally:
        raw.close()
    assert len(raw.requests) == 2
    assert raw.requests[0].serial != raw.requests[1].serial
    assert all(r.route.multidrop == 1 and r.timer == 1 for r in raw.requests)


def test_a_late_answer_is_never_taken_for_the_next_request() -> None:
    # The first request's answer comes only after the retry was sent: first the stale one
    # (its serial), then the retry's. The link must return the retry's value.
    def reply(req: slmp.Request, n: int) -> list[bytes]:
        if n == 1:
            return []
        first = raw.requests[0]
        stale = _value_answer(first, b"\x11\x11", serial=first.serial)
        return [stale, _value_answer(req, b"\x22\x22")]

    raw = RawStation(reply)
    x = link(raw.channel, 1, timeout=0.1)

    async def go() -> bytes:
        async with x:
            return await x.read(STATUSWORD)

    try:
        assert run(go()) == b"\x22\x22"
    finally:
        raw.close()
    assert x.stale == 1


def test_an_answer_for_another_object_or_malformed_is_a_link_error() -> None:
    def reply(req: slmp.Request, n: int) -> list[bytes]:
        if n == 1:  # Index 6064h where 6041h was asked.
            data = slmp.download_data(0x6064, 0, b"\x00\x00\x00\x00")
            return [slmp.build_response(req.serial, req.route, 0, data)]
        return [slmp.build_response(req.serial, req.route, 0, b"\x41\x60")]  # Cut short.

    raw = RawStation(reply)

    async def go() -> None:
        async with link(raw.channel, 1) as x:
            with pytest.raises(LinkError, match="answered for 6064h:00h"):
                await x.read(STATUSWORD)
            with pytest.raises(LinkError, match="malformed"):
                await x.read(STATUSWORD)

    try:
        run(go())
    finally:
        raw.close()
