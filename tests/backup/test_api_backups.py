"""The REST contract of docs/api.md "Backup, compare, restore" against a simulated drive."""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import AsyncIterator

import httpx
import pytest
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.control_helpers import bind_in_process, take_control

pytestmark = pytest.mark.asyncio(loop_scope="module")
_n = itertools.count()
H = {"X-Servodesk-Client": "ui-test-tab"}
#: A servodesk backup is a JSON file: uploaded as an application/json body (api/uploads.py).
JSON_BODY = {"Content-Type": "application/json"}
#: A servodesk backup is JSON: scripts may upload it as an application/json body.
JSON = {"Content-Type": "application/json"}


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def api(tmp_path_factory) -> AsyncIterator[httpx.AsyncClient]:  # type: ignore[no-untyped-def]
    settings = Settings(
        sim=True,
        sim_channel=f"api-backup-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic",
        data_dir=tmp_path_factory.mktemp("data"),
        sdo_timeout=0.3,
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://t/api/v1") as c:
            # The tab holds control (its token on every request) with an in-process
            # connection bound as its dead-man: restoring and servo on change the drive.
            s = await sid(c)
            token = await take_control(c, s, H["X-Servodesk-Client"])
            bind_in_process(app, s, token, H["X-Servodesk-Client"])
            yield c


async def sid(api: httpx.AsyncClient) -> str:
    return str((await api.get("/sessions")).json()[0]["id"])


async def test_backup_list_get_download_patch(api: httpx.AsyncClient) -> None:
    s = await sid(api)
    r = await api.post(f"/sessions/{s}/backups", json={"label": "after tuning", "note": ""})
    assert r.status_code == 201, r.text
    info = r.json()
    assert info["label"] == "after tuning" and info["entries"] > 50 and len(info["sha256"]) == 64
    lst = (await api.get("/backups", params={"drive": info["drive_key"]})).json()
    assert lst[0]["id"] == info["id"]
    f = (await api.get(f"/backups/{info['id']}")).json()
    assert f["schema_version"] == 1 and f["profile"]["id"] == "cia402-generic"
    assert {"address", "name", "data_type", "raw_hex", "value", "unit"} <= set(f["entries"][0])
    for fmt, marker in (
        ("json", b'"schema_version"'),
        ("dcf", b"[DeviceComissioning]"),
        ("csv", b"raw_hex"),
    ):
        d = await api.get(f"/backups/{info['id']}/download", params={"format": fmt})
        assert d.status_code == 200 and marker in d.content
        assert "attachment" in d.headers["content-disposition"]
    p = await api.patch(f"/backups/{info['id']}", json={"note": "checked"})
    assert p.json()["note"] == "checked" and p.json()["sha256"] == info["sha256"]
    assert (await api.get("/backups/nope")).status_code == 404


async def test_upload_compare_restore_and_audit(api: httpx.AsyncClient) -> None:
    s = await sid(api)
    info = (await api.post(f"/sessions/{s}/backups", json={})).json()
    dl = (await api.get(f"/backups/{info['id']}/download", params={"format": "dcf"})).content
    # A file goes as multipart/form-data, as the UI's FormData sends it (api/uploads.py).
    up = await api.post(
        "/backups/upload", params={"filename": "drive.dcf"}, files={"file": ("drive.dcf", dl)}
    )
    assert up.status_code == 201, up.text
    w = await api.put(f"/sessions/{s}/objects/0x6081", json={"value": 123456}, headers=H)
    assert w.status_code == 200, w.text
    cmp = (
        await api.post(
            "/compare",
            json={"a": {"kind": "drive", "session": s}, "b": {"kind": "backup", "id": info["id"]}},
        )
    ).json()
    assert not cmp["equal"]
    assert [d["address"] for d in cmp["differences"]] == ["0x6081:00"]
    assert cmp["differences"][0]["a_value"] == 123456
    pf = (
        await api.post(f"/sessions/{s}/restore/preflight", json={"backup": up.json()["id"]})
    ).json()
    assert pf["ok"] and pf["to_write"] == 1
    dry = (
        await api.post(
            f"/sessions/{s}/restore", json={"backup": info["id"], "dry_run": True}, headers=H
        )
    ).json()
    assert dry["counts"]["would_write"] == 1 and dry["steps"][0]["address"] == "0x6081:00"
    rep = await api.post(f"/sessions/{s}/restore", json={"backup": info["id"]}, headers=H)
    assert rep.status_code == 200, rep.text
    body = rep.json()
    assert body["finished"] and body["stored"] and body["counts"]["written"] == 1
    assert (await api.get(f"/restores/{body['id']}")).json() == body
    res = (await api.post(f"/restores/{body['id']}/resume", json={}, headers=H)).json()
    assert res["finished"]
    audit = (await api.get("/audit/writes", params={"session": s})).json()
    mine = [a for a in audit if a["client"] == "ui-test-tab" and a["address"] == "0x6081:00"]
    assert mine[0]["old_value"] == 123456  # the restore's write, newest first
    assert mine[-1]["new_value"] == 123456
    cmp2 = (
        await api.post(
            "/compare",
            json={
                "a": {"kind": "drive", "session": s},
                "b": {"kind": "defaults", "profile": "cia402-generic"},
            },
        )
    ).json()
    assert cmp2["same"] > 0


async def test_bad_uploads_and_refusals_are_4xx(api: httpx.AsyncClient) -> None:
    s = await sid(api)
    r = await api.post(
        "/backups/upload", params={"filename": "x.json"}, content=b'{"format": "x"', headers=JSON
    )
    assert r.status_code == 400 and "truncated or corrupt" in r.json()["message"]
    info = (await api.post(f"/sessions/{s}/backups", json={})).json()
    doc = json.loads((await api.get(f"/backups/{info['id']}/download")).content)
    doc["schema_version"] = 99
    r = await api.post(
        "/backups/upload", params={"filename": "x.json"}, content=json.dumps(doc), headers=JSON
    )
    assert r.status_code == 400 and "schema version 99" in r.json()["message"]
    on = await api.post(f"/sessions/{s}/state", json={"command": "enable"}, headers=H)
    assert on.status_code == 200, on.text
    try:
        r = await api.post(f"/sessions/{s}/restore", json={"backup": info["id"]}, headers=H)
        assert r.status_code == 409
        assert "drive not enabled" in r.json()["message"] and r.json()["problems"]
    finally:
        await api.post(f"/sessions/{s}/state", json={"command": "disable"}, headers=H)
    assert (await api.post("/compare", json={"a": {"kind": "x"}, "b": {}})).status_code == 422
