"""A request / response server on one UDP socket, for the simulated devices that answer a
fieldbus's object access over UDP (the SLMP station, the PROFINET device).

A subclass answers one datagram in :meth:`UdpServer.answer`; the socket, the thread and the
counters are here. A datagram the subclass cannot answer (None) is dropped, as a device drops
what it cannot parse: the client's time-out says so. A bug in ``answer`` is logged and the
datagram dropped; the server goes on.
"""

from __future__ import annotations

import logging
import socket
import threading
from abc import ABC, abstractmethod
from typing import Self

log = logging.getLogger(__name__)


class UdpServer(ABC):
    """``start()`` binds and serves from a thread, ``stop()`` ends it; ``channel`` tells
    where (``host:port``)."""

    #: The thread's name and what the log calls the server.
    name = "udp-server"
    #: Largest datagram read.
    max_datagram = 65535

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self._host = host
        self._port = port
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        #: Requests answered and datagrams dropped (tests and logs).
        self.answered = 0
        self.dropped = 0
        #: Who sent the datagram being answered (a device that calls its client back, as a
        #: PROFINET device calls its IO controller's ApplicationReady, needs it).
        self.peer: tuple[str, int] = ("", 0)

    @abstractmethod
    def answer(self, frame: bytes) -> bytes | None:
        """The response to one request datagram; None drops it."""

    def answers(self, frame: bytes) -> list[bytes]:
        """The datagrams that answer one request, in order (several where the answer is
        sent in fragments, none where it is dropped); by default :meth:`answer`'s one."""
        one = self.answer(frame)
        return [] if one is None else [one]

    @property
    def address(self) -> tuple[str, int]:
        if self._sock is None:
            raise RuntimeError(f"the {self.name} is not started")
        host, port = self._sock.getsockname()[:2]
        return str(host), int(port)

    @property
    def channel(self) -> str:
        """``host:port``, a link's channel."""
        host, port = self.address
        return f"{host}:{port}"

    def start(self) -> Self:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.bind((self._host, self._port))
        except OSError:
            sock.close()
            raise
        sock.settimeout(0.05)  # Wake up this often to see whether to stop.
        self._sock = sock
        self._thread = threading.Thread(target=self._serve, name=self.name, daemon=True)
        self._thread.start()
        log.info("%s on udp %s", self.name, self.channel)
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def rebind(self, host: str) -> bool:
        """Serve on ``host`` from now on, at the same port (a device whose address was
        changed, e.g. by DCP); False, still serving where it was, when ``host`` cannot be
        bound."""
        if self._sock is None:
            self._host = host
            return True
        old_host, port = self.address
        UdpServer.stop(self)  # the socket only: a subclass's stop() may end more
        self._stop.clear()
        self._host, self._port = host, port
        try:
            self.start()
        except OSError:
            log.info("%s: cannot bind %s:%d, staying on %s", self.name, host, port, old_host)
            self._host = old_host
            self._stop.clear()
            self.start()
            return False
        return True

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _serve(self) -> None:
        sock = self._sock
        assert sock is not None
        while not self._stop.is_set():
            try:
                frame, peer = sock.recvfrom(self.max_datagram)
            except TimeoutError:
                continue
            except OSError:
                return  # Closed.
            self.peer = (str(peer[0]), int(peer[1]))
            try:
                datagrams = self.answers(frame)
            except Exception:  # A bug here must not stop the server.
                log.exception("%s: request not answered", self.name)
                datagrams = []
            if not datagrams:
                self.dropped += 1
                continue
            self.answered += 1  # Before it is sent: the client may look right after.
            for datagram in datagrams:
                try:
                    sock.sendto(datagram, peer)
                except OSError:
                    log.debug("%s: answer to %s not sent", self.name, peer, exc_info=True)
