"""Standard device descriptions to and from servodesk profiles.

- EDS / DCF (CiA 306): :func:`export_eds`, :func:`export_dcf`, :func:`import_eds`,
  :func:`import_dcf` (module :mod:`servodesk.devdesc.eds`)
- ESI XML (ETG.2000, EtherCAT): :func:`export_esi`, :func:`import_esi` (modules ``esi_export``
  and ``esi``)
- XDD / XDC (CiA 311, CANopen XML; CANopenEditor's .xpd project): :func:`import_xdd`

:func:`import_file` picks the reader by the file's suffix; :func:`read_file` also returns the
warnings (what the file holds that the import left out or changed). See
docs/device-descriptions.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from servodesk.devdesc._common import collecting, slug
from servodesk.devdesc.eds import DcfContents, import_dcf, import_eds, read_dcf
from servodesk.devdesc.eds_export import export_dcf, export_eds
from servodesk.devdesc.esi import EsiDevice, esi_devices, import_esi
from servodesk.devdesc.esi_export import export_esi
from servodesk.devdesc.xdd import import_xdd
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import NotFoundError, ProfileError, ValidationError
from servodesk.files import read_bounded

__all__ = [
    "SUPPORTED_SUFFIXES",
    "DcfContents",
    "EsiDevice",
    "ImportResult",
    "esi_devices",
    "export_dcf",
    "export_eds",
    "export_esi",
    "file_devices",
    "import_dcf",
    "import_eds",
    "import_esi",
    "import_file",
    "import_text",
    "import_xdd",
    "read_dcf",
    "read_file",
    "read_text",
]

#: File suffix -> format name, for messages and file pickers.
SUPPORTED_SUFFIXES: dict[str, str] = {
    ".eds": "EDS (CiA 306)",
    ".dcf": "DCF (CiA 306)",
    ".xml": "ESI (ETG.2000 EtherCAT Slave Information)",
    ".xdd": "XDD (CiA 311)",
    ".xdc": "XDC (CiA 311)",
    ".xpd": "XPD (CANopenEditor project, CiA 311 XML)",
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


@dataclass(frozen=True)
class ImportResult:
    """An imported profile and what the import left out or changed, one line each."""

    profile: DeviceProfile
    warnings: tuple[str, ...]


def import_file(
    path: str | Path, profile_id: str | None = None, *, device: int | None = None
) -> DeviceProfile:
    """A profile from a device-description file, chosen by suffix.

    ``profile_id`` defaults to the file name (lower case, dashes). A DCF's values are not
    part of a profile: use :func:`read_dcf` to get them. ``device`` picks one of several
    devices of an ESI (from 1; default the first).
    """
    return read_file(path, profile_id, device=device).profile


def read_file(
    path: str | Path, profile_id: str | None = None, *, device: int | None = None
) -> ImportResult:
    """Like :func:`import_file`, with the warnings of the import."""
    p = Path(path)
    _format_of(p.name)  # A wrong suffix is refused before the file is read.
    return read_text(_read_text(p), p.name, profile_id, source=str(p), device=device)


def file_devices(path: str | Path) -> list[EsiDevice]:
    """The devices an ESI file describes (numbered from 1, for ``device=``)."""
    p = Path(path)
    if _format_of(p.name) != ".xml":
        raise ValidationError(
            f"{p.name}: only an ESI (.xml) file describes several devices",
            field="filename",
            hint="EDS, DCF and XDD files describe one device each",
        )
    return esi_devices(_read_text(p), source=str(p))


def import_text(
    text: str,
    filename: str,
    profile_id: str | None = None,
    *,
    source: str | None = None,
    device: int | None = None,
) -> DeviceProfile:
    """A profile from a device description's text; ``filename``'s suffix names the format."""
    return read_text(text, filename, profile_id, source=source, device=device).profile


def read_text(
    text: str,
    filename: str,
    profile_id: str | None = None,
    *,
    source: str | None = None,
    device: int | None = None,
) -> ImportResult:
    """Like :func:`import_text`, with the warnings of the import."""
    p = Path(filename)
    suffix = _format_of(filename)
    pid = profile_id or slug(p.stem)
    src = source or p.name
    if device is not None and suffix != ".xml":
        raise ValidationError(
            f"{p.name}: a {SUPPORTED_SUFFIXES[suffix]} file describes one device",
            field="device",
            hint="--device picks one of the devices of an ESI (.xml) file",
        )
    with collecting() as notes:
        if suffix == ".eds":
            profile = import_eds(text, profile_id=pid, source=src)
        elif suffix == ".dcf":
            profile = read_dcf(text, profile_id=pid, source=src).profile
        elif suffix == ".xml":
            profile = import_esi(text, profile_id=pid, source=src, device=device)
        else:
            profile = import_xdd(text, profile_id=pid, source=src)
    return ImportResult(profile=profile, warnings=tuple(notes))
