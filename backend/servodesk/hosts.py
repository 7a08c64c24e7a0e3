"""Host names and addresses: which binds are loopback, and which names the server answers to.

Pure functions on text and bytes, for the settings (is the bind loopback, so no token is
needed), the 3D viewer (the same question) and the API's request checks
(``api/same_origin.py``, docs/security.md).
"""

from __future__ import annotations

import ipaddress
import re
import socket
from dataclasses import dataclass

#: The names a loopback server is always reached by (RFC 6761 §6.3 reserves "localhost").
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})

#: A DNS name as a Host header carries it (RFC 1123 §2.1 labels; "_" as some LANs use it).
_LABEL = r"[a-z0-9_](?:[a-z0-9_-]{0,61}[a-z0-9_])?"
_NAME = re.compile(rf"^{_LABEL}(?:\.{_LABEL})*$")

IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address


def ip_literal(host: str) -> IPAddress | None:
    """``host`` as an IP address when it is one written out ("::1" or "[::1]"), else None.

    Only the standard forms count: ``ipaddress`` refuses "127.1", "0x7f.0.0.1" and leading
    zeros, which some resolvers would take for 127.0.0.1.
    """
    text = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    try:
        return ipaddress.ip_address(text)
    except ValueError:
        return None


def is_loopback(host: str) -> bool:
    """True for a literal loopback address (127.0.0.0/8, RFC 1122 §3.2.1.3; ::1, RFC 4291
    §2.5.3) and for "localhost" (RFC 6761 §6.3).

    Any other name is resolved by DNS, which someone else may control: "127.attacker.example"
    can name any machine, so it is not loopback, however it starts.
    """
    if host.strip().lower() == "localhost":
        return True
    address = ip_literal(host.strip())
    return address is not None and address.is_loopback


def split_host(value: bytes | str) -> tuple[str, int | None] | None:
    """(name, port) of a Host header value or of an origin's host part (RFC 9110 §7.2,
    RFC 3986 §3.2.2: ``name``, ``name:port``, ``[v6]`` or ``[v6]:port``); None if it is none.

    The name comes back lower case, without a final dot and an IPv6 address without brackets.
    """
    if isinstance(value, bytes):
        try:
            value = value.decode("ascii")
        except UnicodeDecodeError:
            return None
    text = value.strip().lower()
    port_text: str | None = None
    if text.startswith("["):
        end = text.find("]")
        if end < 0:
            return None
        name, rest = text[1:end], text[end + 1 :]
        if rest:
            if not rest.startswith(":"):
                return None
            port_text = rest[1:]
        address = ip_literal(name)
        if address is None or address.version != 6:
            return None
        name = str(address)
    else:
        name, colon, port_text_or_empty = text.partition(":")
        if colon:
            port_text = port_text_or_empty
        name = name.removesuffix(".")
        if not name or not _NAME.match(name):
            return None
    port: int | None = None
    if port_text is not None:
        if not port_text.isdigit() or len(port_text) > 5 or int(port_text) > 65535:
            return None
        port = int(port_text)
    return name, port


def split_origin(value: bytes | str) -> tuple[str, str, int] | None:
    """(scheme, name, port) of an Origin header (RFC 6454 §7: ``scheme://host[:port]``), the
    port filled in for http and https; None for "null", other schemes and anything else."""
    if isinstance(value, bytes):
        try:
            value = value.decode("ascii")
        except UnicodeDecodeError:
            return None
    scheme, sep, rest = value.strip().lower().partition("://")
    if not sep or scheme not in ("http", "https") or "/" in rest or "@" in rest:
        return None
    host = split_host(rest)
    if host is None:
        return None
    name, port = host
    return scheme, name, port if port is not None else (443 if scheme == "https" else 80)


@dataclass(frozen=True)
class HostPolicy:
    """The names this server answers to, and the origins whose pages may change things.

    ``names``: accepted in Host, and in Origin with the server's own port. ``origins``:
    (name, port) pairs accepted in Origin and Host whatever the server's port (a reverse
    proxy or a mapped container port). ``any_address``: the server listens on every address
    (0.0.0.0, ::), so a Host that is an IP address may be any of this machine's; DNS
    rebinding always comes with a name, never an address.
    """

    names: frozenset[str]
    origins: frozenset[tuple[str, int]]
    any_address: bool

    @classmethod
    def for_server(cls, bind_host: str, extra: str = "") -> HostPolicy:
        """The policy of a server bound to ``bind_host`` with SERVODESK_ALLOWED_HOSTS ``extra``
        (comma-separated ``name`` or ``name:port``); ValueError names a bad entry."""
        names = set(LOOPBACK_NAMES)
        address = ip_literal(bind_host.strip())
        bound = split_host(bind_host) if address is None else (str(address), None)
        wildcard = address is not None and address.is_unspecified
        if bound is not None and not wildcard:
            names.add(bound[0])
        if not is_loopback(bind_host):
            # Reached from other machines: by this machine's own name too.
            hostname = split_host(socket.gethostname())
            if hostname is not None:
                names.add(hostname[0])
        origins: set[tuple[str, int]] = set()
        for entry in parse_allowed_hosts(extra):
            name, port = entry
            if port is None:
                names.add(name)
            else:
                origins.add((name, port))
        return cls(frozenset(names), frozenset(origins), wildcard)

    def host_ok(self, name: str, port: int | None) -> bool:
        if name in self.names or (port is not None and (name, port) in self.origins):
            return True
        return self.any_address and ip_literal(name) is not None

    def origin_ok(self, name: str, port: int, server_port: int) -> bool:
        if (name, port) in self.origins:
            return True
        return port == server_port and self.host_ok(name, None)


def parse_allowed_hosts(text: str) -> list[tuple[str, int | None]]:
    """The entries of SERVODESK_ALLOWED_HOSTS: ``name`` or ``name:port``, comma-separated."""
    out: list[tuple[str, int | None]] = []
    for raw in text.split(","):
        entry = raw.strip()
        if not entry:
            continue
        host = split_host(entry)
        if host is None:
            raise ValueError(
                f"{entry!r} is not a host name or name:port (e.g. servodesk.lan or "
                "servodesk.lan:9000)"
            )
        out.append(host)
    return out
