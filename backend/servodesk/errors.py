"""The one exception tree of servodesk.

Every failure a user can meet is a :class:`ServodeskError`. Subclasses carry structured
fields (a protocol code, the object address, the profile file) so that the API and the CLI
can render one clear message without parsing strings::

    ServodeskError
     +-- ProfileError               a profile or device-description file is invalid
     +-- SettingsError              SERVODESK_* environment settings are invalid (problems listed)
     +-- ValidationError            a value or request is refused before anything is sent
     |    +-- PdoRefused            a PDO mapping breaks the family's rules (problems listed)
     +-- LinkError                  the bus or the device is unreachable or misbehaves
     |    +-- LinkTimeoutError      (also a TimeoutError) no answer in time
     |    +-- LinkUnavailableError  a fieldbus backend's library is missing
     |    +-- LinkClosedError       the link was closed while the call waited
     +-- ObjectAccessError          the device refused an access (SDO abort, ...)
     +-- DriveStateError            a CiA 402 command is not possible in this state
     +-- NotFoundError              no such session, profile or object
     +-- ConflictError              another client holds control of the drive
     +-- WorkerFailed               a worker process ended before its answer (503)
     +-- Unavailable                a service the request needs cannot be reached now (503)
 +-- Forbidden                  the caller's role lacks the right the request needs (403)
     +-- RequestRefused             an HTTP request refused before any route sees it
          +-- Unauthorized          no valid login session or API token where needed (401)
          +-- LockedOut             too many failed logins: refused until a time (429)
          +-- HostNotAllowed        Host names no name this server answers to (400)
          +-- OriginNotAllowed      a state change or WebSocket from another site (403)
          +-- PayloadTooLarge       the body is past the route's limit (413)
          +-- UnsupportedMediaType  not JSON (or multipart where a file is uploaded) (415)
"""

from __future__ import annotations

from typing import Any


class ServodeskError(Exception):
    """Root of every servodesk error.

    ``hint`` says what the user can do about it; the API returns it beside the message.
    """

    def __init__(self, message: str, *, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"error": type(self).__name__, "message": self.message}
        if self.hint:
            out["hint"] = self.hint
        return out

    def __reduce__(self) -> tuple[Any, ...]:
        # Raised in a worker process (api/offload.py) it comes back whole: pickle's default
        # would call __init__ with the message alone and lose the hint, field, code, ...
        return (_rebuild, (type(self), self.args, dict(self.__dict__)))


def _rebuild(cls: type[ServodeskError], args: tuple[Any, ...], state: dict[str, Any]) -> Any:
    err = cls.__new__(cls)
    Exception.__init__(err, *args)
    err.__dict__.update(state)
    return err


class ProfileError(ServodeskError):
    """A profile or imported device description is invalid.

    Example: ``profiles/x/profile.yaml: objects[12].default: 70000 is above max 65535``.
    """

    def __init__(self, message: str, *, path: str | None = None, hint: str | None = None):
        super().__init__(f"{path}: {message}" if path else message, hint=hint)
        self.path = path


class SettingsError(ServodeskError):
    """``SERVODESK_*`` settings are invalid: ``problems`` has one line per bad setting, each
    naming the variable, what is wrong with its value and what to write instead."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = list(problems)


class ValidationError(ServodeskError):
    """A request is refused before it reaches the bus (type, range, access, limits)."""

    def __init__(self, message: str, *, field: str | None = None, hint: str | None = None):
        super().__init__(message, hint=hint)
        self.field = field

    def to_dict(self) -> dict[str, object]:
        out = super().to_dict()
        if self.field:
            out["field"] = self.field
        return out


class PdoRefused(ValidationError):
    """A PDO configuration is refused before anything is written.

    ``problems`` lists every reason (``servodesk.domain.pdo.PdoProblem`` objects or their dicts),
    each saying what is wrong, where, and what to do; the API answers 422 with them.
    """

    def __init__(
        self,
        message: str,
        *,
        problems: list[Any] | None = None,
        field: str | None = None,
        hint: str | None = None,
    ) -> None:
        super().__init__(message, field=field, hint=hint)
        # domain.pdo.PdoProblem objects (errors.py cannot import the domain: it imports us).
        self.problems: list[Any] = list(problems or [])

    def problem_dicts(self) -> list[dict[str, object]]:
        out: list[dict[str, object]] = []
        for p in self.problems:
            if isinstance(p, dict):
                out.append(dict(p))
            else:
                to_dict = getattr(p, "to_dict", None)
                out.append(to_dict() if callable(to_dict) else {"message": str(p)})
        return out

    def to_dict(self) -> dict[str, object]:
        out = super().to_dict()
        out["detail"] = self.message
        out["problems"] = self.problem_dicts()
        return out


class NotFoundError(ServodeskError):
    """No such session, profile, object or file."""


class ConflictError(ServodeskError):
    """Another client holds control of the drive (or another operation runs)."""


class LinkError(ServodeskError):
    """The bus or the device cannot be reached or misbehaves."""


class LinkTimeoutError(LinkError, TimeoutError):
    """The device did not answer in time (SDO timeout, no heartbeat)."""


class LinkUnavailableError(LinkError, NotImplementedError):
    """A fieldbus backend cannot be used here, e.g. its library is not installed."""


class LinkClosedError(LinkError):
    """The link was closed while a call was pending or before it started."""


class ObjectAccessError(ServodeskError):
    """The device refused a read or write.

    ``code`` is the protocol's own code (SDO abort code for CANopen/CoE, PROFIdrive error
    number, SLMP end code), ``protocol`` names which, ``meaning`` is its text.
    """

    def __init__(
        self,
        message: str,
        *,
        code: int,
        meaning: str,
        protocol: str = "sdo",
        address: str | None = None,
        hint: str | None = None,
    ) -> None:
        super().__init__(message, hint=hint)
        self.code = code
        self.meaning = meaning
        self.protocol = protocol
        self.address = address

    def to_dict(self) -> dict[str, object]:
        out = super().to_dict()
        out.update(
            code=self.code,
            # A PROFIdrive error number (004 §20.4.2) and a DCP BlockError are one byte;
            # the others are 32-bit.
            code_hex=f"0x{self.code:02X}"
            if self.protocol in ("profidrive", "dcp")
            else f"0x{self.code:08X}",
            meaning=self.meaning,
            protocol=self.protocol,
        )
        if self.address:
            out["address"] = self.address
        return out


class Forbidden(ServodeskError):
    """The caller is known but their role lacks the right the request needs
    (domain/roles.py); the message names the right and the role."""

    def __init__(self, message: str, *, right: str, role: str, hint: str | None = None):
        super().__init__(message, hint=hint)
        self.right = right
        self.role = role

    def to_dict(self) -> dict[str, object]:
        out = super().to_dict()
        out.update(right=self.right, role=self.role)
        return out


class WorkerFailed(ServodeskError):
    """A worker process (documents, tuning: api/offload.py) ended before it answered, e.g.
    killed for memory by a huge file; the next request starts a new one."""


class Unavailable(ServodeskError):
    """A service the request needs cannot be reached now (the central store: services/db.py
    StoreUnavailable); the next try may work (HTTP 503)."""


class ToolMissing(ServodeskError):
    """A program the server needs for this request is not installed (Chromium for a report's
    PDF); the hint says what to install. The request may work once it is (HTTP 503)."""


class DriveStateError(ServodeskError):
    """A CiA 402 command or operation is not possible in the drive's current state."""


class RequestRefused(ServodeskError):
    """An HTTP request (or WebSocket upgrade) refused by servodesk's request checks before any
    route sees it (docs/security.md); the subclass says why, api/errors.py the status."""


class Unauthorized(RequestRefused):
    """The server requires a login (bound beyond loopback, or accounts exist) and the request
    has no valid session cookie or API token (docs/security.md, Users)."""


class LockedOut(RequestRefused):
    """Too many failed logins for an account or from an address: logins are refused until
    ``until`` (Unix time), even with the right password."""

    def __init__(self, message: str, *, until: float, hint: str | None = None):
        super().__init__(message, hint=hint)
        self.until = until

    def to_dict(self) -> dict[str, object]:
        out = super().to_dict()
        out["until"] = self.until
        return out


class HostNotAllowed(RequestRefused):
    """The request's Host is not a name this server answers to (DNS rebinding)."""


class OriginNotAllowed(RequestRefused):
    """A state-changing request or a WebSocket from a page of another origin (cross-site)."""


class PayloadTooLarge(RequestRefused):
    """The request body is larger than the route takes."""


class UnsupportedMediaType(RequestRefused):
    """A state-changing request whose body is not JSON (or multipart/form-data where a file
    is uploaded)."""
