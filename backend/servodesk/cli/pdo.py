"""``servodesk pdo``: show, plan and apply a drive's PDO mapping; list the family's templates.

    servodesk pdo show --node-id 3 [--json] [--export csv|dcf|esi|json]
    servodesk pdo apply layout.json [--dry-run] --node-id 3 [--json]
    servodesk pdo apply --template csp-touch-probe --node-id 3
    servodesk pdo templates --profile hiwin-e [--json]

``layout.json`` is a PdoLayout (docs/pdo.md), e.g. what ``pdo show --export json`` wrote.
Exit codes: 0 done, 1 the drive refused halfway (the report says whether the previous mapping
is back), 2 bad input or a mapping refused before anything was written.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from servodesk.cli.backup import (
    _bus_options,
    _Context,
    _dump,
    _read_file,
    _run,
    client_id,
    settings_catalog,
)
from servodesk.errors import PdoRefused, ValidationError


def register(sub: Any) -> None:
    p = sub.add_parser("pdo", help="PDO mapping: show, apply, templates")
    cmds = p.add_subparsers(dest="pdo_command", metavar="PDO_COMMAND")

    s = cmds.add_parser("show", help="read and print the drive's PDO configuration")
    s.add_argument(
        "--export", choices=["json", "csv", "dcf", "esi"], help="print the layout in this format"
    )
    _bus_options(s)
    s.set_defaults(func=run_show)

    a = cmds.add_parser("apply", help="apply a PDO layout file (or a template) to the drive")
    a.add_argument("file", nargs="?", help="PdoLayout JSON file (docs/pdo.md)")
    a.add_argument("--template", help="apply this template of the family instead of a file")
    a.add_argument("--dry-run", action="store_true", help="print the plan, write nothing")
    _bus_options(a)
    a.set_defaults(func=run_apply)

    t = cmds.add_parser("templates", help="list the family's PDO templates")
    _bus_options(t)
    t.set_defaults(func=run_templates)
    p.set_defaults(func=lambda args: _usage(p))


def _usage(p: argparse.ArgumentParser) -> int:
    p.print_help(sys.stderr)
    return 2


def _print_view(view: dict[str, Any]) -> None:
    print(f"kind {view['kind']}, NMT {view['nmt_state']}, byte order {view['byte_order']}")
    for p in view["pdos"]:
        flag = "active" if p["active"] else "off"
        comm = ""
        if p["transmission_type"] is not None:
            comm = f" type {p['transmission_type']} ({p['transmission_text']})"
        print(
            f"{p['name']:<18} COB-ID {p['cob_id_hex']} {flag:<6} "
            f"{p['bits']}/{p['max_bits']} bits{comm}"
        )
        for e in p["entries"]:
            print(
                f"    byte {e['offset_byte']:>2} bit {e['offset_bits'] % 8}  {e['bits']:>2} bits  "
                f"{e['address'] or 'padding':<11} {e['name']}"
                + (f" [{e['unit']}]" if e["unit"] else "")
            )


def run_show(args: argparse.Namespace) -> int:
    from servodesk.devdesc import pdo_export
    from servodesk.services import pdo as pdosvc

    async def body(ctx: _Context) -> Any:
        session = await ctx.session()
        if args.export:
            config = await pdosvc.read_config(session)
            return pdo_export.export(session.profile, config, args.export, args.node_id)
        return await pdosvc.view(session)

    out = _run(args, body)
    if isinstance(out, str):
        sys.stdout.write(out if out.endswith("\n") else out + "\n")
    elif args.json:
        _dump(out)
    else:
        _print_view(out)
    return 0


def _layout_file(path: str) -> dict[str, Any]:
    try:
        data = json.loads(_read_file(path))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValidationError(
            f"{path}: not a JSON PDO layout ({exc})",
            field="file",
            hint="write it as in docs/pdo.md, or use `servodesk pdo show --export json`",
        ) from None
    if not isinstance(data, dict) or not isinstance(data.get("pdos", []), list):
        raise ValidationError(f"{path}: a PDO layout is an object with a list 'pdos'", field="file")
    # An export's "layout" section (offsets and types for the PLC programmer) is for reading;
    # applying takes the configuration only.
    data.pop("layout", None)
    return data


def run_apply(args: argparse.Namespace) -> int:
    from servodesk.domain import pdo as pdomod
    from servodesk.services import pdo as pdosvc

    if bool(args.file) == bool(args.template):
        raise ValidationError(
            "give a layout FILE or --template ID (one of them)",
            hint="servodesk pdo templates lists the templates",
        )
    layout = _layout_file(args.file) if args.file else None

    async def body(ctx: _Context) -> dict[str, Any]:
        session = await ctx.session()
        if layout is not None:
            data = layout
        else:
            current = await pdosvc.read_config(session)
            try:
                desired = pdomod.apply_template(session.profile, current, args.template)
            except KeyError:
                raise ValidationError(
                    f"{session.profile.id} has no PDO template {args.template!r}",
                    field="template",
                    hint="servodesk pdo templates lists them",
                ) from None
            data = pdomod.config_to_json(session.profile, desired)
        return await pdosvc.apply(session, data, dry_run=args.dry_run, client=client_id())

    try:
        report = _run(args, body)
    except PdoRefused as exc:
        if args.json:
            _dump({"ok": False, "error": exc.message, "problems": _problems(exc)})
        else:
            print(f"servodesk: error: {exc.message}", file=sys.stderr)
            for p in _problems(exc):
                where = " ".join(str(x) for x in (p.get("pdo"), p.get("field")) if x)
                print(f"  {where}: {p.get('message')}", file=sys.stderr)
        return 2
    if args.json:
        _dump({k: v for k, v in report.items() if k != "view"})
    else:
        for i, s in enumerate(report["steps"], 1):
            what = (
                f"NMT {s['command']}"
                if s["kind"] == "nmt"
                else f"{s['address']} <- {s['value_hex']}"
            )
            print(f"{i:>3}. {what:<28} {s['why']}")
        if report["dry_run"]:
            print(f"dry run: {len(report['steps'])} steps, nothing written")
        elif report["ok"]:
            print(f"applied {report['done']} steps in {report['duration_s']} s, verified")
        else:
            back = "previous mapping restored" if report["rolled_back"] else "NOT restored"
            print(f"failed: {report['error']}; {back}", file=sys.stderr)
    return 0 if report["ok"] else 1


def _problems(exc: PdoRefused) -> list[dict[str, Any]]:
    from servodesk.services.pdo import problem_dict

    out = []
    for p in exc.problems:
        out.append(p if isinstance(p, dict) else problem_dict(p))
    return out


def run_templates(args: argparse.Namespace) -> int:
    from servodesk.domain import pdo as pdomod

    if args.profile:
        catalog = settings_catalog()
        profile = catalog.get(args.profile)
        items = [
            {"id": t.id, "name": t.name, "description": t.description, "section": t.section}
            for t in pdomod.templates(profile)
        ]
    else:
        from servodesk.services import pdo as pdosvc

        async def body(ctx: _Context) -> list[dict[str, Any]]:
            return pdosvc.templates(await ctx.session())

        items = _run(args, body)
    if args.json:
        _dump(items)
    else:
        for t in items:
            print(f"{t['id']:<24} {t['name']}" + (f"  ({t['section']})" if t["section"] else ""))
    return 0
