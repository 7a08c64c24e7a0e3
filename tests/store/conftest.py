"""A real PostgreSQL for the store's tests: one server per test session, one database per
test (issue 49; docs/deployment.md).

Debian's ``postgresql`` package provides ``initdb`` and ``pg_ctl`` (``make test`` installs
it when missing, as it does Chromium). The server runs in a temporary directory on a free
port of 127.0.0.1, with trust authentication for the one local user it is made with; as
root it runs as the ``postgres`` user (PostgreSQL refuses to run as root). ``fsync=off``:
the tests check the store's logic, not the disk, and a crash of the test machine loses
nothing that matters. Stopped (``pg_ctl stop -m fast``) when the session ends.
"""

from __future__ import annotations

import contextlib
import glob
import itertools
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

USER = "servodesk"
ENGINES = ("sqlite", "postgresql")


def _bin(name: str) -> str | None:
    found = sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"), key=_version)
    if found:
        return found[-1]
    return shutil.which(name)


def _version(path: str) -> int:
    try:
        return int(Path(path).parts[4])
    except (IndexError, ValueError):
        return 0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class PgServer:
    port: int
    datadir: Path
    _names: Iterator[int]

    def url(self, database: str = "postgres") -> str:
        return f"postgresql://{USER}@127.0.0.1:{self.port}/{database}"

    def new_database(self) -> str:
        """A fresh, empty database on the session's server; its URL."""
        import psycopg

        name = f"t{os.getpid()}_{next(self._names)}"
        with psycopg.connect(
            f"host=127.0.0.1 port={self.port} user={USER} dbname=postgres", autocommit=True
        ) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)


@pytest.fixture(scope="session")
def pg_server() -> Iterator[PgServer]:
    initdb, pg_ctl = _bin("initdb"), _bin("pg_ctl")
    if initdb is None or pg_ctl is None:
        pytest.fail(
            "PostgreSQL's initdb/pg_ctl are missing: install Debian's postgresql package "
            "(make test does: apt-get install postgresql)"
        )
    base = Path(tempfile.mkdtemp(prefix="servodesk-pg-"))
    datadir = base / "data"
    prefix: list[str] = []
    if os.geteuid() == 0:
        # initdb and postgres refuse root: run them as the package's postgres user.
        pw = pwd.getpwnam("postgres")
        os.chown(base, pw.pw_uid, pw.pw_gid)
        prefix = ["runuser", "-u", "postgres", "--"]
    port = _free_port()
    run = dict(check=True, capture_output=True, text=True, timeout=180)
    try:
        subprocess.run(
            [
                *prefix,
                initdb,
                "-D",
                str(datadir),
                "-U",
                USER,
                "--auth=trust",
                "-E",
                "UTF8",
                "--no-sync",
                "--no-locale",
            ],
            **run,  # type: ignore[call-overload]
        )
        options = (
            f"-p {port} -c listen_addresses=127.0.0.1 -c unix_socket_directories={base} "
            "-c fsync=off -c synchronous_commit=off -c full_page_writes=off "
            "-c max_connections=60"
        )
        subprocess.run(
            [
                *prefix,
                pg_ctl,
                "-D",
                str(datadir),
                "-o",
                options,
                "-w",
                "-t",
                "120",
                "-l",
                str(base / "log"),
                "start",
            ],
            **run,  # type: ignore[call-overload]
        )
    except subprocess.CalledProcessError as exc:
        log = base / "log"
        tail = log.read_text(errors="replace")[-2000:] if log.exists() else ""
        shutil.rmtree(base, ignore_errors=True)
        pytest.fail(f"PostgreSQL did not start: {exc.stderr}\n{tail}")
    try:
        yield PgServer(port, datadir, itertools.count())
    finally:
        with contextlib.suppress(subprocess.SubprocessError):
            subprocess.run(
                [*prefix, pg_ctl, "-D", str(datadir), "-m", "fast", "-w", "-t", "60", "stop"],
                check=False,
                capture_output=True,
                timeout=90,
            )
        shutil.rmtree(base, ignore_errors=True)


@pytest.fixture
def pg_url(pg_server: PgServer) -> str:
    """The URL of a fresh PostgreSQL database (one per test, on the session's server)."""
    return pg_server.new_database()


@pytest.fixture(params=ENGINES)
def engine_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A fresh store's URL, once on SQLite (the default: empty, the data directory's
    file) and once on PostgreSQL. The PostgreSQL server is started only when needed."""
    if request.param == "sqlite":
        return ""
    server: PgServer = request.getfixturevalue("pg_server")
    return server.new_database()
