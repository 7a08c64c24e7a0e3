"""Cyclic process data on a link: the frames PDOs travel in, and the SYNC that paces them.

A :class:`CyclicTransport` is what the session's cyclic exchange (``services/cyclic.py``) needs
from a fieldbus: subscribe to the frames of one identifier, send one, and send SYNC. It is a
separate, small interface rather than more ``DriveLink`` methods, because only some links
have cyclic data and the exchange runs on its own thread at up to 1 kHz, beside the SDO
traffic of the link.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

from servodesk.errors import ConflictError

#: Called on the bus thread with the frame's data and its receive time (seconds, bus clock).
FrameCallback = Callable[[bytes, float], None]

#: CAN FD data lengths (ISO 11898-1:2015): a frame carries 0-8, 12, 16, 20, 24, 32, 48 or 64
#: bytes, so longer process data is padded to the next of these.
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def padded_length(n: int) -> int:
    """Bytes on the bus for ``n`` bytes of process data (CAN FD padding above 8)."""
    for length in FD_LENGTHS:
        if length >= n:
            return length
    raise ValueError(f"{n} bytes do not fit in one CAN FD frame (at most 64)")


class CyclicTransport(ABC):
    """Frames by identifier on one bus (a CAN bus: COB-IDs)."""

    @property
    @abstractmethod
    def bus_key(self) -> object:
        """The same for every transport on the same bus (one SYNC producer per bus)."""

    @abstractmethod
    def subscribe(self, ident: int, callback: FrameCallback) -> None: ...

    @abstractmethod
    def unsubscribe(self, ident: int, callback: FrameCallback) -> None: ...

    @abstractmethod
    def send(self, ident: int, data: bytes) -> None:
        """Send one frame now (from any thread)."""

    @abstractmethod
    def send_rtr(self, ident: int, length: int) -> None:
        """Request a frame by remote transmission request (CiA 301 RTR-only TPDOs)."""

    @abstractmethod
    def send_sync(self, counter: int | None = None) -> None:
        """Send SYNC (CiA 301 §7.2.5), with the counter byte when ``counter`` is given."""

    def health(self) -> dict[str, Any] | None:
        """What the cycles say about the bus (EtherCAT: links/ethercat_health.py, with
        ``state`` and ``stale``); None where the transport cannot tell (CAN: a silent TPDO
        is no fault, services/cyclic.py explains it)."""
        return None

    def link_state(self) -> str | None:
        """The ``state`` of :meth:`health` alone, cheap enough for every cycle."""
        return None


def no_cyclic_reason(link: object) -> str | None:
    """Why ``link`` carries no cyclic process data; None when it does."""
    from servodesk.links.canopen_link import CanopenLink

    if isinstance(link, CanopenLink) or getattr(link, "fieldbus", None) == "ethercat":
        return None
    if getattr(link, "fieldbus", None) == "profinet":
        # servodesk as the drive's IO controller, where a NIC carries RT frames to it.
        return getattr(link, "no_cyclic", None)
    reason: str | None = getattr(link, "no_cyclic", None)
    return reason or f"the {getattr(link, 'fieldbus', '?')} link has no cyclic process data"


def transport_for(link: object) -> CyclicTransport:
    """The cyclic transport of ``link``; :class:`ConflictError` (not possible on this link,
    the link's ``no_cyclic`` says why) when it has none."""
    from servodesk.links.canopen_link import CanopenLink

    if isinstance(link, CanopenLink):
        from servodesk.links.canopen_cyclic import CanopenCyclic

        return CanopenCyclic(link.network)
    if getattr(link, "fieldbus", None) == "ethercat":
        from servodesk.links.ethercat_cyclic import EthercatCyclic
        from servodesk.links.ethercat_link import EthercatLink

        assert isinstance(link, EthercatLink)
        return EthercatCyclic(link)
    if getattr(link, "fieldbus", None) == "profinet" and no_cyclic_reason(link) is None:
        from servodesk.links.profinet_link import ProfinetLink

        assert isinstance(link, ProfinetLink)
        return link.cyclic_transport()
    raise ConflictError(
        f"the {getattr(link, 'fieldbus', '?')} link has no cyclic process data",
        hint=no_cyclic_reason(link),
    )
