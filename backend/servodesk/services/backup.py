"""Backups: reading a drive's configurable parameters, saving, importing, exporting, comparing,
and the audit log of every parameter write.

A backup is a :class:`~servodesk.domain.paramset.ParameterSet` written as a versioned JSON
file under ``<data_dir>/backups`` (atomically, never overwritten) plus a record in the
:class:`~servodesk.services.store.Store`. Files can be exported as DCF (CiA 306) and CSV, and
DCF files imported. The restore lives in :mod:`servodesk.services.restore`.
"""

from __future__ import annotations

import asyncio
import csv
import hashlib
import io
import logging
import re
import secrets
import time
from collections.abc import Sequence
from dataclasses import asdict, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from servodesk import __version__
from servodesk.domain import paramset
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import Value, codec
from servodesk.domain.ids import check_id
from servodesk.domain.paramset import Entry, ParameterSet, Unreadable
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import ServodeskError, ValidationError
from servodesk.services.audit import DISCARD, Recorder
from servodesk.services.backup_files import StoredFile, comparison, read_checked, units_profile
from servodesk.services.events import EventHub
from servodesk.services.session import Session, set_audit_sink
from servodesk.services.store import Store, write_new_file

log = logging.getLogger(__name__)

TOOL = f"servodesk {__version__}"
#: Objects read per progress message.
_CHUNK = 64


def now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def new_id(prefix: str = "") -> str:
    """Sortable, readable ids: ``20250101T120000Z-a1b2c3``."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return f"{prefix}{stamp}-{secrets.token_hex(3)}"


def drive_key(session: Session) -> str:
    """Which physical drive: vendor, product and serial from 1018h, else where it sits."""
    ident = session.identity
    if ident.vendor_id is not None and ident.product_code is not None and ident.serial is not None:
        return f"{ident.vendor_id:08X}-{ident.product_code:08X}-{ident.serial}"
    p = session.link.params
    return f"{session.profile.id}@{p.interface}:{p.channel}:{p.node_id}"


def firmware(session: Session) -> str | None:
    ident = session.identity
    if ident.software_version:
        return ident.software_version
    return f"rev 0x{ident.revision:08X}" if ident.revision is not None else None


def bus_of(session: Session) -> dict[str, Any]:
    p = session.link.params
    return {
        "interface": p.interface,
        "channel": p.channel,
        "bitrate": p.bitrate,
        "node_id": p.node_id,
    }


def progress(session: Session, operation: str, fraction: float, message: str, **extra: Any) -> None:
    session.hub.publish(
        {
            "type": "progress",
            "session": session.id,
            "operation": operation,
            "fraction": round(fraction, 3),
            "message": message,
            **extra,
        },
        session=session.id,
    )


#: What a ``write.object`` audit event keeps of a write (the old table's record, less time).
WRITE_FACTS = (
    "client",
    "drive_key",
    "address",
    "name",
    "old_raw_hex",
    "new_raw_hex",
    "old_value",
    "new_value",
)


class BackupService:
    """Backups of drives in a :class:`Store`; one per application (or CLI run)."""

    def __init__(self, store: Store, catalog: ProfileCatalog) -> None:
        self.store = store
        self.catalog = catalog
        #: The hash-chained audit log (services/audit.py): every write is also an event there.
        self.audit: Recorder = DISCARD

    # Audit log ------------------------------------------------------------------------------

    def attach(self, hub: EventHub) -> None:
        """Record every parameter write of the sessions on ``hub`` in the audit log."""
        set_audit_sink(hub, self._audit)

    def _audit(
        self, session: Session, address: ObjectAddress, old: bytes | None, new: bytes, client: str
    ) -> None:
        rec = self.write_record(session, address, old, new, client)
        self.audit.record(
            "write.object", drive=session.id, details={k: rec[k] for k in WRITE_FACTS}
        )
        try:
            self.store.add_audit(rec)
        except ServodeskError:
            # The write already happened; losing its audit record must not fail it.
            log.exception("audit record lost: %s", rec)

    @staticmethod
    def write_record(
        session: Session, address: ObjectAddress, old: bytes | None, new: bytes, client: str
    ) -> dict[str, Any]:
        """The audit table's record of one write (:meth:`Store.add_audit`); its
        :data:`WRITE_FACTS` are the ``write.object`` event's details."""
        spec = session.profile.spec(address)
        return {
            "time": time.time(),
            "client": client,
            "session": session.id,
            "drive_key": drive_key(session),
            "address": str(address),
            "name": spec.name if spec else None,
            "old_raw_hex": old.hex() if old is not None else None,
            "new_raw_hex": new.hex(),
            "old_value": paramset.typed_value(spec.data_type, old) if spec and old else None,
            "new_value": paramset.typed_value(spec.data_type, new) if spec else None,
        }

    # Reading a drive -----------------------------------------------------------------------

    async def read_set(
        self,
        session: Session,
        *,
        label: str = "",
        note: str = "",
        operation: str | None = "backup",
    ) -> ParameterSet:
        """Every configurable parameter of the drive, with progress over the WebSocket.

        An object the drive refuses to give is listed as unreadable (with its abort code);
        a lost bus raises (LinkError) and nothing is saved.
        """
        specs = paramset.configurable(session.profile)
        entries: list[Entry] = []
        unreadable: list[Unreadable] = []
        total = len(specs) or 1
        for start in range(0, len(specs), _CHUNK):
            chunk = specs[start : start + _CHUNK]
            if operation:
                progress(
                    session, operation, start / total, f"reading {start}/{len(specs)} parameters"
                )
            # The link's bytes: a backup keeps only them, and decoding every value into its
            # views (Session.read_many) cost a fifth of a backup's time (issue 50).
            results = await session.link.read_many([s.address for s in chunk])
            for spec, r in zip(chunk, results, strict=True):
                if isinstance(r, ServodeskError):
                    unreadable.append(
                        Unreadable(spec.address, spec.name, getattr(r, "code", None), r.message)
                    )
                else:
                    entries.append(Entry(spec.address, spec.name, spec.data_type, r, spec.unit))
        if operation:
            progress(session, operation, 1.0, f"read {len(entries)} parameters")
        return ParameterSet(
            profile_id=session.profile.id,
            profile_version=session.profile.version,
            time=now_iso(),
            entries=tuple(entries),
            label=label,
            note=note,
            identity=asdict(session.identity),
            firmware=firmware(session),
            bus=bus_of(session),
            drive_key=drive_key(session),
            unreadable=tuple(unreadable),
            tool=TOOL,
            counts_per_rev=session.counts_per_rev if session.units_rescaled else None,
        )

    def units_profile(self, ps: ParameterSet) -> DeviceProfile | None:
        """The profile whose scales give the set's engineering values (backup_files)."""
        return units_profile(ps, self.profiles_for(ps.profile_id))

    def profiles_for(self, *ids: str) -> dict[str, DeviceProfile]:
        """The catalog's profiles of these ids (those it knows)."""
        known = set(self.catalog.ids())
        return {i: self.catalog.get(i) for i in ids if i in known}

    async def backup(
        self, session: Session, label: str = "", note: str = "", source: str = "drive"
    ) -> dict[str, Any]:
        ps = await self.read_set(session, label=label, note=note)
        # Off the loop: the file's and the store's fsyncs (docs/safety.md: a stop never waits
        # on the disk).
        info = await asyncio.to_thread(self.save, ps, source)
        # The reads' last progress came before the file existed: a page that lists the
        # backups when one ends (All axes) is told again once it is saved.
        progress(session, "backup", 1.0, f"saved {len(ps.entries)} parameters")
        return info

    async def backup_many(
        self, sessions: Sequence[Session], label: str = "", note: str = ""
    ) -> list[dict[str, Any] | ServodeskError]:
        """A backup of each session, all at once (issue 50: a plant's drives): each link
        keeps its own requests in turn, and requests to different drives go out together.
        On CAN they interleave on the bus (each node answers on its own SDO channel, CiA
        301 §7.2.4.1: 600h/580h + node id); an EtherCAT slave has its own mailbox, a
        PROFINET or SLMP drive its own socket. One drive's failure is its own entry: the
        others are still saved."""

        async def one(s: Session) -> dict[str, Any] | ServodeskError:
            try:
                return await self.backup(s, label, note)
            except ServodeskError as exc:
                return exc

        return list(await asyncio.gather(*(one(s) for s in sessions)))

    # Saving and loading ---------------------------------------------------------------------

    def save(
        self, ps: ParameterSet, source: str = "drive", data: bytes | None = None
    ) -> dict[str, Any]:
        """Write the file (atomic, new name) then its record; returns the BackupInfo.

        ``data``: the file's bytes where ``ps`` was read from a servodesk JSON backup that is
        kept byte for byte (``servodesk restore FILE``: the store's copy is the user's file);
        else ``ps`` is written out."""
        bid = new_id()
        # The profile id becomes part of the file name (domain/ids.py).
        name = f"{bid}-{check_id(ps.profile_id, 'profile.id')}.json"
        path = self.store.backup_file(name)
        if data is None:
            data = paramset.dumps(ps, ps.tool or TOOL)
        write_new_file(path, data)
        info = {
            "id": bid,
            "time": ps.time,
            "label": ps.label,
            "note": ps.note,
            "profile_id": ps.profile_id,
            "profile_version": ps.profile_version,
            "drive_key": ps.drive_key,
            "identity": ps.identity,
            "firmware": ps.firmware,
            "bus": ps.bus,
            "entries": len(ps.entries),
            "file": name,
            "sha256": hashlib.sha256(data).hexdigest(),
            "unreadable": paramset.unreadable_dicts(ps.unreadable),
        }
        # The file is complete before the record exists: a crash in between leaves an
        # unlisted but intact file, never a record without its file.
        # Queued: the central store was unreachable; the backup waits in the gateway's local
        # queue and is synced when the store answers (services/outbox.py).
        info["queued"] = self.store.add_backup(info, source)
        info["source"] = source
        info["complete"] = not ps.unreadable
        return info

    def info(self, bid: str) -> dict[str, Any]:
        return self.store.get_backup(bid)

    def stored(self, bid: str) -> StoredFile:
        """What the store knows of backup ``bid``'s file (cheap: no file is read)."""
        info = self.store.backup_file_row(bid)
        return StoredFile(
            bid=bid,
            path=str(self.store.backup_file(str(info["file"]))),
            name=str(info["file"]),
            sha256=str(info["sha256"]),
            profile_id=str(info["profile_id"]),
            directory=str(self.store.backups_dir),
            label=str(info["label"] or ""),
            note=str(info["note"] or ""),
        )

    def file_bytes(self, bid: str) -> bytes:
        return read_checked(self.stored(bid))

    def load(self, bid: str) -> ParameterSet:
        info = self.store.get_backup(bid)
        ps = paramset.loads(self.file_bytes(bid), info["file"])
        # The label and note live in the store (editable); the file keeps the original ones.
        return replace(ps, label=info["label"], note=info["note"])

    # Import ---------------------------------------------------------------------------------

    def parse(self, data: bytes, filename: str, profile_id: str | None = None) -> ParameterSet:
        """A set from a file's bytes: a servodesk JSON backup or a DCF (by suffix/content)."""
        suffix = Path(filename).suffix.lower()
        head = data.lstrip()[:1]
        if suffix == ".dcf" or (suffix != ".json" and head == b"["):
            return self._parse_dcf(data, filename, profile_id)
        if suffix not in (".json", "") and head != b"{":
            raise ValidationError(
                f"{filename}: not a servodesk backup (.json) or DCF (.dcf)",
                field="filename",
                hint="choose a .json backup or a .dcf file",
            )
        return paramset.loads(data, filename)

    def _parse_dcf(self, data: bytes, filename: str, profile_id: str | None) -> ParameterSet:
        from servodesk import devdesc

        text = data.decode("utf-8", errors="replace").lstrip("\ufeff")
        contents = devdesc.read_dcf(text, source=filename)
        dcf_profile = contents.profile
        target = self._dcf_profile(text, dcf_profile, profile_id)
        entries: list[Entry] = []
        for address, value in sorted(contents.values.items()):
            spec = target.spec(address) if target else None
            if spec is None or spec.data_type != (dcf_profile.spec(address) or spec).data_type:
                spec = dcf_profile.spec(address)
            if spec is None:
                continue
            try:
                raw = codec(spec.data_type).encode(value)
            except ServodeskError as exc:
                raise ValidationError(
                    f"{filename}: {address} {spec.name}: {exc.message}",
                    field="file",
                    hint="correct the ParameterValue in the DCF",
                ) from None
            entries.append(Entry(address, spec.name, spec.data_type, raw, spec.unit))
        if not entries:
            raise ValidationError(
                f"{filename}: the DCF holds no ParameterValue",
                field="file",
                hint="export a DCF with values (servodesk backup -o x.dcf)",
            )
        ident = dcf_profile.identity
        profile = target or dcf_profile
        return ParameterSet(
            profile_id=profile.id,
            profile_version=profile.version,
            time=now_iso(),
            entries=tuple(entries),
            label=f"imported from {Path(filename).name}",
            identity={
                "vendor_id": ident.vendor_id,
                "product_code": ident.product_codes[0] if ident.product_codes else None,
                "revision": None,
                "serial": None,
            },
            bus={"node_id": contents.node_id, "bitrate": contents.bitrate},
            drive_key=f"dcf:{Path(filename).name}",
            tool=TOOL,
        )

    def _dcf_profile(
        self, text: str, dcf_profile: DeviceProfile, profile_id: str | None
    ) -> DeviceProfile | None:
        if profile_id:
            return self.catalog.get(profile_id)
        # servodesk's own DCF names the profile in [FileInfo] FileName (<profile id>.dcf).
        m = re.search(r"^\s*FileName\s*=\s*([A-Za-z0-9-]+)\.dcf\s*$", text, re.M | re.I)
        if m and m.group(1).lower() in self.catalog.ids():
            return self.catalog.get(m.group(1).lower())
        ident = dcf_profile.identity
        return self.catalog.match(
            ident.vendor_id, ident.product_codes[0] if ident.product_codes else None, None
        )

    def import_bytes(
        self, data: bytes, filename: str, profile_id: str | None = None
    ) -> dict[str, Any]:
        ps = self.parse(data, filename, profile_id)
        return self.save(ps, source="upload")

    # Export ---------------------------------------------------------------------------------

    def export(self, ps: ParameterSet, fmt: str) -> tuple[bytes, str, str]:
        """(bytes, media type, suffix) of a set as json, dcf or csv."""
        if fmt == "json":
            return paramset.dumps(ps, ps.tool or TOOL), "application/json", "json"
        if fmt == "csv":
            return self._csv(ps), "text/csv", "csv"
        if fmt == "dcf":
            from servodesk import devdesc

            profile = self.catalog.get(ps.profile_id)
            values: dict[ObjectAddress, Value] = {}
            for e in ps.entries:
                if profile.spec(e.address) is None:
                    continue
                v = codec(e.data_type).decode(e.raw)
                values[e.address] = v
            node = ps.bus.get("node_id")
            node_id = node if isinstance(node, int) and 1 <= node <= 127 else 1
            text = devdesc.export_dcf(profile, node_id, values, bitrate=ps.bus.get("bitrate"))
            return text.encode("utf-8"), "text/plain", "dcf"
        raise ValidationError(
            f"unknown export format {fmt!r}", field="format", hint="use json, dcf or csv"
        )

    def _csv(self, ps: ParameterSet) -> bytes:
        profile = self.units_profile(ps)
        out = io.StringIO()
        w = csv.writer(out, lineterminator="\n")
        w.writerow(
            [
                "address",
                "name",
                "group",
                "data_type",
                "value",
                "raw_hex",
                "unit",
                "engineering",
                "raw_unit",
            ]
        )
        for e in ps.entries:
            spec = profile.spec(e.address) if profile else None
            v = e.value
            eng = ""
            if spec and spec.unit and isinstance(v, int | float) and not isinstance(v, bool):
                eng = repr(float(v) * spec.scale)
            w.writerow(
                [
                    str(e.address),
                    e.name,
                    spec.group if spec else "",
                    e.data_type.name,
                    "" if v is None else v,
                    e.raw.hex(),
                    e.unit or "",
                    eng,
                    spec.raw_unit if spec and spec.raw_unit else "",
                ]
            )
        return out.getvalue().encode("utf-8")

    # Compare --------------------------------------------------------------------------------

    def compare(
        self,
        a: tuple[str, ParameterSet],
        b: tuple[str, ParameterSet],
        *,
        include_same: bool = False,
    ) -> dict[str, Any]:
        """A Comparison (docs/api.md) of two labelled sets."""
        # The profile of b (the drive, or the later set), else a's; its scales for b's encoder.
        profile = self.units_profile(b[1]) or self.units_profile(a[1])
        return comparison(a, b, profile, include_same=include_same)

    def defaults(self, profile_id: str, node_id: int = 1) -> ParameterSet:
        return paramset.defaults_set(self.catalog.get(profile_id), node_id, now_iso())
