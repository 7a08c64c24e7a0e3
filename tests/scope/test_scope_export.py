"""Scope recordings as CSV and MDF4 files, and back: the same recording, bit for bit."""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pytest
from asammdf import MDF

from servodesk.domain.scope_export import (
    ChannelData,
    Recording,
    export_csv,
    export_mdf4,
    export_recording,
    import_csv,
    import_mdf4,
    import_recording,
    time_bases,
)
from servodesk.errors import ValidationError

T_REF = 1_700_000_123.456789


def recording() -> Recording:
    """Four time bases: two PDO objects of one TPDO, an SDO poll, the recorder, an empty channel."""
    rng = np.random.default_rng(7)
    t_pdo = np.arange(400) * 0.001 - 0.1
    t_sdo = np.cumsum(rng.uniform(0.02, 0.06, 12))
    t_rec = np.arange(1600) * 0.00025
    awkward = np.array([0.1 + 0.2, 1e-300, -0.0, 2.0**53 + 1, -123456789.0, math.nan, 5e-324])
    rec_v = np.round(rng.normal(scale=1e4, size=t_rec.size))
    rec_v[: awkward.size] = awkward
    return Recording(
        t_ref=T_REF,
        trigger_time=T_REF + 0.05,
        channels=[
            ChannelData(
                0,
                "Position actual value",
                "mm",
                "inc",
                0.0001,
                "6064h:00",
                "s1",
                "pdo",
                t_pdo,
                np.round(rng.normal(scale=1e5, size=t_pdo.size)),
            ),
            ChannelData(
                1,
                "Velocity actual value",
                "rpm",
                "rpm",
                1.0,
                "606Ch:00",
                "s1",
                "pdo",
                t_pdo,
                rng.normal(size=t_pdo.size),
            ),
            ChannelData(
                2,
                "Statusword",
                "",
                "",
                1.0,
                "6041h:00",
                "s2",
                "sdo",
                t_sdo,
                rng.integers(0, 0xFFFF, t_sdo.size).astype(float),
            ),
            ChannelData(
                3,
                'Motorstrom (µ-Regler), "Iq"',
                "A",
                "0.1 %",
                0.0123,
                "2F10h:01",
                "s1",
                "recorder",
                t_rec,
                rec_v,
            ),
            ChannelData(
                4,
                "Torque actual value",
                "Nm",
                "0.1 %",
                0.001,
                "6077h:00",
                "s2",
                "sdo",
                np.zeros(0),
                np.zeros(0),
            ),
        ],
    )


def assert_same(a: Recording, b: Recording) -> None:
    assert (a.t_ref, a.trigger_time) == (b.t_ref, b.trigger_time)
    assert len(a.channels) == len(b.channels)
    for x, y in zip(a.channels, b.channels, strict=True):
        assert x.meta() == y.meta()
        # Bit for bit: -0.0 stays -0.0, NaN stays NaN, 5e-324 stays.
        assert x.t.tobytes() == y.t.tobytes(), x.name
        assert x.v.tobytes() == y.v.tobytes(), x.name


def test_csv_round_trip_is_exact() -> None:
    rec = recording()
    assert_same(rec, import_csv(export_csv(rec)))


def test_mdf4_round_trip_is_exact() -> None:
    rec = recording()
    assert_same(rec, import_mdf4(export_mdf4(rec)))


def test_csv_layout_one_time_column_per_time_base() -> None:
    data = export_csv(recording())
    assert data.startswith(b"\xef\xbb\xbf")  # BOM: Excel reads the UTF-8 names
    rows = list(csv.reader(io.StringIO(data.decode("utf-8-sig"))))
    header = next(r for r in rows if not r[0].startswith("#"))
    assert header == [
        "time_s",
        "Position actual value [inc] (1 inc = 0.0001 mm)",
        "Velocity actual value [rpm]",
        "time_s",
        "Statusword",
        "time_s",
        'Motorstrom (µ-Regler), "Iq" [0.1 %] (1 0.1 % = 0.0123 A)',
        "time_s",
        "Torque actual value [0.1 %] (1 0.1 % = 0.001 Nm)",
    ]
    table = rows[rows.index(header) + 1 :]
    assert len(table) == 1600  # the longest time base
    assert table[0][:3] == ["-0.1", table[0][1], table[0][2]]
    assert table[500][:5] == ["", "", "", "", ""]  # the PDO block ended at 400 rows
    assert table[0][6] == "0.30000000000000004" and table[5][6] == "nan"
    meta = {r[0]: r[1:] for r in rows if r[0].startswith("#") and r[0] != "#channel"}
    assert meta["#t_ref"] == ["1700000123.456789"]
    channel_rows = [r for r in rows if r[0] == "#channel"]
    assert channel_rows[0] == [
        "#channel",
        "1",
        "0",
        "Position actual value",
        "mm",
        "inc",
        "0.0001",
        "6064h:00",
        "s1",
        "pdo",
    ]


def test_one_time_base_is_time_then_one_column_per_channel() -> None:
    rec = recording()
    rec.channels = rec.channels[:2]
    rows = list(csv.reader(io.StringIO(export_csv(rec).decode("utf-8-sig"))))
    header = next(r for r in rows if not r[0].startswith("#"))
    assert header[0] == "time_s" and header.count("time_s") == 1 and len(header) == 3


def test_a_plain_csv_table_opens_too() -> None:
    text = "time_s,Position [inc],Velocity\r\n0.0,1,2.5\r\n0.001,2,nan\r\n"
    rec = import_csv(text.encode())
    assert rec.t_ref == 0.0 and rec.trigger_time is None
    pos, vel = rec.channels
    assert (pos.id, pos.name, pos.raw_unit, pos.scale, pos.source) == (
        0,
        "Position",
        "inc",
        1.0,
        "import",
    )
    assert vel.name == "Velocity" and vel.unit == ""
    assert pos.t.tolist() == [0.0, 0.001] and pos.v.tolist() == [1.0, 2.0]
    assert math.isnan(vel.v[1])


def _csv_with(old: str, new: str) -> bytes:
    text = export_csv(recording()).decode("utf-8-sig")
    assert old in text
    return text.replace(old, new, 1).encode()


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"", r"CSV has no table"),
        (b"\xff\xfe t", r"CSV is not UTF-8 text"),
        (b"a,b\r\n1,2\r\n", r"line 1: the table must start with a time_s column, found 'a'"),
        (b"time_s,x\r\n0.0,abc\r\n", r"CSV line 2, column 2 \(x\): 'abc' is not a number"),
        (b"time_s,x\r\n0.0,\r\n", r"line 2, column 2 \(x\): no value although the row has a time"),
        (b"time_s,x\r\n,1.0\r\n", r"line 2, column 2 \(x\): a value without a time"),
        (b"time_s,x\r\n0.0,1.0,2.0\r\n", r"line 2: 3 cells but the header has 2 columns"),
        (b"#servodesk-scope,2\r\ntime_s\r\n", r"CSV format version \['2'\] is not supported"),
    ],
)
def test_a_bad_csv_is_refused_naming_what_is_wrong(data: bytes, message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        import_csv(data)


def test_a_damaged_servodesk_csv_is_refused() -> None:
    with pytest.raises(ValidationError, match=r"#t_ref: 'x' is not a number"):
        import_csv(_csv_with("#t_ref,1700000123.456789", "#t_ref,x"))
    with pytest.raises(ValidationError, match=r"line 5: column 99 is not a free channel column"):
        import_csv(_csv_with("#channel,1,0,", "#channel,99,0,"))
    with pytest.raises(ValidationError, match=r"4 channels in #channel rows but its table has 5"):
        import_csv(
            _csv_with("#channel,2,1,Velocity actual value,rpm,rpm,1.0,606Ch:00,s1,pdo\r\n", "")
        )


def test_mdf4_has_one_group_per_time_base_with_units_and_comments() -> None:
    rec = recording()
    assert time_bases(rec.channels) == [[0, 1], [2], [3], [4]]
    mdf = MDF(io.BytesIO(export_mdf4(rec)))
    try:
        assert len(mdf.groups) == 4
        names = [[c.name for c in g.channels] for g in mdf.groups]
        assert names[0] == ["time", "Position actual value", "Velocity actual value"]
        pos = mdf.get(group=0, index=1)  # physical values: raw x scale, in the engineering unit
        assert pos.unit == "mm"
        np.testing.assert_allclose(pos.samples, rec.channels[0].v * 0.0001)
        assert np.array_equal(pos.timestamps, rec.channels[0].t)
        comment = str(mdf.groups[0].channels[1].comment)
        assert comment.startswith("6064h:00 on session s1 (source pdo); raw unit inc")
        assert mdf.groups[1].channels[1].comment.startswith("6041h:00 on session s2 (source sdo)")
        assert "servodesk" in str(mdf.header.comment)
    finally:
        mdf.close()


def test_an_mdf4_from_another_tool_opens_with_physical_values() -> None:
    from asammdf import Signal

    mdf = MDF(version="4.10")
    t = np.arange(5) * 0.01
    mdf.append(
        [
            Signal(
                np.arange(5, dtype=np.int16),
                t,
                name="speed",
                unit="km/h",
                conversion={"a": 0.5, "b": 1.0},
            )
        ]
    )
    buf = io.BytesIO()
    mdf.save(buf)
    mdf.close()
    rec = import_recording(buf.getvalue(), "drive.MF4")
    (ch,) = rec.channels
    assert (ch.name, ch.unit, ch.scale, ch.source) == ("speed", "km/h", 1.0, "import")
    assert ch.v.tolist() == [1.0, 1.5, 2.0, 2.5, 3.0] and ch.t.tolist() == t.tolist()


def test_a_damaged_mdf4_is_refused_naming_what_is_wrong() -> None:
    data = export_mdf4(recording())
    with pytest.raises(ValidationError, match=r"not an MDF file: it starts with b'time_s,x'"):
        import_mdf4(b"time_s,x\r\n")
    with pytest.raises(ValidationError, match=r"not an MDF file"):
        import_mdf4(b"")
    # Cut anywhere: refused with a ValidationError, never a crash or a shorter recording.
    for cut in (64, 200, len(data) // 3, len(data) // 2, len(data) - 100):
        with pytest.raises(
            ValidationError, match=r"MDF4 (file|group \d+ channel \d+ \(.*\)) is damaged"
        ):
            import_mdf4(data[:cut])
    # A broken copy: zeroed blocks (MDF has no checksum over the samples themselves, but the
    # structure and the sample counts are checked).
    for tag, message in [
        (b"##CN", r"cannot be opened \(MdfException: Expected \"##CN\" block"),
        (b"##DG", r"cannot be opened"),
        (b"##DT", r"group 0 channel 1 \(Position actual value\) is damaged: 0 samples .* says 400"),
    ]:
        at = data.find(tag)
        with pytest.raises(ValidationError, match=message):
            import_mdf4(data[:at] + bytes(24) + data[at + 24 :])


def test_import_and_export_by_name() -> None:
    rec = recording()
    data, media = export_recording(rec, "csv")
    assert media.startswith("text/csv")
    assert_same(rec, import_recording(data, "scope.csv"))
    data, media = export_recording(rec, "mdf4")
    assert_same(rec, import_recording(data, "scope.mf4"))
    with pytest.raises(ValidationError, match="export format 'xlsx' is unknown"):
        export_recording(rec, "xlsx")
    with pytest.raises(
        ValidationError, match=r"cannot open 'scope.png': the scope opens .csv and .mf4"
    ):
        import_recording(b"", "scope.png")


def test_to_json_is_what_the_page_opens() -> None:
    rec = recording()
    js = rec.to_json()
    assert js["t_ref"] == T_REF and js["trigger_time"] == T_REF + 0.05
    ch3 = js["channels"][3]
    assert ch3["address"] == "2F10h:01" and ch3["v"][5] is None and len(ch3["t"]) == 1600


def test_export_refuses_a_recording_it_cannot_write() -> None:
    with pytest.raises(ValidationError, match="t_ref nan is not a finite time"):
        export_csv(Recording(math.nan, None, []))
    with pytest.raises(ValidationError, match="2 times for 1 values"):
        ChannelData(0, "x", "", "", 1.0, "", "", "sdo", np.zeros(2), np.zeros(1))


def test_csv_says_which_clock_each_time_column_is_on() -> None:
    """Issue 48: a time column per time base (drive, source) must say which clock it is on
    and whose samples it times; all are on servodesk's clock, so they align."""
    rows = list(csv.reader(io.StringIO(export_csv(recording()).decode("utf-8-sig"))))
    header = next(r for r in rows if not r[0].startswith("#"))
    bases = [r for r in rows if r[0] == "#time_base"]
    assert [int(r[1]) for r in bases] == [i for i, h in enumerate(header) if h == "time_s"]
    assert all(r[2].startswith("servodesk's clock, s from t_ref; ") for r in bases)
    assert "s1 PDO frames as received" in bases[0][2]
    assert any("recorder" in r[2] for r in bases)
    # The file still opens as before.
    assert len(import_csv(export_csv(recording())).channels) == len(recording().channels)
