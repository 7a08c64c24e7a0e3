"""Local accounts and their API tokens, in servodesk's store (``<data_dir>/servodesk.db``).

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
end with it. Issue 49 moves this store to SQLAlchemy; the tables are kept small for that.
"""

from __future__ import annotations

import hashlib
import hmac
import re
import secrets
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

from servodesk.domain.roles import Role, parse_role
from servodesk.errors import ConflictError, NotFoundError, ServodeskError, ValidationError

SCHEMA = """
CREATE TABLE IF NOT EXISTS users (
    name TEXT PRIMARY KEY,
    role TEXT NOT NULL,
    hash TEXT NOT NULL,
    disabled INTEGER NOT NULL DEFAULT 0,
    created REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS api_tokens (
    id TEXT PRIMARY KEY,
    user TEXT NOT NULL,
    label TEXT NOT NULL DEFAULT '',
    sha256 TEXT NOT NULL,
    created REAL NOT NULL,
    last_used REAL
);
CREATE INDEX IF NOT EXISTS api_tokens_user ON api_tokens (user);
"""

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
    """Accounts and API tokens. One connection, shared behind a lock; every call is short
    except :meth:`verify_password` (argon2: run it in a thread)."""

    def __init__(self, data_dir: Path) -> None:
        self.path = Path(data_dir) / "servodesk.db"
        self._lock = threading.RLock()
        self._conn: sqlite3.Connection | None = None
        _ = self._db  # Opened now: a store that cannot be opened is refused at start-up.

    @property
    def _db(self) -> sqlite3.Connection:
        """The connection, opened again after :meth:`close` (an application's lifespan may
        run more than once, as in tests)."""
        with self._lock:
            if self._conn is None:
                try:
                    self.path.parent.mkdir(parents=True, exist_ok=True)
                    db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
                    db.row_factory = sqlite3.Row
                    db.execute("PRAGMA journal_mode=WAL")
                    db.execute("PRAGMA synchronous=FULL")
                    db.execute("PRAGMA busy_timeout=5000")
                    db.executescript(SCHEMA)
                except (OSError, sqlite3.Error) as exc:
                    raise UsersError(
                        f"cannot open the account store {self.path}: {exc}",
                        hint="set SERVODESK_DATA_DIR to a directory you can write",
                    ) from exc
                self._conn = db
            return self._conn

    def close(self) -> None:
        with self._lock:
            if self._conn is not None:
                self._conn.close()
                self._conn = None

    def _rows(self, sql: str, args: tuple[Any, ...] = ()) -> list[sqlite3.Row]:
        with self._lock:
            return self._db.execute(sql, args).fetchall()

    def _write(self, sql: str, args: tuple[Any, ...] = ()) -> int:
        with self._lock:
            return self._db.execute(sql, args).rowcount

    # Accounts ---------------------------------------------------------------------------

    def has_accounts(self) -> bool:
        return bool(self._rows("SELECT 1 FROM users LIMIT 1"))

    def get(self, name: str) -> User | None:
        rows = self._rows("SELECT * FROM users WHERE name = ?", (name,))
        return _user(rows[0]) if rows else None

    def require(self, name: str) -> User:
        user = self.get(name)
        if user is None:
            raise NotFoundError(f"no account {name!r}", hint="servodesk users list shows them")
        return user

    def all(self) -> list[User]:
        return [_user(r) for r in self._rows("SELECT * FROM users ORDER BY name")]

    def add(self, name: str, role: str, password: str) -> User:
        check_name(name)
        parse_role(role)
        digest = hash_password(password)
        try:
            self._write(
                "INSERT INTO users (name, role, hash, created) VALUES (?, ?, ?, ?)",
                (name, role, digest, time.time()),
            )
        except sqlite3.IntegrityError:
            raise ConflictError(
                f"the account {name!r} exists",
                hint="choose another name, or change its password (users passwd)",
            ) from None
        return self.require(name)

    def set_password(self, name: str, password: str) -> None:
        self.require(name)
        self._write("UPDATE users SET hash = ? WHERE name = ?", (hash_password(password), name))

    def set_role(self, name: str, role: str) -> User:
        parse_role(role)
        self._refuse_last_admin(name, losing=role != Role.ADMINISTRATOR)
        self._write("UPDATE users SET role = ? WHERE name = ?", (role, name))
        return self.require(name)

    def set_disabled(self, name: str, disabled: bool) -> User:
        self._refuse_last_admin(name, losing=disabled)
        self._write("UPDATE users SET disabled = ? WHERE name = ?", (int(disabled), name))
        return self.require(name)

    def remove(self, name: str) -> None:
        self._refuse_last_admin(name, losing=True)
        with self._lock:
            self._db.execute("DELETE FROM api_tokens WHERE user = ?", (name,))
            self._db.execute("DELETE FROM users WHERE name = ?", (name,))

    def _refuse_last_admin(self, name: str, *, losing: bool) -> None:
        """Nobody could manage accounts any more: refused (the CLI can still add one)."""
        user = self.require(name)
        if not losing or user.role != Role.ADMINISTRATOR or user.disabled:
            return
        others = self._rows(
            "SELECT 1 FROM users WHERE role = ? AND disabled = 0 AND name != ?",
            (Role.ADMINISTRATOR.value, name),
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
        row = self._rows("SELECT * FROM users WHERE name = ?", (name,)) if NAME.match(name) else []
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
            self._write("UPDATE users SET hash = ? WHERE name = ?", (_hasher.hash(password), name))
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
            "INSERT INTO api_tokens (id, user, label, sha256, created) VALUES (?, ?, ?, ?, ?)",
            (tid, user, label, _sha256(full), time.time()),
        )
        return self.tokens(user, tid)[0], full

    def tokens(self, user: str | None = None, tid: str | None = None) -> list[ApiToken]:
        sql, args = "SELECT * FROM api_tokens WHERE 1=1", []
        if user is not None:
            sql += " AND user = ?"
            args.append(user)
        if tid is not None:
            sql += " AND id = ?"
            args.append(tid)
        return [_token(r) for r in self._rows(sql + " ORDER BY created", tuple(args))]

    def delete_token(self, user: str, tid: str) -> None:
        if not self._write("DELETE FROM api_tokens WHERE id = ? AND user = ?", (tid, user)):
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
        rows = self._rows("SELECT * FROM api_tokens WHERE id = ?", (m.group(1),))
        if not rows or not hmac.compare_digest(str(rows[0]["sha256"]), _sha256(text)):
            return None
        token = _token(rows[0])
        user = self.get(token.user)
        if user is None or user.disabled:
            return None
        now = time.time()
        if token.last_used is None or now - token.last_used > 60:  # Not a write per request.
            self._write("UPDATE api_tokens SET last_used = ? WHERE id = ?", (now, token.id))
        return user, token


def _user(r: sqlite3.Row) -> User:
    return User(str(r["name"]), str(r["role"]), bool(r["disabled"]), float(r["created"]))


def _token(r: sqlite3.Row) -> ApiToken:
    last = r["last_used"]
    return ApiToken(
        str(r["id"]),
        str(r["user"]),
        str(r["label"]),
        float(r["created"]),
        float(last) if last is not None else None,
    )
