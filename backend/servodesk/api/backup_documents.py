"""Backup documents parsed in the documents' worker process, not in the server's.

Issue "Motion safety" item 3, measured again with the requests themselves in flight
(bench/bench_deadman.py, 2026-12-07): with a 30 MB backup parsed in a worker *thread*, the
dead-man's stop frame came up to 700 ms after its deadline (GET), 550 ms (compare) and 280 ms
(preflight). The thread was not the problem, the GIL was: ``json.loads`` of 30 MB is one C
call of 0.3-0.9 s, pydantic's validation and serialisation are others, and the dead-man's
thread (services/deadman.py) cannot run Python until each returns. So everything whose size
the file decides runs in the spawned worker (:func:`servodesk.api.offload.in_process`), and
what comes back is a file the route streams (:func:`servodesk.api.offload.file_answer`) or
a few small objects. Not the answer's bytes through the worker's pipe: receiving 28 MB held the
server's GIL for 220 ms in one piece, a stream of a file never more than a read at a time.

- :func:`checked_json`: the GET's answer, the file checked and re-rendered as the schema says;
- :func:`comparison_json`: the whole compare, backups opened by the worker itself;
- :func:`targets` and :func:`preflight_json`: a restore preflight in two steps around the
  drive read that only the server can do (the worker keeps the last parsed file, so the second
  step does not parse it again).

Each ``*_json`` writes the answer to ``out`` (a temporary file the route made and removes).

The functions and their arguments pickle (the error tree does too: errors.py).
"""

from __future__ import annotations

from dataclasses import dataclass

from servodesk.api.schemas_backups import BackupFile, Comparison, PreflightOut
from servodesk.domain import paramset, restore_plan
from servodesk.domain.address import ObjectAddress
from servodesk.domain.paramset import ParameterSet
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.restore_plan import DriveFacts
from servodesk.services.backup_files import (
    StoredFile,
    comparison,
    read_checked,
    restore_targets,
    units_profile,
)

#: The worker's last parsed file: (path, sha256) -> set. A preflight parses once for its two
#: steps; one entry only, so the worker never holds more than one large set.
_LAST: tuple[tuple[str, str], ParameterSet] | None = None


def load(f: StoredFile) -> ParameterSet:
    """The stored backup's set, its label and note from the store (they are editable)."""
    global _LAST
    key = (f.path, f.sha256)
    if _LAST is not None and _LAST[0] == key:
        ps = _LAST[1]
    else:
        ps = paramset.loads(read_checked(f), f.name)
        _LAST = (key, ps)
    return f.labelled(ps)


def _write(out: str, answer: bytes) -> None:
    with open(out, "wb") as fh:
        fh.write(answer)


def checked_json(f: StoredFile, out: str) -> None:
    """GET /backups/{id}: the file as it is, after the same checks as every other use."""
    data = read_checked(f)
    paramset.loads(data, f.name)  # Schema and checksum, with the messages a restore gives.
    _write(out, BackupFile.model_validate_json(data).model_dump_json().encode("utf-8"))


Side = tuple[str, "ParameterSet | StoredFile"]


def comparison_json(
    a: Side, b: Side, profiles: dict[str, DeviceProfile], include_same: bool, out: str
) -> None:
    """POST /compare: both sides opened here, their differences as the answer's bytes."""
    sa = (a[0], load(a[1]) if isinstance(a[1], StoredFile) else a[1])
    sb = (b[0], load(b[1]) if isinstance(b[1], StoredFile) else b[1])
    profile = units_profile(sb[1], profiles) or units_profile(sa[1], profiles)
    result = comparison(sa, sb, profile, include_same=include_same)
    _write(out, Comparison.model_validate(result).model_dump_json().encode("utf-8"))


@dataclass(frozen=True)
class Plan:
    """What the server needs of a backup before it reads the drive for a preflight."""

    profile_id: str
    targets: list[ObjectAddress]


def targets(f: StoredFile, drive_profile: DeviceProfile, map_names: bool) -> Plan:
    """The drive objects a restore of ``f`` would touch (backup_files.restore_targets)."""
    ps = load(f)
    return Plan(ps.profile_id, restore_targets(ps, drive_profile, map_names))


def preflight_json(f: StoredFile, facts: DriveFacts, map_names: bool, out: str) -> None:
    """The preflight's answer from the set and what the server read from the drive."""
    pf = restore_plan.preflight(load(f), facts, map_names=map_names)
    _write(out, PreflightOut.model_validate(pf.to_dict()).model_dump_json().encode("utf-8"))
