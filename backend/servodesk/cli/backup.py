"""``servodesk backup``, ``servodesk restore`` and ``servodesk diff`` (docs/backup.md).

    servodesk backup -o drive.json --interface socketcan --channel can0 --node-id 3
    servodesk restore drive.json [--dry-run] [--no-store] [--force] [--map-by-name]
    servodesk restore --resume RESTORE_ID
    servodesk diff drive.json drive        # exit 0 equal, 1 different (like diff)

Every backup is also kept in the store under SERVODESK_DATA_DIR. Bad input exits with 2.
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import getpass
import hashlib
import json
import re
import socket
import sys
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from servodesk.domain.paramset import ParameterSet
from servodesk.errors import ConflictError, NotFoundError, ValidationError
from servodesk.files import read_bounded

if TYPE_CHECKING:
    from servodesk.domain.profile_loader import ProfileCatalog
    from servodesk.settings import Settings

T = TypeVar("T")

_EXPORTS = {".json": "json", ".dcf": "dcf", ".csv": "csv"}


def _bus_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("bus options (python-can style)")
    g.add_argument(
        "--interface",
        default="virtual",
        help="python-can interface (virtual, socketcan, pcan, ...) for CANopen, slmp for a "
        "CC-Link IE TSN station (channel host:port, node id = axis + 1), profinet for a "
        "PROFIdrive drive (channel host[:port], node id = DO-ID), or ethercat for an EtherCAT "
        "line (channel the network interface, node id = slave position + 1)",
    )
    g.add_argument("--channel", default="servodesk-sim", help="python-can channel, or host:port")
    g.add_argument("--bitrate", type=int, default=None, help="bit rate for real interfaces")
    g.add_argument("--node-id", type=int, default=1, help="node id of the drive (1..127)")
    g.add_argument("--profile", default=None, help="profile id (default: detect from 1018h)")
    g.add_argument("--timeout", type=float, default=None, help="SDO time-out in seconds")
    p.add_argument("--json", action="store_true", help="machine-readable output")


def register(sub: Any) -> None:
    p = sub.add_parser("backup", help="back up a drive's parameters to a file")
    p.add_argument(
        "-o", "--output", required=True, help="file to write (.json, .dcf or .csv); never replaced"
    )
    p.add_argument("--label", default="", help="label of the backup in the store")
    p.add_argument("--note", default="", help="note of the backup in the store")
    _bus_options(p)
    p.set_defaults(func=run_backup)

    p = sub.add_parser("restore", help="restore a backup (.json or .dcf) into a drive")
    p.add_argument("file", nargs="?", help="backup file (.json or .dcf)")
    p.add_argument("--dry-run", action="store_true", help="show what would be written")
    p.add_argument("--no-store", action="store_true", help="do not store to non-volatile memory")
    p.add_argument("--force", action="store_true", help="store even when items failed")
    p.add_argument("--map-by-name", action="store_true", help="restore another family by name")
    p.add_argument("--resume", metavar="RESTORE_ID", help="resume an interrupted restore")
    _bus_options(p)
    p.set_defaults(func=run_restore)

    p = sub.add_parser("diff", help="compare backups and drives (exit 1 when they differ)")
    p.add_argument("a", help="backup file, or 'drive' for the drive on the bus")
    p.add_argument("b", help="backup file, or 'drive' for the drive on the bus")
    p.add_argument("--all", action="store_true", help="also list equal entries")
    _bus_options(p)
    p.set_defaults(func=run_diff)


def client_id() -> str:
    """``cli:<user>@<host>`` for the audit log (docs/api.md)."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "user"
    text = f"cli:{user}@{socket.gethostname()}"
    return re.sub(r"[^A-Za-z0-9._:@-]", "_", text)[:64]


@functools.lru_cache(maxsize=4)
def _catalog(dirs: tuple[Path, ...]) -> Any:
    """One catalog per set of profile directories and process: loading the profiles takes
    seconds, and scripts (and tests) run several commands in one process."""
    from servodesk.domain.profile_loader import ProfileCatalog

    return ProfileCatalog(list(dirs))


def settings_catalog(settings: Settings | None = None) -> ProfileCatalog:
    """The catalog of the profile directories ``settings`` (default: the environment's) name,
    loaded once per process (:func:`_catalog`)."""
    from servodesk.domain.profile_loader import default_profile_dirs
    from servodesk.settings import Settings

    s = settings if settings is not None else Settings()
    catalog: ProfileCatalog = _catalog(tuple(default_profile_dirs(s.profile_paths())))
    return catalog


class _Context:
    """A store, a session manager with the audit hook, and (when needed) one session."""

    def __init__(self, args: argparse.Namespace) -> None:
        from servodesk.services.audit import Actor, AuditLog, acting
        from servodesk.services.backup import BackupService
        from servodesk.services.events import EventHub
        from servodesk.services.manager import SessionManager
        from servodesk.services.restore import RestoreService
        from servodesk.services.store import Store
        from servodesk.settings import Settings

        settings = Settings()
        self.args = args
        self.catalog = settings_catalog(settings)
        self.hub = EventHub()
        timeout = args.timeout or settings.sdo_timeout
        self.manager = SessionManager(self.catalog, self.hub, sdo_timeout=timeout, poll_hz=1.0)
        self.backups = BackupService(Store(settings.data_dir, settings.store_url), self.catalog)
        self.backups.attach(self.hub)
        # Drive writes from the CLI go to the audit log too, as this machine's user
        # (docs/security.md, Audit log); this runs inside asyncio.run, so the actor holds
        # for the whole command.
        self.audit = AuditLog(self.backups.store.url)
        self.backups.audit = self.audit
        acting(Actor(client_id(), "local"))
        self.restores = RestoreService(self.backups)
        self.timeout = timeout

    async def session(self) -> Any:
        from servodesk.links.base import LinkParams
        from servodesk.links.registry import link_for_interface

        a = self.args
        if not 1 <= a.node_id <= 127:
            raise ValidationError(
                f"node id {a.node_id} is outside 1..127", hint="CANopen node ids are 1..127"
            )
        params = LinkParams(
            interface=a.interface,
            channel=a.channel,
            bitrate=a.bitrate,
            node_id=a.node_id,
            timeout=self.timeout,
        )
        return await self.manager.open(params, a.profile, fieldbus=link_for_interface(a.interface))

    async def close(self) -> None:
        await self.manager.close_all()
        self.audit.close()
        self.backups.store.close()


def _run(args: argparse.Namespace, body: Callable[[_Context], Awaitable[T]]) -> T:
    async def main() -> T:
        ctx = _Context(args)
        try:
            return await body(ctx)
        finally:
            await ctx.close()

    return asyncio.run(main())


def _dump(data: object) -> None:
    json.dump(data, sys.stdout, indent=2, ensure_ascii=False, default=str)
    sys.stdout.write("\n")


#: The largest file the CLI reads (a backup, DCF or PDO layout), as POST /backups/upload.
MAX_FILE = 32 << 20


def _read_file(path: str) -> bytes:
    p = Path(path)
    try:
        return read_bounded(p, MAX_FILE)  # /dev/zero or a huge file: exit 2, not MemoryError.
    except FileNotFoundError:
        raise NotFoundError(f"{path}: no such file", hint="check the path") from None
    except OSError as exc:
        raise ValidationError(f"{path}: cannot read: {exc.strerror}", field="file") from None


# backup ------------------------------------------------------------------------------------


def run_backup(args: argparse.Namespace) -> int:
    from servodesk.services.store import write_new_file

    out = Path(args.output)
    fmt = _EXPORTS.get(out.suffix.lower())
    if fmt is None:
        raise ValidationError(
            f"{out.name}: unknown format {out.suffix or '(no suffix)'}",
            field="output",
            hint="name the file .json, .dcf or .csv",
        )
    if out.exists():
        raise ConflictError(
            f"{out} exists; backups are never overwritten", hint="choose a new name"
        )

    async def body(ctx: _Context) -> dict[str, Any]:
        session = await ctx.session()
        info = await ctx.backups.backup(session, args.label, args.note)
        ps = ctx.backups.load(info["id"])
        data = (
            ctx.backups.file_bytes(info["id"]) if fmt == "json" else ctx.backups.export(ps, fmt)[0]
        )
        write_new_file(out, data)
        return {**info, "output": str(out)}

    info = _run(args, body)
    if args.json:
        _dump(info)
    else:
        unreadable = info["unreadable"]
        print(
            f"backed up {info['entries']} parameters of {info['profile_id']} node "
            f"{args.node_id} to {info['output']} (store id {info['id']})"
        )
        if unreadable:
            # The backup lacks these: a restore of it cannot set them (issue 48).
            print(
                f"INCOMPLETE: {len(unreadable)} object(s) could not be read and are not in "
                "the backup:"
            )
            _print_unreadable(unreadable)
    return 0


def _print_not_restored(rep: dict[str, Any]) -> None:
    if rep.get("unreadable"):
        print(
            f"  cannot restore {len(rep['unreadable'])} object(s): the backup lacks them "
            "(unreadable when it was taken); the drive keeps its present values there:"
        )
        _print_unreadable(rep["unreadable"])


def _print_unreadable(items: list[dict[str, Any]]) -> None:
    for u in items:
        code = f"{u['code_hex']} " if u.get("code_hex") else ""
        print(f"  {u['address']} {u['name']}: {code}{u['message']}")


# restore -----------------------------------------------------------------------------------


def run_restore(args: argparse.Namespace) -> int:
    from servodesk.services.restore import PreflightFailed, PreflightStateConflict

    if not args.file and not args.resume:
        raise ValidationError("give a backup FILE or --resume ID", hint="servodesk restore x.json")
    data = _read_file(args.file) if args.file else b""

    async def body(ctx: _Context) -> dict[str, Any]:
        session = await ctx.session()
        if args.resume:
            return await ctx.restores.resume(args.resume, session, client=client_id())
        bid = await _import(ctx, session, data, args.file)
        return await ctx.restores.restore(
            session,
            bid,
            dry_run=args.dry_run,
            store=not args.no_store,
            force=args.force,
            map_by_name=args.map_by_name,
            client=client_id(),
        )

    try:
        rep = _run(args, body)
    except (PreflightFailed, PreflightStateConflict) as exc:
        if args.json:
            _dump(exc.to_dict())
        print("servodesk: error: restore refused, nothing was written:", file=sys.stderr)
        for p in exc.problems:
            where = f"{p.address} " if p.address else ""
            print(f"  - {where}{p.message}" + (f" ({p.hint})" if p.hint else ""), file=sys.stderr)
        return 2
    if args.json:
        _dump(rep)
    else:
        _print_report(rep)
    if rep["dry_run"]:
        return 0
    c = rep["counts"]
    return 0 if rep["finished"] and not c["failed"] and not c["pending"] else 1


async def _import(ctx: _Context, session: Any, data: bytes, filename: str) -> str:
    """The store id of the file's backup (imported once; the same bytes reuse the record).

    A file new to the store is checked against the drive first: a restore the preflight
    refuses must leave no record (and no file) behind, however often it is tried.
    """
    from servodesk.services.restore import refusal

    digest = hashlib.sha256(data).hexdigest()
    for info in ctx.backups.store.list_backups(limit=100_000):
        if info["sha256"] == digest:
            return str(info["id"])
    ps = ctx.backups.parse(data, filename, ctx.args.profile)
    pf, _ = await ctx.restores.preflight(session, ps, map_names=ctx.args.map_by_name)
    if not pf.ok:
        raise refusal(pf)
    # A JSON backup is kept byte for byte: the store's copy is the user's file.
    exact = data if Path(filename).suffix.lower() == ".json" else None
    return str(ctx.backups.save(ps, source="upload", data=exact)["id"])


def _print_report(rep: dict[str, Any]) -> None:
    c = rep["counts"]
    if rep["dry_run"]:
        print(
            f"dry run of restore {rep['id']}: {c['would_write']} to write, {c['unchanged']} "
            f"unchanged, {c['skipped']} read-only skipped; the writes in order:"
        )
        for s in rep["steps"]:
            print(f"  {s['address']} <- {s['raw_hex']}  ({s['why']})")
        _print_not_restored(rep)
        return
    for it in rep["items"]:
        if it["status"] in ("written", "failed", "pending"):
            extra = f"  {it['code_hex']} {it['meaning']}" if it["code_hex"] else ""
            msg = f"  {it['message']}" if it["message"] and it["status"] != "written" else ""
            print(f"  {it['status']:8} {it['address']} {it['name']}{extra}{msg}")
    state = "interrupted" if rep["interrupted"] else ("finished" if rep["finished"] else "open")
    print(
        f"restore {rep['id']} {state}: {c['written']} written, {c['unchanged']} unchanged, "
        f"{c['skipped']} skipped, {c['failed']} failed, {c['pending']} pending; "
        f"{'stored' if rep['stored'] else 'not stored'}"
        + (f"; backup before: {rep['pre_backup']}" if rep["pre_backup"] else "")
    )
    for w in rep["warnings"]:
        print(f"  note: {w}")
    _print_not_restored(rep)
    if rep["message"]:
        print(f"  {rep['message']}")
    if rep["interrupted"]:
        print(f"  resume with: servodesk restore --resume {rep['id']} (same bus options)")


# diff --------------------------------------------------------------------------------------


def run_diff(args: argparse.Namespace) -> int:
    files = {x: _read_file(x) for x in (args.a, args.b) if x != "drive"}

    async def body(ctx: _Context) -> dict[str, Any]:
        parsed = {x: ctx.backups.parse(data, x, args.profile) for x, data in files.items()}
        session = await ctx.session() if "drive" in (args.a, args.b) else None

        def profile_of(x: str) -> str:
            if x in parsed:
                return parsed[x].profile_id
            assert session is not None
            return str(session.profile.id)

        pa, pb = profile_of(args.a), profile_of(args.b)
        if pa != pb:
            # Objects at one address of two profiles need not mean the same (a vendor's
            # 2000h is anything): compared by address, "0 differences" could be a lie.
            a = "the drive" if args.a == "drive" else args.a
            b = "the drive" if args.b == "drive" else args.b
            raise ValidationError(
                f"{a} is of profile {pa}, {b} of profile {pb}: sets of different profiles "
                "are not compared",
                field="b",
                hint="compare sets of one profile; to carry settings to a drive of another "
                "family, see servodesk restore FILE --map-by-name --dry-run",
            )
        sets: list[tuple[str, ParameterSet]] = []
        for name in (args.a, args.b):
            if name == "drive":
                assert session is not None
                sets.append(("drive", await ctx.backups.read_set(session, operation=None)))
            else:
                sets.append((name, parsed[name]))
        return ctx.backups.compare(sets[0], sets[1], include_same=args.all)

    cmp = _run(args, body)
    if args.json:
        _dump(cmp)
    else:
        for d in cmp["differences"]:
            unit = f" {d['unit']}" if d["unit"] else ""
            print(
                f"{d['kind']:8} {d['address']} {d['name']}: {_fmt(d['a_value'])} -> "
                f"{_fmt(d['b_value'])}{unit}  [{d['a_raw_hex'] or '-'} -> {d['b_raw_hex'] or '-'}]"
            )
        changed = sum(1 for d in cmp["differences"] if d["kind"] != "same")
        print(f"{changed} differences, {cmp['same']} equal ({cmp['a']} vs {cmp['b']})")
        for side in ("a", "b"):
            lacks = cmp[f"{side}_unreadable"]
            if lacks:
                print(f"not compared: {len(lacks)} object(s) unreadable in {cmp[side]}:")
                _print_unreadable(lacks)
    return 0 if cmp["equal"] else 1


def _fmt(v: Any) -> str:
    return "-" if v is None else str(v)
