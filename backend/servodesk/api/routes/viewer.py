"""3D viewer routes: where the viser viewer is, and which stage each axis is drawn as.

AppState (api/state.py) starts the viewer (services/viewer.py) once the sessions of
``serve --sim`` exist and stops it at shutdown, after motion halted the axes; that frees its
port.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_viewer import ViewerAxisOut, ViewerAxisRequest, ViewerOut
from servodesk.api.state import state_of
from servodesk.services.viewer import ViewerService


def viewer(app: Any) -> ViewerService:
    """The application's viewer service (AppState builds, starts and stops it)."""
    return state_of(app).viewer


router = APIRouter(tags=["viewer"], responses=ERROR_RESPONSES)


@router.get("/viewer", operation_id="get_viewer")
async def get_viewer(request: Request) -> ViewerOut:
    return ViewerOut.model_validate(viewer(request.app).info())


@router.put("/viewer/axes/{sid}", operation_id="set_viewer_axis")
async def set_viewer_axis(sid: str, body: ViewerAxisRequest, request: Request) -> ViewerAxisOut:
    service = viewer(request.app)
    service.set_axis(sid, body.kind, body.scale)
    return ViewerAxisOut.model_validate(next(a for a in service.axes() if a["session"] == sid))
