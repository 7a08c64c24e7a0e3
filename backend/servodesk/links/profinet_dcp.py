"""DCP on a network interface: find the PROFINET devices on its segment, set a device's
station name or IP address, flash its LED, reset it to factory settings (docs/profinet.md).

Frames are built and parsed by :mod:`servodesk.domain.dcp`; this module sends them on a raw
AF_PACKET socket (EtherType 8892h), which needs root or CAP_NET_RAW, as the EtherCAT link
does. The calls block (a scan waits for its whole time-out); the API runs them in a thread.
"""

from __future__ import annotations

import errno
import random
import select
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass

from servodesk.domain import dcp
from servodesk.errors import LinkError, NotFoundError, ObjectAccessError
from servodesk.nic import check_name, open_raw, require

#: How long one Set waits for its answer, and how often it is sent (the same Xid: a device
#: that set the value and whose answer was lost sets it again, which changes nothing).
SET_TIMEOUT_S = 1.0
SET_ATTEMPTS = 3


@dataclass(frozen=True, slots=True)
class Scan:
    """The devices that answered an Identify, and the answers that could not be read."""

    devices: list[dcp.Device]
    malformed: int = 0


def open_socket(nic: str) -> socket.socket:
    """A raw socket for DCP frames on ``nic``; LinkError / NotFoundError with what to do."""
    check_name(
        nic,
        field="nic",
        hint="give the interface the drives are on, as `ip link` lists it (e.g. eth1)",
    )
    require(nic, hint="give the one the drives are cabled to")
    return open_raw(
        nic,
        dcp.ETHERTYPE,
        what="PROFINET DCP",
        permission_hint="DCP is layer 2 (raw Ethernet frames): run as root or give CAP_NET_RAW",
    )


class DcpClient:
    """A DCP client on one network interface (a context manager)."""

    def __init__(self, nic: str) -> None:
        self.nic = nic
        self._sock = open_socket(nic)
        self.mac: bytes = self._sock.getsockname()[4][:6]

    def close(self) -> None:
        self._sock.close()

    def __enter__(self) -> DcpClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # Services --------------------------------------------------------------------------

    def identify(self, timeout: float, *, name: str | None = None) -> Scan:
        """Every device that answers an Identify within ``timeout`` seconds (or the one
        named ``name``), in the order of their station names and MACs."""
        xid = random.getrandbits(32)
        req = dcp.identify_request(
            self.mac, xid, response_delay=dcp.response_delay_factor(timeout), name=name
        )
        self._send(req.encode())
        found: dict[str, dcp.Device] = {}
        malformed = 0

        def take(p: dcp.Packet) -> bool:
            nonlocal malformed
            if p.frame_id != dcp.FRAME_IDENTIFY_RESPONSE or p.xid != xid:
                return False
            try:
                dev = dcp.device_from(p)
            except dcp.MalformedFrame:
                malformed += 1
                return False
            found.setdefault(dev.mac, dev)
            return False  # keep listening until the time-out: every device may answer

        self._receive(time.monotonic() + timeout, take)
        devices = sorted(found.values(), key=lambda d: (d.name_of_station or "~", d.mac))
        return Scan(devices, malformed)

    def _ask(
        self, mac: bytes, service: int, what: str, build: Callable[[int], bytes]
    ) -> dcp.Packet:
        """Send a unicast request (Get or Set) built for a fresh Xid, resent up to
        SET_ATTEMPTS times, and return the device's successful answer to it; NotFoundError
        when nothing answers, ObjectAccessError (protocol "dcp") when the device answers
        that it does not support the service (its ServiceType)."""
        xid = random.getrandbits(32)
        frame = build(xid)
        answer: list[dcp.Packet] = []

        def take(p: dcp.Packet) -> bool:
            if p.frame_id != dcp.FRAME_GET_SET or p.service_id != service:
                return False
            if p.xid != xid or p.src != mac or p.service_type == dcp.TYPE_REQUEST:
                return False
            answer.append(p)
            return True

        for _ in range(SET_ATTEMPTS):
            self._send(frame)
            if self._receive(time.monotonic() + SET_TIMEOUT_S, take):
                break
        else:
            raise NotFoundError(
                f"no device with MAC {dcp.mac_text(mac)} answers DCP on {self.nic}",
                hint="search the interface again (Identify) and take the MAC from the answer",
            )
        reply = answer[0]
        if reply.service_type != dcp.TYPE_SUCCESS:
            raise ObjectAccessError(
                f"{dcp.mac_text(mac)} does not support {what} (ServiceType {reply.service_type})",
                code=dcp.TYPE_NOT_SUPPORTED,
                meaning="request not supported",
                protocol="dcp",
            )
        return reply

    def get(
        self,
        mac: bytes,
        options: tuple[tuple[int, int], ...] = (
            (dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION),
            (dcp.OPT_IP, dcp.SUB_IP),
            (dcp.OPT_DEVICE, dcp.SUB_DEVICE_ID),
        ),
    ) -> dcp.Device:
        """Ask the device at ``mac`` for ``options`` (DCP Get, unicast; by default its station
        name, IP suite and vendor / device ID); ObjectAccessError (protocol "dcp") when it
        does not support one, NotFoundError when nothing answers."""
        reply = self._ask(
            mac,
            dcp.SERVICE_GET,
            "DCP Get",
            lambda xid: dcp.get_request(mac, self.mac, xid, options),
        )
        try:
            refused = [a for a in dcp.acks(reply) if a.error]
            device = dcp.device_from(reply)
        except dcp.MalformedFrame as exc:
            raise LinkError(f"{dcp.mac_text(mac)} answered a malformed DCP Get: {exc}") from exc
        if refused:
            a = refused[0]
            raise ObjectAccessError(
                f"{dcp.mac_text(mac)} cannot give {dcp.block_name(a.option, a.suboption)}: "
                f"{a.meaning}",
                code=a.error,
                meaning=a.meaning,
                protocol="dcp",
            )
        return device

    def set(self, mac: bytes, blocks: tuple[dcp.Block, ...]) -> list[dcp.Ack]:
        """Send a Set of ``blocks`` to ``mac`` and return its acknowledgements;
        ObjectAccessError (protocol "dcp") when the device refuses a block, NotFoundError
        when nothing answers."""
        reply = self._ask(
            mac,
            dcp.SERVICE_SET,
            "this DCP Set",
            lambda xid: dcp.set_request(mac, self.mac, xid, blocks).encode(),
        )
        try:
            result = dcp.acks(reply)
        except dcp.MalformedFrame as exc:
            raise LinkError(f"{dcp.mac_text(mac)} answered a malformed DCP Set: {exc}") from exc
        for ack in result:
            if ack.error:
                raise ObjectAccessError(
                    f"{dcp.mac_text(mac)} refused {dcp.block_name(ack.option, ack.suboption)}: "
                    f"{ack.meaning}",
                    code=ack.error,
                    meaning=ack.meaning,
                    protocol="dcp",
                    hint=_HINTS.get(ack.error),
                )
        return result

    # Socket ----------------------------------------------------------------------------

    def _send(self, frame: bytes) -> None:
        try:
            self._sock.send(frame)
        except OSError as exc:
            if exc.errno == errno.ENETDOWN:
                raise LinkError(
                    f"{self.nic} is down", hint=f"bring it up (`ip link set {self.nic} up`)"
                ) from exc
            raise LinkError(f"cannot send a DCP frame on {self.nic}: {exc}") from exc

    def _receive(self, deadline: float, take: Callable[[dcp.Packet], bool]) -> bool:
        """Hand each DCP frame arriving before ``deadline`` to ``take`` until it returns
        True (then True); False at the deadline. Frames this socket sent itself, and frames
        that are not DCP, are skipped."""
        while (left := deadline - time.monotonic()) > 0:
            ready, _, _ = select.select([self._sock], [], [], left)
            if not ready:
                break
            data, addr = self._sock.recvfrom(2048)
            if addr[2] == socket.PACKET_OUTGOING:
                continue
            try:
                packet = dcp.parse(data)
            except dcp.MalformedFrame:
                continue
            if take(packet):
                return True
        return False


_HINTS = {
    5: "the device keeps this setting for a reason of its own (an address switch or DHCP "
    "sets it): see the drive's manual",
    6: "the device is in data exchange with its IO controller: stop the controller's "
    "connection (or close servodesk's session on it) and set it again",
}
