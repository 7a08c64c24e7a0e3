"""Large documents for measuring heavy requests (bench/bench_deadman.py and
tests/operation/test_heavy_requests.py): what issue "Motion safety" item 3 sent beside a jog."""

from __future__ import annotations

import json
from typing import Any

from servodesk.domain.paramset import checksum


def big_csv(megabytes: float) -> bytes:
    """A two-column scope recording of about ``megabytes`` (the issue's import: 10 MB)."""
    rows = ["time_s,position [inc]"]
    n = int(megabytes * 1e6 / 18)
    rows += [f"{i * 0.0005:.6f},{(i * 7919) % 1000003}" for i in range(n)]
    return ("\n".join(rows) + "\n").encode()


def padded_backup(doc: dict[str, Any], megabytes: float) -> bytes:
    """A backup file (``doc``, as GET /backups/{id} gives it) padded to about ``megabytes``
    with unreadable entries, its checksum made again: what a drive with many refused
    objects gives (LECSN-T: 541), so that its size is structure to parse, as in a large real
    backup, not one long string."""
    one = {
        "address": "0x3000:01",
        "name": "padding",
        "code": 0x06020000,
        "code_hex": "0x06020000",
        "message": "object does not exist",
    }
    n = int(megabytes * 1e6 / len(json.dumps(one)))
    padded = dict(doc)
    padded["unreadable"] = [
        dict(one, address=f"0x{0x3000 + i // 250:04x}:{i % 250 + 1:02x}") for i in range(n)
    ]
    padded["checksum"] = checksum(padded)
    return json.dumps(padded).encode()
