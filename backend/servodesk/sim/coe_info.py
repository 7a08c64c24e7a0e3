"""The CoE SDO Information service of a simulated slave (ETG.1000.6 §5.6.3).

What a master reads to learn a slave's object dictionary without its ESI (SOEM's
``ecx_readODlist``, ``ecx_readODdescription``, ``ecx_readOE``; pysoem's ``slave.od``):

- Get OD List (opcode 1 -> 2): the list type (0 the counts of lists 1-5, 1 all objects,
  2 RxPDO-mappable, 3 TxPDO-mappable, 4 stored for a device replacement, 5 startup
  parameters), then the indices, UNSIGNED16 each; fragmented over several mailbox answers
  where they do not fit one (the header's "incomplete" bit 7 and fragments left).
- Get Object Description (3 -> 4): index, data type, max subindex, object code (7 VAR,
  8 ARRAY, 9 RECORD), name.
- Get Entry Description (5 -> 6): index, subindex, value info (none given: 0), data type,
  bit length, object access (bits 0-2 readable in PRE-OP / SAFE-OP / OP, 3-5 writable,
  6 RxPDO-, 7 TxPDO-mappable, 8 backup), name.
- An index or subindex the drive does not have: SDO Info Error Request (7) with the abort
  code (0602 0000h, 0609 0011h).
"""

from __future__ import annotations

from servodesk.domain.address import ObjectAddress
from servodesk.domain.ethercat import CoeService
from servodesk.domain.profile import DeviceProfile, ObjectSpec, ObjectType

__all__ = ["INFO_HEADER", "answers"]

#: CoE header (2 bytes) and SDO Information header (opcode, reserved, fragments left).
INFO_HEADER = 6
_ODLIST_REQ, _ODLIST_RES = 1, 2
_OD_REQ, _OD_RES = 3, 4
_OE_REQ, _OE_RES = 5, 6
_ERROR = 7
_INCOMPLETE = 0x80
_OBJECT_CODES = {ObjectType.VAR: 7, ObjectType.ARRAY: 8, ObjectType.RECORD: 9}


def _message(opcode: int, fragments_left: int, payload: bytes) -> bytes:
    head = (CoeService.SDO_INFO << 12).to_bytes(2, "little")
    flag = _INCOMPLETE if fragments_left else 0
    return head + bytes([opcode | flag, 0]) + fragments_left.to_bytes(2, "little") + payload


def _error(code: int) -> list[bytes]:
    return [_message(_ERROR, 0, code.to_bytes(4, "little"))]


def _access(spec: ObjectSpec) -> int:
    bits = 0
    if spec.access.readable:
        bits |= 0x07
    if spec.access.writable:
        bits |= 0x38
    if spec.pdo_mapping.rx:
        bits |= 0x40
    if spec.pdo_mapping.tx:
        bits |= 0x80
    if spec.persist:
        bits |= 0x100
    return bits


def _indices(profile: DeviceProfile, list_type: int) -> list[int]:
    def keep(index: int) -> bool:
        specs = [s for a, s in profile.variables.items() if a.index == index]
        if list_type == 2:
            return any(s.pdo_mapping.rx for s in specs)
        if list_type == 3:
            return any(s.pdo_mapping.tx for s in specs)
        if list_type in (4, 5):
            return any(s.persist for s in specs)
        return True

    return [e.index for e in profile.objects if keep(e.index)]


def answers(profile: DeviceProfile, data: bytes, room: int) -> list[bytes]:
    """The SDO Information answers (CoE header on) to the request ``data``; ``room`` is the
    payload an answer may carry after its SDO Information header (SM1's length less the
    mailbox, CoE and SDO Information headers)."""
    if len(data) < INFO_HEADER:
        return _error(0x05040001)
    opcode, body = data[2] & 0x7F, data[INFO_HEADER:]
    if opcode == _ODLIST_REQ and len(body) >= 2:
        list_type = int.from_bytes(body[:2], "little")
        if list_type == 0:
            counts = [len(_indices(profile, t)) for t in range(1, 6)]
            words = b"".join(c.to_bytes(2, "little") for c in counts)
        elif 1 <= list_type <= 5:
            words = b"".join(i.to_bytes(2, "little") for i in _indices(profile, list_type))
        else:
            return _error(0x06090030)
        payload = body[:2] + words
        step = max(2, room - room % 2)
        parts = [payload[k : k + step] for k in range(0, len(payload), step)] or [payload]
        return [_message(_ODLIST_RES, len(parts) - 1 - n, part) for n, part in enumerate(parts)]
    if opcode == _OD_REQ and len(body) >= 2:
        index = int.from_bytes(body[:2], "little")
        entry = profile.entries.get(index)
        if entry is None:
            return _error(0x06020000)
        specs = [s for a, s in profile.variables.items() if a.index == index]
        max_sub = max(s.subindex for s in specs)
        element = next((s for s in specs if s.subindex == 1), specs[0])
        data_type = int(specs[0].data_type) if entry.object_type is ObjectType.VAR else 0
        if entry.object_type is ObjectType.ARRAY:
            data_type = int(element.data_type)
        head = (
            index.to_bytes(2, "little")
            + data_type.to_bytes(2, "little")
            + bytes([max_sub, _OBJECT_CODES[entry.object_type]])
        )
        name = entry.name.encode("ascii", "replace")[: max(0, room - len(head))]
        return [_message(_OD_RES, 0, head + name)]
    if opcode == _OE_REQ and len(body) >= 4:
        index, sub = int.from_bytes(body[:2], "little"), body[2]
        if index not in profile.entries:
            return _error(0x06020000)
        spec = profile.spec(ObjectAddress(index, sub))
        if spec is None:
            return _error(0x06090011)
        head = (
            body[:3]
            + bytes([0])  # No value info (unit, default, minimum, maximum) given.
            + int(spec.data_type).to_bytes(2, "little")
            + spec.bits.to_bytes(2, "little")
            + _access(spec).to_bytes(2, "little")
        )
        name = spec.name.encode("ascii", "replace")[: max(0, room - len(head))]
        return [_message(_OE_RES, 0, head + name)]
    return _error(0x05040001)  # Command specifier not valid (ETG.1000.6 table 41).
