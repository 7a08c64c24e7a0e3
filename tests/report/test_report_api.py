"""Commissioning reports through the API on a gateway serving a simulated drive, on SQLite and
on PostgreSQL (issue 49; the throw-away server of tests/store/conftest.py): who may make and
read one, what it says of the drive (its tag, approval, a parameter changed
since the approved backup, escaped), its content hash, the PDF, and ``servodesk report
verify`` on both (untouched: exit 0; one byte changed: exit 1; bad arguments: exit 2)."""

from __future__ import annotations

import hashlib
import itertools
import os
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio

from servodesk.cli import main
from servodesk.services.report import content_hash
from servodesk.services.report_html import embedded_data, render
from servodesk.services.report_pdf import find_in_pdf
from tests.backup.helpers import change_plain
from tests.store.conftest import pg_server  # noqa: F401 (the fixture, for the PostgreSQL runs)
from tests.store.gateway import Gateway, gateway

pytestmark = pytest.mark.asyncio(loop_scope="module")
_n = itertools.count()

ROLES = ("engineer", "service", "guest")
TAG = "L2.Press.X"
REASON = "commissioned <script>alert(1)</script> & signed"


@pytest_asyncio.fixture(loop_scope="module", scope="module", params=["sqlite", "postgresql"])
async def gw(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> AsyncIterator[Gateway]:
    url = "" if request.param == "sqlite" else request.getfixturevalue("pg_server").new_database()
    async with gateway(
        tmp_path_factory.mktemp("report"),
        url,
        ROLES,
        timeout=120,
        sim_channel=f"report-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic",
        gateway_name="line-7",
        gateway_url="https://line7.plant.example:8000",
    ) as g:
        yield g


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def made(gw: Gateway) -> dict[str, Any]:
    """A drive tagged, with an approved backup and one parameter changed since; its report."""
    eng = gw.clients["engineer"]
    (session,) = gw.state.manager.all()
    sid = session.id
    r = await eng.get("/fleet", params={"q": "cia402-generic"})
    key = r.json()["drives"][0]["drive_key"]
    assert (await eng.put("/fleet/tag", json={"drive": key, "tag": TAG})).status_code == 200
    r = await eng.post(f"/sessions/{sid}/backups", json={"label": "commissioned"})
    assert r.status_code == 201, r.text
    approve = {"drive": TAG, "backup": r.json()["id"], "reason": REASON}
    assert (await eng.put("/fleet/approved", json=approve)).status_code == 200
    ps = await gw.state.backups.read_set(session, operation=None)
    changed = await change_plain(session, ps, 1)
    r = await eng.post(f"/sessions/{sid}/report")
    assert r.status_code == 201, r.text
    return {"info": r.json(), "sid": sid, "key": key, "changed": changed}


async def test_a_report_needs_the_audit_right_and_an_unknown_one_is_404(
    gw: Gateway, made: dict[str, Any]
) -> None:
    sid, rid = made["sid"], made["info"]["id"]
    for role in ("service", "guest"):
        r = await gw.clients[role].post(f"/sessions/{sid}/report")
        assert r.status_code == 403 and "read_audit" in r.json()["message"], (role, r.text)
        for path in (f"/reports/{rid}", f"/reports/{rid}.html"):
            assert (await gw.clients[role].get(path)).status_code == 403
    eng = gw.clients["engineer"]
    for path in ("/reports/report-nope", "/reports/report-nope.html", "/reports/report-nope.pdf"):
        r = await eng.get(path)
        assert r.status_code == 404 and "no report 'report-nope'" in r.json()["message"], r.text
    r = await eng.post("/sessions/no-such-session/report")
    assert r.status_code == 404


async def test_the_report_says_what_the_drive_is_and_what_changed(
    gw: Gateway, made: dict[str, Any]
) -> None:
    info, key = made["info"], made["key"]
    assert info["drive_key"] == key and info["plant_tag"] == TAG and info["by"] == "engineer"
    assert info["url"] == f"/api/v1/reports/{info['id']}.html" and info["pdf_sha256"] is None
    r = await gw.clients["engineer"].get(f"/reports/{info['id']}")
    assert r.status_code == 200 and r.json() == info
    r = await gw.clients["engineer"].get(f"/reports/{info['id']}.html")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    assert "default-src 'none'" in r.headers["content-security-policy"]
    assert hashlib.sha256(r.content).hexdigest() == info["html_sha256"]
    html = r.text
    # Self-contained: nothing is fetched from anywhere.
    for fetch in ("<link", "src=", "@import", "url("):
        assert fetch not in html, fetch
    assert TAG in html and key in html
    assert f"{info['id']}</span>" in html and info["sha256"] in html  # the footer
    # A user's text is shown, never run.
    assert "<script>alert(1)" not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    data = embedded_data(html)
    assert data is not None and content_hash(data) == info["sha256"]
    assert data["report"]["id"] == info["id"] and data["drive"]["plant_tag"] == TAG
    (address,) = [str(a) for a in made["changed"]]
    vs_approved = data["parameters"]["vs_approved"]["differences"]
    assert [d["address"] for d in vs_approved] == [address]
    assert address in [d["address"] for d in data["parameters"]["vs_defaults"]["differences"]]
    assert data["drive"]["identity"]["serial"] is not None and data["drive"]["firmware"]
    assert data["pdo"]["pdos"] and data["limits"]["modes"]
    assert data["homing"]["method"] is not None and data["alarms"]["history"] is not None
    # The audit extract: who tagged and approved the drive.
    events = {(a["event"], a["user"]) for a in data["audit"]}
    assert ("backup.approved", "engineer") in events and ("backup.taken", "engineer") in events
    # Making it is in the audit log too.
    r = await gw.clients["engineer"].get("/audit", params={"event": "backup.report"})
    assert r.status_code == 200 and r.json()[0]["details"]["report"] == info["id"]


def _verify(gw: Gateway, path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """``servodesk report verify`` on the gateway's store: its data directory, or the central
    store SERVODESK_STORE_URL names."""
    if gw.url:
        with pytest.MonkeyPatch.context() as env:
            env.setenv("SERVODESK_STORE_URL", gw.url)
            code = main(["report", "verify", str(path)])
    else:
        code = main(["report", "verify", str(path), "--data-dir", str(gw.data_dir)])
    out = capsys.readouterr()
    return code, out.out + out.err


def _one_byte_changed(data: bytes, at: bytes) -> bytes:
    i = data.index(at)
    return data[:i] + bytes([data[i] ^ 0x01]) + data[i + 1 :]


async def test_verify_the_html(
    gw: Gateway, made: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    info = made["info"]
    html = (await gw.clients["engineer"].get(f"/reports/{info['id']}.html")).content
    good = tmp_path / "report.html"
    good.write_bytes(html)
    code, out = _verify(gw, good, capsys)
    assert code == 0, out
    assert out.strip() == (
        f"matches report {info['id']} of {info['drive_key']} ({TAG}) made {info['time']} "
        "by engineer"
    )
    # One byte of the text shown, or of the data behind it, changed.
    for where in (b"<h2>Parameters", b'"generated_by":"engineer"'):
        bad = tmp_path / "bad.html"
        bad.write_bytes(_one_byte_changed(html, where))
        code, out = _verify(gw, bad, capsys)
        assert code == 1 and out.startswith("altered:"), out
    # Changing the id changes the data (the id is part of it) ...
    other = html.replace(info["id"].encode(), b"report-20000101t000000z-000000")
    (tmp_path / "other.html").write_bytes(other)
    code, out = _verify(gw, tmp_path / "other.html", capsys)
    assert code == 1 and out.startswith("altered:"), out
    # ... and a report made elsewhere, consistent in itself, is unknown to this store.
    data = embedded_data(html.decode())
    assert data is not None
    data["report"]["id"] = "report-20000101t000000z-000000"
    (tmp_path / "other.html").write_text(render(data, content_hash(data)), encoding="utf-8")
    code, out = _verify(gw, tmp_path / "other.html", capsys)
    assert code == 1 and "unknown: the store has no report" in out, out
    # Bad arguments: exit 2 with a message, never a traceback.
    code, out = _verify(gw, tmp_path / "missing.html", capsys)
    assert code == 2 and "no file" in out and "Traceback" not in out
    code = main(["report", "verify", str(good), "--data-dir", str(tmp_path / "empty")])
    err = capsys.readouterr().err
    assert code == 2 and "no servodesk store" in err


async def test_the_pdf_names_the_report_and_verifies(
    gw: Gateway, made: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    info, eng = made["info"], gw.clients["engineer"]
    r = await eng.get(f"/reports/{info['id']}.pdf")
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "application/pdf" and r.content.startswith(b"%PDF-")
    assert find_in_pdf(r.content) == (info["id"], info["sha256"])
    # Printed once: every download is the same file, recorded in the store.
    again = await eng.get(f"/reports/{info['id']}.pdf")
    assert again.content == r.content
    meta = (await eng.get(f"/reports/{info['id']}")).json()
    assert meta["pdf_sha256"] == hashlib.sha256(r.content).hexdigest()
    pdf = tmp_path / "report.pdf"
    pdf.write_bytes(r.content)
    code, out = _verify(gw, pdf, capsys)
    assert code == 0 and out.startswith(f"matches report {info['id']}"), out
    bad = tmp_path / "bad.pdf"
    bad.write_bytes(_one_byte_changed(r.content, b"/Producer"))
    code, out = _verify(gw, bad, capsys)
    assert code == 1 and out.startswith("altered:"), out


async def test_no_chromium_is_a_503_that_says_what_to_install(
    gw: Gateway, made: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    eng = gw.clients["engineer"]
    r = await eng.post(f"/sessions/{made['sid']}/report")
    assert r.status_code == 201
    monkeypatch.setenv("SERVODESK_CHROMIUM", "/nonexistent/chromium")
    r = await eng.get(f"/reports/{r.json()['id']}.pdf")
    assert r.status_code == 503 and "needs Chromium" in r.json()["message"], r.text
    assert "apt-get install chromium" in r.json()["hint"]
