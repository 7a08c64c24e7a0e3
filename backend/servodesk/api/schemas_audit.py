"""Response models of the audit log routes (api/routes/audit.py; docs/security.md "Audit
log")."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel

from servodesk.services.audit import Category


class AuditRecord(BaseModel):
    seq: int
    time: str  # ISO 8601, UTC ("...Z")
    user: str
    address: str
    category: Category
    event: str
    drive: str | None
    result: Literal["success", "failure"]
    message: str
    details: dict[str, Any]
    prev: str
    hash: str


class AuditVerdict(BaseModel):
    ok: bool
    records: int
    head: str
    broken: int | None
    problem: str | None
