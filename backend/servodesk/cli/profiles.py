"""``servodesk profiles``, ``servodesk profile ID`` and ``servodesk od ID [ADDR]``."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.domain.profile_loader import ProfileCatalog, check_profile, save_profile
from servodesk.files import write_atomic
from servodesk.settings import Settings


def register(sub: Any) -> None:
    p = sub.add_parser("profiles", help="list the drive profiles, or import one")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument(
        "--import",
        dest="import_file",
        metavar="FILE",
        help="import an EDS, DCF, ESI (.xml), XDD/XDC or XPD file as a new profile",
    )
    p.add_argument("--id", dest="new_id", help="id of the imported profile (default: file name)")
    p.add_argument(
        "--device",
        type=int,
        metavar="N",
        help="ESI with several devices: import device N (from 1; default 1)",
    )
    p.add_argument(
        "--list-devices",
        action="store_true",
        help="with --import FILE (ESI): list the file's devices instead of importing",
    )
    p.set_defaults(func=run_list)

    p = sub.add_parser("profile", help="show one profile, or export it")
    p.add_argument("id", help="profile id, e.g. hiwin-e")
    p.add_argument("--json", action="store_true", help="the whole profile as JSON")
    p.add_argument("--export", choices=["eds", "dcf", "esi"], help="write a device description")
    p.add_argument("-o", "--output", help="file to write (default: standard output)")
    p.add_argument("--force", action="store_true", help="replace an existing output file")
    p.set_defaults(func=run_profile)

    p = sub.add_parser("od", help="object dictionary entries of a profile")
    p.add_argument("id", help="profile id")
    p.add_argument("address", nargs="?", help="0x6040, 0x6040:00 or (PROFINET) P24640")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run_od)


def _catalog() -> ProfileCatalog:
    from servodesk.domain.profile_loader import default_profile_dirs

    return ProfileCatalog(default_profile_dirs(Settings().profile_paths()))


def _dump(data: object) -> None:
    json.dump(data, sys.stdout, indent=2, ensure_ascii=False, default=str)
    sys.stdout.write("\n")


def summary(p: DeviceProfile) -> dict[str, Any]:
    tables: dict[str, int] = {}
    for e in p.errors:
        tables[e.table] = tables.get(e.table, 0) + 1
    return {
        "id": p.id,
        "name": p.name,
        "vendor": p.vendor,
        "fieldbus": p.fieldbus,
        "version": p.version,
        "objects": len(p.objects),
        "variables": len(p.variables),
        "errors": len(p.errors),
        "error_tables": tables,
        "modes": list(p.modes),
        "homing_methods": list(p.homing_methods),
        "quirks": len(p.quirks),
        "contradictions": len(p.contradictions),
    }


def od_entry(s: ObjectSpec) -> dict[str, Any]:
    return {
        "index": s.index,
        "subindex": s.subindex,
        "address": str(s.address),
        "name": s.name,
        "name_local": s.name_local,
        "data_type": s.data_type.name,
        "access": s.access.value,
        "pdo_mapping": s.pdo_mapping.value,
        "default": s.default,
        "min": s.min,
        "max": s.max,
        "unit": s.unit,
        "scale": s.scale,
        "raw_unit": s.raw_unit,
        "group": s.group,
        "persist": s.persist,
        "process": s.process,
        "description": s.description,
        "section": s.section,
        "values": {str(k): v for k, v in s.values.items()} if s.values else None,
        "pnu": s.pnu,
        "symbol": s.symbol,
    }


def run_list(args: argparse.Namespace) -> int:
    if args.import_file:
        return _import(args)
    if args.device is not None or args.list_devices:
        print(
            "servodesk: error: --device and --list-devices go with --import FILE", file=sys.stderr
        )
        print("  hint: servodesk profiles --import drive.xml --device 2", file=sys.stderr)
        return 2
    rows = [summary(p) for p in _catalog().all()]
    if args.json:
        _dump(rows)
        return 0
    print(f"{'id':16} {'fieldbus':14} {'objects':>7} {'vars':>6} {'errors':>6}  name")
    for r in rows:
        print(
            f"{r['id']:16} {r['fieldbus']:14} {r['objects']:>7} {r['variables']:>6} "
            f"{r['errors']:>6}  {r['name']}"
        )
    return 0


def _list_devices(path: str, as_json: bool) -> int:
    from servodesk import devdesc

    devices = devdesc.file_devices(path)
    if as_json:
        _dump([dataclasses.asdict(d) for d in devices])
        return 0
    for d in devices:
        code = f"#x{d.product_code:08X}" if d.product_code is not None else "-"
        rev = f"#x{d.revision:08X}" if d.revision is not None else "-"
        print(f"{d.number:4}  product {code}  revision {rev}  {d.name}")
    return 0


def _import(args: argparse.Namespace) -> int:
    from servodesk import devdesc

    if args.list_devices:
        return _list_devices(args.import_file, args.json)
    settings = Settings()
    catalog = _catalog()
    result = devdesc.read_file(args.import_file, args.new_id, device=args.device)
    p = result.profile
    # What the file holds that the profile does not: said before anything else, on stderr.
    for w in result.warnings:
        print(f"servodesk: warning: {w}", file=sys.stderr)
    if p.id in catalog.ids():
        print(f"servodesk: error: a profile {p.id!r} exists already", file=sys.stderr)
        print("  hint: choose another id with --id", file=sys.stderr)
        return 2
    problems = check_profile(p)
    if problems:
        print(
            f"servodesk: error: the imported profile is inconsistent: {problems[0]}",
            file=sys.stderr,
        )
        return 2
    path = save_profile(p, settings.user_profile_dir)
    if args.json:
        _dump({**summary(p), "path": str(path), "warnings": list(result.warnings)})
    else:
        skipped = f", {len(result.warnings)} warning(s) above" if result.warnings else ""
        print(f"imported {p.id}: {len(p.variables)} objects -> {path}{skipped}")
    return 0


def _export(p: DeviceProfile, args: argparse.Namespace) -> int:
    from servodesk import devdesc

    if args.export == "eds":
        text = devdesc.export_eds(p)
    elif args.export == "dcf":
        text = devdesc.export_dcf(p, 1, {})
    else:
        text = devdesc.export_esi(p)
    if not args.output:
        sys.stdout.write(text)
        return 0
    out = Path(args.output)
    if out.exists() and not args.force:
        print(f"servodesk: error: {out} exists; nothing was written", file=sys.stderr)
        print("  hint: choose another file or add --force", file=sys.stderr)
        return 2
    try:
        write_atomic(out, text.encode("utf-8"))  # Never half-written, no leftovers.
    except OSError as exc:
        print(f"servodesk: error: cannot write {out}: {exc.strerror}", file=sys.stderr)
        return 2
    print(f"wrote {out} ({args.export.upper()}, {len(p.variables)} objects)", file=sys.stderr)
    return 0


def run_profile(args: argparse.Namespace) -> int:
    p = _catalog().get(args.id)
    if args.export:
        return _export(p, args)
    if args.json:
        data = summary(p)
        data.update(
            description=p.description,
            manuals=[m.model_dump() for m in p.manuals],
            identity=p.identity.model_dump(),
            groups=[g.model_dump() for g in p.groups],
            objects=[od_entry(s) for s in p.variables.values()],
            errors=[{**e.model_dump(), "code_hex": f"0x{e.code:X}"} for e in p.errors],
            quirks=[q.model_dump() for q in p.quirks],
            contradictions=[c.model_dump() for c in p.contradictions],
            pdo=p.pdo.model_dump(),
            problems=check_profile(p),
        )
        data["object_count"] = len(p.objects)
        _dump(data)
        return 0
    s = summary(p)
    for k, v in s.items():
        print(f"{k:15} {v}")
    return 0


def run_od(args: argparse.Namespace) -> int:
    p = _catalog().get(args.id)
    specs = list(p.variables.values())
    if args.address:
        addr = ObjectAddress.parse(args.address)
        explicit_sub = ":" in args.address or "." in args.address or "[" in args.address
        specs = [
            s
            for s in specs
            if s.index == addr.index and (not explicit_sub or s.subindex == addr.subindex)
        ]
        if not specs:
            print(f"servodesk: error: {args.address} is not in profile {p.id}", file=sys.stderr)
            print("  hint: run 'servodesk od " + p.id + "' to list its objects", file=sys.stderr)
            return 2
    if args.json:
        _dump([od_entry(s) for s in specs])
        return 0
    for s in specs:
        unit = f" [{s.unit}]" if s.unit else ""
        print(f"{s.address}  {s.data_type.name:14} {s.access.value:5} {s.name}{unit}")
    return 0
