"""SDO abort codes and their meaning (CiA 301 §7.2.4.3.17, table 22).

Family profiles add the non-standard codes their manuals use (error table ``sdo_abort``);
:func:`abort_text` looks there first.
"""

from __future__ import annotations

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import ObjectAccessError

ABORT_CODES: dict[int, str] = {
    0x05030000: "Toggle bit not alternated",
    0x05040000: "SDO protocol timed out",
    0x05040001: "Client/server command specifier not valid or unknown",
    0x05040002: "Invalid block size (block mode only)",
    0x05040003: "Invalid sequence number (block mode only)",
    0x05040004: "CRC error (block mode only)",
    0x05040005: "Out of memory",
    0x06010000: "Unsupported access to an object",
    0x06010001: "Attempt to read a write only object",
    0x06010002: "Attempt to write a read only object",
    0x06020000: "Object does not exist in the object dictionary",
    0x06040041: "Object cannot be mapped to the PDO",
    0x06040042: "The number and length of the objects to be mapped would exceed PDO length",
    0x06040043: "General parameter incompatibility reason",
    0x06040047: "General internal incompatibility in the device",
    0x06060000: "Access failed due to a hardware error",
    0x06070010: "Data type does not match, length of service parameter does not match",
    0x06070012: "Data type does not match, length of service parameter too high",
    0x06070013: "Data type does not match, length of service parameter too low",
    0x06090011: "Sub-index does not exist",
    0x06090030: "Invalid value for parameter (download only)",
    0x06090031: "Value of parameter written too high (download only)",
    0x06090032: "Value of parameter written too low (download only)",
    0x06090036: "Maximum value is less than minimum value",
    0x060A0023: "Resource not available: SDO connection",
    0x08000000: "General error",
    0x08000020: "Data cannot be transferred or stored to the application",
    0x08000021: "Data cannot be transferred or stored to the application because of local control",
    0x08000022: (
        "Data cannot be transferred or stored to the application because of the present "
        "device state"
    ),
    0x08000023: "Object dictionary dynamic generation fails or no object dictionary is present",
    0x08000024: "No data available",
}

# What a user can do about the common ones.
ABORT_HINTS: dict[int, str] = {
    0x06010002: "the object is read-only; choose a writable object",
    0x06010001: "the object is write-only; it cannot be read back",
    0x06020000: "check the index against the profile's object dictionary",
    0x06090011: "check the subindex; read subindex 0 for the number of entries",
    0x06090030: "the drive refused the value; see the object's allowed values",
    0x06090031: "the value is above the object's maximum",
    0x06090032: "the value is below the object's minimum",
    0x06070010: "the value's size does not match the object's data type",
    0x06070012: "the value has more bytes than the object's data type",
    0x06070013: "the value has fewer bytes than the object's data type",
    0x08000022: (
        "the drive refuses this in its present state (e.g. disable it or go to PRE-OPERATIONAL)"
    ),
    0x05040000: "the drive did not answer in time; check the node id, bitrate and cabling",
}


def abort_text(code: int, profile: DeviceProfile | None = None) -> str:
    if profile is not None:
        e = profile.error("sdo_abort", code)
        if e is not None:
            return e.name
    return ABORT_CODES.get(code, "Unknown abort code")


def abort_error(code: int, address: ObjectAddress, op: str) -> ObjectAccessError:
    """The error a link raises when the drive aborts an SDO (CANopen, or carried by SLMP)."""
    meaning = abort_text(code)
    return ObjectAccessError(
        f"{op} {address} refused by the drive: {meaning} (0x{code:08X})",
        code=code,
        meaning=meaning,
        protocol="sdo",
        address=str(address),
        hint=ABORT_HINTS.get(code),
    )
