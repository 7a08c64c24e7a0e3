"""The committed wire contract matches the code (docs/architecture.md, "Wire contract").

backend/openapi.json is what `servodesk openapi` prints, and the UI's types,
frontend/src/api/schema.ts, are generated from it by `npm run gen:api`; `make openapi` writes
both, and `npm run check:api` (in `make typecheck`) fails when schema.ts is stale. A route or
a pydantic model changed without regenerating leaves the UI typed against an API that no
longer exists: this test fails and says what to run.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import pytest

from servodesk.cli import openapi as openapi_cli

COMMITTED = Path(__file__).resolve().parents[2] / "backend" / "openapi.json"
REGENERATE = "make openapi (it writes backend/openapi.json and frontend/src/api/schema.ts)"


def fresh_text(capsys: pytest.CaptureFixture[str]) -> str:
    """What `servodesk openapi` prints now, through the command itself (no second copy of
    its formatting here)."""
    capsys.readouterr()
    assert openapi_cli.run(argparse.Namespace()) == 0
    return capsys.readouterr().out


def drift(committed: dict[str, Any], fresh: dict[str, Any]) -> list[str]:
    """The operations and schemas that differ, named so that a person sees what changed."""
    out: list[str] = []
    old_paths, new_paths = committed.get("paths", {}), fresh.get("paths", {})
    for path in sorted(set(old_paths) | set(new_paths)):
        old, new = old_paths.get(path, {}), new_paths.get(path, {})
        for method in sorted(set(old) | set(new)):
            if old.get(method) != new.get(method):
                what = "new" if method not in old else "gone" if method not in new else "changed"
                out.append(f"{method.upper()} {path}: {what}")
    old_s = committed.get("components", {}).get("schemas", {})
    new_s = fresh.get("components", {}).get("schemas", {})
    for name in sorted(set(old_s) | set(new_s)):
        if old_s.get(name) != new_s.get(name):
            what = "new" if name not in old_s else "gone" if name not in new_s else "changed"
            out.append(f"schema {name}: {what}")
    rest = {k for k in set(committed) | set(fresh) if k not in ("paths", "components")}
    out.extend(f"{k}: changed" for k in sorted(rest) if committed.get(k) != fresh.get(k))
    return out


def test_committed_openapi_matches_the_code(capsys: pytest.CaptureFixture[str]) -> None:
    assert COMMITTED.is_file(), f"{COMMITTED} is missing: run {REGENERATE}"
    committed_text = COMMITTED.read_text(encoding="utf-8")
    text = fresh_text(capsys)
    if committed_text == text:
        return
    changes = drift(json.loads(committed_text), json.loads(text))
    listed = "\n  ".join(changes[:40]) or "(formatting only)"
    more = f"\n  ... and {len(changes) - 40} more" if len(changes) > 40 else ""
    pytest.fail(
        f"backend/openapi.json is stale against the code; run: {REGENERATE}\n  {listed}{more}",
        pytrace=False,
    )


def test_drift_names_what_changed(capsys: pytest.CaptureFixture[str]) -> None:
    """The report a stale file gets: a route gone, a field of a model changed, a model new."""
    fresh = json.loads(fresh_text(capsys))
    stale = json.loads(json.dumps(fresh))
    del stale["paths"]["/api/v1/health"]
    props = stale["components"]["schemas"]["ObjectValueOut"]["properties"]
    props["renamed"] = props.pop(sorted(props)[0])
    stale["components"]["schemas"]["Gone"] = {"type": "object"}

    assert drift(fresh, fresh) == []
    assert drift(stale, fresh) == [
        "GET /api/v1/health: new",
        "schema Gone: gone",
        "schema ObjectValueOut: changed",
    ]


def test_every_route_of_the_ui_is_in_the_contract() -> None:
    """The UI's wrapper types paths below /api/v1 (frontend/src/api/http.ts): every operation
    is there, each with an operation id the generated types name it by, and JSON errors."""
    spec = json.loads(COMMITTED.read_text(encoding="utf-8"))
    ids = [op["operationId"] for ops in spec["paths"].values() for op in ops.values()]
    assert all(path.startswith("/api/v1/") for path in spec["paths"])
    assert len(ids) == len(set(ids)), "operation ids must be unique: schema.ts names them"
    assert "ErrorOut" in spec["components"]["schemas"]
