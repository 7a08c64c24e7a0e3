"""``servodesk users``: the accounts of this machine's servodesk (docs/security.md, "Users").

Works on the store in SERVODESK_DATA_DIR directly, whether a server runs or not: a server
notices a disabled or removed account within seconds and ends its sessions. Passwords come
from an interactive prompt (twice) or, for scripts, from standard input (``--password-stdin``,
one line); never from the command line, where ``ps`` and the shell's history would show them.
"""

from __future__ import annotations

import argparse
import contextlib
import getpass
import sys
import time
from collections.abc import Iterator
from typing import Any

from servodesk.domain.roles import Role
from servodesk.errors import ValidationError
from servodesk.services.users import MAX_PASSWORD, UserStore
from servodesk.settings import Settings


def register(sub: Any) -> None:
    p = sub.add_parser("users", help="add, list and change accounts (login beyond loopback)")
    users = p.add_subparsers(dest="users_command", metavar="ACTION", required=True)
    roles = [r.value for r in Role]

    add = users.add_parser("add", help="add an account")
    add.add_argument("name")
    add.add_argument("--role", required=True, choices=roles)
    add.add_argument("--password-stdin", action="store_true", help="read the password from stdin")
    add.set_defaults(func=run_add)

    ls = users.add_parser("list", help="list the accounts")
    ls.set_defaults(func=run_list)

    pw = users.add_parser("passwd", help="set an account's password")
    pw.add_argument("name")
    pw.add_argument("--password-stdin", action="store_true", help="read the password from stdin")
    pw.set_defaults(func=run_passwd)

    dis = users.add_parser("disable", help="disable an account (its sessions end)")
    dis.add_argument("name")
    dis.set_defaults(func=run_disable, disabled=True)

    en = users.add_parser("enable", help="enable a disabled account")
    en.add_argument("name")
    en.set_defaults(func=run_disable, disabled=False)

    rm = users.add_parser("remove", help="remove an account and its API tokens")
    rm.add_argument("name")
    rm.set_defaults(func=run_remove)

    tok = users.add_parser("token", help="make an API token for a script (printed once)")
    tok.add_argument("name")
    tok.add_argument("--label", default="", help="what the token is for")
    tok.set_defaults(func=run_token)


@contextlib.contextmanager
def _store() -> Iterator[UserStore]:
    """The accounts of the data directory, closed however the command ends."""
    settings = Settings()
    users = UserStore(settings.data_dir, settings.store_url)
    try:
        yield users
    finally:
        users.close()


def _audit(event: str, **details: object) -> None:
    """Record a user-administration event (docs/security.md, Audit log) as
    ``cli:<user>@<host>``, as ``servodesk backup`` does."""
    from servodesk.cli.backup import client_id
    from servodesk.services.audit import Actor, AuditLog
    from servodesk.services.db import store_url

    settings = Settings()
    log = AuditLog(store_url(settings.data_dir, settings.store_url))
    try:
        log.record(event, who=Actor(client_id()), details=dict(details))
    finally:
        log.close()


def _password(args: argparse.Namespace) -> str:
    if args.password_stdin:
        line = sys.stdin.readline(MAX_PASSWORD + 2)
        return line.rstrip("\r\n")
    if not sys.stdin.isatty():
        raise ValidationError(
            "no terminal to ask the password on",
            hint="pipe it in with --password-stdin",
        )
    first = getpass.getpass("Password: ")
    if getpass.getpass("Again: ") != first:
        raise ValidationError("the two passwords differ", hint="type the same password twice")
    return first


def run_add(args: argparse.Namespace) -> int:
    with _store() as users:
        from servodesk.services.users import check_name

        check_name(args.name)  # Before the prompt: a bad name needs no password typed.
        user = users.add(args.name, args.role, _password(args))
    _audit("user.created", account=user.name, role=user.role)
    print(f"added {user.name} ({user.role})")
    return 0


def run_list(args: argparse.Namespace) -> int:
    with _store() as users:
        rows = users.all()
    if not rows:
        print("no accounts (a loopback server runs in the single-user mode)")
        return 0
    width = max(len(u.name) for u in rows)
    for u in rows:
        made = time.strftime("%Y-%m-%d %H:%M", time.localtime(u.created))
        state = "disabled" if u.disabled else "enabled"
        print(f"{u.name:<{width}}  {u.role:<13}  {state:<8}  created {made}")
    return 0


def run_passwd(args: argparse.Namespace) -> int:
    with _store() as users:
        users.require(args.name)
        users.set_password(args.name, _password(args))
    _audit("user.password_set", account=args.name)
    print(f"password of {args.name} set")
    return 0


def run_disable(args: argparse.Namespace) -> int:
    with _store() as users:
        users.set_disabled(args.name, args.disabled)
    _audit("user.disabled" if args.disabled else "user.enabled", account=args.name)
    print(f"{args.name} {'disabled' if args.disabled else 'enabled'}")
    return 0


def run_remove(args: argparse.Namespace) -> int:
    with _store() as users:
        users.remove(args.name)
    _audit("user.removed", account=args.name)
    print(f"removed {args.name}")
    return 0


def run_token(args: argparse.Namespace) -> int:
    with _store() as users:
        token, secret = users.create_token(args.name, args.label)
    _audit("user.token_created", account=args.name, token=token.id, label=token.label)
    print(
        f"API token {token.id} of {args.name} (shown once; send it as Authorization: Bearer):",
        file=sys.stderr,
    )
    print(secret)
    return 0
