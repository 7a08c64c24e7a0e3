"""The token never reaches the server's log.

uvicorn logs every request line with its query string (logger ``uvicorn.access``) and every
WebSocket upgrade with its URL (``uvicorn.error``): both would carry ``?token=...`` of the
first page load and of each WebSocket (docs/api.md). A filter on those two loggers replaces
the value, whatever handlers and formatters a deployment configures; the request itself is
still logged.
"""

from __future__ import annotations

import logging
import re

#: A ``token`` query parameter's value (up to the next parameter, a space or a quote).
_TOKEN = re.compile(r"([?&]token=)[^&\s\"']*", re.IGNORECASE)
REDACTED = "[redacted]"
LOGGERS = ("uvicorn.access", "uvicorn.error")


def redact(text: str) -> str:
    return _TOKEN.sub(rf"\g<1>{REDACTED}", text)


class RedactToken(logging.Filter):
    """Redacts ``token=`` query values in a record's arguments (uvicorn logs the path as an
    argument; its access formatter unpacks them by position, so their number is kept)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple) and record.args:
            record.args = tuple(redact(a) if isinstance(a, str) else a for a in record.args)
        elif isinstance(record.msg, str):
            record.msg = redact(record.msg)
        return True


_FILTER = RedactToken()


def install() -> None:
    """Put the filter on uvicorn's loggers (once per process; create_app calls it)."""
    for name in LOGGERS:
        logger = logging.getLogger(name)
        if _FILTER not in logger.filters:
            logger.addFilter(_FILTER)
