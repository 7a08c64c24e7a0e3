"""``servodesk users`` (docs/security.md, Users): accounts from the command line, errors exit 2
with a message, passwords never on the command line; ``serve`` beyond loopback refuses to
start before an administrator exists."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest

from servodesk.cli import main
from servodesk.services.users import UserStore


@pytest.fixture
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path))
    return tmp_path


def run(
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    *argv: str,
    stdin: str = "",
) -> tuple[int, str, str]:
    monkeypatch.setattr(sys, "stdin", io.StringIO(stdin))
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse's own errors
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def test_add_list_passwd_disable_remove(
    data_dir: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pw = "first password\n"
    args = ("users", "add", "admin", "--role", "administrator", "--password-stdin")
    assert run(capsys, monkeypatch, *args, stdin=pw)[0] == 0
    code, out, _ = run(
        capsys,
        monkeypatch,
        "users",
        "add",
        "ann",
        "--role",
        "operator",
        "--password-stdin",
        stdin=pw,
    )
    assert code == 0 and "ann" in out
    code, out, _ = run(capsys, monkeypatch, "users", "list")
    assert code == 0 and "admin" in out and "administrator" in out and "operator" in out
    store = UserStore(data_dir)
    try:
        assert store.verify_password("ann", "first password") is not None
        # Only the argon2id hash is stored, never the password.
        raw = (data_dir / "servodesk.db").read_bytes()
        assert b"first password" not in raw and b"$argon2id$" in raw
        code, _, _ = run(
            capsys,
            monkeypatch,
            "users",
            "passwd",
            "ann",
            "--password-stdin",
            stdin="second password\n",
        )
        assert code == 0
        assert store.verify_password("ann", "first password") is None
        assert store.verify_password("ann", "second password") is not None
        assert run(capsys, monkeypatch, "users", "disable", "ann")[0] == 0
        assert store.verify_password("ann", "second password") is None
        assert run(capsys, monkeypatch, "users", "enable", "ann")[0] == 0
        code, out, err = run(capsys, monkeypatch, "users", "token", "ann")
        assert code == 0 and out.startswith("sdt_") and "shown once" in err
        assert store.verify_token(out.strip().encode()) is not None
        assert run(capsys, monkeypatch, "users", "remove", "ann")[0] == 0
        assert store.get("ann") is None and store.verify_token(out.strip().encode()) is None
    finally:
        store.close()
    # Each change is in the audit log, by the CLI's user (docs/security.md, Audit log).
    from servodesk.services.audit import AuditLog

    log = AuditLog(data_dir / "servodesk.db")
    try:
        events = [(r["event"], r["user"][:4]) for r in reversed(log.query(category="user_admin"))]
    finally:
        log.close()
    assert [e for e, _ in events] == [
        "user.created",
        "user.created",
        "user.password_set",
        "user.disabled",
        "user.enabled",
        "user.token_created",
        "user.removed",
    ]
    assert {who for _, who in events} == {"cli:"}
    assert b"second password" not in (data_dir / "servodesk.db").read_bytes()


@pytest.mark.parametrize(
    ("argv", "stdin", "said"),
    [
        (("users", "add", "bob", "--role", "king", "--password-stdin"), "long enough", "king"),
        (("users", "add", "b b", "--role", "guest", "--password-stdin"), "long enough", "name"),
        (("users", "add", "local", "--role", "guest", "--password-stdin"), "long enough", "name"),
        (("users", "add", "bob", "--role", "guest", "--password-stdin"), "short", "8 to"),
        (("users", "add", "bob", "--role", "guest"), "", "--password-stdin"),
        (("users", "passwd", "nobody", "--password-stdin"), "long enough", "nobody"),
        (("users", "remove", "nobody"), "", "nobody"),
        (("users", "disable", "admin"), "", "last enabled administrator"),
        (("users", "remove", "admin"), "", "last enabled administrator"),
        (("users", "add", "admin", "--role", "guest", "--password-stdin"), "long enough", "exists"),
    ],
)
def test_errors_exit_2_with_a_message(
    data_dir: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    argv: tuple[str, ...],
    stdin: str,
    said: str,
) -> None:
    run(
        capsys,
        monkeypatch,
        "users",
        "add",
        "admin",
        "--role",
        "administrator",
        "--password-stdin",
        stdin="admin password",
    )
    code, _, err = run(capsys, monkeypatch, *argv, stdin=stdin)
    assert code == 2, err
    assert said in err and "Traceback" not in err


def test_serve_beyond_loopback_without_an_account_refuses_to_start(tmp_path: Path) -> None:
    env = {"SERVODESK_DATA_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"}
    r = subprocess.run(
        [sys.executable, "-m", "servodesk", "serve", "--host", "0.0.0.0", "--port", "1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    assert "servodesk users add admin --role administrator" in r.stderr
