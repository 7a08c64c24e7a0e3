"""The PROFINET link against the simulated LECSN-T over real UDP sockets.

Every request goes through PNIO-CM (connect, record write / read, release) to the twin's
RPC server, which carries out PROFIdrive parameter requests on the drive model. Silent,
lossy and restarted devices are real UDP peers too.
"""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import pytest

from servodesk.domain.address import ObjectAddress as A
from servodesk.domain.profile_loader import ProfileCatalog, default_profile_dirs
from servodesk.errors import (
    ConflictError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ValidationError,
)
from servodesk.links import profinet_link
from servodesk.links.base import LinkParams
from servodesk.links.profinet_link import ProfinetLink
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.profinet_device import ProfinetDevice

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def catalog() -> ProfileCatalog:
    return ProfileCatalog()


@pytest.fixture
def device(catalog: ProfileCatalog) -> Iterator[ProfinetDevice]:
    with ProfinetDevice(SimulatedDrive(catalog.get("lecsn-t"), 1)) as dev:
        yield dev


def params(channel: str, node_id: int = 1, timeout: float = 0.5) -> LinkParams:
    return LinkParams(interface="profinet", channel=channel, node_id=node_id, timeout=timeout)


@pytest.fixture
async def link(device: ProfinetDevice) -> AsyncIterator[ProfinetLink]:
    lk = ProfinetLink(params(device.channel))
    await lk.open()
    try:
        yield lk
    finally:
        await lk.close()


def i32(v: int) -> bytes:
    return v.to_bytes(4, "little", signed=True)


async def test_opening_sets_up_an_ar_and_closing_ends_it(device: ProfinetDevice) -> None:
    lk = ProfinetLink(params(device.channel))
    await lk.open()
    assert device.ars == 1
    ident = await lk.identity()
    # I&M0 of 004 §20.4.4: Mitsubishi's manufacturer ID and the MR-J4-TM order ID.
    assert (ident.vendor_id, ident.device_name) == (540, "MR-J4-TM")
    assert ident.software_version is not None and ident.software_version.startswith("V")
    await lk.close()
    assert device.ars == 0


async def test_values_arrive_in_coe_byte_order(link: ProfinetLink, device: ProfinetDevice) -> None:
    await link.write(A(0x607A), i32(-123456))
    assert device.drive.read(0x607A) == -123456
    assert await link.read(A(0x607A)) == i32(-123456)
    assert await link.read(A(0x039A)) == (1).to_bytes(2, "little")  # P922, telegram 1
    device.drive.write(0x6081, 0, 4321)
    assert await link.read(A(0x6081)) == (4321).to_bytes(4, "little")
    # Every parameter of the manual holds a value (issue 47): the model name string too.
    assert await link.read(A(0x2D30)) == b"MR-J4-TM"


async def test_arrays_map_by_the_pnu_subindex_rule(
    link: ProfinetLink, device: ProfinetDevice
) -> None:
    device.drive.write(0x6099, 1, 2500)  # PNU 24729.0
    device.drive.write(0x6099, 2, 700)  # PNU 24729.1
    assert await link.read(A(0x6099, 1)) == (2500).to_bytes(4, "little")
    assert await link.read(A(0x6099, 2)) == (700).to_bytes(4, "little")
    # CoE sub 0: the number of entries, from the parameter's description (element 2).
    assert await link.read(A(0x6099, 0)) == b"\x02"
    await link.write(A(0x607D, 2), i32(90000))
    assert device.drive.read(0x607D, 2) == 90000
    # Below 1000h the subindex is the PNU's own: P964.0 is the manufacturer ID.
    assert await link.read(A(0x03C4, 0)) == (540).to_bytes(2, "little")


async def test_refusals_carry_the_profidrive_error_number(link: ProfinetLink) -> None:
    async def refused(coro: object) -> ObjectAccessError:
        with pytest.raises(ObjectAccessError) as info:
            await coro  # type: ignore[misc]
        assert info.value.protocol == "profidrive"
        return info.value

    e = await refused(link.read(A(0x7777)))
    assert e.code == 0x00 and "Impermissible parameter number" in e.message
    e = await refused(link.write(A(0x6041), b"\0\0"))
    assert e.code == 0x01
    e = await refused(link.read(A(0x2D52)))  # P11602, the tuning stop: write-only
    assert e.code == 0xFF and e.hint and "write-only" in e.hint
    e = await refused(link.write(A(0x6099, 0), b"\x03"))  # the number of entries
    assert e.code == 0x07
    e = await refused(link.read(A(0x6099, 5)))
    assert e.code == 0x03
    # A value of the wrong size never leaves servodesk.
    with pytest.raises(ValidationError, match="no value of the parameter's format 04h"):
        await link.write(A(0x607A), b"\x01")


async def test_a_write_only_parameter_is_written_with_its_identifier_s_type(
    link: ProfinetLink, device: ProfinetDevice
) -> None:
    # P11602 (2D52h) takes only 1EA5h (004 §20.8.7); anything else is error 02h.
    with pytest.raises(ObjectAccessError) as info:
        await link.write(A(0x2D52), (0x1234).to_bytes(2, "little"))
    assert info.value.code == 0x02
    await link.write(A(0x2D52), (0x1EA5).to_bytes(2, "little"))


async def test_read_many_packs_up_to_39_parameters_per_request(
    link: ProfinetLink, device: ProfinetDevice
) -> None:
    addresses = [A(0x6041), A(0x6064), A(0x7777), A(0x6081)] * 10  # 40 objects
    before = device.answered
    first = await link.read_many(addresses[:4])
    # Not known yet whether they are arrays: three parameters each, one request (a record
    # write and read: two RPC calls).
    assert device.answered - before == 2
    before = device.answered
    got = await link.read_many(addresses)
    # Known now: two parameter requests (39 + 1 parameters), four RPC calls.
    assert device.answered - before == 4
    assert got[:4] == first or all(isinstance(g, ObjectAccessError) for g in (got[2], first[2]))
    assert isinstance(got[2], ObjectAccessError) and got[2].code == 0x00
    assert got[3] == (10000).to_bytes(4, "little")  # 6081h's default
    assert all(isinstance(g, bytes) for i, g in enumerate(got) if i % 4 != 2)


LONG_TEXT = "".join(chr(ord("a") + i % 26) for i in range(600))


@pytest.fixture
def long_text_device(tmp_path: Path) -> Iterator[ProfinetDevice]:
    """A drive with a 600-character string: more than one 240-byte response holds."""
    (tmp_path / "long-text").mkdir()
    (tmp_path / "long-text" / "profile.yaml").write_text(
        "id: long-text\nname: Long text drive\nvendor: test\nfieldbus: profinet\n"
        "extends: cia402-generic\nidentity: {vendor_id: 0x12345678}\n"
        "objects:\n- index: 0x2100\n  name: Long text\n  data_type: VISIBLE_STRING\n"
        f"  access: ro\n  default: {LONG_TEXT}\n"
    )
    profile = ProfileCatalog(default_profile_dirs([tmp_path])).get("long-text")
    with ProfinetDevice(SimulatedDrive(profile, 1)) as dev:
        yield dev


async def test_a_value_longer_than_one_response_is_read_in_blocks(
    long_text_device: ProfinetDevice,
) -> None:
    lk = ProfinetLink(params(long_text_device.channel))
    await lk.open()
    try:
        assert await lk.read(A(0x2100)) == LONG_TEXT.encode()
        got = await lk.read_many([A(0x6041), A(0x2100), A(0x6041)])
        assert got[1] == LONG_TEXT.encode()
        assert got[0] == got[2] == long_text_device.drive.read_bytes(0x6041, 0)
    finally:
        await lk.close()


async def test_a_drive_object_that_is_not_there_is_not_found(device: ProfinetDevice) -> None:
    lk = ProfinetLink(params(device.channel, node_id=2))
    await lk.open()
    try:
        with pytest.raises(NotFoundError, match="no drive object 2"):
            await lk.read(A(0x6041))
    finally:
        await lk.close()


async def test_nothing_listening_is_not_found() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    lk = ProfinetLink(params(f"127.0.0.1:{port}"))
    with pytest.raises(NotFoundError, match="nothing answers PNIO-CM"):
        await lk.open()


async def test_a_silent_device_times_out_after_two_connect_requests() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as silent:
        silent.bind(("127.0.0.1", 0))
        port = silent.getsockname()[1]
        lk = ProfinetLink(params(f"127.0.0.1:{port}", timeout=0.2))
        with pytest.raises(NotFoundError, match="no answer to 2 connect requests"):
            await lk.open()
        silent.settimeout(0.5)
        assert len({silent.recv(2048)[:80] for _ in range(2)}) == 1  # the same call, twice


async def test_a_device_that_forgot_the_ar_is_connected_again(
    link: ProfinetLink, device: ProfinetDevice
) -> None:
    await link.read(A(0x6041))
    device._state.ars.clear()  # the device restarted
    assert await link.read(A(0x6041)) == device.drive.read_bytes(0x6041, 0)
    assert link.reconnects == 1 and device.ars == 1


async def test_an_idle_ar_times_out_on_the_device_and_the_next_access_sets_it_up_again(
    device: ProfinetDevice, monkeypatch: pytest.MonkeyPatch
) -> None:
    # CMInitiatorActivityTimeoutFactor 5: the device drops the AR after 0.5 s without a
    # record read or write (IEC 61158-6-10 CMSM).
    monkeypatch.setattr(profinet_link, "ACTIVITY_TIMEOUT_FACTOR", 5)
    lk = ProfinetLink(params(device.channel))
    await lk.open()
    try:
        for _ in range(10):  # 1 s of reads 0.1 s apart: each one restarts the time-out
            await lk.read(A(0x6041))
            await asyncio.sleep(0.1)
        assert (device.ars, lk.reconnects) == (1, 0)
        await asyncio.sleep(0.7)
        assert device.ars == 0  # silent for longer than 0.5 s: dropped
        assert await lk.read(A(0x6041)) == device.drive.read_bytes(0x6041, 0)
        assert (device.ars, lk.reconnects) == (1, 1)
    finally:
        await lk.close()
    assert device.ars == 0


@pytest.mark.parametrize("factor", [0, 1001])
async def test_an_activity_time_out_outside_0_1_to_100_s_is_refused(
    device: ProfinetDevice, monkeypatch: pytest.MonkeyPatch, factor: int
) -> None:
    monkeypatch.setattr(profinet_link, "ACTIVITY_TIMEOUT_FACTOR", factor)
    lk = ProfinetLink(params(device.channel))
    with pytest.raises(ConflictError, match="refused the supervisor AR") as info:
        await lk.open()
    assert "PNIOStatus DB81010Ah" in info.value.message  # ARBlockReq field 10
    assert device.ars == 0


async def test_a_device_that_went_away_times_out_and_is_found_again_after_its_restart(
    catalog: ProfileCatalog,
) -> None:
    drive = SimulatedDrive(catalog.get("lecsn-t"), 1)
    first = ProfinetDevice(drive).start()
    host, port = first.address
    lk = ProfinetLink(params(f"{host}:{port}", timeout=0.2))
    await lk.open()
    try:
        await lk.write(A(0x6081), (1234).to_bytes(4, "little"))
        first.stop()  # Power off: nothing answers (or the port is closed).
        with pytest.raises((LinkTimeoutError, NotFoundError)):
            await lk.read(A(0x6081))
        with ProfinetDevice(drive, host, port) as second:  # Powered again, no AR known.
            assert await lk.read(A(0x6081)) == (1234).to_bytes(4, "little")
            assert lk.reconnects == 1 and second.ars == 1
    finally:
        await lk.close()


class _LossyProxy:
    """A UDP relay between the link and the device that drops the device's first answer to
    a change request (the write of record 0xB02E)."""

    def __init__(self, target: tuple[str, int]) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.target = target
        self.client: tuple[str, int] | None = None
        self.drop_next_write_answer = False
        self.dropped = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @property
    def channel(self) -> str:
        return f"127.0.0.1:{self.sock.getsockname()[1]}"

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, peer = self.sock.recvfrom(65535)
            except TimeoutError:
                continue
            if peer != self.target:
                self.client = peer
                self.sock.sendto(data, self.target)
                continue
            opnum = int.from_bytes(data[68:70], "little")
            if self.drop_next_write_answer and opnum == 3:
                self.drop_next_write_answer = False
                self.dropped += 1
                continue
            assert self.client is not None
            self.sock.sendto(data, self.client)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1)
        self.sock.close()


async def test_a_lost_answer_is_asked_again_and_the_request_runs_once(
    device: ProfinetDevice,
) -> None:
    proxy = _LossyProxy(device.address)
    lk = ProfinetLink(params(proxy.channel, timeout=0.2))
    try:
        await lk.open()
        await lk.write(A(0x607A), i32(1))
        changes = device.answered
        proxy.drop_next_write_answer = True
        await lk.write(A(0x607A), i32(777))
        assert proxy.dropped == 1
        # The resend had the same sequence number: the device answered it from its cache.
        assert device.resends == 1
        assert device.drive.read(0x607A) == 777
        assert device.answered - changes == 3  # write (twice, one lost) + read of the answer
    finally:
        await lk.close()
        proxy.close()


async def test_two_links_to_one_device_keep_their_own_ars(device: ProfinetDevice) -> None:
    a, b = ProfinetLink(params(device.channel)), ProfinetLink(params(device.channel))
    await a.open()
    await b.open()
    try:
        assert device.ars == 2
        results = await asyncio.gather(
            *(lk.write(A(0x6081), (n * 100).to_bytes(4, "little")) for lk, n in ((a, 1), (b, 2)))
        )
        assert results == [None, None]
        assert device.drive.read(0x6081) in (100, 200)
    finally:
        await a.close()
        await b.close()
    assert device.ars == 0


def test_a_wrong_interface_or_node_is_refused_before_anything_is_sent() -> None:
    with pytest.raises(ValidationError, match="does not carry PROFINET"):
        ProfinetLink(LinkParams(interface="virtual", channel="x", node_id=1))
    with pytest.raises(ValidationError, match="no PROFIdrive DO-ID"):
        ProfinetLink(params("127.0.0.1", node_id=0))
    with pytest.raises(ValidationError, match="port"):
        ProfinetLink(params("127.0.0.1:99999"))


async def test_the_device_keeps_resend_answers_for_its_recent_clients_only(
    device: ProfinetDevice,
) -> None:
    # Each session is a client activity of its own; a long-running device must not keep an
    # answer for every client it ever had (it did: the cache grew by one per session).
    from servodesk.sim.profinet_device import RESEND_CACHE

    for _ in range(RESEND_CACHE + 6):
        lk = ProfinetLink(params(device.channel))
        await lk.open()
        await lk.close()
    assert device.cached_activities == RESEND_CACHE
    # And a new client is served as before.
    lk = ProfinetLink(params(device.channel))
    await lk.open()
    try:
        assert await lk.read(A(0x6041)) is not None
    finally:
        await lk.close()
    assert device.cached_activities == RESEND_CACHE
