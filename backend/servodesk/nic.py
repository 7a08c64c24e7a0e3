"""Network interfaces for the layer 2 fieldbus frames (EtherCAT, PROFINET DCP): a name checked
as Linux checks it, the interface looked up, a raw AF_PACKET socket for one EtherType.

Used by the links (the EtherCAT master's interface, the DCP client) and by the simulated
devices on the other end of a veth pair (the ESCs, the DCP responder); it imports nothing
but the error tree, so the ESC process stays light.
"""

from __future__ import annotations

import errno
import os
import socket

from servodesk.errors import LinkError, NotFoundError, ValidationError

#: Longest interface name: IFNAMSIZ (16) less the terminating NUL.
NAME_MAX = 15
#: Where a missing interface is looked up.
LIST_HINT = "list the interfaces with `ip link`"


def check_name(nic: str, *, field: str, hint: str) -> str:
    """``nic`` if it can be an interface name (Linux's dev_valid_name: 1-15 characters, not
    "." or "..", no "/", ":" or white space); ValidationError naming ``field`` otherwise."""
    if (
        not 0 < len(nic) <= NAME_MAX
        or nic in (".", "..")
        or any(c in "/:" or c.isspace() for c in nic)
    ):
        raise ValidationError(f"{nic!r} is no network interface name", field=field, hint=hint)
    return nic


def require(nic: str, *, hint: str) -> None:
    """NotFoundError "no network interface" unless ``nic`` exists."""
    if not os.path.exists(f"/sys/class/net/{nic}"):
        raise NotFoundError(f"no network interface {nic!r}", hint=f"{LIST_HINT}; {hint}")


def open_raw(nic: str, ethertype: int, *, what: str, permission_hint: str) -> socket.socket:
    """A raw socket for ``ethertype`` frames on ``nic`` (blocking); LinkError without the
    permission (root or CAP_NET_RAW, ``permission_hint``), NotFoundError when ``nic`` is
    missing. ``what`` names the protocol in the messages."""
    try:
        sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ethertype))
    except PermissionError as exc:
        raise LinkError(
            f"cannot open a raw socket for {what} on {nic}: {exc}", hint=permission_hint
        ) from exc
    try:
        sock.bind((nic, ethertype))
    except OSError as exc:
        sock.close()
        if exc.errno == errno.ENODEV:
            raise NotFoundError(f"no network interface {nic!r}", hint=LIST_HINT) from exc
        raise LinkError(f"cannot bind a {what} socket to {nic!r}: {exc}") from exc
    return sock
