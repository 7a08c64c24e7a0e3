"""A backup lacks what the drive refused to give: every place that shows it says so (issue 48).

The smartris twin is made to hold no value for 607Fh (Max profile velocity): it answers abort
0800 0024h "No data available", as a drive whose firmware lacks the value does, and its backup
is therefore incomplete. (Every object of the manual has a value in the twins, issue 47:
``SERVODESK_SIM_WITHHOLD`` and ``SimulatedDrive.withhold`` take one away.)
"""

from __future__ import annotations

import itertools
import json
import os
import sqlite3
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import httpx
import pytest
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.cli import main
from servodesk.services.store import Store
from servodesk.settings import Settings
from servodesk.sim.bus import SimulatedBus
from tests.control_helpers import bind_in_process, take_control

_n = itertools.count()
H = {"X-Servodesk-Client": "ui-test-tab"}
LACKS = "0x607F:00"


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def api(tmp_path_factory) -> AsyncIterator[httpx.AsyncClient]:  # type: ignore[no-untyped-def]
    settings = Settings(
        sim=True,
        sim_channel=f"unreadable-{os.getpid()}-{next(_n)}",
        sim_profiles="smartris",
        sim_withhold=f"smartris={LACKS}",
        data_dir=tmp_path_factory.mktemp("data"),
        sdo_timeout=0.3,
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://t/api/v1") as c:
            s = str((await c.get("/sessions")).json()[0]["id"])
            token = await take_control(c, s, H["X-Servodesk-Client"])
            bind_in_process(app, s, token, H["X-Servodesk-Client"])
            yield c


def _lacks(items: list[dict[str, object]]) -> dict[str, object]:
    by = {str(u["address"]): u for u in items}
    assert LACKS in by, items
    u = by[LACKS]
    assert u["code_hex"] == "0x08000024" and "No data available" in str(u["message"])
    return u


@pytest.mark.asyncio(loop_scope="module")
async def test_incomplete_backup_everywhere(api: httpx.AsyncClient) -> None:
    sid = str((await api.get("/sessions")).json()[0]["id"])
    r = await api.post(f"/sessions/{sid}/backups", json={"label": "x", "note": ""})
    assert r.status_code == 201, r.text
    info = r.json()
    # Taken: how many, which, and why.
    assert info["complete"] is False
    assert _lacks(info["unreadable"])["name"] == "Max profile velocity"
    # History (list and one record).
    listed = {b["id"]: b for b in (await api.get("/backups")).json()}[info["id"]]
    assert listed["complete"] is False and _lacks(listed["unreadable"])
    # Compare: neither side has the object; it is not compared, and the result says so.
    c = (
        await api.post(
            "/compare",
            json={
                "a": {"kind": "drive", "session": sid},
                "b": {"kind": "backup", "id": info["id"]},
            },
        )
    ).json()
    assert _lacks(c["a_unreadable"]) and _lacks(c["b_unreadable"])
    # Restore preflight: what it cannot restore, as a list and a warning.
    pf = (await api.post(f"/sessions/{sid}/restore/preflight", json={"backup": info["id"]})).json()
    assert pf["ok"] and _lacks(pf["unreadable"])
    assert any("incomplete" in w and LACKS in w for w in pf["warnings"]), pf["warnings"]
    # The report (dry run and real) names them too, also when read again later.
    rep = (
        await api.post(
            f"/sessions/{sid}/restore", json={"backup": info["id"], "dry_run": True}, headers=H
        )
    ).json()
    assert _lacks(rep["unreadable"])
    rep = (
        await api.post(f"/sessions/{sid}/restore", json={"backup": info["id"]}, headers=H)
    ).json()
    assert rep["finished"] and _lacks(rep["unreadable"])
    again = (await api.get(f"/restores/{rep['id']}")).json()
    assert _lacks(again["unreadable"])


def test_old_store_records_learn_it_from_their_file(tmp_path: Path) -> None:
    """A store of an older servodesk (no column) shows its incomplete backups as such."""
    store = Store(tmp_path)
    doc = {
        "unreadable": [
            {
                "address": LACKS,
                "name": "Max profile velocity",
                "code": 1,
                "code_hex": "0x00000001",
                "message": "refused",
            }
        ]
    }
    (tmp_path / "backups" / "b1-smartris.json").write_text(json.dumps(doc))
    store.add_backup(
        {
            "id": "b1",
            "time": "2026-01-01T00:00:00Z",
            "label": "",
            "note": "",
            "profile_id": "smartris",
            "profile_version": "1",
            "drive_key": "k",
            "identity": {},
            "firmware": None,
            "bus": {},
            "entries": 1,
            "file": "b1-smartris.json",
            "sha256": "0" * 64,
        }
    )
    store.close()
    db = sqlite3.connect(tmp_path / "servodesk.db")
    db.execute("ALTER TABLE backups DROP COLUMN unreadable")
    db.commit()
    db.close()
    store = Store(tmp_path)
    try:
        b = store.get_backup("b1")
        assert b["complete"] is False and b["unreadable"][0]["address"] == LACKS
    finally:
        store.close()


@pytest.fixture(scope="module")
def sim() -> Iterator[list[str]]:
    channel = f"cli-unreadable-{os.getpid()}-{next(_n)}"
    bus = SimulatedBus.start([("smartris", 4)], channel=channel)
    bus.drives[0].withhold(0x607F, 0)
    try:
        yield ["--interface", "virtual", "--channel", channel, "--timeout", "0.3", "--node-id", "4"]
    finally:
        bus.stop()


def test_cli_says_what_the_backup_lacks(
    sim: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path / "data"))
    out = tmp_path / "s.json"
    assert main(["backup", "-o", str(out), *sim]) == 0
    text = capsys.readouterr().out
    assert "INCOMPLETE: 1 object(s) could not be read" in text
    assert f"{LACKS} Max profile velocity: 0x08000024" in text
    assert main(["restore", str(out), *sim, "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "cannot restore 1 object(s)" in text and LACKS in text
    assert main(["diff", str(out), "drive", *sim]) == 0
    text = capsys.readouterr().out
    assert "not compared: 1 object(s) unreadable" in text and LACKS in text
