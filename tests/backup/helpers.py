"""Changing a drive's parameters the way a user would (through the session)."""

from __future__ import annotations

from servodesk.domain import restore_plan
from servodesk.domain.address import ObjectAddress as A
from servodesk.domain.datatypes import codec
from servodesk.domain.paramset import ParameterSet
from servodesk.domain.values import check_value
from servodesk.errors import ObjectAccessError, ValidationError
from servodesk.services.session import Session


async def change_plain(session: Session, ps: ParameterSet, count: int) -> list[A]:
    """Change ``count`` plain integer parameters to other valid values; returns them."""
    changed: list[A] = []
    for e in ps.entries:
        spec = session.profile.spec(e.address)
        if (
            spec is None
            or not spec.data_type.is_integer
            or spec.writable_in
            or restore_plan.is_pdo_object(e.address.index)
            or spec.values
        ):
            continue
        v = codec(spec.data_type).decode(e.raw)
        assert isinstance(v, int)
        for nv in (v + 1, v - 1):
            try:
                check_value(spec, nv)
                await session.write_object(e.address, nv, client="test-user")
            except (ValidationError, ObjectAccessError):
                continue
            changed.append(e.address)
            break
        if len(changed) == count:
            break
    return changed


async def change_pdo(session: Session) -> list[A]:
    """Disable RPDO 1 (COB-ID bit 31), empty its mapping and change entry 1 (CiA 301)."""
    prof = session.profile
    if prof.spec(A(0x1600, 2)) is None or not prof.spec(A(0x1600, 0)).access.writable:  # type: ignore[union-attr]
        return []
    changed: list[A] = []
    if prof.spec(A(0x1400, 1)) is not None:
        cob = int.from_bytes(
            bytes.fromhex((await session.read_object(A(0x1400, 1))).raw_hex), "little"
        )
        await session.write_object(A(0x1400, 1), cob | 0x80000000, client="test-user")
        changed.append(A(0x1400, 1))
    second = (await session.read_object(A(0x1600, 2))).raw_hex
    first = (await session.read_object(A(0x1600, 1))).raw_hex
    await session.write_object(A(0x1600, 0), 0, client="test-user")
    changed.append(A(0x1600, 0))
    if second != first and int(second, 16):
        await session.write_object(A(0x1600, 1), raw_hex=second, client="test-user")
        changed.append(A(0x1600, 1))
    return changed
