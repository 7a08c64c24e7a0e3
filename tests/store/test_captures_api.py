"""Kept scope captures through the API on a gateway serving a simulated drive, on SQLite and
on PostgreSQL (issue 49; docs/scope.md "Kept captures"): keeping what the scope recorded with
a title and note, the drive's list, one by id as JSON and CSV, who may do what (the backups'
rights: a guest reads, never keeps or deletes), bad input as 4xx naming the field, a delete
only with a reason and in the audit log, and an attached capture in the drive's
commissioning report: drawn, in the hashed data, and checked by ``servodesk report verify``."""

from __future__ import annotations

import asyncio
import itertools
import os
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio

from servodesk.cli import main
from servodesk.domain.scope_export import import_csv
from servodesk.services.report import content_hash
from servodesk.services.report_html import embedded_data
from tests.store.gateway import Gateway, gateway

pytestmark = pytest.mark.asyncio(loop_scope="module")
_n = itertools.count()

ROLES = ("administrator", "engineer", "service", "guest")
POSITION, VELOCITY = "0x6064:00", "0x606C:00"


@pytest_asyncio.fixture(loop_scope="module", scope="module", params=["sqlite", "postgresql"])
async def gw(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> AsyncIterator[Gateway]:
    url = "" if request.param == "sqlite" else request.getfixturevalue("pg_server").new_database()
    async with gateway(
        tmp_path_factory.mktemp("captures"),
        url,
        ROLES,
        timeout=120,
        sim_channel=f"captures-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic",
        gateway_name="line-7",
    ) as g:
        yield g


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def sid(gw: Gateway) -> str:
    """The drive's session, with the scope having polled its position and velocity by SDO
    for a moment (the buffer a capture is kept from)."""
    (session,) = gw.state.manager.all()
    eng = gw.clients["engineer"]
    channels = [
        {"id": i, "session": session.id, "address": a, "source": "sdo", "rate_hz": 100.0}
        for i, a in enumerate((POSITION, VELOCITY))
    ]
    r = await eng.put("/scope/channels", json={"channels": channels})
    assert r.status_code == 200, r.text
    assert (await eng.post("/scope/run", json={"action": "start"})).status_code == 200
    await asyncio.sleep(1.0)
    assert (await eng.post("/scope/run", json={"action": "stop"})).status_code == 200
    return str(session.id)


async def _keep(gw: Gateway, sid: str, role: str = "engineer", **body: Any) -> dict[str, Any]:
    r = await gw.clients[role].post(
        f"/sessions/{sid}/scope/captures",
        json={"title": "velocity ripple", "window": "buffer"} | body,
    )
    assert r.status_code == 201, r.text
    out: dict[str, Any] = r.json()
    return out


async def test_a_kept_capture_is_listed_read_and_exported(gw: Gateway, sid: str) -> None:
    kept = await _keep(gw, sid, note="belt tension 40 N", role="service")
    assert kept["by"] == "service" and kept["client"] == "service"
    assert kept["gateway"] == "line-7" and kept["session"] == sid
    assert kept["window"] == "buffer" and kept["attached"] is False
    pos, vel = kept["channels"]
    assert pos["address"] == POSITION and vel["address"] == VELOCITY
    assert pos["unit"] and pos["raw_unit"] and pos["samples"] > 10
    assert kept["samples"] == pos["samples"] + vel["samples"]
    assert pos["period_s"] is not None and 0.001 < pos["period_s"] < 0.2
    # Whoever may read the drive lists and reads it: the guest too.
    guest = gw.clients["guest"]
    r = await guest.get(f"/sessions/{sid}/scope/captures")
    assert r.status_code == 200, r.text
    assert kept["id"] in [c["id"] for c in r.json()]
    r = await guest.get(f"/scope/captures/{kept['id']}")
    assert r.status_code == 200, r.text
    full = r.json()
    assert {k: full[k] for k in kept} == kept and full["trigger"] is None
    rec = full["recording"]
    assert [c["address"] for c in rec["channels"]] == [POSITION, VELOCITY]
    assert len(rec["channels"][0]["v"]) == pos["samples"]
    assert rec["channels"][0]["scale"] == pos["scale"]  # engineering = raw x scale
    # The CSV is the scope's own: it opens again with every sample.
    r = await guest.get(f"/scope/captures/{kept['id']}.csv")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert f"{kept['id']}.csv" in r.headers["content-disposition"]
    back = import_csv(r.content)
    assert [c.address for c in back.channels] == [POSITION, VELOCITY]
    assert back.channels[0].v.tolist() == rec["channels"][0]["v"]


async def test_rights_and_bad_input(gw: Gateway, sid: str) -> None:
    guest, eng = gw.clients["guest"], gw.clients["engineer"]
    base = f"/sessions/{sid}/scope/captures"
    r = await guest.post(base, json={"title": "x", "window": "buffer"})
    assert r.status_code == 403 and "backup" in r.json()["message"], r.text
    for title in ("", "   "):
        r = await eng.post(base, json={"title": title, "window": "buffer"})
        assert r.status_code == 422 and r.json()["field"] == "title", r.text
    r = await eng.post(base, json={"window": "buffer"})
    assert r.status_code == 422 and "title" in r.json()["message"], r.text
    r = await eng.post(base, json={"title": "x", "window": "everything"})
    assert r.status_code == 422 and r.json()["field"] == "window", r.text
    r = await eng.post(base, json={"title": "x\x00", "window": "buffer"})
    assert r.status_code == 422 and r.json()["field"] == "title", r.text
    r = await eng.post("/sessions/no-such-session/scope/captures", json={"title": "x"})
    assert r.status_code == 404, r.text
    r = await eng.get("/scope/captures/capture-none")
    assert r.status_code == 404 and "no scope capture 'capture-none'" in r.json()["message"]
    r = await eng.get("/scope/captures/capture-none.csv")
    assert r.status_code == 404 and "capture-none" in r.json()["message"]
    for bad in ("Not%20An%20Id.csv", "Not%20An%20Id"):
        r = await eng.patch(f"/scope/captures/{bad}", json={"attached": True})
        assert r.status_code == 422, r.text
    r = await eng.patch("/scope/captures/capture-none", json={"attached": "yes please"})
    assert r.status_code == 422 and r.json()["field"] == "attached", r.text
    r = await eng.get("/scope/captures/Not%20An%20Id")
    assert r.status_code == 422 and "cid" in r.json()["field"], r.text
    r = await eng.get(f"{base}", params={"limit": 0})
    assert r.status_code == 422


async def test_a_capture_is_deleted_only_with_a_reason_and_audited(gw: Gateway, sid: str) -> None:
    kept = await _keep(gw, sid, title="to delete")
    path = f"/scope/captures/{kept['id']}"

    async def delete(role: str, body: dict[str, Any]) -> Any:
        return await gw.clients[role].request("DELETE", path, json=body)

    r = await delete("guest", {"reason": "wrong drive"})
    assert r.status_code == 403, r.text
    r = await gw.clients["engineer"].request("DELETE", path)
    assert r.status_code == 422, r.text
    r = await delete("engineer", {"reason": " "})
    assert r.status_code == 422 and r.json()["field"] == "reason", r.text
    assert (await gw.clients["guest"].get(path)).status_code == 200  # Still there.
    r = await delete("engineer", {"reason": "recorded on the wrong axis"})
    assert r.status_code == 200 and r.json()["id"] == kept["id"], r.text
    assert (await gw.clients["guest"].get(path)).status_code == 404
    r = await delete("engineer", {"reason": "again"})
    assert r.status_code == 404
    r = await gw.clients["administrator"].get("/audit", params={"event": "backup.capture_deleted"})
    (rec,) = r.json()
    assert rec["user"] == "engineer" and rec["message"] == "recorded on the wrong axis"
    assert rec["details"]["capture"] == kept["id"] and rec["details"]["sha256"] == kept["sha256"]
    r = await gw.clients["administrator"].get("/audit", params={"event": "backup.capture_kept"})
    assert kept["id"] in [x["details"]["capture"] for x in r.json()]


def _verify(gw: Gateway, path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    if gw.url:
        with pytest.MonkeyPatch.context() as env:
            env.setenv("SERVODESK_STORE_URL", gw.url)
            code = main(["report", "verify", str(path)])
    else:
        code = main(["report", "verify", str(path), "--data-dir", str(gw.data_dir)])
    out = capsys.readouterr()
    return code, out.out + out.err


async def test_an_attached_capture_is_in_the_report_and_verified(
    gw: Gateway, sid: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    eng = gw.clients["engineer"]
    kept = await _keep(gw, sid, title="ripple <b>before</b> tuning")
    other = await _keep(gw, sid, title="not attached")
    r = await gw.clients["guest"].patch(f"/scope/captures/{kept['id']}", json={"attached": True})
    assert r.status_code == 403, r.text
    r = await eng.patch(f"/scope/captures/{kept['id']}", json={"attached": True})
    assert r.status_code == 200 and r.json()["attached"] is True, r.text
    r = await eng.post(f"/sessions/{sid}/report")
    assert r.status_code == 201, r.text
    info = r.json()
    html = (await eng.get(f"/reports/{info['id']}.html")).content
    text = html.decode()
    assert "<h2>Scope captures</h2>" in text and kept["id"] in text
    assert "ripple &lt;b&gt;before&lt;/b&gt; tuning" in text and "<b>before" not in text
    assert text.count('aria-label="ripple &lt;b&gt;before&lt;/b&gt; tuning: ') == 2  # a plot each
    data = embedded_data(text)
    assert data is not None and content_hash(data) == info["sha256"]
    (cap,) = data["captures"]  # Not the capture left unattached.
    assert other["id"] != cap["id"]
    full = (await eng.get(f"/scope/captures/{kept['id']}")).json()
    assert cap["id"] == kept["id"] and cap["sha256"] == kept["sha256"]
    assert [c["v"] for c in cap["channels"]] == [c["v"] for c in full["recording"]["channels"]]
    # The capture is part of what the hash covers.
    assert content_hash({**data, "captures": []}) != info["sha256"]
    good = tmp_path / "report.html"
    good.write_bytes(html)
    code, out = _verify(gw, good, capsys)
    assert code == 0, out
    # One sample of the capture changed in the report's data: altered.
    first = cap["channels"][0]["v"][0]
    needle = f'"v":[{first!r}'.encode()
    assert needle in html, needle
    bad = tmp_path / "bad.html"
    bad.write_bytes(html.replace(needle, f'"v":[{first + 1!r}'.encode(), 1))
    code, out = _verify(gw, bad, capsys)
    assert code == 1 and out.startswith("altered:"), out
    # Detached, the next report shows no capture.
    r = await eng.patch(f"/scope/captures/{kept['id']}", json={"attached": False})
    assert r.status_code == 200 and r.json()["attached"] is False
    assert gw.state.captures.attached(kept["drive_key"]) == []


async def test_a_triggered_window_is_kept_with_its_trigger(gw: Gateway, sid: str) -> None:
    """The captured window of a single level trigger, kept as it is: the window's bounds, the
    trigger sample at 0 s, and the trigger as set."""
    from tests.scope.test_scope_service import enable_pp, move, wait_reached

    eng = gw.clients["engineer"]
    assert gw.state.sim is not None
    (drive,) = gw.state.sim.drives
    enable_pp(drive)
    level = float(drive.read(0x6064, 0)) + 20_000
    trigger = {"mode": "single", "kind": "level", "channel": 0, "level": level,
               "slope": "rising", "pre": 0.2, "window_s": 0.5, "holdoff_s": 0.0}  # fmt: skip
    assert (await eng.put("/scope/trigger", json=trigger)).status_code == 200
    assert (await eng.post("/scope/run", json={"action": "arm"})).status_code == 200
    try:
        await asyncio.sleep(0.2)
        await move(drive, 65_536)
        await wait_reached(drive)
        for _ in range(100):
            if (await eng.get("/scope")).json()["state"] == "done":
                break
            await asyncio.sleep(0.1)
        kept = await _keep(gw, sid, title="the move", window="capture")
    finally:
        await eng.post("/scope/run", json={"action": "stop"})
        await eng.put("/scope/trigger", json={"mode": "roll"})
        drive.write(0x6040, 0, 0x06)  # Servo off again (CiA 402-2 §6.2: Shutdown).
    assert kept["window"] == "capture"
    full = (await eng.get(f"/scope/captures/{kept['id']}")).json()
    assert full["trigger"] == trigger
    rec = full["recording"]
    assert rec["window"] == pytest.approx([-0.1, 0.4], abs=0.05)
    t = [x for x in rec["channels"][0]["t"] if x is not None]
    assert t[0] < 0 < t[-1]  # The trigger sample is at 0 s, pre-trigger before it.
