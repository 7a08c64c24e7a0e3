"""The right each route needs: one table, checked in one place (docs/security.md, "Roles").

IEC 62443-4-2 CR 2.1 asks that every access is checked against the permissions of the
caller's role. :data:`ROUTE_RIGHTS` names, per route (its ``operation_id``, or its function's
name for a WebSocket), the one :class:`~servodesk.domain.roles.Right` it needs;
:func:`check_route_right` is a dependency of the whole application (api/app.py), so no route
can be added without passing it. A route missing from the table needs
:attr:`Right.MANAGE_USERS` (administrators only) until someone writes it down: fail closed.

Reading is :attr:`Right.READ`. Stopping an axis (halt, quick stop, stopping a tuning) is READ
too: whoever may see a drive may stop it (services/control.py: stopping is never refused).
"""

from __future__ import annotations

from typing import Any

from fastapi import Depends
from starlette.requests import HTTPConnection

from servodesk.api.identity import Caller, caller_of
from servodesk.domain.roles import Right, rights_of
from servodesk.errors import Forbidden

R = Right

#: Routes anyone may reach before logging in (the login itself, the offline API docs page).
PUBLIC = frozenset({"login", "docs", "no_ui", "openapi"})

#: operation_id (or WebSocket function name) -> the right it needs.
ROUTE_RIGHTS: dict[str, Right] = {
    # system.py
    "health": R.READ,
    "list_profiles": R.READ,
    "get_profile": R.READ,
    "export_profile": R.READ,
    "import_profile": R.WRITE_PARAMETERS,
    # sessions.py
    "scan_bus": R.CONNECT,
    "list_sessions": R.READ,
    # status.py
    "get_status": R.READ,
    "open_session": R.CONNECT,
    "get_session": R.READ,
    "get_session_profile": R.READ,
    "close_session": R.CONNECT,
    "read_object": R.READ,
    "write_object": R.WRITE_PARAMETERS,
    "read_objects": R.READ,
    "store_parameters": R.SAVE_EEPROM,
    "restore_defaults": R.SAVE_EEPROM,
    "get_state": R.READ,
    "command_state": R.JOG_HOME,  # Servo on/off: a jog needs Operation enabled.
    # dcp.py
    "dcp_identify": R.CONNECT,
    "dcp_signal": R.CONNECT,
    "dcp_set": R.WRITE_PARAMETERS,
    "dcp_reset": R.WRITE_PARAMETERS,
    # backups.py
    "create_backup": R.BACKUP,
    "create_plant_backup": R.BACKUP,
    "list_backups": R.READ,
    "upload_backup": R.BACKUP,
    "get_backup": R.READ,
    "download_backup": R.READ,
    "update_backup": R.BACKUP,
    "compare": R.READ,
    "restore_preflight": R.READ,  # What a restore would change; writes nothing.
    "restore": R.RESTORE,
    "get_restore": R.READ,
    "resume_restore": R.RESTORE,
    "list_parameter_writes": R.READ_AUDIT,  # Who wrote what (docs/backup.md).
    # fleet.py (every drive of the store; approving a backup is an engineer's decision)
    "list_fleet": R.READ,
    "list_gateways": R.READ,
    "list_drift": R.READ,
    "set_plant_tag": R.WRITE_PARAMETERS,
    "approve_backup": R.WRITE_PARAMETERS,
    "clear_approval": R.WRITE_PARAMETERS,  # Undoes an approval: the same decision's right.
    "check_drift": R.BACKUP,  # Reads the drive as a backup does; writes nothing to it.
    # reports.py: a report holds the drive's audit extract (who did what), so it is read
    # with the audit log's right; making one also needs BACKUP (the route asks for it).
    "create_report": R.READ_AUDIT,
    "get_report": R.READ_AUDIT,
    "report_html": R.READ_AUDIT,
    "report_pdf": R.READ_AUDIT,
    # audit.py (the audit log, IEC 62443-4-2 CR 2.8)
    "list_audit": R.READ_AUDIT,
    "verify_audit": R.READ_AUDIT,
    "export_audit": R.READ_AUDIT,
    # motion.py
    "get_control": R.READ,
    "set_control": R.TAKE_CONTROL,
    "jog": R.JOG_HOME,
    "move": R.CONTROL_DRIVE,
    "run_velocity": R.CONTROL_DRIVE,
    "run_torque": R.CONTROL_DRIVE,
    "run_cyclic": R.CONTROL_DRIVE,
    "halt": R.READ,
    "quick_stop": R.READ,
    "stop_all": R.READ,  # routes/stop_all.py: every axis the caller controls, never refused.
    "get_motion": R.READ,
    "get_limits": R.READ,
    # operation.py
    "homing_methods": R.READ,
    "start_homing": R.JOG_HOME,
    "homing_plan": R.READ,
    "homing_status": R.READ,
    "get_alarms": R.READ,
    "reset_alarms": R.ACKNOWLEDGE_ALARMS,
    "clear_alarm_history": R.CLEAR_ALARMS,
    # pdo.py
    "pdo_view": R.READ,
    "pdo_mappable": R.READ,
    "pdo_templates": R.READ,
    "pdo_from_template": R.READ,  # Fills a layout in from a template; writes nothing.
    "pdo_validate": R.READ,
    "pdo_plan": R.READ,
    "pdo_apply": R.PDO,
    "pdo_export": R.READ,
    "pdo_cyclic_status": R.READ,
    "pdo_cyclic_start": R.PDO,
    "pdo_cyclic_stop": R.PDO,
    "pdo_cyclic_outputs": R.PDO,
    # scope.py (the scope is one for the whole server: configuring it is tuning work)
    "scope_status": R.READ,
    "scope_set_channels": R.TUNE,
    "scope_set_trigger": R.TUNE,
    "scope_run": R.TUNE,
    "scope_capture": R.READ,
    "scope_export": R.READ,
    "scope_import": R.TUNE,
    "scope_recorder": R.READ,
    # Kept scope captures (issue 49): the store's, with the backups' rights; deleting one
    # is a backup's change too (with a reason, audited).
    "keep_scope_capture": R.BACKUP,
    "list_scope_captures": R.READ,
    "get_scope_capture": R.READ,
    "export_scope_capture": R.READ,
    "attach_scope_capture": R.BACKUP,
    "delete_scope_capture": R.BACKUP,
    # tuning.py
    "tuning_info": R.READ,
    "tuning_start": R.TUNE,
    "tuning_stop": R.READ,
    "tuning_result": R.READ,
    "tuning_results": R.READ,  # The store's tunings of the drive (issue 49).
    "tuning_stored_result": R.READ,
    "tuning_undo": R.TUNE,
    "tuning_store": R.TUNE,
    # viewer.py (what the 3D view shows; moves nothing)
    "get_viewer": R.READ,
    "set_viewer_axis": R.READ,
    # WebSockets (ws.py, scope_ws.py): watching.
    "websocket": R.READ,
    "scope_socket": R.READ,
    # auth.py: everyone logged in manages their own session and API tokens.
    "logout": R.READ,
    "me": R.READ,
    "list_tokens": R.READ,
    "create_token": R.READ,
    "delete_token": R.READ,
    "list_users": R.MANAGE_USERS,
    "create_user": R.MANAGE_USERS,
    "update_user": R.MANAGE_USERS,
    "delete_user": R.MANAGE_USERS,
    "list_login_sessions": R.MANAGE_USERS,
    "end_login_session": R.MANAGE_USERS,
}


def route_key(conn: HTTPConnection) -> str | None:
    """The table's key of the route this request reached (None: no route, e.g. a 404)."""
    route: Any = conn.scope.get("route")
    if route is None:
        return None
    return getattr(route, "operation_id", None) or getattr(route, "name", None)


def right_for(key: str | None) -> Right | None:
    """The right route ``key`` needs; None for a public route."""
    if key in PUBLIC:
        return None
    if key is None:
        return Right.MANAGE_USERS
    return ROUTE_RIGHTS.get(key, Right.MANAGE_USERS)


def demand(who: Caller, right: Right) -> None:
    """Raise :class:`Forbidden` unless ``who``'s role has ``right``."""
    if right not in rights_of(who.role):
        raise Forbidden(
            f"{who.role} {who.user!r} lacks the right {right.value!r} this request needs",
            right=right.value,
            role=who.role,
            hint="ask an administrator for a role with that right (docs/security.md, Roles)",
        )


async def check_route_right(conn: HTTPConnection) -> None:
    """The application-wide dependency: the caller's role must have the route's right.

    For a WebSocket the refusal is raised before it is accepted; FastAPI then closes the
    upgrade (code 1008, policy violation)."""
    right = right_for(route_key(conn))
    if right is not None:
        demand(caller_of(conn), right)


def require(right: Right) -> Any:
    """``Depends(require(Right.X))`` for a check beside the table (a route that needs a
    second right in some case, e.g. force_take)."""

    async def dep(conn: HTTPConnection) -> Caller:
        who = caller_of(conn)
        demand(who, right)
        return who

    return Depends(dep)
