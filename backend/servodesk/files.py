"""Files servodesk reads and writes: bounded reads, paths kept inside their directory,
atomic writes, and no temporary file outliving a crash.

- Every file a user names is read with a bound (:func:`read_bounded`): ``/dev/zero`` or a
  huge file is refused with a message, never a MemoryError.
- A path built from a name is resolved and must stay inside its directory
  (:func:`inside`), whatever the name held.
- A file is written to a temporary file in the same directory and moved over its name
  (:func:`write_atomic`), so it is never half-written under its name. The temporary file is
  removed on any error; only a crash (power loss, SIGKILL) can leave one, and
  :func:`remove_stale_temp_files` removes those when servodesk next opens the directory.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import tempfile
import time
from pathlib import Path

from servodesk.errors import ValidationError

log = logging.getLogger(__name__)

MiB = 1 << 20

#: Temporary files: ``.<final name>.<8 random characters>.tmp`` (tempfile.mkstemp's names).
_TEMP = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")
#: A temporary file this old belongs to no write in progress (a write takes milliseconds);
#: a younger one may be another process's (serve and the CLI share the data directory).
STALE_AFTER_S = 3600.0


def read_bounded(path: str | Path, limit: int) -> bytes:
    """The bytes of ``path``, refused (ValidationError) past ``limit`` bytes.

    Reads at most ``limit + 1`` bytes, so a device that never ends (/dev/zero) or a file of
    any size costs no more memory than the limit. OSError (no such file, no permission)
    passes through for the caller to word.
    """
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValidationError(
            f"{path}: the file is larger than the {limit / MiB:g} MiB servodesk reads here",
            field="file",
            hint="check that this is the right file",
        )
    return data


def inside(directory: Path, name: str) -> Path:
    """``directory / name`` resolved, refused unless it lies inside ``directory``."""
    base = Path(directory).resolve()
    path = (base / name).resolve()
    if path == base or not path.is_relative_to(base):
        raise ValidationError(
            f"{name!r} names a file outside {base}; nothing was read or written",
            field="file",
            hint="file names of servodesk's data are made from checked ids",
        )
    return path


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` (replacing it) through a temporary file in the same
    directory, fsync and ``os.replace`` (atomic on POSIX and Windows); the temporary file is
    removed whatever fails. OSError passes through."""
    try:
        mode = path.stat().st_mode & 0o777  # A replaced file keeps its permissions.
    except FileNotFoundError:
        mode = 0o644  # What open() gives under the usual umask; mkstemp's are 0600.
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            if hasattr(os, "fchmod"):  # POSIX (Windows has no modes to keep).
                os.fchmod(f.fileno(), mode)
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)  # Gone after os.replace; left by an error before it.


def remove_stale_temp_files(directory: Path) -> int:
    """Remove servodesk's temporary files older than :data:`STALE_AFTER_S` in ``directory``
    (left by a crash mid-write); returns how many."""
    removed = 0
    cutoff = time.time() - STALE_AFTER_S
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return 0
    for entry in entries:
        if not _TEMP.fullmatch(entry.name):
            continue
        with contextlib.suppress(OSError):
            if entry.is_file(follow_symlinks=False) and entry.stat().st_mtime < cutoff:
                os.unlink(entry.path)
                removed += 1
    if removed:
        log.info("removed %d stale temporary file(s) in %s", removed, directory)
    return removed
