"""The composition root: one :class:`AppState` builds, starts and stops every service.

``create_app`` (api/app.py) makes one per application and keeps it on ``app.state.servodesk``;
routes reach it through :func:`state_of` (or ``StateDep`` in api/deps.py), never through
attributes of their own on ``app.state``. Its lifespan calls :meth:`AppState.start` and
:meth:`AppState.aclose`: the one place that says in which order things stop.

The order of :meth:`AppState.aclose` is safety-relevant (docs/architecture.md, Decisions):

1. tuning jobs stop and put the gains back (they drive the axis through motion);
2. motion halts and quick-stops every moving axis, and the dead-man's thread ends; control's
   release timers are cancelled;
3. the scope and then the 3D viewer stop (their stop waits on threads and sockets: an axis
   must not keep moving meanwhile);
4. the login sweeper stops, then the fleet's jobs (heartbeat, scheduled drift scan: it reads
   drives);
5. the sessions close (their links, the buses);
6. the sync of the local queue stops (services/outbox.py: what it has not synced stays on
   disk for the next start), then the store, the audit log and the accounts close, then the
   worker pools;
7. the simulated drives (``serve --sim``) stop last: they are the devices the sessions talked to.

Each service is built once, with the application, and reused if the lifespan runs again (a
test may enter the same app twice), as the services created on first use were before.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from servodesk.api.auth import Auth
from servodesk.domain.dcp import mac_text
from servodesk.domain.profile_loader import ProfileCatalog, default_profile_dirs
from servodesk.errors import ServodeskError
from servodesk.services.audit import Actor, AuditLog
from servodesk.services.backup import BackupService
from servodesk.services.capture_store import CaptureStore
from servodesk.services.control import ControlService
from servodesk.services.dcp import DcpService
from servodesk.services.drift import DriftService, gateway_url
from servodesk.services.events import EventHub
from servodesk.services.fleet import FleetStore
from servodesk.services.logins import LoginService, LoginSession
from servodesk.services.manager import SessionManager
from servodesk.services.motion import PP, MotionService
from servodesk.services.outbox import StoreSync
from servodesk.services.report import ReportService
from servodesk.services.report_store import ReportStore
from servodesk.services.restore import RestoreService
from servodesk.services.scope import ScopeService
from servodesk.services.store import Store
from servodesk.services.tuning.jobs import TuningService
from servodesk.services.tuning_store import TuningStore
from servodesk.services.users import UserStore
from servodesk.services.viewer import ViewerService
from servodesk.settings import Settings

if TYPE_CHECKING:
    from servodesk.sim.bus import SimulatedBus

log = logging.getLogger(__name__)


@dataclass
class AppState:
    """Every service of one application, built by :meth:`build`."""

    settings: Settings
    catalog: ProfileCatalog
    hub: EventHub
    manager: SessionManager
    backups: BackupService
    restores: RestoreService
    #: The audit log (services/audit.py): ``state.audit.record("access.login", who=...)``.
    audit: AuditLog
    #: The accounts, the login sessions and the mode (api/auth.py).
    auth: Auth
    #: Who holds which drive, and the bound dead-man sockets (services/control.py).
    control: ControlService
    motion: MotionService
    scope: ScopeService
    tuning: TuningService
    viewer: ViewerService
    #: Every drive the store knows: plant tags, approved backups, drift (services/fleet.py).
    fleet: FleetStore
    #: This gateway in the fleet and its drift checks (services/drift.py).
    drift: DriftService
    #: PROFINET DCP on the server's network interfaces (services/dcp.py).
    dcp: DcpService
    #: The tuning results of every drive, in the store (services/tuning_store.py).
    tuning_results: TuningStore
    #: The scope captures users kept, of every drive, in the store (services/capture_store.py).
    captures: CaptureStore
    #: Commissioning reports: made of connected drives, kept in the store (services/report.py).
    reports: ReportService
    #: The simulated drives of ``serve --sim`` while the application runs (else None).
    sim: SimulatedBus | None = None
    #: The sync of the local queue while the central store is away (PostgreSQL stores only,
    #: services/outbox.py); None on a SQLite store.
    store_sync: StoreSync | None = None
    _sweeper: asyncio.Task[None] | None = field(default=None, repr=False)

    @classmethod
    def build(cls, settings: Settings) -> AppState:
        """Every service, wired; nothing runs yet (:meth:`start` does that)."""
        catalog = ProfileCatalog(default_profile_dirs(settings.profile_paths()))
        hub = EventHub()
        manager = SessionManager(
            catalog, hub, sdo_timeout=settings.sdo_timeout, poll_hz=settings.poll_hz
        )
        # Backups, restore reports and the audit log of every parameter write (docs/backup.md).
        backups = BackupService(Store(settings.data_dir, settings.store_url), catalog)
        backups.attach(hub)
        # Beside the store, in the same database (docs/security.md, Audit log).
        audit = AuditLog(backups.store.url)
        backups.audit = audit
        # A central store that cannot be reached: backups, tuning results and audit records
        # wait in the gateway's local queue (services/outbox.py) until it answers.
        outbox = backups.store.outbox
        audit.outbox = outbox
        auth = Auth(
            settings,
            UserStore(settings.data_dir, settings.store_url),
            LoginService(idle_s=settings.session_idle_s, lockout_s=settings.lockout_s),
        )
        control = ControlService(hub, audit=audit)
        motion = MotionService(manager, control, hub, deadman_s=settings.deadman_ms / 1000.0)
        scope = ScopeService(manager)
        fleet = FleetStore(backups.store.engine)
        drift = DriftService(
            fleet,
            backups,
            manager,
            gateway=settings.gateway_name or socket.gethostname(),
            url=settings.gateway_url or gateway_url(settings.host, settings.port, settings.https),
            interval_s=settings.drift_interval_s,
            webhook=settings.drift_webhook,
        )
        tuning = TuningService(manager, motion, hub)
        # Every tuning that ends is kept in the store (issue 49; services/tuning_store.py).
        tuning_results = TuningStore(backups.store.engine, drift.gateway, outbox)
        tuning.recorder = tuning_results.add
        captures = CaptureStore(backups.store.engine, drift.gateway)
        reports = ReportService(
            ReportStore(backups.store.engine),
            backups,
            fleet,
            audit,
            tuning.result,
            stored_tuning=tuning_results.latest,
            captures=captures.attached,
        )
        state = cls(
            settings=settings,
            catalog=catalog,
            hub=hub,
            manager=manager,
            backups=backups,
            restores=RestoreService(backups),
            audit=audit,
            auth=auth,
            control=control,
            motion=motion,
            scope=scope,
            tuning=tuning,
            viewer=ViewerService(
                manager,
                host=settings.host,
                port=settings.viewer_port,
                public=settings.viewer_public,
            ),
            fleet=fleet,
            drift=drift,
            dcp=DcpService(manager, catalog, backups.store, audit),
            reports=reports,
            tuning_results=tuning_results,
            captures=captures,
            store_sync=(
                StoreSync(outbox, audit.sync_queued, audit.record, settings.store_retry_s)
                if outbox is not None
                else None
            ),
        )
        # Late-bound through the state: a benchmark may put a scope of its own in place.
        state.tuning.recorder_busy = state._recorder_busy
        state.viewer.target_of = state._target_of
        drift.on_drift = state._drift_found
        state.dcp.simulated_ports = state._simulated_dcp_ports
        return state

    # Wiring between services ------------------------------------------------------------

    def _recorder_busy(self, sid: str) -> bool:
        """A drive-side recorder of the scope runs on ``sid`` (tuning must not start)."""
        scope = self.scope
        if not scope.running:
            return False
        return any(r.get("session") == sid for r in scope.status().get("recorders", []))

    def _target_of(self, sid: str) -> float | None:
        # A profile-position move's set-point is known before 607Ah reads it back.
        try:
            status = self.motion.status(sid)
        except ServodeskError:
            return None
        if status["active"] and status["mode"] == PP and status["target"] is not None:
            return float(status["target"])
        return None

    def _simulated_dcp_ports(self) -> dict[str, int]:
        # The PROFINET twins of ``serve --sim`` answer DCP for a MAC on a free PNIO-CM port.
        out: dict[str, int] = {}
        for pn in self.sim.profinet if self.sim is not None else ():
            mac, port = pn.dcp_mac, pn.port
            if mac is not None and port is not None:
                out[mac_text(mac)] = port
        return out

    def _drift_found(self, result: dict[str, Any]) -> None:
        # Drift that is news (services/drift.py) is an event of the drive, like a backup.
        self.audit.record(
            "backup.drift",
            drive=result["session"],
            message=f"{result['count']} parameters differ from the approved backup",
            details={
                "drive_key": result["drive_key"],
                "backup": result["backup"],
                "result": result["id"],
                "parameters": [d["address"] for d in result["differences"][:20]],
            },
        )

    def _session_ended(self, session: LoginSession, reason: str) -> None:
        # IEC 62443-4-2 CR 2.8: session termination is an access-control event.
        self.audit.record(
            "access.session_ended",
            who=Actor(session.user, session.address),
            message=reason,
            details={"session": session.id},
        )

    # Lifecycle --------------------------------------------------------------------------

    async def start(self) -> None:
        """The simulated drives (``serve --sim``: their sessions open), the login sweeper,
        then the 3D viewer (it draws the sessions that exist by then)."""
        if self.settings.sim:
            from servodesk.services.simulation import start_simulation

            self.sim = await start_simulation(self.settings, self.catalog, self.manager)
        logins = self.auth.logins
        logins.on_end = self._session_ended
        every = min(2.0, max(0.2, logins.idle_s / 4))
        self._sweeper = asyncio.create_task(
            logins.run_sweeper(self.auth.enabled, every), name="logins"
        )
        await self.viewer.start()
        await self.drift.start()
        if self.store_sync is not None:
            self.store_sync.start()  # A queue left by a crash is synced at the first period.

    async def aclose(self) -> None:
        """Stop everything, in the order of the module's docstring.

        A stop that fails is logged and the ones after it still run (an axis halted but its
        bus never closed helps nobody); the first failure is raised at the end."""
        failures: list[Exception] = []

        async def step(name: str, stop: Callable[[], Awaitable[Any] | None]) -> None:
            try:
                result = stop()
                if result is not None:
                    await result
            except Exception as exc:
                log.exception("stopping %s at shutdown", name)
                failures.append(exc)

        await step("tuning", self.tuning.shutdown)  # Jobs end, the gains go back.
        await step("motion", self.motion.shutdown)  # Moving axes halt and quick-stop.
        await step("control", self.control.close)
        await step("scope", self.scope.close)
        await step("viewer", self.viewer.stop)
        await step("logins", self._stop_sweeper)
        await step("fleet", self.drift.stop)
        await step("sessions", self.manager.close_all)
        await step("store sync", self._stop_store_sync)
        await step("store", self.backups.store.close)
        await step("audit", self.audit.close)
        await step("users", self.auth.users.close)
        await step("workers", _stop_workers)
        await step("sim", self._stop_sim)
        if failures:
            raise failures[0]

    async def _stop_sweeper(self) -> None:
        sweeper, self._sweeper = self._sweeper, None
        if sweeper is not None:
            sweeper.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await sweeper

    async def _stop_store_sync(self) -> None:
        if self.store_sync is not None:
            await self.store_sync.stop()

    def _stop_sim(self) -> None:
        sim, self.sim = self.sim, None
        if sim is not None:
            sim.stop()


def _stop_workers() -> None:
    """The process pools of the tuning's searches and of the off-loop work (documents)."""
    from servodesk.api import offload
    from servodesk.services.tuning import worker as tuning_worker

    tuning_worker.shutdown()
    offload.shutdown()


def state_of(app: Any) -> AppState:
    """The application's :class:`AppState` (``app``: the FastAPI or Starlette app)."""
    state: AppState = app.state.servodesk
    return state
