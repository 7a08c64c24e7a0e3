"""The status bar's numbers (issue 48; docs/api.md "Status")."""

from __future__ import annotations

from fastapi import APIRouter
from starlette.concurrency import run_in_threadpool

from servodesk.api.deps import StateDep
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_status import StatusOut
from servodesk.services.status import bus_status, store_status

router = APIRouter(tags=["status"], responses=ERROR_RESPONSES)


@router.get("/status", operation_id="get_status")
async def get_status(state: StateDep) -> StatusOut:
    """Per bus of the open sessions: link state, traffic, errors and cycle time, from counts
    the links keep (no bus traffic is made to answer it); and the store: reachable or not,
    and what waits in the gateway's local queue (no request to the database either)."""
    store = await run_in_threadpool(store_status, state.backups.store)
    return StatusOut.model_validate({"buses": bus_status(state.manager.all()), "store": store})
