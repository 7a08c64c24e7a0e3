"""The SLMP side of a simulated CC-Link IE TSN station: CiA 402 object access over UDP.

:class:`SlmpStation` answers SLMP 4E binary requests (:mod:`servodesk.domain.slmp`) on a UDP
socket, as the CTMM04x answers its manager's transient transmission (003 §4-2): the
request-destination multidrop station no. picks the axis (0 = X ... 3 = U), and 4020h
SDO Upload / SDO Download read and write that axis's object dictionary. It serves the same
:class:`~servodesk.sim.engine.SimulatedDrive` objects the CANopen front-end does, so a drive
can be reached over both.

What it answers, and how (docs/slmp.md):

- A frame whose 4E binary request header (subheader 5400h and the 13 bytes up to the request
  data length) is not there is dropped: there is nobody to address an answer to (the client's
  time-out says so).
- A readable header with a wrong rest is answered, as SLMP servers do: a request data length
  that does not match the bytes that follow, or a body too short for the monitoring timer,
  command and sub-command: C061h; a fixed field (bytes 4-5) other than 0000h: C05Ch.
- A multidrop no. with no axis: end code CF10h; a command other than 4020h / 0001h, 0002h:
  C059h; 4020h data whose lengths do not add up: C061h. Each with the error information.
- A refused SDO: end code C05Ch with the CiA 301 abort code after the error information.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Mapping

from servodesk.domain import slmp
from servodesk.sim.engine import SimAbort, SimulatedDrive
from servodesk.sim.udp_server import UdpServer

log = logging.getLogger(__name__)


class SlmpStation(UdpServer):
    """A UDP SLMP server for up to four axes; ``start()`` binds, ``address`` tells where."""

    name = "slmp-station"
    max_datagram = slmp.MAX_FRAME

    def __init__(
        self, axes: Mapping[int, SimulatedDrive], host: str = "127.0.0.1", port: int = 0
    ) -> None:
        for axis in axes:
            if not 0 <= axis <= 3:
                raise ValueError(f"axis {axis} is outside 0..3 (X, Y, Z, U)")
        super().__init__(host, port)
        self.axes = dict(axes)

    def answer(self, frame: bytes) -> bytes | None:
        """The response to one request frame; None for a frame that is dropped."""
        try:
            req = slmp.parse_request(frame)
        except slmp.SlmpFrameError as exc:
            return self._malformed(frame, exc)

        def refuse(end_code: int, extra: bytes = b"") -> bytes:
            info = slmp.error_info(req.route, req.command, req.subcommand)
            return slmp.build_response(req.serial, req.route, end_code, info + extra)

        drive = self.axes.get(req.route.multidrop)
        if drive is None:
            return refuse(0xCF10)
        if req.command != slmp.CMD_OBJECT or req.subcommand not in (
            slmp.SUB_UPLOAD,
            slmp.SUB_DOWNLOAD,
        ):
            return refuse(0xC059)
        download = req.subcommand == slmp.SUB_DOWNLOAD
        try:
            obj = slmp.parse_object_data(req.data, with_value=download)
        except slmp.SlmpFrameError:
            return refuse(0xC061)
        try:
            if download:
                drive.write_bytes(obj.index, obj.subindex, obj.data)
                value = b""
            else:
                value = drive.read_bytes(obj.index, obj.subindex)
        except SimAbort as exc:
            return refuse(slmp.END_SDO_REFUSED, exc.code.to_bytes(4, "little"))
        data = slmp.download_data(obj.index, obj.subindex, value)
        return slmp.build_response(req.serial, req.route, 0, data)

    def _malformed(self, frame: bytes, exc: slmp.SlmpFrameError) -> bytes | None:
        """The answer to a request that does not parse: an end code where its header is
        readable (the serial no. and the route to answer), silence where it is not."""
        head = slmp.read_request_header(frame)
        if head is None:
            log.debug("SLMP frame dropped: %s", exc)
            return None
        command = subcommand = 0
        if len(head.body) >= 6:
            _timer, command, subcommand = struct.unpack_from("<HHH", head.body)
        info = slmp.error_info(head.route, command, subcommand)
        # C05Ch request content error (the fixed field is not 0000h); C061h the request data
        # length does not match what follows, or leaves no room for the command.
        code = 0xC05C if head.fixed != 0 else 0xC061
        log.debug("SLMP request refused with %04Xh: %s", code, exc)
        return slmp.build_response(head.serial, head.route, code, info)
