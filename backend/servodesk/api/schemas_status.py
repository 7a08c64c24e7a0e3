"""Response model of GET /status (api/routes/status.py): the status bar's numbers per bus,
built from the dicts of services/status.py (api/reply.py). A number the link cannot give is
null; the UI shows "not reported", never 0."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from servodesk.api.reply import Reply
from servodesk.api.schemas_pdo import SyncMode


class BusSessionOut(Reply):
    id: str
    node_id: int
    connected: bool = Field(description="the drive answered the session's last polls")


class BusTrafficOut(Reply):
    """Counted from the frames the bus delivered (links/can_traffic.py); CAN only."""

    frames_per_s: float = Field(description="frames received per second (other nodes' frames)")
    load_percent: float | None = Field(
        description="their bits (without stuffing) per second over the bitrate [%]; "
        "null without a bitrate or on CAN FD"
    )
    load_basis: str = Field(description="what the numbers count, or why there is no load")
    error_frames: int | None = Field(
        description="error frames received since the bus opened; null: the interface "
        "does not deliver them"
    )
    bus_state: str | None = Field(
        description='the controller\'s state ("active", "passive", "error"); null: the '
        "interface does not report it"
    )


class BusCycleOut(Reply):
    """A cyclic process data exchange running on the bus (services/cyclic.py)."""

    session: str
    sync: SyncMode
    configured_ms: float
    measured_ms: float | None = Field(
        description="average cycle since the exchange started; null before its first cycle"
    )
    cycles: int


class BusEthercatOut(Reply):
    """The EtherCAT line's counters while cyclic data runs (links/ethercat_health.py)."""

    wkc_errors: int
    missing_frames: int
    losses: int


class BusProfinetOut(Reply):
    """The IO controller AR's counters while cyclic data runs (links/profinet_io.py)."""

    output_frames: int = Field(description="output frames servodesk sent")
    input_frames: int = Field(description="input frames received from the device")
    lost: int = Field(description="input frames lost (gaps in their cycle counter)")
    data_status_errors: int = Field(
        description="input frames whose DataStatus or IOPS was not good (not used)"
    )
    losses: int = Field(description="times the link was lost (watchdog or no carrier)")
    cycle_ms: float = Field(description="the IOCRs' cycle (SendClockFactor x ReductionRatio)")


class BusStatusOut(Reply):
    link: str = Field(description='the link: "canopen", "ethercat", "cclink-ie-tsn", "profinet"')
    interface: str
    channel: str
    bitrate: int | None
    state: Literal["up", "degraded", "down", "reconnecting"]
    reason: str | None = Field(
        description="why an EtherCAT line or a PROFINET IO AR is not up, in words"
    )
    sessions: list[BusSessionOut]
    requests: int = Field(description="requests servodesk made on this bus's sessions")
    failed_requests: int = Field(
        description="of those, refused, unanswered or lost (time-out, bus error, abort)"
    )
    traffic: BusTrafficOut | None = Field(description="null: this link counts no traffic")
    cycle: BusCycleOut | None = Field(description="null: no cyclic exchange runs")
    ethercat: BusEthercatOut | None = Field(description="null: not an EtherCAT line in cycles")
    profinet: BusProfinetOut | None = Field(
        description="null: not a PROFINET IO AR exchanging cyclic data"
    )


class StoreStatusOut(Reply):
    engine: Literal["sqlite", "postgresql"]
    url: str = Field(description="the store's URL without its password")
    reachable: bool = Field(
        description="the central store answered its last write or sync (always true on "
        "SQLite: the store is the local file)"
    )
    since: float | None = Field(description="unreachable since (epoch s); null while it answers")
    queued: dict[str, int] = Field(
        description="records waiting in the local queue by kind (backups, tuning_results, "
        "audit_log); empty on SQLite"
    )
    last_sync: float | None = Field(description="when the queue last synced records (epoch s)")
    last_error: str | None = Field(description="why the store was last found unreachable")
    synced: int = Field(description="records synced from the queue since the server started")


class StatusOut(Reply):
    buses: list[BusStatusOut]
    store: StoreStatusOut = Field(
        description="the store: reachability and the local queue (docs/deployment.md)"
    )
