"""PDO frames: where each mapped entry sits, and packing and unpacking the payload.

:func:`layout` places the entries at their bit offsets (CiA 301 §7.5.2.36; a fixed telegram names
its non-object words), :func:`pack` and :func:`unpack` convert between object values and the
payload in the family's byte order, :func:`frame_length` gives the bytes on the bus (padded to a
CAN FD length except for classic CANopen PDOs) and :func:`bus_cob_id` the CAN id a PDO uses.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value, codec, coerce_int
from servodesk.domain.pdo_model import Direction, Pdo, Slot
from servodesk.domain.pdo_objects import _telegram_entries, rules_of
from servodesk.domain.profile import DeviceProfile, PdoWord
from servodesk.errors import ServodeskError, ValidationError

#: CAN FD data lengths (ISO 11898-1): a PDO is padded to the next one.
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def _telegram_words(profile: DeviceProfile, pdo: Pdo) -> tuple[PdoWord, ...] | None:
    """The word names of a fixed telegram whose layout ``pdo`` carries (telegram 1's
    STW1/NSOLL_A are no objects, so only the telegram can name them)."""
    if pdo.kind != "telegram":
        return None
    for tg in rules_of(profile).telegrams:
        if tg.variable:
            continue
        words = tg.rx if pdo.direction is Direction.RX else tg.tx
        if len(words) == len(pdo.entries) and any(w.address is None for w in words):
            try:
                if _telegram_entries(profile, tg, pdo.direction) == pdo.entries:
                    return words
            except ServodeskError:
                continue
    return None


def layout(profile: DeviceProfile, pdo: Pdo) -> list[Slot]:
    """Each entry at its bit offset in the frame (CiA 301: entries follow each other)."""
    words = _telegram_words(profile, pdo)
    out: list[Slot] = []
    offset = 0
    for i, e in enumerate(pdo.entries):
        if e.is_padding:
            w = words[i] if words is not None else None
            if w is not None and w.address is None:
                name = w.name or "Reserved"
                if w.note:
                    name = f"{name} ({w.note})"
                out.append(Slot(e, offset, e.bits, None, name, w.data_type, None))
            elif e.index == 0:
                out.append(Slot(e, offset, e.bits, None, "Reserved", None, None))
            else:
                dt = DataType(e.index)
                out.append(Slot(e, offset, e.bits, None, f"dummy {dt.name}", dt, None))
        else:
            addr = ObjectAddress(e.index, e.subindex)
            spec = profile.spec(addr)
            out.append(
                Slot(
                    e,
                    offset,
                    e.bits,
                    addr,
                    spec.name if spec else f"unknown object {addr}",
                    spec.data_type if spec else None,
                    spec.unit if spec else None,
                )
            )
        offset += e.bits
    return out


def frame_length(profile: DeviceProfile, pdo: Pdo) -> int:
    """Bytes on the bus: the mapped bytes, padded to a CAN FD length except classic PDOs."""
    n = pdo.bytes
    if rules_of(profile).kind == "canopen":
        return n
    for length in FD_LENGTHS:
        if length >= n:
            return length
    raise ValidationError(
        f"{pdo.name} has {n} bytes: more than a CAN FD frame (64) carries",
        hint="map fewer objects",
    )


def _raw_of(value: Value, dt: DataType | None, bits: int, where: str) -> int:
    mask = (1 << bits) - 1
    if dt is None:
        return coerce_int(value) & mask
    if dt.is_real:
        fv = float(value) if not isinstance(value, str | bytes) else float(str(value))
        fmt = "<f" if dt is DataType.REAL32 else "<d"
        return int.from_bytes(struct.pack(fmt, fv), "little") & mask
    if not dt.is_integer:
        data = codec(dt).encode(value)
        return int.from_bytes(data[: (bits + 7) // 8].ljust((bits + 7) // 8, b"\0"), "little")
    try:
        data = codec(dt).encode(value)
    except ValidationError as exc:
        raise ValidationError(f"{where}: {exc.message}", field=where) from None
    return int.from_bytes(data, "little") & mask


def _value_of(raw: int, dt: DataType | None, bits: int) -> Value:
    if dt is None:
        return raw
    if dt is DataType.BOOLEAN:
        return bool(raw & 1)
    if dt.is_real:
        n = dt.bits // 8
        fmt = "<f" if dt is DataType.REAL32 else "<d"
        return float(struct.unpack(fmt, raw.to_bytes(n, "little"))[0])
    if dt.is_integer:
        if dt.is_signed and bits == dt.bits and raw >> (bits - 1) & 1:
            return raw - (1 << bits)
        return raw
    n = (bits + 7) // 8
    return codec(dt).decode(raw.to_bytes(n, "little"))


def pack(profile: DeviceProfile, pdo: Pdo, values: Mapping[ObjectAddress, Value]) -> bytes:
    """The PDO's payload (without CAN FD padding) from object values; a missing value is 0."""
    slots = layout(profile, pdo)
    total = sum(s.bits for s in slots)
    nbytes = (total + 7) // 8
    big = rules_of(profile).byte_order == "big"
    acc = 0
    for s in slots:
        if s.address is None or s.address not in values:
            continue
        raw = _raw_of(values[s.address], s.data_type, s.bits, str(s.address))
        if big:
            # Big-endian (004 §20.1.2): each value's bytes most significant first, the
            # entries in order from the first byte.
            acc |= raw << (nbytes * 8 - s.offset_bits - s.bits)
        else:
            # CiA 301 §7.5.2.36: entries fill the frame from bit 0 of byte 0 upwards.
            acc |= raw << s.offset_bits
    return acc.to_bytes(nbytes, "big" if big else "little")


def unpack(profile: DeviceProfile, pdo: Pdo, data: bytes) -> dict[ObjectAddress, Value]:
    """Object values from a received payload; bytes beyond the mapping (padding) are
    ignored, a frame shorter than the mapping is refused."""
    slots = layout(profile, pdo)
    total = sum(s.bits for s in slots)
    nbytes = (total + 7) // 8
    if len(data) < nbytes:
        raise ValidationError(
            f"{pdo.name}: {len(data)} bytes received, the mapping needs {nbytes}",
            hint="the drive's mapping differs from the one read; read the PDO configuration again",
        )
    big = rules_of(profile).byte_order == "big"
    acc = int.from_bytes(data[:nbytes], "big" if big else "little")
    out: dict[ObjectAddress, Value] = {}
    for s in slots:
        if s.address is None:
            continue
        mask = (1 << s.bits) - 1
        if big:
            raw = acc >> (nbytes * 8 - s.offset_bits - s.bits) & mask
        else:
            raw = acc >> s.offset_bits & mask
        out[s.address] = _value_of(raw, s.data_type, s.bits)
    return out


def bus_cob_id(profile: DeviceProfile, pdo: Pdo, node_id: int) -> int | None:
    """The CAN id the PDO uses on the (twin's) bus: its COB-ID, else 200h/180h + node id."""
    if pdo.comm is not None:
        return pdo.comm.cob_id
    return (0x200 if pdo.direction is Direction.RX else 0x180) + node_id
