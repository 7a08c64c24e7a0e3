"""FastAPI dependencies: the application state as typed aliases."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Any

from fastapi import Depends, Request

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.services.audit import AuditLog
from servodesk.services.backup import BackupService
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.restore import RestoreService
from servodesk.settings import Settings


@dataclass
class AppState:
    settings: Settings
    catalog: ProfileCatalog
    hub: EventHub
    manager: SessionManager
    backups: BackupService
    restores: RestoreService
    #: The audit log (services/audit.py): ``state.audit.record("access.login", who=...)``.
    audit: AuditLog
    sim: Any = None
    #: The PROFINET vendor and device ID each MAC answered the last DCP Identify with.
    dcp_seen: dict[str, tuple[int | None, int | None]] = field(default_factory=dict)


def get_state(request: Request) -> AppState:
    state: AppState = request.app.state.servodesk
    return state


StateDep = Annotated[AppState, Depends(get_state)]
