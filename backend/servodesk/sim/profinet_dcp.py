"""The DCP side of a simulated PROFINET device: it answers Identify and Set on a network
interface (the device end of a veth pair) as a PROFINET IO device does
(:mod:`servodesk.domain.dcp`).

:meth:`DcpResponder.answer` turns one request frame into the response frame (pure, no
socket); :meth:`DcpResponder.start` serves a raw socket from a thread. What it holds is a
:class:`DcpStation`: the station name, the IP suite, the identity it reports, and how often its
LED was asked to flash. Setting an address goes through ``on_ip`` (the PNIO-CM server moves
to it, sim/profinet_device.py); a device with an application relation open refuses a new name
or address (BlockError 6, "in operation"), as a device in data exchange does.
"""

from __future__ import annotations

import ipaddress
import logging
import select
import socket
import struct
import threading
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from servodesk.domain import dcp
from servodesk.errors import NotFoundError, ValidationError
from servodesk.nic import open_raw, require

log = logging.getLogger(__name__)


@dataclass(slots=True)
class DcpStation:
    """What a device holds and reports over DCP."""

    vendor_id: int
    device_id: int
    type_of_station: str
    name_of_station: str = ""
    ip: str = "0.0.0.0"
    netmask: str = "0.0.0.0"
    gateway: str = "0.0.0.0"
    #: DeviceRole: an IO device.
    role: int = 0x01
    instance: int = 1
    #: Control / Signal requests seen (the LED flashes).
    flashes: int = 0
    #: Reset to factory modes carried out, in order.
    resets: list[int] = field(default_factory=list)
    #: The address switches (the LECSN-T's axis rotary switches SW2/SW3): 00h lets the IO
    #: controller (DCP) set the IP address; any other value sets it from the switches, and
    #: a DCP Set of the IP suite is refused with BlockError 5 (004 §20.1.3(4)).
    address_switch: int = 0


def _ack_set(block: dcp.Block, error: int) -> dcp.Block:
    return dcp.ack_block(block.option, block.suboption, error)


class DcpResponder:
    """Answers DCP for one :class:`DcpStation` with the MAC ``mac``."""

    def __init__(
        self,
        station: DcpStation,
        mac: bytes,
        *,
        busy: Callable[[], bool] = lambda: False,
        on_ip: Callable[[str], bool] | None = None,
        on_factory: Callable[[int], None] | None = None,
    ) -> None:
        self.station = station
        self.mac = mac
        self._busy = busy
        self._on_ip = on_ip
        self._on_factory = on_factory
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        #: Requests answered (tests).
        self.answered = 0

    # Frames ----------------------------------------------------------------------------

    def answer(self, frame: bytes) -> bytes | None:
        """The response to one frame; None for a frame that is not for this device."""
        try:
            req = dcp.parse(frame)
        except dcp.MalformedFrame:
            return None
        if req.service_type != dcp.TYPE_REQUEST:
            return None
        if req.frame_id == dcp.FRAME_IDENTIFY_REQUEST and req.service_id == dcp.SERVICE_IDENTIFY:
            if req.dst not in (dcp.IDENTIFY_MULTICAST, self.mac) or not self._matches(req):
                return None
            return dcp.Packet(
                req.src,
                self.mac,
                dcp.FRAME_IDENTIFY_RESPONSE,
                dcp.SERVICE_IDENTIFY,
                dcp.TYPE_SUCCESS,
                req.xid,
                0,
                self._identity(),
            ).encode()
        if req.frame_id != dcp.FRAME_GET_SET or req.dst != self.mac:
            return None
        if req.service_id == dcp.SERVICE_SET:
            blocks = tuple(self._set(b) for b in req.blocks)
            service_type = dcp.TYPE_SUCCESS
        elif req.service_id == dcp.SERVICE_GET:
            # (0, 0) pairs are skipped: some clients (pnio-dcp) send each option with a zero
            # block length after it.
            wanted = [
                (b.option, b.suboption) for b in req.blocks if (b.option, b.suboption) != (0, 0)
            ]
            blocks = tuple(self._get(o, s) for o, s in wanted)
            service_type = dcp.TYPE_SUCCESS
        else:
            blocks, service_type = (), dcp.TYPE_NOT_SUPPORTED
        return dcp.Packet(
            req.src, self.mac, dcp.FRAME_GET_SET, req.service_id, service_type, req.xid, 0, blocks
        ).encode()

    def response_delay(self, frame: bytes) -> float:
        """Seconds to wait before answering an Identify: (a hash of the MAC mod the request's
        ResponseDelayFactor) x 10 ms, so that devices do not all answer at once."""
        try:
            factor = dcp.parse(frame).response_delay
        except dcp.MalformedFrame:
            return 0.0
        if factor <= 1:
            return 0.0
        return (zlib.crc32(self.mac) % factor) * dcp.RESPONSE_DELAY_UNIT_S

    def _matches(self, req: dcp.Packet) -> bool:
        s = self.station
        for b in req.blocks:
            key = (b.option, b.suboption)
            if key == (dcp.OPT_ALL, dcp.SUB_ALL):
                continue
            if key == (dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION):
                if b.data.decode("ascii", "replace") != s.name_of_station:
                    return False
            elif key == (dcp.OPT_DEVICE, dcp.SUB_DEVICE_ID):
                if b.data != struct.pack(">HH", s.vendor_id, s.device_id):
                    return False
            else:
                return False  # A filter this device cannot satisfy.
        return True

    def _identity(self) -> tuple[dcp.Block, ...]:
        s = self.station
        ip_info = dcp.IP_INFO_NOT_SET if s.ip == "0.0.0.0" else dcp.IP_INFO_SET
        suite = b"".join(ipaddress.IPv4Address(a).packed for a in (s.ip, s.netmask, s.gateway))
        options = bytes(
            (
                dcp.OPT_IP, dcp.SUB_MAC, dcp.OPT_IP, dcp.SUB_IP,
                dcp.OPT_DEVICE, dcp.SUB_TYPE_OF_STATION, dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION,
                dcp.OPT_DEVICE, dcp.SUB_DEVICE_ID, dcp.OPT_DEVICE, dcp.SUB_ROLE,
                dcp.OPT_DEVICE, dcp.SUB_INSTANCE, dcp.OPT_CONTROL, dcp.SUB_SIGNAL,
                dcp.OPT_CONTROL, dcp.SUB_RESET_TO_FACTORY,
            )
        )  # fmt: skip
        return (
            dcp.response_block(dcp.OPT_DEVICE, dcp.SUB_OPTIONS, 0, options),
            dcp.response_block(
                dcp.OPT_DEVICE, dcp.SUB_TYPE_OF_STATION, 0, s.type_of_station.encode()
            ),
            dcp.response_block(
                dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION, 0, s.name_of_station.encode()
            ),
            dcp.response_block(
                dcp.OPT_DEVICE, dcp.SUB_DEVICE_ID, 0, struct.pack(">HH", s.vendor_id, s.device_id)
            ),
            dcp.response_block(dcp.OPT_DEVICE, dcp.SUB_ROLE, 0, bytes((s.role, 0))),
            dcp.response_block(dcp.OPT_DEVICE, dcp.SUB_INSTANCE, 0, struct.pack(">H", s.instance)),
            dcp.response_block(dcp.OPT_IP, dcp.SUB_IP, ip_info, suite),
        )

    def _get(self, option: int, suboption: int) -> dcp.Block:
        """One Get answer: the option's block as Identify reports it, its MAC, or a
        Control / Response block with BlockError 1 (option) / 2 (suboption not supported)
        (IEC 61158-6-10 DCP-Get.Res)."""
        if (option, suboption) == (dcp.OPT_IP, dcp.SUB_MAC):
            return dcp.response_block(dcp.OPT_IP, dcp.SUB_MAC, 0, self.mac)
        for b in self._identity():
            if (b.option, b.suboption) == (option, suboption):
                return b
        known = option in (dcp.OPT_IP, dcp.OPT_DEVICE, dcp.OPT_CONTROL)
        return dcp.ack_block(option, suboption, 2 if known else 1)

    def _set(self, b: dcp.Block) -> dcp.Block:
        """Carry out one Set block; its Control / Response block."""
        s = self.station
        key = (b.option, b.suboption)
        if key in ((dcp.OPT_CONTROL, dcp.SUB_START), (dcp.OPT_CONTROL, dcp.SUB_END)):
            return _ack_set(b, 0)
        if key == (dcp.OPT_CONTROL, dcp.SUB_SIGNAL):
            s.flashes += 1  # The Network Status LED blinks green (004 §20.2.3).
            return _ack_set(b, 0)
        if b.option not in (dcp.OPT_IP, dcp.OPT_DEVICE, dcp.OPT_CONTROL):
            return _ack_set(b, 1)
        if key not in (
            (dcp.OPT_IP, dcp.SUB_IP),
            (dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION),
            (dcp.OPT_CONTROL, dcp.SUB_RESET_TO_FACTORY),
        ):
            return _ack_set(b, 2)
        if self._busy():
            return _ack_set(b, 6)
        if len(b.data) < 2:
            return _ack_set(b, 5)
        qualifier, data = struct.unpack_from(">H", b.data)[0], b.data[2:]
        if key == (dcp.OPT_IP, dcp.SUB_IP):
            if s.address_switch:
                return _ack_set(b, 5)  # The switches set the address, not the master.
            if len(data) != 12:
                return _ack_set(b, 5)
            suite = [str(ipaddress.IPv4Address(data[i : i + 4])) for i in (0, 4, 8)]
            try:
                ip, mask, gw = dcp.check_ip_suite(*suite)
            except ValidationError:
                return _ack_set(b, 5)
            if self._on_ip is not None and not self._on_ip(ip):
                return _ack_set(b, 5)
            s.ip, s.netmask, s.gateway = ip, mask, gw
            return _ack_set(b, 0)
        if key == (dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION):
            try:
                s.name_of_station = dcp.check_name_of_station(data.decode("ascii"))
            except (UnicodeDecodeError, ValidationError):
                return _ack_set(b, 5)
            return _ack_set(b, 0)
        mode = qualifier >> 1
        if mode not in dcp.RESET_MODES:
            return _ack_set(b, 2)
        # 004 §20.4.5: the station name becomes "" and the IP 0.0.0.0 (both modes); mode 8
        # also restores the drive's parameters; then a reset like a power cycle.
        if self._on_ip is not None:
            self._on_ip("0.0.0.0")
        s.name_of_station = ""
        s.ip = s.netmask = s.gateway = "0.0.0.0"
        s.resets.append(mode)
        if self._on_factory is not None:
            self._on_factory(mode)
        return _ack_set(b, 0)

    # Socket ----------------------------------------------------------------------------

    def start(self, ifname: str) -> DcpResponder:
        """Answer on ``ifname`` from a thread (LinkError when it cannot be opened)."""
        # The device side opens its own socket: sim never imports a link (docs/architecture.md,
        # the layer rules that `lint-imports` checks).
        require(ifname, hint="the simulated line's veth pair (sim/veth.py) must exist")
        self._sock = open_raw(
            ifname,
            dcp.ETHERTYPE,
            what="PROFINET DCP",
            permission_hint="DCP is layer 2 (raw Ethernet frames): run as root or give CAP_NET_RAW",
        )
        self._thread = threading.Thread(target=self._serve, name="dcp-device", daemon=True)
        self._thread.start()
        log.info("DCP device %s on %s", dcp.mac_text(self.mac), ifname)
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _serve(self) -> None:
        sock = self._sock
        assert sock is not None
        while not self._stop.is_set():
            ready, _, _ = select.select([sock], [], [], 0.05)
            if not ready:
                continue
            try:
                frame, addr = sock.recvfrom(2048)
            except OSError:
                return
            if addr[2] == socket.PACKET_OUTGOING:
                continue
            try:
                answer = self.answer(frame)
            except Exception:  # A bug here must not stop the device.
                log.exception("DCP request not answered")
                continue
            if answer is None:
                continue
            self.answered += 1
            delay = self.response_delay(frame)
            if delay > 0:
                timer = threading.Timer(delay, self._send, (answer,))
                timer.daemon = True
                timer.start()
            else:
                self._send(answer)

    def _send(self, frame: bytes) -> None:
        sock = self._sock
        if sock is None:
            return
        try:
            sock.send(frame)
        except OSError:
            log.debug("DCP answer not sent", exc_info=True)


def interface_mac(ifname: str) -> bytes:
    """The MAC address of a network interface (from sysfs); NotFoundError without one."""
    try:
        text = Path(f"/sys/class/net/{ifname}/address").read_text().strip()
    except OSError:
        raise NotFoundError(
            f"no network interface {ifname!r}",
            hint="give the device end of a veth pair (servodesk.sim.veth) or a NIC",
        ) from None
    return bytes.fromhex(text.replace(":", ""))
