"""The scope's REST routes: status, channels, trigger, run, capture, export and import, the
recorder description, the refusals (4xx naming what is wrong), and the token on its socket."""

from __future__ import annotations

import asyncio
import csv
import io
from collections.abc import AsyncIterator
from typing import Any

import httpx
import pytest
import pytest_asyncio
import websockets

from servodesk.domain import scope_wire as wire
from servodesk.settings import Settings
from tests.scope.test_scope_service import (
    GENERIC,
    HDR,
    LECSN,
    Rig,
    put_channels,
    run,
    serve,
    sim_settings,
)
from tests.scope.test_scope_service import fresh as fresh  # The fixture, on this rig.

pytestmark = pytest.mark.asyncio(loop_scope="module")


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rig(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Rig]:
    async with serve(sim_settings(tmp_path_factory.mktemp("data"))) as r:
        yield r


def channel(cid: int, address: str, **kw: Any) -> dict[str, Any]:
    return {"id": cid, "session": GENERIC, "address": address, **kw}


async def refused(rig: Rig, body: dict[str, Any], status: int) -> dict[str, Any]:
    r = await rig.client.put("/api/v1/scope/channels", json=body)
    assert r.status_code == status, r.text
    out: dict[str, Any] = r.json()
    return out


async def test_status_of_an_idle_scope(fresh: Rig) -> None:
    st = (await fresh.client.get("/api/v1/scope")).json()
    assert st["running"] is False and st["state"] == "idle"
    assert st["trigger"]["mode"] == "roll" and st["channels"] == []
    assert st["clients"] == 0 and st["buffer_s"] > 0


async def test_channels_are_described_with_unit_and_display_settings(fresh: Rig) -> None:
    st = await put_channels(
        fresh,
        [
            channel(0, "0x6064:00", source="sdo", label="pos", scale=2.0, offset=-1.0),
            channel(4, "6077h", visible=False),
        ],
    )
    a, b = st["channels"]
    assert a["address"] == "0x6064:00" and a["name"] == "Position actual value"
    assert a["raw_unit"] == "inc" and a["unit"] and a["eng_scale"] > 0
    assert (a["label"], a["scale"], a["offset"], a["visible"]) == ("pos", 2.0, -1.0, True)
    assert a["source"] == "sdo" and a["requested_source"] == "sdo"
    assert b["id"] == 4 and b["address"] == "0x6077:00" and b["visible"] is False
    assert b["requested_source"] == "auto" and b["source"] in ("recorder", "sdo", "pdo")
    assert a["rate_hz"] is None and a["samples"] == 0  # Nothing measured before it runs.


async def test_refusals_name_what_is_wrong(fresh: Rig) -> None:
    rig = fresh
    body = await refused(
        rig, {"channels": [{"id": 0, "session": "nope-9", "address": "0x6064:00"}]}, 404
    )
    assert "nope-9" in body["message"]
    body = await refused(
        rig, {"channels": [channel(i, "0x6041:00", source="sdo") for i in range(33)]}, 400
    )
    assert "33 channels" in body["message"] and "at most 32" in body["message"]
    body = await refused(rig, {"channels": [channel(0, "0x5FFF:00")]}, 404)
    assert "0x5FFF:00" in body["message"]
    body = await refused(rig, {"channels": [channel(0, "0x1008:00")]}, 400)
    assert "VISIBLE_STRING" in body["message"]
    body = await refused(rig, {"channels": [channel(0, "bogus")]}, 400)
    assert "bogus" in body["message"]
    body = await refused(rig, {"channels": [channel(1, "0x6041:00"), channel(1, "6064")]}, 400)
    assert "same id" in body["message"]
    body = await refused(rig, {"channels": [channel(32, "0x6041:00")]}, 400)
    assert "channel id 32 is outside 0..31" in body["message"]
    # A drive's recorder keeps its own limit (the generic twin's: 8 channels): a ninth
    # recorder channel is refused naming the drive and the limit.
    body = await refused(
        rig, {"channels": [channel(i, "0x6064:00", source="recorder") for i in range(9)]}, 400
    )
    assert "channel 8" in body["message"] and GENERIC in body["message"]
    assert "recorder has 8 channels" in body["message"] and body["field"] == "source"
    # Not in an active TPDO (cyclic data is not running): no PDO source.
    body = await refused(rig, {"channels": [channel(0, "0x6064:00", source="pdo")]}, 400)
    assert "TPDO" in body["message"] and body["field"] == "source"
    # The drive refuses to read it, named with its code: a LECSN-T over PROFINET whose
    # parameter holds no value answers PROFIdrive error 14h (004 §20.4.2). Every parameter
    # of the manual has a value in the twin, so one is taken away here, as a drive whose
    # firmware lacks it would answer.
    lecsn = next(d for d in rig.app.state.servodesk.sim.drives if d.profile.id == "lecsn-t")
    key = 0x2001 << 8
    kept = lecsn._values.pop(key)
    try:
        body = await refused(
            rig, {"channels": [{"id": 2, "session": LECSN, "address": "0x2001:00"}]}, 400
        )
    finally:
        lecsn._values[key] = kept
    assert "0x2001:00" in body["message"] and "channel 2" in body["message"]
    assert body["code"] == 0x14 and body["protocol"] == "profidrive"
    # A refused list changes nothing.
    assert (await rig.client.get("/api/v1/scope")).json()["channels"] == []
    r = await rig.client.put(
        "/api/v1/scope/channels", json={"channels": [channel(0, "0x6041:00", source="x")]}
    )
    assert r.status_code == 422


async def test_a_scope_takes_32_channels_of_two_drives(fresh: Rig) -> None:
    # Issue 50: 4 drives x 8 channels; here 16 of the generic twin (CANopen) and 16 of the
    # LECSN-T (PROFINET), polled, with the trigger on the last one. Every channel samples and
    # the CSV export has a column for each.
    rig = fresh
    objects = ("0x6041:00", "0x6064:00", "0x606C:00", "0x6077:00")
    chans = [
        {"id": i, "session": GENERIC if i < 16 else LECSN, "address": objects[i % 4]}
        | {"source": "sdo", "rate_hz": 50.0}
        for i in range(32)
    ]
    st = await put_channels(rig, chans)
    assert [c["id"] for c in st["channels"]] == list(range(32))
    r = await rig.client.put(
        "/api/v1/scope/trigger", json={"mode": "roll", "kind": "level", "channel": 31}
    )
    assert r.status_code == 200 and r.json()["trigger"]["channel"] == 31
    await run(rig, "start")
    await asyncio.sleep(1.0)
    st = await run(rig, "stop")
    assert all(c["samples"] > 0 for c in st["channels"]), [
        (c["id"], c["samples"], c["error"]) for c in st["channels"]
    ]
    r = await rig.client.get("/api/v1/scope/export", params={"format": "csv", "window": "buffer"})
    assert r.status_code == 200, r.text
    rows = csv.reader(io.StringIO(r.content.decode("utf-8-sig")))
    header = next(row for row in rows if row[:1] == ["time_s"])
    assert sum(1 for h in header if h != "time_s") == 32, header


async def test_trigger_and_run_refusals(fresh: Rig) -> None:
    rig = fresh
    c = rig.client
    r = await c.post("/api/v1/scope/run", json={"action": "start"})
    assert r.status_code == 409 and "no channels" in r.json()["message"]
    await put_channels(rig, [channel(0, "0x6041:00", source="sdo")])
    r = await c.post("/api/v1/scope/run", json={"action": "arm"})
    assert r.status_code == 409 and "roll" in r.json()["message"]
    r = await c.post("/api/v1/scope/run", json={"action": "pause"})
    assert r.status_code == 422
    for bad in (
        {"mode": "single", "pre": 1.5},
        {"mode": "often"},
        {"mode": "single", "window_s": 0},
    ):
        r = await c.put("/api/v1/scope/trigger", json=bad)
        assert r.status_code == 422, (bad, r.text)
    r = await c.put("/api/v1/scope/trigger", json={"mode": "single", "channel": 3})
    assert r.status_code == 400 and "channel 3" in r.json()["message"]
    r = await c.put(
        "/api/v1/scope/trigger",
        json={"mode": "normal", "kind": "edge", "channel": 0, "level": 1, "slope": "either"},
    )
    assert r.status_code == 200
    assert r.json()["trigger"] == {
        "mode": "normal",
        "kind": "edge",
        "channel": 0,
        "level": 1.0,
        "slope": "either",
        "pre": 0.2,
        "window_s": 1.0,
        "holdoff_s": 0.0,
    }
    st = (await c.post("/api/v1/scope/run", json={"action": "arm"})).json()
    assert st["running"] and st["state"] == "armed"
    st = (await c.post("/api/v1/scope/run", json={"action": "stop"})).json()
    assert not st["running"] and st["state"] == "idle"
    r = await c.get("/api/v1/scope/capture")
    assert r.status_code == 404 and "no captured window" in r.json()["message"]
    r = await c.get("/api/v1/scope/export", params={"format": "csv", "window": "capture"})
    assert r.status_code == 404


async def test_recorder_description(fresh: Rig) -> None:
    r = await fresh.client.get(f"/api/v1/sessions/{GENERIC}/recorder")
    assert r.status_code == 200
    info = r.json()
    assert info["present"] is True
    assert (info["max_channels"], info["rate_hz"], info["depth"]) == (8, 4000.0, 32768)
    assert {"0x6064:00", "0x606C:00", "0x6077:00", "0x60F4:00"} <= set(info["objects"])
    assert not any(a.startswith("0x2F0") for a in info["objects"])  # Not its own objects.
    r = await fresh.client.get("/api/v1/sessions/nope-9/recorder")
    assert r.status_code == 404


async def test_export_and_import_give_back_the_recording(fresh: Rig) -> None:
    rig = fresh
    await put_channels(
        rig,
        [
            channel(0, "0x6041:00", source="sdo", label="status"),
            channel(1, "0x6077:00", source="recorder"),
        ],
    )
    await run(rig, "start")
    await asyncio.sleep(0.5)
    await run(rig, "stop")
    counts = {ch.id: len(ch.ring) for ch in rig.scope.channels}
    assert all(counts.values()), counts
    for fmt, name in (("csv", "x.csv"), ("mdf4", "x.mf4")):
        r = await rig.client.get("/api/v1/scope/export", params={"format": fmt, "window": "buffer"})
        assert r.status_code == 200, r.text
        assert "attachment" in r.headers["content-disposition"]
        data = r.content
        if fmt == "csv":
            text = data.decode("utf-8-sig")
            assert text.startswith("#servodesk-scope")
            rows = [row for row in csv.reader(io.StringIO(text)) if row and row[0] == "time_s"]
            assert rows, "a header row starting with time_s"
        back = await rig.client.post(
            "/api/v1/scope/import", params={"filename": name}, files={"file": (name, data)}
        )
        assert back.status_code == 200, back.text
        rec = back.json()
        got = {c["id"]: c for c in rec["channels"]}
        for cid, n in counts.items():
            t, v = rig.scope.channels[cid].ring.all()
            assert len(got[cid]["v"]) == n, (fmt, cid)
            assert got[cid]["v"] == v.tolist(), (fmt, cid)
            assert [rec["t_ref"] + x for x in got[cid]["t"]] == pytest.approx(t.tolist(), abs=1e-6)
    r = await rig.client.post(
        "/api/v1/scope/import", params={"filename": "x.txt"}, files={"file": ("x.txt", b"1")}
    )
    assert r.status_code == 400 and "x.txt" in r.json()["message"]
    r = await rig.client.post(
        "/api/v1/scope/import", params={"filename": "x.csv"}, files={"file": ("x.csv", b"")}
    )
    assert r.status_code == 400


async def test_the_scope_socket_needs_a_login_when_the_server_has_accounts(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    from tests.security.server import make_accounts

    data = tmp_path_factory.mktemp("tok")
    token = make_accounts(data, {"ada": "guest"})["ada"]  # An account: logins are needed.
    settings = Settings(data_dir=data, viewer_port=0)
    async with serve(settings) as r:
        # Accepted, then closed with 4401 and a reason (docs/api.md), as every WebSocket.
        async with websockets.connect(r.ws_url, subprotocols=[wire.SUBPROTOCOL]) as ws:  # type: ignore[list-item]
            with pytest.raises(websockets.ConnectionClosed) as info:
                await asyncio.wait_for(ws.recv(), 5)
            assert info.value.rcvd is not None and info.value.rcvd.code == 4401
        async with websockets.connect(
            r.ws_url,
            subprotocols=[wire.SUBPROTOCOL],  # type: ignore[list-item]
            additional_headers={"Authorization": f"Bearer {token}"},
        ) as ws:
            data = await asyncio.wait_for(ws.recv(decode=False), 5)
            f = wire.decode_frame(data)
            assert f.kind == wire.KIND_STATUS and f.seq == 1
        async with httpx.AsyncClient(base_url=f"http://127.0.0.1:{r.port}", headers=HDR) as c:
            assert (await c.get("/api/v1/scope")).status_code == 401
            ok = await c.get("/api/v1/scope", headers={"Authorization": f"Bearer {token}"})
            assert ok.status_code == 200
