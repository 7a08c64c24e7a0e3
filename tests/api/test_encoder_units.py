"""A session shows degrees and rpm of the drive's own encoder (608Fh), not the profile's.

The generic profile's scales are written for 2^17 counts per revolution; a twin on a plant
file has 2^20 (as a real drive on another motor may). Over real CANopen SDO the session reads
608Fh and the API, the pages and the tuning then show the same machine in the same units.
"""

from __future__ import annotations

import json
from collections.abc import AsyncIterator
from pathlib import Path

import httpx
import pytest
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.domain.paramset import checksum
from servodesk.domain.profile_loader import ProfileCatalog, check_profile
from servodesk.model.plantfile import parse_plant_toml
from servodesk.settings import Settings
from tests.conftest import StartSims
from tests.control_helpers import take_control

GENERIC = "cia402-generic"
#: A servodesk backup is a JSON file: uploaded as an application/json body (api/uploads.py).
JSON_BODY = {"Content-Type": "application/json"}


@pytest_asyncio.fixture
async def api(tmp_path: Path) -> AsyncIterator[httpx.AsyncClient]:
    settings = Settings(sim=False, data_dir=tmp_path)
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as c:
            yield c


async def _open(api: httpx.AsyncClient, channel: str, node: int) -> dict:  # type: ignore[type-arg]
    r = await api.post(
        "/api/v1/sessions",
        json={"interface": "virtual", "channel": channel, "node_id": node, "profile": GENERIC},
    )
    assert r.status_code == 201, r.text
    return r.json()  # type: ignore[no-any-return]


async def test_a_2_20_count_drive_shows_the_same_rpm_as_the_profiles_own(
    api: httpx.AsyncClient, channel: str, sim_bus: StartSims
) -> None:
    plant = parse_plant_toml("[motor]\nencoder_counts = 1048576\n")
    sim_bus((GENERIC, 5), plant=plant)
    sim_bus((GENERIC, 6), channel=channel + "-plain")
    info = await _open(api, channel, 5)
    assert info["encoder"] == {"counts_per_rev": 1048576.0, "source": "608Fh", "rescaled": True}
    sid = info["id"]
    other = await _open(api, channel + "-plain", 6)
    assert other["encoder"] == {
        "counts_per_rev": 131072.0,
        "source": "608Fh",
        "rescaled": False,
    }

    # 607Fh: 8,000,000 inc/s on the 2^20 twin and 1,000,000 on the 2^17 one are both
    # 7.63 rev/s; the engineering value says so in rpm, the raw value stays the drive's.
    fast = (await api.get(f"/api/v1/sessions/{sid}/objects/0x607F")).json()
    slow = (await api.get(f"/api/v1/sessions/{other['id']}/objects/0x607F")).json()
    assert fast["value"] == 8 * slow["value"] == 8_000_000
    assert fast["unit"] == slow["unit"] == "rpm" and fast["raw_unit"] == "inc/s"
    assert (
        fast["engineering"]
        == pytest.approx(slow["engineering"])
        == pytest.approx(1_000_000 * 60 / 131072)
    )

    # The session's profile (what the pages load) carries the rescaled scales; the
    # catalog's profile is the family's and does not change.
    mine = (await api.get(f"/api/v1/sessions/{sid}/profile")).json()
    family = (await api.get(f"/api/v1/profiles/{GENERIC}")).json()
    scale = {o["address"]: o["scale"] for o in mine["object_list"]}
    base = {o["address"]: o["scale"] for o in family["object_list"]}
    assert scale["0x6064:00"] == pytest.approx(360 / 1048576)
    assert base["0x6064:00"] == pytest.approx(360 / 131072)
    assert scale["0x607D:02"] == pytest.approx(360 / 1048576)
    assert scale["0x6083:00"] == pytest.approx(60 / 1048576)
    # Only objects counted in increments change, every one of them with a unit by 8 x;
    # a gain or a time keeps its scale.
    raw = {o["address"]: (o["raw_unit"], o["unit"]) for o in family["object_list"]}
    changed = {a for a in base if base[a] != scale[a]}
    counted = {a for a, (r, u) in raw.items() if r in ("inc", "inc/s", "inc/s²") and u}
    assert changed == counted and len(counted) >= 15
    assert all(base[a] == pytest.approx(8 * scale[a]) for a in changed)
    assert scale["0x2100:00"] == base["0x2100:00"]

    # The live state's engineering position uses it too: a move of one revolution
    # reads 360 deg, whatever the encoder.
    st = (await api.get(f"/api/v1/sessions/{sid}/state")).json()
    assert st["position_eng"] == pytest.approx(st["position"] * 360 / 1048576)

    # A backup of the 2^20 drive restored onto the 2^17 one: the raw counts would mean
    # 8 x the speeds and windows there, and the preflight says so before anything is written.
    made = await api.post(f"/api/v1/sessions/{sid}/backups", json={})
    assert made.status_code == 201, made.text
    pf = await api.post(
        f"/api/v1/sessions/{other['id']}/restore/preflight", json={"backup": made.json()["id"]}
    )
    warns = [w for w in pf.json()["warnings"] if "counts/rev" in w]
    assert len(warns) == 1 and "1048576 counts/rev, this drive has 131072" in warns[0]
    assert "mean 8 x" in warns[0]
    # And the other way round; a backup of its own drive has no such warning.
    back = (await api.post(f"/api/v1/sessions/{other['id']}/backups", json={})).json()
    pf2 = await api.post(f"/api/v1/sessions/{sid}/restore/preflight", json={"backup": back["id"]})
    assert any("mean 0.125 x" in w for w in pf2.json()["warnings"])
    own = await api.post(
        f"/api/v1/sessions/{other['id']}/restore/preflight", json={"backup": back["id"]}
    )
    assert not any("counts/rev" in w for w in own.json()["warnings"])


async def test_a_backup_keeps_the_drive_encoder_for_its_engineering_values(
    api: httpx.AsyncClient, channel: str, sim_bus: StartSims
) -> None:
    plant = parse_plant_toml("[motor]\nencoder_counts = 1048576\n")
    sim_bus((GENERIC, 5), plant=plant)
    sid = (await _open(api, channel, 5))["id"]
    made = await api.post(f"/api/v1/sessions/{sid}/backups", json={"label": "plant"})
    assert made.status_code == 201, made.text
    bid = made.json()["id"]
    csv_text = (await api.get(f"/api/v1/backups/{bid}/download?format=csv")).text
    row = next(r for r in csv_text.splitlines() if r.startswith("0x607F:00,"))
    # raw 8,000,000 inc/s at 2^20 counts is 457.8 rpm (the profile's scale says 3662).
    assert row.split(",")[4] == "8000000"
    assert float(row.split(",")[7]) == pytest.approx(8_000_000 * 60 / 1048576)

    # The file says which encoder; uploaded again it gives the same figures.
    doc = (await api.get(f"/api/v1/backups/{bid}/download?format=json")).content
    assert json.loads(doc)["encoder"] == {"counts_per_rev": 1048576.0}
    up = await api.post(
        "/api/v1/backups/upload?filename=plant.json", content=doc, headers=JSON_BODY
    )
    assert up.status_code == 201, up.text
    csv2 = (await api.get(f"/api/v1/backups/{up.json()['id']}/download?format=csv")).text
    assert next(r for r in csv2.splitlines() if r.startswith("0x607F:00,")) == row

    # A change is compared in the axis's own units. It needs control: nobody holds it yet,
    # so a write is refused and nothing is written (docs/api.md "Control and motion").
    w = await api.put(
        f"/api/v1/sessions/{sid}/objects/0x6081",
        json={"value": 1_048_576},
        headers={"X-Servodesk-Client": "encoder-test"},
    )
    assert w.status_code == 409 and "nobody holds control" in w.json()["message"], w.text
    await take_control(api, sid, "encoder-test")
    w = await api.put(
        f"/api/v1/sessions/{sid}/objects/0x6081",
        json={"value": 1_048_576},
        headers={"X-Servodesk-Client": "encoder-test"},
    )
    assert w.status_code == 200, w.text
    cmp = await api.post(
        "/api/v1/compare",
        json={"a": {"kind": "drive", "session": sid}, "b": {"kind": "backup", "id": bid}},
    )
    diff = cmp.json()["differences"]
    assert [d["address"] for d in diff] == ["0x6081:00"]
    assert diff[0]["a_engineering"] == pytest.approx(60.0)  # one revolution per second
    # A bad encoder entry in an uploaded file is refused, naming it.
    bad = json.loads(doc)
    bad["encoder"] = {"counts_per_rev": -5}
    bad["checksum"] = checksum(bad)
    r = await api.post(
        "/api/v1/backups/upload?filename=bad.json", content=json.dumps(bad), headers=JSON_BODY
    )
    assert r.status_code == 400 and "encoder.counts_per_rev" in r.json()["message"]


def test_the_profile_check_holds_increment_scales_to_the_profiles_encoder() -> None:
    p = ProfileCatalog().get(GENERIC)
    assert check_profile(p) == []
    wrong = p.model_copy(
        update={"simulation": p.simulation.model_copy(update={"counts_per_rev": 1 << 20})}
    )
    problems = check_profile(wrong)
    assert any("0x6064:00" in s and "simulation.counts_per_rev (1048576)" in s for s in problems)
