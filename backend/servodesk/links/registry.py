"""Fieldbus name -> link class, imported lazily (python-can's interface registry pattern).

A link whose library is missing is reported by :meth:`LinkRegistry.available`, not fatal at
import time.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from servodesk.errors import LinkUnavailableError, NotFoundError
from servodesk.links.base import DriveLink


@dataclass(frozen=True, slots=True)
class LinkEntry:
    name: str
    module: str
    cls: str
    description: str


class LinkRegistry:
    def __init__(self) -> None:
        self._entries: dict[str, LinkEntry] = {}

    def register(self, name: str, module: str, cls: str, description: str = "") -> None:
        self._entries[name] = LinkEntry(name, module, cls, description)

    def names(self) -> list[str]:
        return sorted(self._entries)

    def get(self, name: str) -> type[DriveLink]:
        entry = self._entries.get(name)
        if entry is None:
            raise NotFoundError(
                f"no fieldbus link {name!r}", hint=f"known links: {', '.join(self.names())}"
            )
        try:
            mod = importlib.import_module(entry.module)
        except ImportError as exc:
            raise LinkUnavailableError(
                f"the {name} link cannot be loaded: {exc}",
                hint="install servodesk with its dependencies (make setup)",
            ) from exc
        cls: type[DriveLink] = getattr(mod, entry.cls)
        return cls

    def available(self) -> dict[str, str | None]:
        """Each link name -> None when usable, else the reason it is not."""
        out: dict[str, str | None] = {}
        for name in self.names():
            try:
                self.get(name)
                out[name] = None
            except LinkUnavailableError as exc:
                out[name] = exc.message
        return out


def can_interfaces() -> list[str]:
    """The python-can interface names (empty when python-can is missing)."""
    try:
        import can
    except ImportError:
        return []
    return sorted(can.interfaces.VALID_INTERFACES)


registry = LinkRegistry()
registry.register(
    "canopen",
    "servodesk.links.canopen_link",
    "CanopenLink",
    "CANopen over any python-can interface (virtual, udp_multicast, socketcan, pcan, kvaser, ...)",
)
registry.register(
    "cclink-ie-tsn",
    "servodesk.links.slmp_link",
    "SlmpLink",
    "CC-Link IE TSN object access over SLMP (4E frames on UDP; interface slmp, channel host:port)",
)

registry.register(
    "ethercat",
    "servodesk.links.ethercat_link",
    "EthercatLink",
    "EtherCAT CoE object access with pysoem (SOEM) (interface ethercat, channel the NIC name)",
)

registry.register(
    "profinet",
    "servodesk.links.profinet_link",
    "ProfinetLink",
    "PROFINET PROFIdrive parameter access over PNIO-CM record read / write (interface profinet, "
    "channel host[:port])",
)

#: Interfaces that are no python-can interface, and the link that speaks over each.
_INTERFACE_LINKS = {"slmp": "cclink-ie-tsn", "ethercat": "ethercat", "profinet": "profinet"}


def link_for_interface(interface: str) -> str:
    """The registry name of the link a bus interface is reached by: ``slmp`` is the SLMP
    link, ``ethercat`` the EtherCAT link, every python-can interface CANopen."""
    return _INTERFACE_LINKS.get(interface, "canopen")


def bus_interfaces() -> list[str]:
    """Every interface a session can be opened on: python-can's and the other links'."""
    return sorted({*can_interfaces(), *_INTERFACE_LINKS})
