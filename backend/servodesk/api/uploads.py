"""Request bodies: how large each route takes, and reading an uploaded file.

Every state-changing request carries JSON, except on the routes in :data:`FILE_LIMITS`,
which take a file as multipart/form-data (field ``file``, what the UI's FormData sends).
The limits are enforced while the body streams in (``api/body_limit.py``), before any route
reads it whole; docs/security.md.
"""

from __future__ import annotations

from typing import Any

from fastapi import Request
from starlette.datastructures import UploadFile
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.formparsers import MultiPartException

from servodesk.errors import PayloadTooLarge, UnsupportedMediaType, ValidationError

MiB = 1 << 20

#: The largest JSON body of any other request (the largest, a PDO layout or a read of 512
#: objects, is a few kB).
JSON_LIMIT = 1 * MiB

#: The routes that take a file, and the largest file each takes.
FILE_LIMITS: dict[str, int] = {
    "/api/v1/backups/upload": 32 * MiB,
    "/api/v1/profiles/import": 16 * MiB,
    "/api/v1/scope/import": 64 * MiB,  # services/scope.py MAX_IMPORT_BYTES
}

#: Room for the multipart framing around the file (boundaries, the part's headers).
_FRAMING = 64 * 1024


def body_limit(path: str) -> tuple[int, int]:
    """(the most bytes a request body to ``path`` may have, the limit to tell the user: the
    file's, without the multipart framing)."""
    limit = FILE_LIMITS.get(path)
    return (JSON_LIMIT, JSON_LIMIT) if limit is None else (limit + _FRAMING, limit)


def takes_file(path: str) -> bool:
    return path in FILE_LIMITS


def too_large(limit: int) -> PayloadTooLarge:
    return PayloadTooLarge(
        f"the request body is larger than the {limit / MiB:g} MiB this route takes",
        hint="send a smaller file; a backup, device description or recording is far smaller",
    )


def media_type(value: str | bytes | None) -> str | None:
    """The media type of a Content-Type value, lower case, without parameters."""
    if value is None:
        return None
    if isinstance(value, bytes):
        value = value.decode("latin-1")
    return value.split(";", 1)[0].strip().lower() or None


def openapi_file_body(*, json_too: bool = False) -> dict[str, Any]:
    """The OpenAPI request body of a file route (FastAPI cannot infer it from a Request)."""
    content: dict[str, Any] = {
        "multipart/form-data": {
            "schema": {
                "type": "object",
                "properties": {"file": {"type": "string", "format": "binary"}},
                "required": ["file"],
            }
        }
    }
    if json_too:
        content["application/json"] = {"schema": {"type": "object"}}
    return {"requestBody": {"required": True, "content": content}}


async def read_file(request: Request, *, json_too: bool = False) -> bytes:
    """The uploaded file's bytes: field ``file`` of a multipart/form-data body or, where
    ``json_too``, a JSON body as it is (a servodesk backup is a JSON file)."""
    limit = FILE_LIMITS[request.url.path]
    kind = media_type(request.headers.get("content-type"))
    if kind == "multipart/form-data":
        try:
            async with request.form(max_files=1, max_fields=4) as form:
                part = form.get("file")
                if not isinstance(part, UploadFile):
                    raise ValidationError(
                        "the form has no file field named 'file'",
                        field="file",
                        hint="send the file as multipart/form-data field 'file'",
                    )
                data = await part.read(limit + 1)
        except (MultiPartException, StarletteHTTPException) as exc:
            detail = getattr(exc, "message", None) or getattr(exc, "detail", str(exc))
            raise ValidationError(
                f"the multipart body cannot be read: {detail}",
                field="file",
                hint="send the file as multipart/form-data field 'file'",
            ) from None
    elif kind == "application/json" and json_too:
        data = await request.body()
    else:
        accepted = "multipart/form-data" + (" or application/json" if json_too else "")
        raise UnsupportedMediaType(
            f"this route takes a file as {accepted}, not {kind or 'an empty body'}",
            hint="send the file as multipart/form-data field 'file'",
        )
    if len(data) > limit:
        raise too_large(limit)
    return data
