"""Answers built from a service's dict (api/reply.py): the client gets the service's keys, no
fewer (a key the model forgot fails under the tests) and no more (a key the service sends only
sometimes is not invented as null)."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from pydantic import ValidationError

from servodesk.api.reply import STRICT_ENV
from servodesk.api.schemas_pdo import PdoCyclicStatus, PdoTemplateOut
from servodesk.services.pdo import idle_status

TEMPLATE = {"id": "default", "name": "Default", "description": "as shipped", "section": None}


def _stopped_status() -> dict[str, Any]:
    """services/pdo.py idle_status with the offer, as DELETE /pdo/cyclic answers it: no
    ``link``, ``stale`` or ``unavailable``."""
    return {
        **idle_status(),
        "values": {
            "0x6041:00": {
                "value": True,
                "engineering": None,
                "unit": None,
                "raw_unit": None,
                "pdo": "TPDO1",
                "age_s": 0.01,
                "stale": False,
            }
        },
        "sync_modes": ["freerun"],
        "dc_cycle_ns": None,
    }


def test_a_key_the_model_does_not_declare_fails_under_the_tests(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv(STRICT_ENV, "1")
    with pytest.raises(ValidationError, match="PdoTemplateOut does not declare pdos"):
        PdoTemplateOut.model_validate({**TEMPLATE, "pdos": []})


def test_served_a_key_the_model_does_not_declare_is_left_out(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv(STRICT_ENV, raising=False)
    out = PdoTemplateOut.model_validate({**TEMPLATE, "pdos": []})
    assert out.model_dump() == TEMPLATE


def test_the_answer_has_exactly_the_keys_and_values_the_service_gave() -> None:
    app = FastAPI()

    @app.get("/status", response_model_exclude_unset=True)
    def status() -> PdoCyclicStatus:
        return PdoCyclicStatus.model_validate(_stopped_status())

    with TestClient(app) as client:
        body = client.get("/status").json()
    # Nothing added as null, nothing dropped, a boolean value still a boolean.
    assert body == _stopped_status()
