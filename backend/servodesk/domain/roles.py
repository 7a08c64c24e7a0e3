"""Roles and their rights: the one table of who may do what (docs/security.md, "Roles").

IEC 62443-4-2 CR 1.1 / CR 2.1 (SL 2) ask for unique user ids and permissions given to roles,
enforced on every access; the newest drive web servers ship the same shape (SINAMICS V6:
fixed roles with rights such as "control drive", "backup", "traces"). A route names the one
:class:`Right` it needs (api/rights.py); a role is a set of rights. Nothing else decides.
"""

from __future__ import annotations

from enum import StrEnum

from servodesk.errors import ValidationError


class Right(StrEnum):
    #: See drives, parameters, state, alarms, backups, profiles; watch the scope. Also stop an
    #: axis (halt, quick stop, stop a tuning): whoever sees it move may stop it
    #: (services/control.py: stopping is never refused).
    READ = "read"
    #: Reset (acknowledge) a drive's fault: CiA 402-2 §6.2 transition 15.
    ACKNOWLEDGE_ALARMS = "acknowledge_alarms"
    #: Clear the drive's error history (0x1003): evidence of what happened is erased.
    CLEAR_ALARMS = "clear_alarms"
    #: Scan buses, open and close sessions to drives, find PROFINET devices by DCP.
    CONNECT = "connect"
    #: Take and release control of a drive (services/control.py): every change of a drive
    #: needs it, so every role that may change anything has it (the operator, to acknowledge).
    TAKE_CONTROL = "take_control"
    #: Servo on and off (state commands), jog and homing: the commissioning moves a service
    #: technician makes (a jog needs Operation enabled: CiA 402-2 §6.2).
    JOG_HOME = "jog_home"
    #: Make, upload, label and download backups.
    BACKUP = "backup"
    #: Restore a backup onto a drive.
    RESTORE = "restore"
    #: Write objects and parameters, import profiles, set a PROFINET name or address.
    WRITE_PARAMETERS = "write_parameters"
    #: Free moves: target positions, velocity, torque and cyclic set-points.
    CONTROL_DRIVE = "control_drive"
    #: Tuning runs and their results; the scope's channels, trigger and runs.
    TUNE = "tune"
    #: PDO mapping and cyclic process data.
    PDO = "pdo"
    #: Store parameters to the drive's non-volatile memory (0x1010) or restore its defaults.
    SAVE_EEPROM = "save_eeprom"
    #: Take control over from another user (force_take); the previous holder's motion stops.
    FORCE_CONTROL = "force_control"
    #: Accounts and everyone's login sessions.
    MANAGE_USERS = "manage_users"
    #: Read and export the audit log.
    READ_AUDIT = "read_audit"


class Role(StrEnum):
    ADMINISTRATOR = "administrator"
    ENGINEER = "engineer"
    SERVICE = "service"
    OPERATOR = "operator"
    GUEST = "guest"


_GUEST = frozenset({Right.READ})
_OPERATOR = _GUEST | {Right.TAKE_CONTROL, Right.ACKNOWLEDGE_ALARMS}
_SERVICE = _OPERATOR | {
    Right.CLEAR_ALARMS,
    Right.CONNECT,
    Right.JOG_HOME,
    Right.BACKUP,
    Right.RESTORE,
}
#: Everything on drives; not accounts, not taking control over from another user.
_ENGINEER = _SERVICE | {
    Right.WRITE_PARAMETERS,
    Right.CONTROL_DRIVE,
    Right.TUNE,
    Right.PDO,
    Right.SAVE_EEPROM,
    Right.READ_AUDIT,
}

#: The table: the rights of each role (docs/security.md prints it).
RIGHTS: dict[Role, frozenset[Right]] = {
    Role.ADMINISTRATOR: frozenset(Right),
    Role.ENGINEER: frozenset(_ENGINEER),
    Role.SERVICE: frozenset(_SERVICE),
    Role.OPERATOR: frozenset(_OPERATOR),
    Role.GUEST: _GUEST,
}


def parse_role(name: str) -> Role:
    """The role called ``name``; a ValidationError listing the roles otherwise."""
    try:
        return Role(name)
    except ValueError:
        raise ValidationError(
            f"no role {name!r}",
            field="role",
            hint="roles: " + ", ".join(r.value for r in Role),
        ) from None


def rights_of(role: str) -> frozenset[Right]:
    """The rights of ``role`` (none for a name that is not a role: fail closed)."""
    try:
        return RIGHTS[Role(role)]
    except ValueError:
        return frozenset()


def may(role: str, right: Right) -> bool:
    return right in rights_of(role)
