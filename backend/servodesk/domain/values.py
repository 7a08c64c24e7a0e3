"""Typed values of objects: validation before a write, and the value views of a read.

Validation follows the profile (access, data type, min/max, enumerations) so that a bad value
is refused before anything reaches the bus. The views of a read are the typed value, the raw
bytes in hex, and the engineering value (raw * scale, in ``unit``) side by side.
"""

from __future__ import annotations

from dataclasses import dataclass

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value, codec, coerce_float, coerce_int
from servodesk.domain.profile import ObjectSpec
from servodesk.domain.sdo_abort import ABORT_CODES
from servodesk.errors import ObjectAccessError, ValidationError


@dataclass(frozen=True, slots=True)
class ObjectValue:
    address: ObjectAddress
    name: str | None
    data_type: str | None
    access: str | None
    value: int | float | bool | str | None
    raw_hex: str
    engineering: float | None
    unit: str | None
    raw_unit: str | None
    value_text: str | None


def describe(address: ObjectAddress, spec: ObjectSpec | None, raw: bytes) -> ObjectValue:
    """All views of the bytes read from ``address``."""
    value: int | float | bool | str | None = None
    engineering: float | None = None
    text: str | None = None
    if spec is not None:
        try:
            decoded = codec(spec.data_type).decode(raw)
        except ValidationError:
            decoded = None
        value = decoded.hex() if isinstance(decoded, bytes) else decoded
        if spec.unit and isinstance(value, int | float) and not isinstance(value, bool):
            engineering = float(value) * spec.scale
        if spec.values and isinstance(value, int):
            text = spec.values.get(int(value))
    return ObjectValue(
        address=address,
        name=spec.name if spec else None,
        data_type=spec.data_type.name if spec else None,
        access=spec.access.value if spec else None,
        value=value,
        raw_hex=raw.hex(),
        engineering=engineering,
        unit=spec.unit if spec else None,
        raw_unit=spec.raw_unit if spec else None,
        value_text=text,
    )


def encode_write(
    address: ObjectAddress,
    spec: ObjectSpec | None,
    value: Value | None = None,
    raw_hex: str | None = None,
) -> bytes:
    """Validate a write against the profile and return the bytes to send.

    Exactly one of ``value`` (typed) and ``raw_hex`` (little-endian bytes as the device
    holds them) is given. An object the profile does not know takes raw bytes only.
    """
    if (value is None) == (raw_hex is None):
        raise ValidationError(
            "give either a value or raw_hex",
            field="value",
            hint='send {"value": 1000} or {"raw_hex": "e8030000"}',
        )
    if spec is not None and not spec.access.writable:
        # Refused before the bus, but reported with the abort code the drive would send
        # (CiA 301 0601 0002h) so the user sees the familiar code and text.
        code = 0x06010002
        raise ObjectAccessError(
            f"write {address} {spec.name} refused: {ABORT_CODES[code]} "
            f"(the profile marks it {spec.access.value}; nothing was sent)",
            code=code,
            meaning=ABORT_CODES[code],
            protocol="profile",
            address=str(address),
            hint="choose a writable object",
        )
    if value is not None and spec is not None:
        check_kind(spec, value)
    if raw_hex is not None:
        try:
            data = bytes.fromhex(raw_hex.replace(" ", "").removeprefix("0x"))
        except ValueError:
            raise ValidationError(
                f"{raw_hex!r} is not hex bytes", field="raw_hex", hint="write bytes like e8 03"
            ) from None
        if spec is None:
            return data
        if spec.bits and len(data) != spec.bits // 8:
            raise ValidationError(
                f"{address} {spec.name} is {spec.data_type.name} ({spec.bits // 8} bytes); "
                f"{len(data)} bytes given",
                field="raw_hex",
            )
        value = codec(spec.data_type).decode(data) if spec.data_type.is_numeric else None
        if value is None:
            return data
    assert value is not None
    if spec is None:
        raise ValidationError(
            f"{address} is not in the session's profile; its type is unknown",
            field="value",
            hint="write raw bytes with raw_hex, or choose the right profile",
        )
    dt = spec.data_type
    checked = check_value(spec, value)
    try:
        return codec(dt).encode(checked)
    except ValidationError as exc:
        raise ValidationError(f"{address} {spec.name}: {exc.message}", field="value") from exc


def check_kind(spec: ObjectSpec, value: Value) -> None:
    """Refuse a written value that is not of the object's kind (docs/api.md, PUT objects).

    JSON has true/false, numbers and text, and each goes only where it means what it says:
    true/false (or 0/1, CiA 301 §7.1.4.1) to BOOLEAN, numbers to integer and real objects,
    text to string objects, hex text (the form a read shows them in) to OCTET_STRING and
    DOMAIN. So ``true`` is never written as 1 to an integer object, nor "0x10" as 16: a
    number in hex goes as ``raw_hex``, the bytes as the drive holds them.
    """
    dt = spec.data_type
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if dt is DataType.BOOLEAN:
        ok, expected = isinstance(value, bool) or (number and value in (0, 1)), "true or false"
    elif dt.is_numeric:
        ok, expected = number, "a number"
    elif dt.is_string:
        ok, expected = isinstance(value, str), "text"
    else:
        ok, expected = isinstance(value, str | bytes), "hex text of its bytes"
    if not ok:
        raise ValidationError(
            f"{spec.address} {spec.name} is {dt.name}: it takes {expected}, not {value!r}",
            field="value",
            hint='send a JSON number such as {"value": 16}, or the bytes as raw_hex '
            '(little-endian, e.g. {"raw_hex": "10000000"})'
            if dt.is_numeric
            else f"send {expected}",
        )
    if dt is DataType.VISIBLE_STRING and isinstance(value, str):
        try:
            value.encode("latin-1")  # What the codec sends; it would put "?" for the rest.
        except UnicodeEncodeError:
            raise ValidationError(
                f"{spec.address} {spec.name} is VISIBLE_STRING: {value!r} has characters it "
                "cannot hold",
                field="value",
                hint="use ASCII characters",
            ) from None


def check_value(spec: ObjectSpec, value: Value) -> Value:
    """Coerce ``value`` to the spec's type and check the profile's limits."""
    dt = spec.data_type
    where = f"{spec.address} {spec.name}"
    typed: Value
    if dt.is_integer:
        try:
            typed = coerce_int(value, dt)
        except ValidationError as exc:
            raise ValidationError(f"{where}: {exc.message}", field="value") from exc
    elif dt.is_real:
        try:
            typed = coerce_float(value)
        except ValidationError as exc:
            raise ValidationError(f"{where}: {exc.message}", field="value") from exc
    else:
        return value
    lo, hi = spec.limits()
    unit = f" {spec.raw_unit}" if spec.raw_unit else ""
    if lo is not None and typed < lo:
        raise ValidationError(
            f"{where}: {typed}{unit} is below the minimum {lo}{unit}",
            field="value",
            hint=f"allowed range {lo} .. {hi}",
        )
    if hi is not None and typed > hi:
        raise ValidationError(
            f"{where}: {typed}{unit} is above the maximum {hi}{unit}",
            field="value",
            hint=f"allowed range {lo} .. {hi}",
        )
    if spec.values and dt.is_integer and spec.index in _CLOSED_ENUMS and typed not in spec.values:
        allowed = ", ".join(f"{k} ({v})" for k, v in sorted(spec.values.items()))
        raise ValidationError(
            f"{where}: {typed} is not an allowed value", field="value", hint=f"allowed: {allowed}"
        )
    return typed


# Objects whose documented value list is closed (anything else is refused by the drive).
# CiA 402-2: modes of operation (6060h) and homing method (6098h).
_CLOSED_ENUMS = frozenset({0x6060, 0x6098})
