"""The CTMM04x twin answers malformed SLMP requests as SLMP servers do (issue 47).

An end code where the 4E request header is readable (the answer can be addressed: serial
no. and route), silence only where it is not; all four axes from one station (one
`servodesk sim` process, multidrop 0-3). Real UDP sockets; docs/slmp.md lists each
assumption and where it comes from.
"""

from __future__ import annotations

import socket
import struct
import subprocess
import sys
from collections.abc import Iterator

import pytest

from servodesk.domain import slmp
from servodesk.sim.bus import SimulatedBus

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def station() -> Iterator[tuple[SimulatedBus, socket.socket]]:
    with SimulatedBus.start(
        drives=[("ctmm04x", n) for n in (1, 2, 3, 4)], interface="slmp", channel="127.0.0.1:0"
    ) as bus:
        assert bus.station is not None
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.settimeout(0.3)
        sock.connect(bus.station.address)
        try:
            yield bus, sock
        finally:
            sock.close()


def ask(sock: socket.socket, frame: bytes) -> slmp.Response | None:
    sock.send(frame)
    try:
        return slmp.parse_response(sock.recv(4096))
    except TimeoutError:
        return None


def upload(serial: int, multidrop: int, index: int = 0x6041) -> bytes:
    return slmp.build_request(
        serial, slmp.Route(multidrop=multidrop), slmp.CMD_OBJECT, slmp.SUB_UPLOAD,
        slmp.upload_data(index, 0),
    )  # fmt: skip


def test_one_station_serves_all_four_axes(station: tuple[SimulatedBus, socket.socket]) -> None:
    # 003 §4-2: the request-destination multidrop no. picks the axis (0 = X ... 3 = U).
    bus, sock = station
    for multidrop in range(4):
        bus.drives[multidrop].write(0x607A, 0, 1000 + multidrop)
        r = ask(sock, upload(10 + multidrop, multidrop, 0x607A))
        assert r is not None and r.end_code == 0 and r.serial == 10 + multidrop
        assert r.route.multidrop == multidrop
        assert slmp.parse_object_data(r.data, with_value=True).data == struct.pack(
            "<i", 1000 + multidrop
        )
    r = ask(sock, upload(20, 4))
    assert r is not None and r.end_code == 0xCF10  # no axis behind multidrop 4


def test_a_readable_header_with_a_wrong_length_gets_c061(
    station: tuple[SimulatedBus, socket.socket],
) -> None:
    # SLMP: C061h "request data length does not match the number of data". The answer
    # carries the request's serial no. and route, and the error information.
    _bus, sock = station
    good = upload(33, 1)
    longer = good[:11] + struct.pack("<H", len(good) - 13 + 4) + good[13:]
    for frame in (longer, good[:-2], good[:13] + b"\x04\x00"):
        if frame is not longer:
            frame = frame[:11] + struct.pack("<H", len(frame) - 13) + frame[13:]
        r = ask(sock, frame)
        assert r is not None, frame.hex()
        assert (r.end_code, r.serial, r.route.multidrop) == (0xC061, 33, 1)
        assert len(r.data) == 9  # network, station, module I/O, multidrop, command, sub


def test_a_fixed_field_other_than_zero_gets_c05c(
    station: tuple[SimulatedBus, socket.socket],
) -> None:
    _bus, sock = station
    good = upload(34, 0)
    r = ask(sock, good[:4] + b"\x01\x00" + good[6:])
    assert r is not None and (r.end_code, r.serial) == (0xC05C, 34)


@pytest.mark.parametrize(
    "frame",
    [
        b"GET / HTTP/1.1\r\n\r\n",  # not SLMP
        bytes.fromhex("5000") + bytes(20),  # a 3E subheader: no serial no. to answer with
        bytes.fromhex("54000100"),  # a 4E request cut inside its header
        b"5400",  # an ASCII-coded frame on a binary station
    ],
)
def test_an_unreadable_header_gets_no_answer(
    station: tuple[SimulatedBus, socket.socket], frame: bytes
) -> None:
    _bus, sock = station
    assert ask(sock, frame) is None
    r = ask(sock, upload(35, 0))  # and the station goes on answering
    assert r is not None and r.end_code == 0


def test_servodesk_sim_serves_four_axes_from_one_process() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "servodesk", "sim", "--profile", "ctmm04x", "--interface",
         "slmp", "--channel", "127.0.0.1:0", "--axes", "4"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline() for _ in range(4)]
        channels = {line.rsplit(" on ", 1)[1].split(";")[0] for line in lines}
        assert len(channels) == 1, lines  # one station, one port
        host, port = next(iter(channels)).removeprefix("slmp:").rsplit(":", 1)
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.settimeout(1.0)
        sock.connect((host, int(port)))
        for multidrop in range(4):
            r = ask(sock, upload(40 + multidrop, multidrop))
            assert r is not None and r.end_code == 0
        sock.close()
    finally:
        proc.terminate()
        proc.wait(10)
    bad = subprocess.run(
        [sys.executable, "-m", "servodesk", "sim", "--axes", "2"], capture_output=True, text=True
    )
    assert bad.returncode == 2 and "--interface slmp" in bad.stderr
