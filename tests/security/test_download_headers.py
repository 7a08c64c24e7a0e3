"""Defect 5: headers built from ids. Content-Disposition follows RFC 6266 §4.1 with an ASCII
fallback ``filename`` and an RFC 8187 (was 5987) ``filename*``; no id can break the header."""

from __future__ import annotations

import hashlib
from pathlib import Path
from urllib.parse import unquote

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

BASE = "http://127.0.0.1:8000"


@pytest.mark.parametrize(
    ("name", "fallback"),
    [
        ("b1-cia402-generic.json", "b1-cia402-generic.json"),
        ("b1-ドライブ.json", "b1-____.json"),
        ('b1-x"; filename=evil.sh.json', "b1-x__ filename_evil.sh.json"),
        ("b1-a\r\nSet-Cookie: x=1.json", "b1-a__Set-Cookie_ x_1.json"),
        ("b1-\\..\\x.json", "b1-_.._x.json"),
    ],
)
def test_content_disposition_has_a_safe_fallback_and_the_exact_name(
    name: str, fallback: str
) -> None:
    from servodesk.api.downloads import content_disposition

    value = content_disposition(name)
    value.encode("ascii")  # A header value servers can always send.
    assert "\r" not in value and "\n" not in value
    assert value.startswith(f"attachment; filename=\"{fallback}\"; filename*=UTF-8''")
    assert unquote(value.split("filename*=UTF-8''", 1)[1]) == name


def test_a_backup_download_of_any_profile_id_is_a_clean_200(
    loopback_app: FastAPI, tmp_path: Path
) -> None:
    # A record as a store written before ids were checked may hold: a profile id with a
    # character outside Latin-1, a quote and CRLF.
    state = loopback_app.state.servodesk
    store = state.backups.store
    data = b'{"not": "checked by download"}\n'
    (store.backups_dir / "b1.json").write_bytes(data)
    evil = 'ドライブ"\r\nSet-Cookie: a=b'
    store.add_backup(
        {
            "id": "b1",
            "time": "t",
            "label": "",
            "note": "",
            "profile_id": evil,
            "profile_version": "",
            "drive_key": "",
            "identity": {},
            "firmware": None,
            "bus": {},
            "entries": 0,
            "file": "b1.json",
            "sha256": hashlib.sha256(data).hexdigest(),
        }
    )
    with TestClient(loopback_app, base_url=BASE) as c:
        r = c.get("/api/v1/backups/b1/download")
        assert r.status_code == 200, r.text
        assert r.content == data
        assert "set-cookie" not in r.headers
        cd = r.headers["content-disposition"]
        assert cd.startswith('attachment; filename="b1-')
        assert unquote(cd.split("filename*=UTF-8''", 1)[1]) == f"b1-{evil}.json"
