"""Defect 6: an object write's value must be of the object's data type: true is not 1 for an
integer object, and text is not a number (hex goes as raw_hex, docs/api.md)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import ObjectSpec
from servodesk.domain.values import encode_write
from servodesk.errors import ValidationError
from servodesk.settings import Settings

SID = "cia402-generic-1"


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    s = Settings(
        sim=True,
        sim_channel=f"security-values-{os.getpid()}",
        sim_profiles="cia402-generic",
        data_dir=Path(tmp_path_factory.mktemp("data")),
    )
    with TestClient(create_app(s)) as c:
        # Writes may need control of the drive (docs/api.md, Operation): take it, and send
        # what identifies the holder with every write.
        who = {"X-Servodesk-Client": "security-values"}
        r = c.post(f"/api/v1/sessions/{SID}/control", json={"action": "take"}, headers=who)
        assert r.status_code == 200, r.text
        token = r.json().get("token")
        c.headers.update({**who, **({"X-Servodesk-Control": token} if token else {})})
        yield c


@pytest.mark.parametrize(
    ("value", "what"),
    [(True, "true"), (False, "false"), ("0x10", "text"), ("16", "text"), ("true", "text")],
)
def test_an_integer_object_refuses_booleans_and_text(
    client: TestClient, value: object, what: str
) -> None:
    url = f"/api/v1/sessions/{SID}/objects/0x6081"
    before = client.get(url).json()["raw_hex"]
    r = client.put(url, json={"value": value})
    assert r.status_code == 400, r.text
    body = r.json()
    assert body["field"] == "value" and "UNSIGNED32" in body["message"] and body["hint"]
    assert client.get(url).json()["raw_hex"] == before


def test_numbers_and_raw_hex_still_write(client: TestClient) -> None:
    url = f"/api/v1/sessions/{SID}/objects/0x6081"
    assert client.put(url, json={"value": 16}).json()["value"] == 16
    assert client.put(url, json={"value": 17.0}).json()["value"] == 17  # A whole number.
    assert client.put(url, json={"raw_hex": "10000000"}).json()["value"] == 16


def _spec(data_type: str) -> ObjectSpec:
    return ObjectSpec(index=0x2000, subindex=0, name="test", data_type=data_type, access="rw")


def test_boolean_objects_take_booleans_and_0_or_1() -> None:
    a = ObjectAddress(0x2000, 0)
    spec = _spec("BOOLEAN")
    assert encode_write(a, spec, True) == b"\x01"
    assert encode_write(a, spec, 0) == b"\x00"
    for bad in (2, "true", 1.5):
        with pytest.raises(ValidationError):
            encode_write(a, spec, bad)


def test_real_string_and_byte_objects_take_their_own_kind() -> None:
    a = ObjectAddress(0x2000, 0)
    assert encode_write(a, _spec("REAL32"), 1) == b"\x00\x00\x80?"
    for bad in (True, "1.5"):
        with pytest.raises(ValidationError):
            encode_write(a, _spec("REAL32"), bad)
    assert encode_write(a, _spec("VISIBLE_STRING"), "abc") == b"abc"
    with pytest.raises(ValidationError):
        encode_write(a, _spec("VISIBLE_STRING"), 5)
    # OCTET_STRING / DOMAIN: hex text, as a read shows them (docs/api.md, ObjectValue).
    assert encode_write(a, _spec("OCTET_STRING"), "0102") == b"\x01\x02"
    with pytest.raises(ValidationError):
        encode_write(a, _spec("OCTET_STRING"), 5)
