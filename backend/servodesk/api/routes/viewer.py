"""3D viewer routes: where the viser viewer is, and which stage each axis is drawn as.

The router's lifespan starts the viewer (services/viewer.py) after the application's own
start-up (sessions of ``serve --sim`` exist by then) and stops it first at shutdown, which
frees its port.
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import Any

from fastapi import APIRouter, FastAPI, Request

from servodesk.api.control_deps import operation
from servodesk.api.deps import AppState
from servodesk.api.schemas import ERROR_RESPONSES, ViewerAxisOut, ViewerAxisRequest, ViewerOut
from servodesk.errors import ServodeskError
from servodesk.services.motion import PP
from servodesk.services.viewer import ViewerService


def viewer(app: Any) -> ViewerService:
    """The application's viewer service (created on first use, started by the lifespan)."""
    service: ViewerService | None = getattr(app.state, "servodesk_viewer", None)
    if service is None:
        state: AppState = app.state.servodesk
        motion = operation(app).motion

        def target_of(sid: str) -> float | None:
            # A profile-position move's set-point is known before 607Ah reads it back.
            try:
                status = motion.status(sid)
            except ServodeskError:
                return None
            if status["active"] and status["mode"] == PP and status["target"] is not None:
                return float(status["target"])
            return None

        service = ViewerService(
            state.manager,
            host=state.settings.host,
            port=state.settings.viewer_port,
            target_of=target_of,
            public=state.settings.viewer_public,
        )
        app.state.servodesk_viewer = service
    return service


@contextlib.asynccontextmanager
async def _lifespan(app: FastAPI) -> AsyncIterator[None]:
    service = viewer(app)
    await service.start()
    try:
        yield
    finally:
        await service.stop()


router = APIRouter(tags=["viewer"], responses=ERROR_RESPONSES, lifespan=_lifespan)


@router.get("/viewer", operation_id="get_viewer")
async def get_viewer(request: Request) -> ViewerOut:
    return ViewerOut.model_validate(viewer(request.app).info())


@router.put("/viewer/axes/{sid}", operation_id="set_viewer_axis")
async def set_viewer_axis(sid: str, body: ViewerAxisRequest, request: Request) -> ViewerAxisOut:
    service = viewer(request.app)
    service.set_axis(sid, body.kind, body.scale)
    return ViewerAxisOut.model_validate(next(a for a in service.axes() if a["session"] == sid))
