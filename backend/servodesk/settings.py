"""Settings from environment variables ``SERVODESK_*`` (one pydantic-settings object)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Self

import pydantic
from pydantic import Field, ModelWrapValidatorHandler, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from servodesk import hosts
from servodesk.domain.address import ObjectAddress
from servodesk.errors import ServodeskError, SettingsError

ENV_PREFIX = "SERVODESK_"
#: The levels uvicorn knows (uvicorn.config.LOG_LEVELS), quietest first.
LOG_LEVELS = ("critical", "error", "warning", "info", "debug", "trace")


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix=ENV_PREFIX, extra="ignore")

    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=1, le=65535)
    #: On loopback, stay in the single-user mode (no login, the caller may do everything)
    #: even when accounts exist (``serve --single-user``). Ignored beyond loopback.
    single_user: bool = False
    #: A login session unused this long (no HTTP request) ends: IEC 62443-4-2 CR 2.5.
    session_idle_s: float = Field(default=900.0, gt=0, le=86400)
    #: How long an account (or address) stays locked after too many failed logins (s).
    lockout_s: float = Field(default=300.0, gt=0, le=86400)
    #: Host names the server answers to beside localhost, 127.0.0.1, [::1], ``host`` and
    #: (beyond loopback) the machine's name: comma-separated ``name`` or ``name:port`` (a
    #: port: pages of that origin may change things whatever port the server has, e.g.
    #: behind a proxy or a mapped container port). docs/security.md.
    allowed_hosts: str = ""
    #: Start one simulated drive per family profile on a virtual bus.
    sim: bool = False
    sim_interface: str = "virtual"
    sim_channel: str = "servodesk-sim"
    #: Comma-separated profile ids to simulate; empty: one drive per shipped profile.
    sim_profiles: str = ""
    #: A TOML plant file (docs/tuning.md, "Plant files") the simulated drives run on in place
    #: of their profiles' simulation sections; None: the profiles' own.
    sim_plant: Path | None = None
    #: Where the simulated CC-Link IE TSN station (the CTMM04x twin) answers SLMP, as
    #: ``host:port`` on UDP (port 0: a free port, shown as the session's channel); empty: the
    #: CTMM04x twin is a CANopen node like the others.
    sim_slmp: str = "127.0.0.1:0"
    #: Where the simulated PROFINET IO device (the LECSN-T twin) answers PNIO-CM record access,
    #: as ``host:port`` on UDP (port 0: a free port, shown as the session's channel); empty:
    #: the LECSN-T twin is a CANopen node, with cyclic PDOs (docs/profinet.md).
    sim_profinet: str = "127.0.0.1:0"
    #: Serve the EtherCAT twin (HIWIN E) on a simulated EtherCAT line behind a veth pair and
    #: open it with the EtherCAT link (pysoem). Needs root or CAP_NET_ADMIN / CAP_NET_RAW; off,
    #: or where the pair cannot be made, the twin is a CANopen node (docs/ethercat.md).
    sim_ethercat: bool = False
    #: The PROFINET twin (LECSN-T) also answers DCP on one end of a veth pair, so that the
    #: Connect page's DCP search finds it on the other end (named in the session's note) and
    #: can set its station name and IP address. Needs root or CAP_NET_ADMIN / CAP_NET_RAW.
    sim_dcp: bool = False
    #: Objects the twins hold no value for: comma-separated ``profile=address`` (for example
    #: ``smartris=0x607F:00``); their reads answer 0800 0024h "no data available", as a drive
    #: whose firmware lacks the value does. Every object of the manual has a value in the
    #: twins (issue 47): this is how the UI's handling of a refusal is shown and tested.
    sim_withhold: str = ""
    #: Extra profile directories, searched before the shipped profiles (os.pathsep list).
    profile_dirs: str = ""
    #: Where backups, the audit log and the store live.
    data_dir: Path = Path.home() / ".servodesk"
    #: The store (backups and their content, restores, the audit log, accounts): empty, the
    #: SQLite file ``data_dir/servodesk.db``; or ``postgresql://user@host:port/db`` (a central
    #: PostgreSQL several gateways share; ``?sslmode=verify-full`` for TLS). Checked when the
    #: store opens (services/db.py, docs/deployment.md).
    store_url: str = ""
    #: While a central store is unreachable, try it (and sync the local queue) this often,
    #: s (services/outbox.py, docs/deployment.md).
    store_retry_s: float = Field(default=5.0, gt=0, le=3600)
    #: This gateway's name in the fleet (services/drift.py); empty: the machine's host name.
    gateway_name: str = Field(default="", max_length=64, pattern=r"^[A-Za-z0-9._-]*$")
    #: The URL other machines reach this gateway's UI at (the fleet page's links to its
    #: drives); empty: http(s)://<host or host name>:<port>.
    gateway_url: str = Field(default="", max_length=300)
    #: Compare every connected drive with its approved backup this often (s); 0: never (the
    #: default). docs/deployment.md, "Drift".
    drift_interval_s: float = Field(default=0.0, ge=0, le=7 * 86400)
    #: POSTed a JSON summary when a drift check finds differences (http:// or https://);
    #: empty: no notification.
    drift_webhook: str = Field(default="", max_length=2000)
    #: How often a session polls the drive's state for live updates (Hz).
    poll_hz: float = Field(default=20.0, gt=0, le=200)
    #: SDO response time-out in seconds.
    sdo_timeout: float = Field(default=0.5, gt=0, le=30)
    #: Dead-man: motion started by a client stops when its WebSocket heartbeat has been
    #: missing this long (ms). Clients send one at least every 100 ms.
    deadman_ms: int = Field(default=250, ge=50, le=5000)
    #: Port of the 3D viewer (viser), served on ``host``; 0 disables the viewer.
    viewer_port: int = Field(default=8080, ge=0, le=65535)
    #: The viewer's port has no token check: with ``host`` beyond loopback it is started only
    #: when this is set (anyone who reaches host:viewer_port then sees the 3D view).
    viewer_public: bool = False
    #: uvicorn's log level (its LOG_LEVELS; any case).
    log_level: str = "info"
    #: HTTPS (servodesk/tls.py, docs/security.md "TLS"): the certificate (PEM) and its key.
    #: ``servodesk serve`` beyond loopback fills them with a self-signed pair made in
    #: ``data_dir/tls`` when they are not given; set, the server speaks only HTTPS.
    tls_cert: Path | None = None
    tls_key: Path | None = None
    #: Serve plain HTTP beyond loopback (``serve --insecure-http``): logins and tokens then
    #: cross the network in clear text.
    insecure_http: bool = False

    def profile_paths(self) -> list[Path]:
        """User profile directories: SERVODESK_PROFILE_DIRS, then imported ones in data_dir."""
        import os

        return [Path(p) for p in self.profile_dirs.split(os.pathsep) if p] + [self.user_profile_dir]

    @property
    def user_profile_dir(self) -> Path:
        """Where imported device descriptions are saved as profiles."""
        return self.data_dir / "profiles"

    @model_validator(mode="wrap")
    @classmethod
    def _explain(cls, data: Any, handler: ModelWrapValidatorHandler[Self]) -> Self:
        # pydantic's ValidationError names fields, not variables, and reached the user as a
        # traceback: one line per bad setting instead, which the CLI prints, exit 2.
        try:
            return handler(data)
        except pydantic.ValidationError as exc:
            raise SettingsError([_problem(e) for e in exc.errors()]) from None

    @field_validator("drift_webhook", "gateway_url")
    @classmethod
    def _http_url(cls, v: str) -> str:
        from urllib.parse import urlsplit

        if v and (urlsplit(v).scheme not in ("http", "https") or not urlsplit(v).netloc):
            raise ValueError(f"{v!r} is not an http:// or https:// URL")
        return v.rstrip("/")

    @field_validator("log_level")
    @classmethod
    def _log_level(cls, v: str) -> str:
        # Refused here: uvicorn.run met it as a KeyError traceback after the banner.
        if v.lower() not in LOG_LEVELS:
            raise ValueError(f"{v!r} is not a log level")
        return v

    @field_validator("sim_withhold")
    @classmethod
    def _withhold(cls, v: str) -> str:
        withheld(v)  # A bad entry is refused at start-up, not ignored.
        return v

    @field_validator("allowed_hosts")
    @classmethod
    def _hosts(cls, v: str) -> str:
        hosts.parse_allowed_hosts(v)  # A bad entry is refused at start-up, not ignored.
        return v

    @property
    def https(self) -> bool:
        """The server speaks HTTPS (cookies get Secure, responses HSTS)."""
        return self.tls_cert is not None

    @property
    def is_loopback(self) -> bool:
        """Only this machine can reach the server (no token needed): hosts.is_loopback."""
        return hosts.is_loopback(self.host)


def withheld(text: str) -> list[tuple[str, ObjectAddress]]:
    """``SERVODESK_SIM_WITHHOLD``: the (profile id, object) pairs, in order."""
    out: list[tuple[str, ObjectAddress]] = []
    for item in (p.strip() for p in text.split(",")):
        if not item:
            continue
        pid, sep, addr = item.partition("=")
        if not sep or not pid.strip():
            raise ValueError(f"{item!r}: write profile=address, e.g. smartris=0x607F:00")
        try:
            out.append((pid.strip(), ObjectAddress.parse(addr.strip())))
        except ServodeskError as exc:
            raise ValueError(f"{item!r}: {exc.message}") from None
    return out


#: What to write, for the settings whose type and bounds do not say it (see _what_to_write).
_WRITE = {
    "drift_webhook": "write an http:// or https:// URL, or leave it empty",
    "gateway_url": "write an http:// or https:// URL, or leave it empty",
    "gateway_name": "write at most 64 letters, digits, '.', '_' or '-', or leave it empty",
    # Their validators' messages already say what to write (e.g. smartris=0x607F:00).
    "sim_withhold": "",
    "allowed_hosts": "",
    "log_level": f"write one of {', '.join(LOG_LEVELS)} (default info)",
}


def _problem(error: Any) -> str:
    """One line for one pydantic error: the variable, what is wrong, what to write."""
    name = str(error["loc"][0]) if error["loc"] else ""
    if name not in Settings.model_fields:
        return str(error["msg"])
    var = ENV_PREFIX + name.upper()
    # Named as the variable where it comes from the environment (matched without case, as
    # pydantic-settings does); a keyword a command passed is named as itself.
    where = var if any(k.upper() == var for k in os.environ) else f"setting {name}"
    value, kind, msg = error.get("input"), error["type"], str(error["msg"])
    if kind == "value_error":
        wrong = msg.removeprefix("Value error, ")
    elif kind in ("int_parsing", "int_from_float"):
        wrong = f"{value!r} is not a whole number"
    elif kind == "float_parsing":
        wrong = f"{value!r} is not a number"
    elif kind == "bool_parsing":
        wrong = f"{value!r} is neither true nor false"
    elif kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        wrong = f"{value!r} is out of range"
    elif kind == "string_too_long":
        wrong = f"{value!r} is too long"
    elif kind == "string_pattern_mismatch":
        wrong = f"{value!r} has a character that is not allowed"
    else:
        wrong = f"{value!r}: {msg[:1].lower()}{msg[1:]}"
    hint = _what_to_write(name)
    return f"{where}: {wrong}" + (f"; {hint}" if hint else "")


def _what_to_write(name: str) -> str:
    """From the field's type, bounds and default: "write a whole number from 50 to 5000"."""
    if name in _WRITE:
        return _WRITE[name]
    field = Settings.model_fields[name]
    kind = field.annotation
    if kind is bool:
        return "write true or false"
    if kind not in (int, float):
        return ""
    # pydantic keeps Field(ge=, gt=, le=) as annotated_types' Ge, Gt, Le in the metadata.
    lo = hi = None
    above = False
    for m in field.metadata:
        if getattr(m, "ge", None) is not None:
            lo = m.ge
        elif getattr(m, "gt", None) is not None:
            lo, above = m.gt, True
        elif getattr(m, "le", None) is not None:
            hi = m.le
    what = "a whole number" if kind is int else "a number"
    if lo is not None:
        what += f" above {lo}" if above else f" from {lo}"
    if hi is not None:
        what += f" up to {hi}" if lo is None or above else f" to {hi}"
    return f"write {what} (default {field.default})"
