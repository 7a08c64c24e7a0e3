"""Every JSON message of the WebSocket ``/api/v1/ws``, as one discriminated union per direction.

``ServerMessage`` is what the server may send, ``ClientMessage`` what it reads; ``type`` tells
them apart. They are the WebSocket's half of the wire contract (docs/architecture.md, "Wire
contract"; issue 51 item 1): api/ws.py sends nothing that :func:`encode` has not validated
against ``ServerMessage``, and reads client frames through ``ClientMessage``; :func:`add_to_openapi`
puts both unions into the OpenAPI document's components, from which openapi-typescript
generates the UI's types (frontend/src/api/schema.ts), so neither side writes them by hand.

The services publish plain dicts to the event hub (services/events.py; the services may not
import ``api``), and a payload that is already a REST answer reuses that answer's model
(``SessionInfo``, ``DriveStateOut``, ``MotionStatusOut``, ``HomingStatus``, ``ProtectionOut``,
``EmcyLogEntry``). Messages forbid unknown fields: a field a publisher adds without adding it
here fails validation, and the test that runs a real session over the socket says which.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError
from pydantic.json_schema import JsonSchemaMode

from servodesk.api.schemas_homing import EmcyLogEntry, HomingStatus
from servodesk.api.schemas_motion import MotionStatusOut, ProtectionOut
from servodesk.api.schemas_pdo import PdoLinkHealth, PdoLiveValue
from servodesk.api.schemas_scope import ScopeStatusFrame
from servodesk.api.schemas_sessions import DriveStateOut, SessionInfo
from servodesk.api.schemas_tuning import TuningJob

log = logging.getLogger(__name__)


def _optional_means_absent(schema: dict[str, Any]) -> None:
    """Drop the defaults from a message's JSON schema: :func:`encode` sends only the fields
    the publisher gave, so a field with a default may be absent, and openapi-typescript types
    a field that has a default as always present (docs/architecture.md, "Types")."""
    for prop in schema.get("properties", {}).values():
        prop.pop("default", None)


class _Server(BaseModel):
    model_config = ConfigDict(
        extra="forbid", populate_by_name=True, json_schema_extra=_optional_means_absent
    )

    dropped: int = Field(
        default=0,
        description="Messages dropped for this socket so far because it read too slowly "
        "(present once any were: the oldest queued message goes first)",
    )


class HelloMessage(_Server):
    """The first message on every socket."""

    type: Literal["hello"]
    version: str = Field(description="servodesk's version")
    protocol: int = Field(description="The WebSocket protocol's version (subprotocol servodesk.v1)")
    client: str = Field(description="The client id the server took for this socket: a label")
    connection: str = Field(description="The server's id of this connection")


class SessionsMessage(_Server):
    """The open sessions: on connect and whenever the list or a session's summary changes."""

    type: Literal["sessions"]
    sessions: list[SessionInfo]


class StateMessage(_Server, DriveStateOut):
    """A subscribed session's drive state: on a change, and once a second unchanged."""

    type: Literal["state"]
    session: str


class EmcyMessage(_Server, EmcyLogEntry):
    """An emergency message of a subscribed session's drive (CiA 301 §7.2.7)."""

    type: Literal["emcy"]
    session: str
    data: str = Field(description="The manufacturer-specific bytes of the EMCY frame, hex")


class NmtMessage(_Server):
    """A subscribed session's NMT state, as its heartbeat or an NMT command says."""

    type: Literal["nmt"]
    session: str
    state: str | None
    time: float = Field(description="Unix time")


class LinkMessage(_Server):
    """A subscribed session's link to its drive changed."""

    type: Literal["link"]
    session: str
    event: Literal["lost", "restored", "closed", "heartbeat_lost", "heartbeat_restored"]
    message: str | None


class ProgressItem(BaseModel):
    """The step a restore is writing (services/restore.py)."""

    model_config = ConfigDict(extra="forbid")

    address: str
    name: str | None
    why: str = Field(description='Why this write: "entry", or a step of a PDO mapping')


class ProgressMessage(_Server):
    """Progress of a long operation of a subscribed session (store, backup, restore, ...)."""

    type: Literal["progress"]
    session: str
    operation: str
    fraction: float = Field(ge=0.0, le=1.0)
    message: str | None
    item: ProgressItem | None = Field(default=None, description="A restore's present step")


class ControlMessage(_Server):
    """Who holds control of a session changed (to every socket; never the token)."""

    type: Literal["control"]
    session: str
    owner: str | None = Field(description="Client id (label) of the holder, or null")
    user: str | None = Field(description="The account holding control, or null")
    since: float | None = Field(description="When it was taken (Unix time)")
    bound: bool = Field(description="A WebSocket is bound to the holder's control (its dead-man)")
    orphaned: bool = Field(
        description="The holder's socket closed: the drive was made safe; control lapses soon"
    )


class ProtectionMessage(_Server, ProtectionOut):
    """What stops a session's drive when its operator is lost changed (a watchdog armed)."""

    type: Literal["protection"]
    session: str


class BindMessage(_Server):
    """The answer to this socket's ``bind``: whether it is now the session's dead-man."""

    type: Literal["bind"]
    session: str
    ok: bool
    message: str | None = None
    hint: str | None = None


class SafeStateMessage(_Server):
    """A drive was made safe because its holder was lost: motion stopped, drive disabled."""

    type: Literal["safe_state"]
    session: str
    reason: str
    client: str | None
    ok: bool = Field(description="The drive reached Switch on disabled")
    state: str | None = Field(default=None, description="The state it ended in (absent: unread)")
    message: str


class MotionSettingsMessage(_Server):
    """After a motion: the settings it wrote that were put back, and those that stay written."""

    type: Literal["motion_settings"]
    session: str
    restored: list[str]
    kept: list[str]


class MotionMessage(_Server, MotionStatusOut):
    """A subscribed session's motion started, changed or ended."""

    type: Literal["motion"]


class DeadmanMessage(_Server):
    """The dead-man stopped a subscribed session's axis (docs/safety.md)."""

    type: Literal["deadman"]
    session: str
    reason: str
    client: str | None = Field(default=None, description="The client whose motion was stopped")
    latency_ms: float | None = Field(description="From the last heartbeat to the first stop")
    detect_ms: float | None = None
    quick_stop_ms: float | None = None
    stop_frame_ms: float | None = None
    from_: Literal["dead-man thread", "event loop"] | None = Field(
        default=None, alias="from", description="Which path sent the first stop"
    )
    message: str | None = Field(default=None, description="Set when the stop could not be sent")


class HomingMessage(_Server, HomingStatus):
    """A subscribed session's homing run: its phases and its end."""

    type: Literal["homing"]


class TuningMessage(_Server):
    """A subscribed session's tuning job: progress and end (docs/tuning.md)."""

    type: Literal["tuning"]
    session: str
    sid: str
    job: TuningJob = Field(description="As GET /sessions/{sid}/tuning answers it")


class PdoMessage(_Server):
    """A subscribed session's cyclic data (docs/pdo.md), while cyclic data runs."""

    type: Literal["pdo"]
    session: str
    # The transport's own view of the bus (EtherCAT's working counters, CAN: none).
    link: PdoLinkHealth | None
    values: dict[str, PdoLiveValue] = Field(description="Keyed by address, e.g. 0x606C:00")
    rates: dict[str, float] = Field(description="Frames per second of each TPDO, by name")
    time: float = Field(description="Unix time")


class PongMessage(_Server):
    """The answer to ``ping``, with its ``time``."""

    type: Literal["pong"]
    time: float | None


class ErrorMessage(_Server):
    """A client frame the server could not read; the socket stays open."""

    type: Literal["error"]
    message: str


ServerMessage = Annotated[
    HelloMessage
    | SessionsMessage
    | StateMessage
    | EmcyMessage
    | NmtMessage
    | LinkMessage
    | ProgressMessage
    | ControlMessage
    | ProtectionMessage
    | BindMessage
    | SafeStateMessage
    | MotionSettingsMessage
    | MotionMessage
    | DeadmanMessage
    | HomingMessage
    | TuningMessage
    | PdoMessage
    | PongMessage
    | ErrorMessage,
    Field(discriminator="type"),
]


class _Client(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SubscribeMessage(_Client):
    """Follow a session: its state, EMCY, link, progress, motion, ... messages."""

    type: Literal["subscribe"]
    session: str


class UnsubscribeMessage(_Client):
    type: Literal["unsubscribe"]
    session: str


class HeartbeatMessage(_Client):
    """The dead-man's heartbeat: counts only on a socket bound to the session's control."""

    type: Literal["heartbeat"]
    session: str


class BindRequest(_Client):
    """Make this socket the dead-man of a session whose control the caller holds."""

    type: Literal["bind"]
    session: str
    # Optional so that a bind without one is answered by a refusing ``bind`` with its hint.
    token: str | None = Field(
        default=None, description="The control token (POST /sessions/{sid}/control)"
    )


class PingMessage(_Client):
    type: Literal["ping"]
    time: float | None = Field(default=None, description="Sent back in the pong")


ClientMessage = Annotated[
    SubscribeMessage | UnsubscribeMessage | HeartbeatMessage | BindRequest | PingMessage,
    Field(discriminator="type"),
]

_SERVER: TypeAdapter[ServerMessage] = TypeAdapter(ServerMessage)
_CLIENT: TypeAdapter[ClientMessage] = TypeAdapter(ClientMessage)


class RefusedMessage(ValueError):
    """A message that is not one of ``ServerMessage``'s: it is not sent."""


def encode(msg: Mapping[str, Any]) -> str:
    """The text frame of ``msg``, validated as a ``ServerMessage``; RefusedMessage otherwise.

    The frame has the fields the publisher gave (``exclude_unset``), so an optional field it
    left out stays out, as the schema (required = always sent) says.
    """
    try:
        model = _SERVER.validate_python(msg)
    except ValidationError as exc:
        raise RefusedMessage(f"{msg.get('type')!r} is not a ServerMessage: {exc}") from None
    # fallback=str: what json.dumps(default=str) did for the untyped parts (a tuning job).
    return _SERVER.dump_json(model, by_alias=True, exclude_unset=True, fallback=str).decode()


def decode(data: Any) -> ClientMessage:
    """A client frame's JSON as a ``ClientMessage``; ValidationError otherwise."""
    return _CLIENT.validate_python(data)


def _without_defaults(schema: dict[str, Any]) -> dict[str, Any]:
    props = {
        k: {kk: vv for kk, vv in v.items() if kk != "default"}
        for k, v in schema.get("properties", {}).items()
    }
    return {**schema, "properties": props}


def add_to_openapi(schema: dict[str, Any]) -> dict[str, Any]:
    """Put ``ServerMessage``, ``ClientMessage``, the scope stream's ``ScopeStatusFrame`` and
    their models into ``schema``'s components.

    The WebSocket has no operation in OpenAPI; its messages travel with the REST models so that
    one generator (openapi-typescript) types both. A model that shares a name with a REST
    model must be that model: a clash fails here, at generation, not in the UI.
    """
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    ref = "#/components/schemas/{model}"
    unions: tuple[tuple[str, TypeAdapter[Any], JsonSchemaMode], ...] = (
        ("ServerMessage", _SERVER, "serialization"),
        ("ClientMessage", _CLIENT, "validation"),
        # The scope stream's one JSON body (its binary layout: scripts/gen_scope_wire.py).
        ("ScopeStatusFrame", TypeAdapter(ScopeStatusFrame), "serialization"),
    )
    for name, adapter, mode in unions:
        union = adapter.json_schema(ref_template=ref, mode=mode)
        defs = union.pop("$defs", {})
        for model, body in {**defs, name: union}.items():
            # FastAPI writes a REST answer's schema without its fields' defaults; a message's
            # model that is a REST answer's (TuningJob, PdoLiveValue...) is the same otherwise.
            if _without_defaults(components.setdefault(model, body)) != _without_defaults(body):
                raise RuntimeError(f"WebSocket schema {model} differs from the REST schema")
    return schema
