"""The scope's binary frame format: golden bytes, round trips, refusals, speed, and the fixture
the TypeScript decoder reads (frontend/src/scope/wire.test.ts)."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from servodesk.domain.scope_wire import (
    BLOCK_SIZE,
    HEADER_SIZE,
    KIND_CAPTURE,
    KIND_SAMPLES,
    KIND_STATUS,
    SOURCE_PDO,
    SOURCE_RECORDER,
    SOURCE_SDO,
    Block,
    decode_frame,
    encode_frame,
    encode_status,
)
from servodesk.errors import ValidationError

FIXTURES = Path(__file__).resolve().parents[1] / "data" / "scope"

# A small frame written out field by field (docs/scope.md "Wire format", little-endian).
GOLDEN = bytes.fromhex(
    "53445343"  # magic "SDSC"
    "01"  # version 1
    "01"  # kind 1 samples
    "0100"  # flags: bit 0, frames were skipped before this one
    "07000000"  # seq 7
    "02000000"  # skipped 2
    "0200"  # nchan 2
    "0000"  # reserved
    "00000000"  # padding: t_ref on an 8-byte boundary (header = 32 bytes)
    "000000000000f83f"  # t_ref 1.5
    # block 1: equidistant, no times
    "03"  # id 3
    "01"  # source pdo
    "0000"  # reserved
    "02000000"  # n 2
    "000000000000d03f"  # dt 0.25
    "000000000000e03f"  # t0 0.5
    "000000000000f03f"  # 1.0
    "00000000000000c0"  # -2.0
    # block 2: explicit times
    "07"  # id 7
    "02"  # source sdo
    "0000"  # reserved
    "01000000"  # n 1
    "0000000000000000"  # dt 0: times follow
    "000000000000c03f"  # t0 0.125
    "000000000000c03f"  # times[0] 0.125
    "0000000000002440"  # values[0] 10.0
)


def golden_blocks() -> list[Block]:
    return [
        Block(3, SOURCE_PDO, np.array([1.0, -2.0]), dt=0.25, t0=0.5),
        Block(7, SOURCE_SDO, np.array([10.0]), times=np.array([0.125])),
    ]


def test_encode_is_byte_exact() -> None:
    assert HEADER_SIZE == 32 and BLOCK_SIZE == 24
    assert encode_frame(KIND_SAMPLES, 7, 2, 1.5, golden_blocks(), flags=1) == GOLDEN


def test_decode_golden() -> None:
    f = decode_frame(GOLDEN)
    assert (f.kind, f.seq, f.skipped, f.flags, f.t_ref) == (KIND_SAMPLES, 7, 2, 1, 1.5)
    assert f.skipped_before
    a, b = f.blocks
    assert (a.id, a.source, a.n, a.dt, a.t0, a.times) == (3, SOURCE_PDO, 2, 0.25, 0.5, None)
    assert a.values.tolist() == [1.0, -2.0]
    assert a.offsets().tolist() == [0.5, 0.75]
    assert (b.id, b.source, b.n, b.dt, b.t0) == (7, SOURCE_SDO, 1, 0.0, 0.125)
    assert b.offsets().tolist() == [0.125] and b.values.tolist() == [10.0]


def test_status_frame_is_header_then_json() -> None:
    frame = encode_status(1, 0, 0.0, {"type": "status", "running": True})
    assert frame[:HEADER_SIZE] == bytes.fromhex(
        "53445343"  # magic
        "0103"  # version 1, kind 3 status
        "0000"  # flags
        "01000000"  # seq 1
        "00000000"  # skipped 0
        "00000000"  # nchan 0, reserved
        "00000000"  # padding
        "0000000000000000"  # t_ref 0.0
    )
    assert frame[HEADER_SIZE:] == b'{"type":"status","running":true}'
    decoded = decode_frame(frame)
    assert decoded.kind == KIND_STATUS and decoded.status == {"type": "status", "running": True}
    assert decoded.blocks == []


def test_round_trip_keeps_every_bit() -> None:
    rng = np.random.default_rng(1)
    t_ref = 1_700_000_000.123456
    abs_times = t_ref + np.cumsum(rng.uniform(0.001, 0.05, 50))
    blocks = [
        Block(0, SOURCE_PDO, rng.normal(size=120), dt=0.001, t0=0.0123),
        Block.from_times(5, SOURCE_SDO, t_ref, abs_times, rng.normal(size=50)),
        Block(6, SOURCE_RECORDER, np.array([np.nan, np.inf, -0.0, 1e-300]), dt=0.00025, t0=-0.5),
        Block(7, SOURCE_RECORDER, np.zeros(0), dt=0.00025, t0=0.0),
        Block(2, SOURCE_SDO, np.zeros(0), times=np.zeros(0)),
    ]
    frame = decode_frame(encode_frame(KIND_CAPTURE, 2**32 - 1, 0, t_ref, blocks))
    assert (frame.kind, frame.seq, frame.skipped_before) == (KIND_CAPTURE, 2**32 - 1, False)
    for sent, got in zip(blocks, frame.blocks, strict=True):
        assert (got.id, got.source, got.dt, got.n) == (sent.id, sent.source, sent.dt, sent.n)
        assert got.values.tobytes() == np.asarray(sent.values, dtype=np.float64).tobytes()
        assert got.offsets().tobytes() == sent.offsets().tobytes()
    # The explicit times come back on the backend clock as they were (offsets are exact enough).
    np.testing.assert_allclose(frame.blocks[1].offsets() + t_ref, abs_times, rtol=0, atol=1e-6)
    assert frame.blocks[1].t0 == frame.blocks[1].offsets()[0]


def _with(data: bytes, offset: int, patch: bytes) -> bytes:
    return data[:offset] + patch + data[offset + len(patch) :]


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"", r"truncated: 0 bytes, the header alone needs 32"),
        (GOLDEN[:31], r"truncated: 31 bytes"),
        (_with(GOLDEN, 0, b"SDSX"), r"not a scope frame: magic is b'SDSX'"),
        (_with(GOLDEN, 4, b"\x02"), r"version 2 is not supported"),
        (_with(GOLDEN, 5, b"\x09"), r"kind 9 is unknown"),
        (GOLDEN[:40], r"truncated in channel block 1 of 2"),
        (GOLDEN[: 32 + 24 + 8], r"truncated in channel 3: 2 samples need 16 bytes, 8 are left"),
        (GOLDEN[:-1], r"truncated in channel 7: 1 samples need 16 bytes, 15 are left"),
        (GOLDEN + b"\x00", r"1 bytes after its 2 channel blocks"),
        (_with(GOLDEN, 16, b"\x03\x00"), r"truncated in channel block 3 of 3"),
        (_with(GOLDEN, 32 + 8, bytes.fromhex("000000000000f0bf")), r"sample period -1.0 is"),
        (encode_status(1, 0, 0.0, {})[:32] + b"{not json", r"status frame: the body is not"),
        (encode_status(1, 0, 0.0, {})[:32] + b"[1, 2]", r"JSON body is not an object"),
        (encode_status(1, 0, 0.0, {})[:32] + b"\xff", r"not UTF-8 JSON"),
    ],
)
def test_decode_refuses_a_bad_frame_with_a_clear_message(data: bytes, message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        decode_frame(data)


def test_encode_refuses_what_the_format_cannot_carry() -> None:
    v = np.zeros(2)
    with pytest.raises(ValidationError, match="kind 4 is unknown"):
        encode_frame(4, 0, 0, 0.0, [])
    with pytest.raises(ValidationError, match="channel id 256 does not fit"):
        encode_frame(1, 0, 0, 0.0, [Block(256, SOURCE_PDO, v, dt=0.001)])
    with pytest.raises(ValidationError, match="source 4 is unknown"):
        encode_frame(1, 0, 0, 0.0, [Block(1, 4, v, dt=0.001)])
    with pytest.raises(ValidationError, match="3 times for 2 values"):
        encode_frame(1, 0, 0, 0.0, [Block(1, SOURCE_SDO, v, times=np.zeros(3))])
    with pytest.raises(ValidationError, match="needs its times"):
        encode_frame(1, 0, 0, 0.0, [Block(1, SOURCE_SDO, v)])
    with pytest.raises(ValidationError, match=r"dt -0\.001 must be 0"):
        encode_frame(1, 0, 0, 0.0, [Block(1, SOURCE_SDO, v, dt=-0.001)])
    with pytest.raises(ValidationError, match="seq 4294967296 does not fit"):
        encode_frame(1, 2**32, 0, 0.0, [])
    with pytest.raises(ValidationError, match="carries no channel blocks"):
        encode_frame(KIND_STATUS, 0, 0, 0.0, [Block(1, SOURCE_PDO, v, dt=0.001)])


def test_encoding_8_channels_of_120_samples_takes_well_under_a_millisecond() -> None:
    rng = np.random.default_rng(2)
    blocks = [Block(i, SOURCE_PDO, rng.normal(size=120), dt=0.00025) for i in range(4)]
    blocks += [
        Block(i, SOURCE_SDO, rng.normal(size=120), times=np.sort(rng.uniform(0, 0.03, 120)))
        for i in range(4, 8)
    ]
    runs = []
    for _ in range(50):
        start = time.perf_counter()
        for _ in range(20):
            encode_frame(KIND_SAMPLES, 1, 0, 1.0, blocks)
        runs.append((time.perf_counter() - start) / 20)
    # Measured about 0.03 ms; the bound leaves room for a loaded machine.
    assert min(runs) < 0.25e-3, f"encode_frame took {min(runs) * 1e3:.3f} ms"


def fixture_frames() -> dict[str, bytes]:
    """Frames the TypeScript test decodes; its expectations mirror these values."""
    t_ref = 1_700_000_000.25
    samples = encode_frame(
        KIND_CAPTURE,
        42,
        3,
        t_ref,
        [
            Block(0, SOURCE_PDO, np.array([1.5, -2.0, 3.25, 1e-9]), dt=0.001, t0=-0.002),
            Block(
                5, SOURCE_SDO, np.array([100.0, 200.0, -0.001]), times=np.array([0.0, 0.0125, 0.03])
            ),
            Block(7, SOURCE_RECORDER, np.zeros(0), dt=0.00025, t0=0.0),
        ],
        flags=1,
    )
    status = encode_status(43, 3, t_ref, {"type": "status", "running": True, "state": "armed"})
    return {"frame1": samples, "status1": status}


def test_fixtures_for_the_typescript_decoder_are_current() -> None:
    """tests/data/scope/frames.json holds these frames as hex for frontend/src/scope/wire.test.ts
    (JSON because the browser build's TypeScript cannot read files). It must be what the encoder
    writes today; SERVODESK_REGEN_FIXTURES=1 (or a missing file) writes it anew."""
    path = FIXTURES / "frames.json"
    frames = {name: data.hex() for name, data in fixture_frames().items()}
    text = json.dumps({"_": "written by tests/scope/test_scope_wire.py", **frames}, indent=2) + "\n"
    if os.environ.get("SERVODESK_REGEN_FIXTURES") == "1" or not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    assert path.read_text() == text, f"{path} is stale: rerun with SERVODESK_REGEN_FIXTURES=1"
    for data in fixture_frames().values():
        assert decode_frame(data).seq in (42, 43)
