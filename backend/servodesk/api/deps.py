"""FastAPI dependencies: the application state (api/state.py) as a typed alias."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from servodesk.api.state import AppState, state_of

__all__ = ["AppState", "StateDep", "get_state"]


def get_state(request: Request) -> AppState:
    return state_of(request.app)


StateDep = Annotated[AppState, Depends(get_state)]
