"""Headers of file downloads, built so that no id can break them.

File names come from ids (a backup's profile id, a session id, a profile's id) that were not
always checked, and may hold any character: one outside Latin-1 cannot be sent in a header
at all (a 500), CR LF would end the header (a dropped connection, or a header of the
attacker's), and a quote would end the quoted name early.
"""

from __future__ import annotations

import re
from urllib.parse import quote

#: What may stand in the quoted ASCII name: printable ASCII but the quote, the backslash (a
#: quoted-string's escape, RFC 9110 §5.6.4) and the characters file systems refuse.
_UNSAFE = re.compile(r'[^\x20-\x7e]|["\\/:*?<>|;=]')


def content_disposition(filename: str, disposition: str = "attachment") -> str:
    """``attachment; filename="..."; filename*=UTF-8''...`` for ``filename`` (RFC 6266 §4.1).

    ``filename`` is an ASCII fallback with every unsafe character replaced by "_", for
    clients that do not read ``filename*``; ``filename*`` is the exact name, UTF-8 and
    percent-encoded (RFC 8187 §3.2, which obsoletes RFC 5987), which RFC 6266 §4.3 says a
    client prefers. The value is plain ASCII whatever ``filename`` holds.
    """
    fallback = _UNSAFE.sub("_", filename).strip() or "download"
    exact = quote(filename, safe="!#$&+-.^_`|~")  # RFC 8187 attr-char, less what quote adds.
    return f"{disposition}; filename=\"{fallback}\"; filename*=UTF-8''{exact}"
