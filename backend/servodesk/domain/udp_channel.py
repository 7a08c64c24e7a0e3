"""``host[:port]`` channels of the links that reach a device over UDP (SLMP, PROFINET)."""

from __future__ import annotations

from servodesk.errors import ValidationError


def parse_host_port(
    channel: str, *, default_port: int, hint: str, server: bool = False
) -> tuple[str, int]:
    """``host`` or ``host:port`` -> (host, port), the port ``default_port`` when none is
    given; :class:`ValidationError` naming the fault, with ``hint``. A ``server`` may ask for
    port 0: any free port."""
    host, sep, port_text = channel.strip().rpartition(":")
    if not sep:
        host, port_text = channel.strip(), str(default_port)
    if not host:
        raise ValidationError(f"channel {channel!r} names no host", field="channel", hint=hint)
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not (0 if server else 1) <= port <= 65535:
        raise ValidationError(
            f"channel {channel!r}: port {port_text!r} is not a number in 1..65535",
            field="channel",
            hint=hint,
        )
    return host, port
