"""Standard device descriptions to and from servodesk profiles.

- EDS / DCF (CiA 306): :func:`export_eds`, :func:`export_dcf`, :func:`import_eds`,
  :func:`import_dcf` (module :mod:`servodesk.devdesc.eds`)
- ESI XML (ETG.2000, EtherCAT): :func:`export_esi`, :func:`import_esi` (module ``esi``)
- XDD / XDC (CiA 311, CANopen XML): :func:`import_xdd` (module ``xdd``)

:func:`import_file` picks the reader by the file's suffix. See docs/device-descriptions.md.
"""

from __future__ import annotations

from pathlib import Path

from servodesk.devdesc._common import slug
from servodesk.devdesc.eds import (
    DcfContents,
    export_dcf,
    export_eds,
    import_dcf,
    import_eds,
    read_dcf,
)
from servodesk.devdesc.esi import export_esi, import_esi
from servodesk.devdesc.xdd import import_xdd
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import NotFoundError, ProfileError, ValidationError
from servodesk.files import read_bounded

__all__ = [
    "SUPPORTED_SUFFIXES",
    "DcfContents",
    "export_dcf",
    "export_eds",
    "export_esi",
    "import_dcf",
    "import_eds",
    "import_esi",
    "import_file",
    "import_text",
    "import_xdd",
    "read_dcf",
]

#: File suffix -> format name, for messages and file pickers.
SUPPORTED_SUFFIXES: dict[str, str] = {
    ".eds": "EDS (CiA 306)",
    ".dcf": "DCF (CiA 306)",
    ".xml": "ESI (ETG.2000 EtherCAT Slave Information)",
    ".xdd": "XDD (CiA 311)",
    ".xdc": "XDC (CiA 311)",
}


#: The largest device description read (as POST /profiles/import takes).
MAX_FILE = 16 << 20


def _read_text(path: Path) -> str:
    try:
        data = read_bounded(path, MAX_FILE)  # Never read a device (/dev/zero) to the end.
    except FileNotFoundError:
        raise NotFoundError(f"{path}: no such file", hint="check the path") from None
    except OSError as exc:
        raise ProfileError(f"cannot read: {exc.strerror}", path=str(path)) from None
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        # CiA 306 files are ASCII; older tools write Windows-1252 (a superset of Latin-1).
        return data.decode("latin-1")


def _format_of(filename: str) -> str:
    """The file's suffix when servodesk reads that format, else a ValidationError."""
    suffix = Path(filename).suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        formats = ", ".join(f"{s} {name}" for s, name in SUPPORTED_SUFFIXES.items())
        raise ValidationError(
            f"{Path(filename).name}: cannot import a {suffix or 'suffix-less'} file",
            field="filename",
            hint=f"supported formats: {formats}",
        )
    return suffix


def import_file(path: str | Path, profile_id: str | None = None) -> DeviceProfile:
    """A profile from a device-description file, chosen by suffix.

    ``profile_id`` defaults to the file name (lower case, dashes). A DCF's values are not
    part of a profile: use :func:`read_dcf` to get them.
    """
    p = Path(path)
    _format_of(p.name)  # A wrong suffix is refused before the file is read.
    return import_text(_read_text(p), p.name, profile_id, source=str(p))


def import_text(
    text: str, filename: str, profile_id: str | None = None, *, source: str | None = None
) -> DeviceProfile:
    """A profile from a device description's text; ``filename``'s suffix names the format."""
    p = Path(filename)
    suffix = _format_of(filename)
    pid = profile_id or slug(p.stem)
    src = source or p.name
    if suffix == ".eds":
        return import_eds(text, profile_id=pid, source=src)
    if suffix == ".dcf":
        return read_dcf(text, profile_id=pid, source=src).profile
    if suffix == ".xml":
        return import_esi(text, profile_id=pid, source=src)
    return import_xdd(text, profile_id=pid, source=src)
