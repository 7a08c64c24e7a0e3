"""PROFINET DCP (Discovery and basic Configuration Protocol): the frames that find PROFINET
devices on a network segment and set their station name and IP address (pure, no sockets).

DCP runs directly on Ethernet (EtherType 8892h, IEC 61158-6-10 §4.3 "DCP"). A tool sends
**Identify** to the multicast address 01-0E-CF-00-00-00 (FrameID FEFEh) and every device (or
the one whose name matches the filter) answers unicast (FEFFh) with its blocks: MAC, IP
suite, station name, vendor and device ID, role. **Set** (FEFDh, unicast) writes a station
name or an IP suite, flashes a device's LED (Control / Signal) or resets it to its factory
settings (Control / ResetToFactory); the device acknowledges each block with a Control /
Response block carrying a BlockError.

The LECSN-T's chapter never names DCP, but it is how the station name (004 §20.1.3(2)), the IP
address set "by the master" (§20.1.3(4)), the "engineering tool is checking the node" LED
state (Network Status LED green blinking, §20.2.3) and the reset to factory options 2 and 8
(§20.4.5) reach a PROFINET device.

Frame layout after the Ethernet header (all fields big-endian):
FrameID (2), ServiceID (1), ServiceType (1), Xid (4), ResponseDelay (2), DCPDataLength (2),
then blocks: Option (1), Suboption (1), DCPBlockLength (2), data, one pad byte to an even
length (not counted in the block length, counted in DCPDataLength). A response block's data
starts with BlockInfo (2), a Set request block's with BlockQualifier (2); an Identify filter
block has neither.
"""

from __future__ import annotations

import ipaddress
import re
import struct
from dataclasses import dataclass, field

from servodesk.errors import ValidationError

ETHERTYPE = 0x8892
VLAN_TPID = 0x8100
#: The DCP Identify multicast address (IEC 61158-6-10: PN-MC-Identify).
IDENTIFY_MULTICAST = bytes.fromhex("010ecf000000")
#: Shortest Ethernet frame without the FCS: shorter frames are padded with zeros.
MIN_FRAME = 60

FRAME_HELLO = 0xFEFC
FRAME_GET_SET = 0xFEFD
FRAME_IDENTIFY_REQUEST = 0xFEFE
FRAME_IDENTIFY_RESPONSE = 0xFEFF

SERVICE_GET = 3
SERVICE_SET = 4
SERVICE_IDENTIFY = 5

TYPE_REQUEST = 0
TYPE_SUCCESS = 1
TYPE_NOT_SUPPORTED = 5

# Options and suboptions.
OPT_IP = 0x01
SUB_MAC = 0x01
SUB_IP = 0x02
SUB_FULL_IP = 0x03
OPT_DEVICE = 0x02
SUB_TYPE_OF_STATION = 0x01
SUB_NAME_OF_STATION = 0x02
SUB_DEVICE_ID = 0x03
SUB_ROLE = 0x04
SUB_OPTIONS = 0x05
SUB_ALIAS = 0x06
SUB_INSTANCE = 0x07
OPT_DHCP = 0x03
OPT_CONTROL = 0x05
SUB_START = 0x01
SUB_END = 0x02
SUB_SIGNAL = 0x03
SUB_RESPONSE = 0x04
SUB_FACTORY_RESET = 0x05
SUB_RESET_TO_FACTORY = 0x06
OPT_ALL = 0xFF
SUB_ALL = 0xFF

#: BlockQualifier of a Set block: keep the value over a power cycle, or until then only.
QUALIFIER_TEMPORARY = 0x0000
QUALIFIER_PERMANENT = 0x0001
#: Control / Signal: flash the device's LED (SignalValue 0100h: flash once, for about 3 s).
SIGNAL_FLASH = 0x0100

#: IP parameter BlockInfo: bits 0-1 how the address was set, bit 7 an address conflict.
IP_INFO_NOT_SET = 0
IP_INFO_SET = 1
IP_INFO_DHCP = 2
IP_INFO_CONFLICT = 0x80

#: DeviceRole bits (IEC 61158-6-10 DeviceRoleDetails).
ROLES = {0x01: "IO device", 0x02: "IO controller", 0x04: "IO multidevice", 0x08: "IO supervisor"}

#: ResetToFactory modes: the BlockQualifier is the mode shifted left by one. Manual 004
#: §20.4.5 offers 2 (communication parameters: station name "" and IP 0.0.0.0) and 8 (that
#: and the drive's parameters and point tables to their defaults).
RESET_MODES = {
    2: "reset the communication parameters (station name and IP address)",
    8: "reset the communication parameters and restore the drive's parameters and point "
    "tables to their defaults",
}

#: What a Set block sets, in words.
BLOCK_NAMES = {
    (OPT_IP, SUB_IP): "the IP address",
    (OPT_DEVICE, SUB_NAME_OF_STATION): "the station name",
    (OPT_CONTROL, SUB_SIGNAL): "the LED signal",
    (OPT_CONTROL, SUB_RESET_TO_FACTORY): "a reset to factory",
}


def block_name(option: int, suboption: int) -> str:
    what = BLOCK_NAMES.get((option, suboption), "DCP block")
    return f"{what} ({option:02X}h/{suboption:02X}h)"


#: Control / Response BlockError (IEC 61158-6-10).
BLOCK_ERRORS = {
    0: "no error",
    1: "option not supported",
    2: "suboption not supported or no data set available",
    3: "suboption not set",
    4: "resource error",
    5: "set not possible by local reasons",
    6: "in operation, set not possible",
}

#: Most responses a tool waits for, per response delay unit (IEC 61158-6-10: the device
#: answers an Identify after (its MAC's hash mod ResponseDelayFactor) x 10 ms).
RESPONSE_DELAY_UNIT_S = 0.01
RESPONSE_DELAY_FACTOR_MAX = 6400


class MalformedFrame(ValueError):
    """A frame that is not a well-formed DCP frame (its reason in the message)."""


@dataclass(frozen=True, slots=True)
class Block:
    """One DCP block: ``data`` is everything after the block length (BlockInfo or
    BlockQualifier included), without the pad byte."""

    option: int
    suboption: int
    data: bytes = b""

    def encode(self) -> bytes:
        out = struct.pack(">BBH", self.option, self.suboption, len(self.data)) + self.data
        return out + b"\x00" if len(self.data) % 2 else out


@dataclass(frozen=True, slots=True)
class Packet:
    """One DCP frame."""

    dst: bytes
    src: bytes
    frame_id: int
    service_id: int
    service_type: int
    xid: int
    response_delay: int = 0
    blocks: tuple[Block, ...] = ()

    def encode(self) -> bytes:
        body = b"".join(b.encode() for b in self.blocks)
        frame = (
            self.dst
            + self.src
            + struct.pack(
                ">HHBBIHH",
                ETHERTYPE,
                self.frame_id,
                self.service_id,
                self.service_type,
                self.xid,
                self.response_delay,
                len(body),
            )
            + body
        )
        return frame.ljust(MIN_FRAME, b"\x00")

    def block(self, option: int, suboption: int) -> Block | None:
        return next(
            (b for b in self.blocks if (b.option, b.suboption) == (option, suboption)), None
        )


def parse(frame: bytes) -> Packet:
    """A DCP frame (an optional 802.1Q tag is skipped); MalformedFrame otherwise."""
    if len(frame) < 14:
        raise MalformedFrame(f"{len(frame)} bytes is shorter than an Ethernet header")
    dst, src = frame[0:6], frame[6:12]
    at = 12
    (ethertype,) = struct.unpack_from(">H", frame, at)
    if ethertype == VLAN_TPID:
        at += 4
        if len(frame) < at + 2:
            raise MalformedFrame("the frame ends inside its VLAN tag")
        (ethertype,) = struct.unpack_from(">H", frame, at)
    if ethertype != ETHERTYPE:
        raise MalformedFrame(f"EtherType {ethertype:04X}h is not DCP's 8892h")
    at += 2
    if len(frame) < at + 12:
        raise MalformedFrame("the frame ends inside the DCP header")
    frame_id, service_id, service_type, xid, delay, length = struct.unpack_from(
        ">HBBIHH", frame, at
    )
    if not FRAME_HELLO <= frame_id <= FRAME_IDENTIFY_RESPONSE:
        raise MalformedFrame(f"FrameID {frame_id:04X}h is not a DCP frame (FEFCh-FEFFh)")
    at += 12
    end = at + length
    if end > len(frame):
        raise MalformedFrame(
            f"DCPDataLength {length} runs past the end of the frame ({len(frame) - at} bytes)"
        )
    blocks: list[Block] = []
    if service_id == SERVICE_GET and service_type == TYPE_REQUEST:
        # A Get request lists option / suboption pairs without lengths.
        if length % 2:
            raise MalformedFrame("a Get request's option list has an odd length")
        blocks = [Block(frame[i], frame[i + 1]) for i in range(at, end, 2)]
    else:
        while at < end:
            if at + 4 > end:
                raise MalformedFrame("a block header runs past DCPDataLength")
            option, suboption, blen = struct.unpack_from(">BBH", frame, at)
            at += 4
            if at + blen > end:
                raise MalformedFrame(
                    f"block {option:02X}h/{suboption:02X}h of {blen} bytes runs past DCPDataLength"
                )
            blocks.append(Block(option, suboption, frame[at : at + blen]))
            at += blen + (blen % 2)
    return Packet(dst, src, frame_id, service_id, service_type, xid, delay, tuple(blocks))


# Requests ------------------------------------------------------------------------------


def response_delay_factor(timeout: float) -> int:
    """The ResponseDelayFactor that spreads the answers over half of ``timeout`` (at least 1:
    no spread), so that many devices do not answer at the same instant and the last still
    arrives in time."""
    factor = int(timeout / 2 / RESPONSE_DELAY_UNIT_S)
    return max(1, min(RESPONSE_DELAY_FACTOR_MAX, factor))


def identify_request(
    src: bytes, xid: int, *, response_delay: int = 1, name: str | None = None
) -> Packet:
    """Identify all devices (the All selector) or the one whose station name is ``name``."""
    block = (
        Block(OPT_ALL, SUB_ALL)
        if name is None
        else Block(OPT_DEVICE, SUB_NAME_OF_STATION, name.encode("ascii"))
    )
    return Packet(
        IDENTIFY_MULTICAST,
        src,
        FRAME_IDENTIFY_REQUEST,
        SERVICE_IDENTIFY,
        TYPE_REQUEST,
        xid,
        response_delay,
        (block,),
    )


def get_request(dst: bytes, src: bytes, xid: int, options: tuple[tuple[int, int], ...]) -> bytes:
    """A Get request frame for ``options`` ((option, suboption) pairs): IEC 61158-6-10
    DCP-Get.Req-PDU lists the pairs without block lengths."""
    body = b"".join(bytes(o) for o in options)
    frame = (
        dst
        + src
        + struct.pack(">HHBBIHH", ETHERTYPE, FRAME_GET_SET, SERVICE_GET, TYPE_REQUEST, xid, 0,
                      len(body))
        + body
    )  # fmt: skip
    return frame.ljust(MIN_FRAME, b"\x00")


def set_request(dst: bytes, src: bytes, xid: int, blocks: tuple[Block, ...]) -> Packet:
    return Packet(dst, src, FRAME_GET_SET, SERVICE_SET, TYPE_REQUEST, xid, 0, blocks)


def ip_block(ip: str, netmask: str, gateway: str, *, permanent: bool = True) -> Block:
    """Set the IP suite (address, subnet mask, gateway)."""
    data = struct.pack(">H", QUALIFIER_PERMANENT if permanent else QUALIFIER_TEMPORARY) + b"".join(
        ipaddress.IPv4Address(a).packed for a in (ip, netmask, gateway)
    )
    return Block(OPT_IP, SUB_IP, data)


def name_block(name: str, *, permanent: bool = True) -> Block:
    """Set the station name (already validated: :func:`check_name_of_station`)."""
    qualifier = QUALIFIER_PERMANENT if permanent else QUALIFIER_TEMPORARY
    return Block(OPT_DEVICE, SUB_NAME_OF_STATION, struct.pack(">H", qualifier) + name.encode())


def signal_block() -> Block:
    """Flash the device's LED so that it can be found in the cabinet."""
    return Block(OPT_CONTROL, SUB_SIGNAL, struct.pack(">HH", 0, SIGNAL_FLASH))


def reset_to_factory_block(mode: int) -> Block:
    """Reset to factory in one of :data:`RESET_MODES` (BlockQualifier = mode << 1)."""
    if mode not in RESET_MODES:
        raise ValidationError(
            f"reset mode {mode} is not offered: 2 (communication parameters) or 8 (and the "
            "drive's parameters), 004 §20.4.5",
            field="mode",
            hint="give mode 2 or 8",
        )
    return Block(OPT_CONTROL, SUB_RESET_TO_FACTORY, struct.pack(">H", mode << 1))


# Responses -----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Device:
    """What one device says of itself in its Identify response."""

    mac: str
    name_of_station: str | None = None
    ip: str | None = None
    netmask: str | None = None
    gateway: str | None = None
    #: "not set", "static" or "dhcp" (IP parameter BlockInfo bits 0-1).
    ip_origin: str | None = None
    ip_conflict: bool = False
    vendor_id: int | None = None
    device_id: int | None = None
    type_of_station: str | None = None
    roles: tuple[str, ...] = ()
    alias: str | None = None
    instance: int | None = None
    options: tuple[tuple[int, int], ...] = field(default_factory=tuple)


def mac_text(mac: bytes) -> str:
    return ":".join(f"{b:02x}" for b in mac)


def mac_bytes(text: str) -> bytes:
    """A MAC address from ``aa:bb:cc:dd:ee:ff`` (or with ``-``); ValidationError otherwise."""
    parts = re.split(r"[:-]", text.strip())
    if len(parts) != 6 or not all(re.fullmatch(r"[0-9A-Fa-f]{2}", p) for p in parts):
        raise ValidationError(
            f"{text!r} is not a MAC address", field="mac", hint="write it as 00:30:11:aa:bb:cc"
        )
    mac = bytes(int(p, 16) for p in parts)
    if mac[0] & 1:
        raise ValidationError(
            f"{text!r} is a multicast address, not a device's",
            field="mac",
            hint="take the MAC from the device's Identify answer (or its label)",
        )
    return mac


def _text(data: bytes) -> str:
    return data.decode("ascii", errors="replace").rstrip("\x00")


def device_from(packet: Packet) -> Device:
    """The device an Identify response describes (MalformedFrame for a block too short)."""
    info: dict[str, object] = {"mac": mac_text(packet.src)}
    for b in packet.blocks:
        if len(b.data) < 2:
            raise MalformedFrame(f"block {b.option:02X}h/{b.suboption:02X}h has no BlockInfo")
        block_info, data = struct.unpack_from(">H", b.data)[0], b.data[2:]
        key = (b.option, b.suboption)
        if key == (OPT_IP, SUB_IP):
            if len(data) != 12:
                raise MalformedFrame(f"IP parameter block of {len(data)} bytes, not 12")
            ip, mask, gw = (str(ipaddress.IPv4Address(data[i : i + 4])) for i in (0, 4, 8))
            info.update(
                ip=ip,
                netmask=mask,
                gateway=gw,
                ip_origin={0: "not set", 1: "static", 2: "dhcp"}.get(block_info & 3, "static"),
                ip_conflict=bool(block_info & IP_INFO_CONFLICT),
            )
        elif key == (OPT_DEVICE, SUB_NAME_OF_STATION):
            info["name_of_station"] = _text(data)
        elif key == (OPT_DEVICE, SUB_TYPE_OF_STATION):
            info["type_of_station"] = _text(data)
        elif key == (OPT_DEVICE, SUB_ALIAS):
            info["alias"] = _text(data)
        elif key == (OPT_DEVICE, SUB_DEVICE_ID):
            if len(data) != 4:
                raise MalformedFrame(f"device ID block of {len(data)} bytes, not 4")
            info["vendor_id"], info["device_id"] = struct.unpack(">HH", data)
        elif key == (OPT_DEVICE, SUB_ROLE) and data:
            info["roles"] = tuple(t for bit, t in ROLES.items() if data[0] & bit)
        elif key == (OPT_DEVICE, SUB_INSTANCE) and len(data) == 2:
            info["instance"] = (data[0] << 8) | data[1]
        elif key == (OPT_DEVICE, SUB_OPTIONS):
            info["options"] = tuple((data[i], data[i + 1]) for i in range(0, len(data) - 1, 2))
    return Device(**info)  # type: ignore[arg-type]


def response_block(option: int, suboption: int, block_info: int, data: bytes) -> Block:
    """A response block: BlockInfo, then the data."""
    return Block(option, suboption, struct.pack(">H", block_info) + data)


def ack_block(option: int, suboption: int, error: int) -> Block:
    """Control / Response: the Set of ``option``/``suboption`` done (0) or refused."""
    return Block(OPT_CONTROL, SUB_RESPONSE, bytes((option, suboption, error)))


@dataclass(frozen=True, slots=True)
class Ack:
    option: int
    suboption: int
    error: int

    @property
    def meaning(self) -> str:
        return BLOCK_ERRORS.get(self.error, f"BlockError {self.error}")


def acks(packet: Packet) -> list[Ack]:
    """The Control / Response blocks of a Set response."""
    out: list[Ack] = []
    for b in packet.blocks:
        if (b.option, b.suboption) == (OPT_CONTROL, SUB_RESPONSE):
            if len(b.data) < 3:
                raise MalformedFrame(f"Control/Response block of {len(b.data)} bytes, not 3")
            out.append(Ack(b.data[0], b.data[1], b.data[2]))
    return out


# What may be set -----------------------------------------------------------------------

_LABEL = re.compile(r"[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?")
_PORT_NAME = re.compile(r"port-\d{3}(-\d{5})?")


def check_name_of_station(name: str) -> str:
    """``name`` if it is a valid NameOfStation (IEC 61158-6-10: labels of 1-63 lower-case
    letters, digits and hyphens separated by dots, no hyphen at a label's ends, at most 240
    characters, not of the form ``port-xyz`` or ``port-xyz-abcde``, not an IP address);
    ValidationError naming the rule it breaks otherwise."""

    def refuse(why: str, hint: str) -> ValidationError:
        return ValidationError(f"station name {name!r} {why}", field="name_of_station", hint=hint)

    if not name:
        raise refuse("is empty", "give a name such as lecsn-t-axis1")
    if len(name) > 240:
        raise refuse(f"has {len(name)} characters", "at most 240 characters")
    if name != name.lower():
        raise refuse("has capital letters", f"PROFINET names are lower case: {name.lower()!r}")
    for label in name.split("."):
        if not _LABEL.fullmatch(label):
            raise refuse(
                f"has the part {label!r}",
                "each part between dots: 1-63 of a-z, 0-9 and '-', not starting or ending with '-'",
            )
    if _PORT_NAME.fullmatch(name.split(".")[0]):
        raise refuse("looks like a port name (port-xyz)", "port-xyz names are reserved")
    if re.fullmatch(r"\d+\.\d+\.\d+\.\d+", name):
        raise refuse("is an IP address", "give the station a name, and its address apart")
    return name


def check_ip_suite(ip: str, netmask: str, gateway: str) -> tuple[str, str, str]:
    """The IP suite normalised, or ValidationError naming what is wrong. 0.0.0.0 for all
    three deletes the device's address (DCP allows it); otherwise the address must be a
    unicast host address in its subnet and the gateway 0.0.0.0 or in that subnet."""

    def addr(text: str, what: str) -> ipaddress.IPv4Address:
        try:
            return ipaddress.IPv4Address(text.strip())
        except ValueError:
            raise ValidationError(
                f"{what} {text!r} is not an IPv4 address", field=what, hint="e.g. 192.168.0.10"
            ) from None

    a, m, g = addr(ip, "ip"), addr(netmask, "netmask"), addr(gateway, "gateway")
    zero = ipaddress.IPv4Address(0)
    if a == m == g == zero:
        return str(a), str(m), str(g)
    try:
        net = ipaddress.IPv4Network(f"{a}/{m}", strict=False)
    except ValueError:
        raise ValidationError(
            f"netmask {m} is not contiguous", field="netmask", hint="e.g. 255.255.255.0"
        ) from None
    if net.prefixlen == 0 or net.prefixlen > 30:
        raise ValidationError(
            f"netmask {m} leaves no room for hosts and a gateway",
            field="netmask",
            hint="use a prefix between /1 and /30, e.g. 255.255.255.0",
        )
    if a.is_multicast or a.is_loopback or a.is_unspecified or a.is_reserved:
        raise ValidationError(
            f"{a} is not a device address", field="ip", hint="give a unicast host address"
        )
    if a in (net.network_address, net.broadcast_address):
        raise ValidationError(
            f"{a} is the {'network' if a == net.network_address else 'broadcast'} address of {net}",
            field="ip",
            hint="give a host address inside the subnet",
        )
    # A gateway equal to the device's own address means "no router", as 0.0.0.0 does
    # (engineering tools write either).
    if g not in (zero, a) and (g not in net or g in (net.network_address, net.broadcast_address)):
        raise ValidationError(
            f"gateway {g} is not another host of {net}",
            field="gateway",
            hint="give a router in the device's subnet, or 0.0.0.0 for none",
        )
    return str(a), str(m), str(g)
