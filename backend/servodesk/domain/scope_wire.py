"""The scope's binary WebSocket frame format: the one source of truth (docs/scope.md "Wire format").

The layout is data (:data:`HEADER_FIELDS`, :data:`BLOCK_FIELDS` and the codes below): the
structs here are built from it, and scripts/gen_scope_wire.py writes it out as
``frontend/src/scope/layout.gen.ts``, which the browser's decoder (``frontend/src/scope/wire.ts``)
reads its offsets and codes from; ``make typecheck`` fails when that file is stale. A status
frame's JSON body is ``ScopeStatusFrame`` in openapi.json (api/schemas_scope.py), so its type in
the UI is generated too. tests/scope/test_scope_wire.py holds the golden bytes and writes the
fixture the TypeScript test decodes (tests/data/scope/).

Layout, little-endian::

    header (32 bytes)
      0  magic    4s   b"SDSC"
      4  version  u8   1
      5  kind     u8   1 samples, 2 capture, 3 status (UTF-8 JSON body)
      6  flags    u16  bit 0: frames were skipped for this client before this one
      8  seq      u32  per client, +1 per frame sent
     12  skipped  u32  frames skipped for this client so far
     16  nchan    u16  channel blocks that follow
     18  reserved u16  0
     20  (pad)    u32  0
     24  t_ref    f64  reference time (s, backend clock); channel times are offsets from it
    per channel block (24 bytes, then the arrays)
      0  id       u8   channel id
      1  source   u8   1 pdo, 2 sdo, 3 recorder
      2  reserved u16  0
      4  n        u32  samples
      8  dt       f64  sample period (s) when equidistant, else 0 and the times follow
     16  t0       f64  offset of the first sample from t_ref (s)
     24  times    f64[n]  offsets from t_ref, only when dt == 0
         values   f64[n]  raw values

The field list of docs/scope.md adds up to 28 header bytes while it states 32; the 4 padding bytes
at offset 20 make up the difference and put ``t_ref`` and every f64 array of the frame on an 8-byte
boundary, so the browser can view them as ``Float64Array`` without copying. Reserved and padding
bytes are written as 0 and ignored when decoding.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from servodesk.errors import ValidationError

FloatArray = npt.NDArray[np.float64]

MAGIC = b"SDSC"
VERSION = 1
SUBPROTOCOL = "servodesk.scope.v1"

KIND_SAMPLES = 1
KIND_CAPTURE = 2
KIND_STATUS = 3
KINDS = (KIND_SAMPLES, KIND_CAPTURE, KIND_STATUS)

FLAG_SKIPPED = 0x0001

SOURCE_PDO = 1
SOURCE_SDO = 2
SOURCE_RECORDER = 3
SOURCE_CODES = {"pdo": SOURCE_PDO, "sdo": SOURCE_SDO, "recorder": SOURCE_RECORDER}
SOURCE_NAMES = {code: name for name, code in SOURCE_CODES.items()}


@dataclass(frozen=True)
class WireField:
    """One fixed field of the header or of a channel block: its name, its type (``struct``
    code, little-endian) and what it holds."""

    name: str
    code: str
    doc: str


#: The frame header, in order (32 bytes; the module's docstring draws it).
HEADER_FIELDS: tuple[WireField, ...] = (
    WireField("magic", "4s", 'b"SDSC"'),
    WireField("version", "B", "format version (1)"),
    WireField("kind", "B", "1 samples, 2 capture, 3 status (UTF-8 JSON body)"),
    WireField("flags", "H", "bit 0: frames were skipped for this client before this one"),
    WireField("seq", "I", "per client, +1 per frame sent"),
    WireField("skipped", "I", "frames skipped for this client so far"),
    WireField("nchan", "H", "channel blocks that follow"),
    WireField("reserved", "H", "0"),
    WireField("pad", "I", "0: puts t_ref and every array on an 8-byte boundary"),
    WireField("t_ref", "d", "reference time (s, backend clock); channel times are offsets"),
)
#: A channel block's fixed part, in order (24 bytes; ``times`` and ``values`` follow it).
BLOCK_FIELDS: tuple[WireField, ...] = (
    WireField("id", "B", "channel id"),
    WireField("source", "B", "1 pdo, 2 sdo, 3 recorder"),
    WireField("reserved", "H", "0"),
    WireField("n", "I", "samples"),
    WireField("dt", "d", "sample period (s) when equidistant, else 0 and the times follow"),
    WireField("t0", "d", "offset of the first sample from t_ref (s)"),
)


def _struct(fields: Sequence[WireField]) -> struct.Struct:
    return struct.Struct("<" + "".join(f.code for f in fields))


def offsets(fields: Sequence[WireField]) -> dict[str, int]:
    """Each field's byte offset (no implicit padding: ``<`` packs as written)."""
    at, out = 0, {}
    for f in fields:
        out[f.name] = at
        at += struct.calcsize("<" + f.code)
    return out


HEADER = _struct(HEADER_FIELDS)
BLOCK = _struct(BLOCK_FIELDS)
HEADER_SIZE = HEADER.size  # 32
BLOCK_SIZE = BLOCK.size  # 24


def layout() -> dict[str, Any]:
    """The whole format as data: what scripts/gen_scope_wire.py writes for the browser."""

    def fields(table: Sequence[WireField]) -> list[dict[str, Any]]:
        at = offsets(table)
        return [{"name": f.name, "code": f.code, "offset": at[f.name], "doc": f.doc} for f in table]

    return {
        "magic": MAGIC.decode("ascii"),
        "version": VERSION,
        "subprotocol": SUBPROTOCOL,
        "header_size": HEADER_SIZE,
        "block_size": BLOCK_SIZE,
        "header": fields(HEADER_FIELDS),
        "block": fields(BLOCK_FIELDS),
        "kinds": {"samples": KIND_SAMPLES, "capture": KIND_CAPTURE, "status": KIND_STATUS},
        "flags": {"skipped": FLAG_SKIPPED},
        "sources": dict(SOURCE_CODES),
    }


_F8 = np.dtype("<f8")
_U32 = 0xFFFFFFFF


@dataclass
class Block:
    """One channel's samples in a frame.

    ``dt > 0``: equidistant samples at ``t0 + i * dt`` (no times on the wire). ``dt == 0``: explicit
    ``times``, offsets from the frame's ``t_ref``; ``t0`` is then ``times[0]`` (0 when empty).
    """

    id: int
    source: int
    values: FloatArray
    dt: float = 0.0
    t0: float = 0.0
    times: FloatArray | None = None

    @property
    def n(self) -> int:
        return int(np.asarray(self.values).size)

    def offsets(self) -> FloatArray:
        """Sample times as offsets from ``t_ref`` (computed when equidistant)."""
        if self.dt > 0.0:
            return self.t0 + np.arange(self.n, dtype=np.float64) * self.dt
        if self.times is None:
            return np.zeros(0, dtype=np.float64) if self.n == 0 else np.full(self.n, self.t0)
        return np.asarray(self.times, dtype=np.float64)

    @classmethod
    def from_times(
        cls, id: int, source: int, t_ref: float, t: npt.ArrayLike, v: npt.ArrayLike
    ) -> Block:
        """A block with explicit times given on the backend clock (converted to offsets)."""
        ta = np.asarray(t, dtype=np.float64).reshape(-1) - t_ref
        va = np.asarray(v, dtype=np.float64).reshape(-1)
        return cls(id, source, va, 0.0, float(ta[0]) if ta.size else 0.0, ta)


@dataclass
class Frame:
    """A decoded frame; ``status`` holds the JSON body of a status frame (kind 3)."""

    kind: int
    seq: int
    skipped: int
    t_ref: float
    flags: int = 0
    blocks: list[Block] = field(default_factory=list)
    status: dict[str, Any] | None = None
    version: int = VERSION

    @property
    def skipped_before(self) -> bool:
        """Frames were dropped for this client just before this one (flag bit 0)."""
        return bool(self.flags & FLAG_SKIPPED)


def _check_u(name: str, value: int, bits: int) -> None:
    if (
        isinstance(value, bool)
        or not isinstance(value, int | np.integer)
        or not 0 <= value < (1 << bits)
    ):
        raise ValidationError(
            f"scope frame {name} {value!r} does not fit an unsigned {bits}-bit field", field=name
        )


def encode_frame(
    kind: int,
    seq: int,
    skipped: int,
    t_ref: float,
    blocks: Sequence[Block] = (),
    flags: int = 0,
    *,
    status: Mapping[str, Any] | None = None,
) -> bytes:
    """Encode one frame. Kind 3 (status) carries ``status`` as its JSON body and no blocks."""
    if kind not in KINDS:
        raise ValidationError(f"scope frame kind {kind!r} is unknown; use 1, 2 or 3", field="kind")
    _check_u("seq", seq, 32)
    _check_u("skipped", skipped, 32)
    _check_u("flags", flags, 16)
    if kind == KIND_STATUS:
        if blocks:
            raise ValidationError("a status frame (kind 3) carries no channel blocks")
        body = json.dumps(dict(status or {}), separators=(",", ":"), allow_nan=False)
        head = HEADER.pack(MAGIC, VERSION, kind, flags, seq, skipped, 0, 0, 0, t_ref)
        return head + body.encode("utf-8")
    if status is not None:
        raise ValidationError("only a status frame (kind 3) carries a JSON body")
    _check_u("nchan", len(blocks), 16)
    parts: list[bytes] = [
        HEADER.pack(MAGIC, VERSION, kind, flags, seq, skipped, len(blocks), 0, 0, t_ref)
    ]
    for b in blocks:
        _check_u("channel id", b.id, 8)
        if b.source not in SOURCE_NAMES:
            raise ValidationError(
                f"channel {b.id}: source {b.source!r} is unknown; use 1 pdo, 2 sdo or 3 recorder",
                field="source",
            )
        values = np.ascontiguousarray(b.values, dtype=_F8).reshape(-1)
        n = values.size
        _check_u("sample count", n, 32)
        if not (math.isfinite(b.dt) and b.dt >= 0.0):
            raise ValidationError(
                f"channel {b.id}: dt {b.dt!r} must be 0 (times follow) or a positive period",
                field="dt",
            )
        if b.dt > 0.0:
            parts.append(BLOCK.pack(int(b.id), b.source, 0, n, b.dt, b.t0))
        else:
            if b.times is None:
                raise ValidationError(f"channel {b.id}: dt is 0, so the block needs its times")
            times = np.ascontiguousarray(b.times, dtype=_F8).reshape(-1)
            if times.size != n:
                raise ValidationError(
                    f"channel {b.id}: {times.size} times for {n} values; give one time per value"
                )
            t0 = float(times[0]) if n else 0.0
            parts.append(BLOCK.pack(int(b.id), b.source, 0, n, 0.0, t0))
            parts.append(times.tobytes())
        parts.append(values.tobytes())
    return b"".join(parts)


def encode_status(
    seq: int, skipped: int, t_ref: float, status: Mapping[str, Any], flags: int = 0
) -> bytes:
    """A status frame (kind 3) with ``status`` as its JSON body."""
    return encode_frame(KIND_STATUS, seq, skipped, t_ref, (), flags, status=status)


def decode_frame(data: bytes | bytearray | memoryview) -> Frame:
    """Decode one frame; a frame that is not exactly this format raises ValidationError."""
    buf = bytes(data)
    size = len(buf)
    if size < HEADER_SIZE:
        raise ValidationError(
            f"scope frame truncated: {size} bytes, the header alone needs {HEADER_SIZE}"
        )
    magic, version, kind, flags, seq, skipped, nchan, _res, _pad, t_ref = HEADER.unpack_from(buf)
    if magic != MAGIC:
        raise ValidationError(f"not a scope frame: magic is {magic!r}, expected {MAGIC!r}")
    if version != VERSION:
        raise ValidationError(
            f"scope frame version {version} is not supported (this servodesk speaks {VERSION}); "
            "reload the page after an upgrade"
        )
    if kind not in KINDS:
        raise ValidationError(
            f"scope frame kind {kind} is unknown (1 samples, 2 capture, 3 status)"
        )
    frame = Frame(kind=kind, seq=seq, skipped=skipped, t_ref=t_ref, flags=flags, version=version)
    if kind == KIND_STATUS:
        try:
            body = json.loads(buf[HEADER_SIZE:].decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValidationError(
                f"scope status frame: the body is not UTF-8 JSON ({exc})"
            ) from exc
        if not isinstance(body, dict):
            raise ValidationError("scope status frame: the JSON body is not an object")
        frame.status = body
        return frame
    off = HEADER_SIZE
    for i in range(nchan):
        if size < off + BLOCK_SIZE:
            raise ValidationError(
                f"scope frame truncated in channel block {i + 1} of {nchan}: {size} bytes, "
                f"its header ends at byte {off + BLOCK_SIZE}"
            )
        cid, source, _r, n, dt, t0 = BLOCK.unpack_from(buf, off)
        off += BLOCK_SIZE
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValidationError(f"scope frame channel {cid}: sample period {dt!r} is invalid")
        need = n * 8 * (1 if dt > 0.0 else 2)
        if size < off + need:
            raise ValidationError(
                f"scope frame truncated in channel {cid}: {n} samples need {need} bytes, "
                f"{size - off} are left"
            )
        times: FloatArray | None = None
        if dt == 0.0:
            times = np.frombuffer(buf, dtype=_F8, count=n, offset=off).astype(np.float64)
            off += 8 * n
        values = np.frombuffer(buf, dtype=_F8, count=n, offset=off).astype(np.float64)
        off += 8 * n
        frame.blocks.append(Block(cid, source, values, dt, t0, times))
    if off != size:
        raise ValidationError(
            f"scope frame has {size - off} bytes after its {nchan} channel blocks; "
            "the sender and this decoder disagree on the format"
        )
    return frame
