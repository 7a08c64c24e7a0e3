"""What every route's models share: the error answer (ErrorOut and the ERROR_RESPONSES each route
documents), the ids and value types several resources use, and the service's health.

Each resource's request and response models live in their own api/schemas_<resource>.py
(sessions, objects, profiles, dcp, motion, homing, backups, viewer, pdo, scope, tuning, ...);
the OpenAPI schema is generated from all of them and names models, not modules.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, Field

#: A value as JSON carries it (an object's default in the profile).
Scalar = int | float | bool | str | None

#: The id of a record the store made for a report or a tuning's result (lower-case
#: ``report-20261207t142600z-a1b2c3``: a safe id of domain/ids.py without dots). One that is
#: not cannot exist, and the schema says so: a 422 naming the rule, not the lookup's 400.
STORED_ID = r"^[a-z0-9][a-z0-9_-]{0,63}$"


class ErrorOut(BaseModel):
    error: str = Field(description="Error class, e.g. ObjectAccessError")
    message: str
    hint: str | None = None
    field: str | None = None
    code: int | None = Field(default=None, description="Protocol code (SDO abort code, ...)")
    code_hex: str | None = None
    meaning: str | None = None
    protocol: str | None = None
    address: str | None = None


#: Error answers every route may give (documented so clients and schema checks know them).
ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    code: {"model": ErrorOut, "description": text}
    for code, text in (
        (400, "Bad value or refused by the drive (with the protocol code)"),
        (401, "Not logged in: no valid session cookie or API token (docs/security.md)"),
        (
            403,
            "The role lacks the route's right (Forbidden), or a state change or WebSocket "
            "from a page of another origin",
        ),
        (404, "No such session, profile, object or node"),
        (409, "Not possible in the present state, or control held by another client"),
        (413, "The request body is larger than the route takes"),
        (415, "The body is not application/json (multipart/form-data for a file)"),
        (502, "Bus failure"),
        (504, "The drive did not answer in time"),
    )
}


class MessageOut(BaseModel):
    message: str


# GET /health: the service itself, not a resource. (A comment, not a docstring: that would
# become the schema's description.)
class HealthOut(BaseModel):
    status: Literal["ok"]
    version: str
    simulation: bool
    links: dict[str, str | None]
