"""A store that a newer servodesk upgraded (a schema revision this one does not ship) is
refused with what to do, and left as it was (services/db.py ``upgrade``); ``servodesk openapi``
never opens the user's store at all (it failed on such a store in CI)."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

from servodesk.services.store import Store


def test_a_store_from_a_newer_servodesk_is_refused_and_left_alone(tmp_path: Path) -> None:
    Store(tmp_path).close()
    db = tmp_path / "servodesk.db"
    with sqlite3.connect(db) as c:
        c.execute("UPDATE alembic_version SET version_num = '9999'")
    # Another process (the schema is checked once per store and process, when it opens).
    code = (
        "import sys; from pathlib import Path; from servodesk.services.db import StoreError\n"
        "from servodesk.services.store import Store\n"
        "try:\n    Store(Path(sys.argv[1]))\n"
        "except StoreError as e:\n    print(e.message); print(e.hint); sys.exit(3)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 3, done.stderr
    assert "schema revision this servodesk does not know" in done.stdout
    assert "newer servodesk" in done.stdout and "Traceback" not in done.stderr
    with sqlite3.connect(db) as c:
        assert c.execute("SELECT version_num FROM alembic_version").fetchall() == [("9999",)]


def test_openapi_does_not_open_the_users_store(tmp_path: Path) -> None:
    data = tmp_path / "data"
    done = subprocess.run(
        [sys.executable, "-m", "servodesk", "openapi"],
        capture_output=True,
        text=True,
        timeout=120,
        env={"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "SERVODESK_DATA_DIR": str(data)},
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert '"openapi"' in done.stdout
    assert not data.exists() and not (tmp_path / ".servodesk").exists()
