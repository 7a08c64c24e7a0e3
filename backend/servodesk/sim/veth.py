"""A veth pair: two connected virtual Ethernet interfaces, for an EtherCAT master and a
simulated slave on one machine.

A frame sent on one end arrives on the other, so SOEM (the master, on one end) and
:class:`~servodesk.sim.ethercat_slave.EthercatSlaveSim` (on the other) exchange real EtherCAT
frames over AF_PACKET sockets. Creating one needs root or CAP_NET_ADMIN; without it the
error says so.
"""

from __future__ import annotations

import itertools
import os
import shutil
import subprocess
from dataclasses import dataclass

from servodesk.errors import LinkError, ValidationError
from servodesk.nic import NAME_MAX

#: Longest interface name (servodesk.nic: IFNAMSIZ less the terminating NUL).
IFNAME_MAX = NAME_MAX
_counter = itertools.count(1)


@dataclass(frozen=True, slots=True)
class VethPair:
    """``master`` and ``slave``: the two interface names of one pair."""

    master: str
    slave: str

    def delete(self) -> None:
        """Delete the pair (deleting one end deletes both); gone already is fine."""
        _ip("link", "delete", self.master, missing_ok=True)

    def __enter__(self) -> VethPair:
        return self

    def __exit__(self, *exc: object) -> None:
        self.delete()


def _ip(*args: str, missing_ok: bool = False) -> None:
    ip = shutil.which("ip") or next(
        (p for p in ("/usr/sbin/ip", "/sbin/ip") if os.path.exists(p)), None
    )
    if ip is None:
        raise LinkError(
            "the ip command (iproute2) is not installed",
            hint="install iproute2 to create a veth pair for the simulated EtherCAT slave",
        )
    done = subprocess.run([ip, *args], capture_output=True, text=True, check=False)
    if done.returncode == 0:
        return
    err = (done.stderr or done.stdout).strip()
    if missing_ok and ("Cannot find device" in err or "does not exist" in err):
        return
    if "Operation not permitted" in err or "permission" in err.lower():
        raise LinkError(
            f"ip {' '.join(args)}: not permitted ({err})",
            hint="creating a veth pair needs root or CAP_NET_ADMIN",
        )
    raise LinkError(f"ip {' '.join(args)} failed: {err}")


def create_veth(prefix: str = "sdk") -> VethPair:
    """Create a veth pair ``<prefix><pid>m<n>`` / ``<prefix><pid>s<n>``, both up.

    Names are unique per process and call; a prefix that leaves no room in 15 characters is
    refused.
    """
    if not prefix.isalnum():
        raise ValidationError(f"veth prefix {prefix!r} is not alphanumeric", field="prefix")
    tag = f"{os.getpid() % 100000}x{next(_counter)}"
    master, slave = f"{prefix}{tag}m", f"{prefix}{tag}s"
    if len(master) > IFNAME_MAX:
        raise ValidationError(
            f"interface name {master!r} is longer than {IFNAME_MAX} characters",
            field="prefix",
            hint="use a shorter prefix",
        )
    _ip("link", "add", master, "type", "veth", "peer", "name", slave)
    pair = VethPair(master, slave)
    try:
        for name in (master, slave):
            _ip("link", "set", name, "up")
    except BaseException:
        pair.delete()
        raise
    return pair


def add_address(ifname: str, ip: str) -> None:
    """Give ``ifname`` the address ``ip`` alone (/32: no route to a subnet is added), as a
    simulated device on that end takes an address set by DCP (sim/profinet_dcp.py)."""
    _ip("addr", "add", f"{ip}/32", "dev", ifname)


def delete_address(ifname: str, ip: str) -> None:
    """Remove an address :func:`add_address` gave; gone already is fine."""
    try:
        _ip("addr", "del", f"{ip}/32", "dev", ifname, missing_ok=True)
    except LinkError as exc:
        if "Cannot assign" not in exc.message and "not found" not in exc.message.lower():
            raise
