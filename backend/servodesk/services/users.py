"""Local accounts and their API tokens, in servodesk's store (``<data_dir>/servodesk.db``, or
the PostgreSQL of ``SERVODESK_STORE_URL``: services/db.py).

- Passwords are hashed with argon2id (argon2-cffi's defaults: RFC 9106 §4's second
  recommended set, 64 MiB, 3 passes); only the hash is stored, nothing logs a password.
  Checking one costs tens of milliseconds of CPU on purpose: callers on the event loop run it
  in a thread (api/routes/auth.py), where the dead-man's heartbeats are not held up.
- API tokens (for scripts and the CLI) are 256-bit random secrets shown once; the store keeps
  their SHA-256. A slow hash protects guessable passwords; a 256-bit secret cannot be guessed,
  and every API request checks its token, so a fast hash is the right one here (the
  approach of GitHub's and PyPI's tokens).
- Account names: letters, digits and ``. _ @ -``, up to 64; ``local`` is the single-user
  mode's caller (api/identity.py) and cannot be an account.

Sessions (logins) are not stored: they live in the server's memory (services/logins.py) and
end with it (a gateway's logins are its own; the accounts are the store's, shared).
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import re
import secrets
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

from servodesk.domain.roles import Role, parse_role
from servodesk.errors import (
    ConflictError,
    NotFoundError,
    ServodeskError,
    Unavailable,
    ValidationError,
)
from servodesk.services import db

NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,63}$")
#: IEC 62443-4-2 CR 1.7 (password strength): a minimum length; the upper bound keeps one
#: hash from being made arbitrarily expensive.
MIN_PASSWORD = 8
MAX_PASSWORD = 1024
#: API tokens look like ``sdt_<id>_<secret>``: the id finds the row, the secret is checked.
TOKEN_PREFIX = "sdt_"
_TOKEN = re.compile(r"^sdt_([A-Za-z0-9]{12})_([A-Za-z0-9_-]{43})$")

_hasher = PasswordHasher()  # argon2id
#: Checked when the account does not exist, so that an unknown name takes as long as a wrong
#: password (the answer's timing must not tell which names exist).
_DUMMY = _hasher.hash(secrets.token_urlsafe(16))


class UsersError(ServodeskError):
    """The account store cannot be opened or written."""


class UsersUnavailable(UsersError, Unavailable):
    """The accounts are in a central store that cannot be reached now (HTTP 503)."""


@dataclass(frozen=True)
class User:
    name: str
    role: str
    disabled: bool
    created: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "role": self.role,
            "disabled": self.disabled,
            "created": self.created,
        }


@dataclass(frozen=True)
class ApiToken:
    id: str
    user: str
    label: str
    created: float
    last_used: float | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "user": self.user,
            "label": self.label,
            "created": self.created,
            "last_used": self.last_used,
        }


def check_name(name: str) -> str:
    if not NAME.match(name) or name == "local":
        raise ValidationError(
            f"{name!r} is not a valid account name",
            field="user",
            hint="use letters, digits and . _ @ - (up to 64, starting with a letter or digit); "
            "'local' is reserved for the single-user mode",
        )
    return name


def check_password(password: str) -> str:
    if not MIN_PASSWORD <= len(password) <= MAX_PASSWORD:
        raise ValidationError(
            f"a password needs {MIN_PASSWORD} to {MAX_PASSWORD} characters "
            f"(this one has {len(password)})",
            field="password",
            hint="choose a longer passphrase",
        )
    return password


def hash_password(password: str) -> str:
    return _hasher.hash(check_password(password))


def _sha256(secret: str) -> str:
    return hashlib.sha256(secret.encode("utf-8", "surrogatepass")).hexdigest()


class UserStore:
    """Accounts and API tokens in the store at ``url`` (empty: the SQLite file in
    ``data_dir``). Every call is short and one transaction, except
    :meth:`verify_password` (argon2: run it in a thread)."""

    def __init__(self, data_dir: Path, url: str = "") -> None:
        self.path = Path(data_dir) / db.SQLITE_FILE
        self.url = db.store_url(Path(data_dir), url)
        self._lock = threading.RLock()
        self._engine: sa.Engine | None = None
        self._has_accounts = True  # has_accounts' last answer
        _ = self._db  # Opened now: a store that cannot be opened is refused at start-up.
        self.has_accounts()

    @property
    def _db(self) -> sa.Engine:
        """The engine, opened again after :meth:`close` (an application's lifespan may run
        more than once, as in tests)."""
        with self._lock:
            if self._engine is None:
                try:
                    self._engine = db.open_engine(self.url)
                except db.StoreError as exc:
                    raise UsersError(exc.message, hint=exc.hint) from exc
            return self._engine

    def close(self) -> None:
        with self._lock:
            if self._engine is not None:
                self._engine.dispose()
                self._engine = None

    def _rows(self, statement: sa.Executable) -> list[sa.RowMapping]:
        try:
            with db.read(self._db) as conn:
                return list(conn.execute(statement).mappings().all())
        except sa.exc.SQLAlchemyError as exc:
            raise _error(exc) from exc

    def _write(self, *statements: sa.Executable) -> int:
        """The statements in one transaction; the rows the last one changed."""
        try:
            with db.write(self._db) as conn:
                count = 0
                for statement in statements:
                    count = conn.execute(statement).rowcount
                return count
        except sa.exc.IntegrityError:
            raise
        except sa.exc.SQLAlchemyError as exc:
            raise _error(exc) from exc

    # Accounts ---------------------------------------------------------------------------

    def has_accounts(self) -> bool:
        """Whether any account exists (the auth middleware asks on every request). While a
        central store is unreachable, the last answer (the first is read when the store opens),
        so that a loopback gateway keeps working on its local queue (services/outbox.py)."""
        with contextlib.suppress(UsersUnavailable):
            self._has_accounts = bool(self._rows(sa.select(sa.literal(1)).select_from(_U).limit(1)))
        return self._has_accounts

    def get(self, name: str) -> User | None:
        rows = self._rows(sa.select(_U).where(_U.c.name == name))
        return _user(rows[0]) if rows else None

    def require(self, name: str) -> User:
        user = self.get(name)
        if user is None:
            raise NotFoundError(f"no account {name!r}", hint="servodesk users list shows them")
        return user

    def all(self) -> list[User]:
        return [_user(r) for r in self._rows(sa.select(_U).order_by(_U.c.name))]

    def add(self, name: str, role: str, password: str) -> User:
        check_name(name)
        parse_role(role)
        digest = hash_password(password)
        try:
            self._write(
                sa.insert(_U).values(name=name, role=role, hash=digest, created=time.time())
            )
        except sa.exc.IntegrityError:
            raise ConflictError(
                f"the account {name!r} exists",
                hint="choose another name, or change its password (users passwd)",
            ) from None
        return self.require(name)

    def set_password(self, name: str, password: str) -> None:
        self.require(name)
        self._write(sa.update(_U).where(_U.c.name == name).values(hash=hash_password(password)))

    def set_role(self, name: str, role: str) -> User:
        parse_role(role)
        self._refuse_last_admin(name, losing=role != Role.ADMINISTRATOR)
        self._write(sa.update(_U).where(_U.c.name == name).values(role=role))
        return self.require(name)

    def set_disabled(self, name: str, disabled: bool) -> User:
        self._refuse_last_admin(name, losing=disabled)
        self._write(sa.update(_U).where(_U.c.name == name).values(disabled=int(disabled)))
        return self.require(name)

    def remove(self, name: str) -> None:
        self._refuse_last_admin(name, losing=True)
        # The account and its tokens together: never tokens left of a removed account.
        self._write(
            sa.delete(_T).where(_T.c.user == name),
            sa.delete(_U).where(_U.c.name == name),
        )

    def _refuse_last_admin(self, name: str, *, losing: bool) -> None:
        """Nobody could manage accounts any more: refused (the CLI can still add one)."""
        user = self.require(name)
        if not losing or user.role != Role.ADMINISTRATOR or user.disabled:
            return
        others = self._rows(
            sa.select(sa.literal(1))
            .select_from(_U)
            .where(_U.c.role == Role.ADMINISTRATOR.value, _U.c.disabled == 0, _U.c.name != name)
        )
        if not others:
            raise ConflictError(
                f"{name!r} is the last enabled administrator",
                hint="add another administrator first (servodesk users add NAME "
                "--role administrator)",
            )

    def verify_password(self, name: str, password: str) -> User | None:
        """The enabled account ``name`` if ``password`` is its password, else None. Slow
        (argon2): call it in a thread from the event loop."""
        row = self._rows(sa.select(_U).where(_U.c.name == name)) if NAME.match(name) else []
        digest = str(row[0]["hash"]) if row else _DUMMY
        try:
            _hasher.verify(digest, password)
        except (VerificationError, InvalidHashError):
            return None
        if not row:
            return None
        user = _user(row[0])
        if user.disabled:
            return None
        if _hasher.check_needs_rehash(digest):  # Parameters raised since it was made.
            self._write(sa.update(_U).where(_U.c.name == name).values(hash=_hasher.hash(password)))
        return user

    # API tokens -------------------------------------------------------------------------

    def create_token(self, user: str, label: str = "") -> tuple[ApiToken, str]:
        """A new token of ``user``: its record and the secret (shown once, never stored)."""
        self.require(user)
        if len(label) > 100:
            raise ValidationError("a token's label has up to 100 characters", field="label")
        tid = "".join(
            secrets.choice("ABCDEFGHJKLMNPQRSTUVWXYZabcdefghijkmnopqrstuvwxyz23456789")
            for _ in range(12)
        )
        secret = secrets.token_urlsafe(32)
        full = f"{TOKEN_PREFIX}{tid}_{secret}"
        self._write(
            sa.insert(_T).values(
                id=tid, user=user, label=label, sha256=_sha256(full), created=time.time()
            )
        )
        return self.tokens(user, tid)[0], full

    def tokens(self, user: str | None = None, tid: str | None = None) -> list[ApiToken]:
        query = sa.select(_T)
        if user is not None:
            query = query.where(_T.c.user == user)
        if tid is not None:
            query = query.where(_T.c.id == tid)
        return [_token(r) for r in self._rows(query.order_by(_T.c.created))]

    def delete_token(self, user: str, tid: str) -> None:
        if not self._write(sa.delete(_T).where(_T.c.id == tid, _T.c.user == user)):
            raise NotFoundError(f"{user!r} has no API token {tid!r}")

    def verify_token(self, presented: bytes) -> tuple[User, ApiToken] | None:
        """The enabled account and token ``presented`` (raw header bytes) belongs to."""
        try:
            text = presented.decode("ascii")
        except UnicodeDecodeError:
            return None
        m = _TOKEN.match(text)
        if m is None:
            return None
        rows = self._rows(sa.select(_T).where(_T.c.id == m.group(1)))
        if not rows or not hmac.compare_digest(str(rows[0]["sha256"]), _sha256(text)):
            return None
        token = _token(rows[0])
        user = self.get(token.user)
        if user is None or user.disabled:
            return None
        now = time.time()
        if token.last_used is None or now - token.last_used > 60:  # Not a write per request.
            self._write(sa.update(_T).where(_T.c.id == token.id).values(last_used=now))
        return user, token


_U, _T = db.users, db.api_tokens


def _error(exc: sa.exc.SQLAlchemyError) -> UsersError:
    err = db.store_error(exc)
    kind = UsersUnavailable if isinstance(err, db.StoreUnavailable) else UsersError
    return kind(err.message, hint=err.hint)


def _user(r: sa.RowMapping) -> User:
    return User(str(r["name"]), str(r["role"]), bool(r["disabled"]), float(r["created"]))


def _token(r: sa.RowMapping) -> ApiToken:
    last = r["last_used"]
    return ApiToken(
        str(r["id"]),
        str(r["user"]),
        str(r["label"]),
        float(r["created"]),
        float(last) if last is not None else None,
    )
