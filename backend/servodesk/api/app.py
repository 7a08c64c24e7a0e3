"""Application assembly: ``create_app(settings)`` wires services, routes and the UI."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import AsyncIterator
from pathlib import Path

from fastapi import Depends, FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

from servodesk import __version__
from servodesk.api import access_log, errors
from servodesk.api.audit_requests import AuditRequests
from servodesk.api.auth import AuthMiddleware
from servodesk.api.body_limit import BodyLimit
from servodesk.api.hsts import Hsts
from servodesk.api.rights import check_route_right
from servodesk.api.routes import (
    audit,
    auth,
    backups,
    dcp,
    fleet,
    motion,
    operation,
    pdo,
    scope,
    sessions,
    stop_all,
    system,
    tuning,
    viewer,
)
from servodesk.api.same_origin import SameOriginGuard
from servodesk.api.scope_ws import router as scope_ws_router
from servodesk.api.state import AppState
from servodesk.api.ws import router as ws_router
from servodesk.hosts import HostPolicy
from servodesk.settings import Settings

log = logging.getLogger(__name__)

WEB_DIST = Path(__file__).resolve().parent.parent / "web" / "dist"

_NO_UI = """<!doctype html><title>servodesk</title>
<h1>servodesk API is running</h1>
<p>The browser UI has not been built. Run <code>make build</code> (or
<code>cd frontend && npm ci && npm run build</code>) and reload. The API docs are at
<a href="/docs">/docs</a>.</p>"""


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    # The composition root: every service, and the one order they stop in (api/state.py).
    state = AppState.build(settings)

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        try:
            await state.start()
            yield
        finally:
            # Also after a failed start: what did start (drives, sweeper) stops again.
            await state.aclose()

    app = FastAPI(
        title="servodesk",
        version=__version__,
        description="Commissioning API for CiA 402 servo drives.",
        lifespan=lifespan,
        docs_url=None,
        redoc_url=None,
        # Every route's right, from one table (api/rights.py, docs/security.md "Roles").
        dependencies=[Depends(check_route_right)],
    )
    app.state.servodesk = state
    errors.install(app)
    # No router has a lifespan of its own: AppState starts and stops every service, in one
    # documented order (tuning, motion, scope, viewer, sessions, store; api/state.py).
    app.include_router(system.router, prefix="/api/v1")
    app.include_router(auth.router, prefix="/api/v1")  # Users, login sessions, API tokens.
    app.include_router(sessions.router, prefix="/api/v1")
    app.include_router(dcp.router, prefix="/api/v1")
    app.include_router(backups.router, prefix="/api/v1")
    app.include_router(audit.router, prefix="/api/v1")
    app.include_router(fleet.router, prefix="/api/v1")  # Drives of every gateway, drift.
    app.include_router(ws_router, prefix="/api/v1")
    app.include_router(operation.router, prefix="/api/v1")
    app.include_router(viewer.router, prefix="/api/v1")
    app.include_router(pdo.router, prefix="/api/v1")
    app.include_router(scope.router, prefix="/api/v1")
    app.include_router(scope_ws_router, prefix="/api/v1")
    app.include_router(motion.router, prefix="/api/v1")
    app.include_router(stop_all.router, prefix="/api/v1")  # The header's global stop.
    app.include_router(tuning.router, prefix="/api/v1")

    swagger = WEB_DIST / "vendor" / "swagger-ui"

    @app.get("/docs", include_in_schema=False)
    async def docs() -> HTMLResponse:
        # Served from the bundled swagger-ui-dist so the docs work offline.
        if (swagger / "swagger-ui-bundle.js").is_file():
            return get_swagger_ui_html(
                openapi_url="/openapi.json",
                title="servodesk API",
                swagger_js_url="/vendor/swagger-ui/swagger-ui-bundle.js",
                swagger_css_url="/vendor/swagger-ui/swagger-ui.css",
                swagger_favicon_url="/favicon.svg",
            )
        return HTMLResponse(
            "<p>The offline API docs need the built frontend (make build). "
            'The schema is at <a href="/openapi.json">/openapi.json</a>.</p>'
        )

    if (WEB_DIST / "index.html").is_file():
        app.mount("/", StaticFiles(directory=WEB_DIST, html=True), name="ui")
    else:

        @app.get("/", include_in_schema=False)
        async def no_ui() -> HTMLResponse:
            return HTMLResponse(_NO_UI)

    # Outermost last: the same-origin checks, then authentication, then the body limit, so
    # that nothing reads a body of a request refused before (docs/security.md).
    app.add_middleware(BodyLimit)
    app.add_middleware(AuthMiddleware, auth=state.auth)
    app.add_middleware(
        SameOriginGuard,
        policy=HostPolicy.for_server(settings.host, settings.allowed_hosts),
        port=settings.port,
    )
    if settings.https:
        app.add_middleware(Hsts)
    # Outermost: it records what every check inside refuses (docs/security.md, Audit log).
    app.add_middleware(AuditRequests, audit=state.audit)
    access_log.install()  # ?token= never reaches uvicorn's log.
    return app
