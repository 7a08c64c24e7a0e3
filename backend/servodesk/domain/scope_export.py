"""Scope recordings as files: CSV and MDF4 export, and import of both back into a Recording.

The contract is docs/scope.md (issue 7, "Export"). A recording is what the scope captured or holds
in its buffer: channels with their own times (seconds from ``t_ref``) and raw values, each with the
profile's unit, raw unit and scale (engineering = raw x scale), the object address and the session.
Exporting and importing a recording gives back the same recording: the same channels in the same
order, and the same times and values bit for bit (MDF4 stores the float64 arrays; the CSV prints
every number with Python's shortest round-trip ``repr``).

CSV layout (UTF-8 with a BOM so Excel reads non-ASCII names)::

    #servodesk-scope,1
    #t_ref,1700000000.25
    #trigger_time,1700000000.5                 (empty cell: no trigger)
    #fields,column,id,name,unit,raw_unit,scale,address,session,source
    #channel,1,0,Position actual value,mm,inc,0.0001,6064h:00,s1,pdo
    ...
    time_s,Position actual value [inc] (1 inc = 0.0001 mm),...,time_s,Velocity actual value [rpm]
    0.0,1200.0,...,0.0123,15.0

A ``#time_base,<column>,<text>`` row per time column says which clock it is on and whose samples
it times: every time column is seconds from ``t_ref`` on servodesk's own clock (PDO frames by
their bus timestamp, SDO reads as answered, a drive recorder's period placed on it), so the
columns of several drives align on one time axis.

The rows starting with ``#`` describe the recording; then one table. There is one ``time_s`` column
(seconds from ``t_ref``) per distinct time base, followed by the channels sampled on it; a channel
belongs to the nearest ``time_s`` column on its left. Channels taken together (the objects of one
TPDO, the recorder's channels) share one time column, so the usual file is exactly "time_s, then one
column per channel". Channels on different time bases (an SDO-polled object beside PDO data) get
their own time column instead of one union time axis: a union would leave most cells empty (a 4 kHz
recorder beside a 20 Hz poll), break Excel line charts into dots, and could not hold two samples of
one channel at the same time; side by side, each block is a plain x/y table Excel charts directly,
and the file reopens without loss. A block shorter than the longest one ends in empty cells; a
missing sample inside a block is written ``nan``. Values are raw (as read from the drive).

MDF4 layout (asammdf): one channel group per time base, its master channel ``time`` in seconds
from ``t_ref``; each channel stores the raw float64 values with a linear conversion
``phys = scale x raw`` and the engineering unit, so MDF tools show engineering values. The
channel comment names the address, session and source and ends with a ``servodesk:`` JSON line
that an import reads back; the file header's comment holds ``t_ref`` and the trigger time
(``common_properties`` of the HDcomment, ASAM MDF 4.1). Files from other tools import too: each
channel's physical values, scale 1.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import gc
import io
import json
import logging
import math
import re
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from servodesk.errors import ValidationError

FloatArray = npt.NDArray[np.float64]

CSV_MAGIC = "#servodesk-scope"
CSV_VERSION = "1"
CSV_FIELDS = ("column", "id", "name", "unit", "raw_unit", "scale", "address", "session", "source")
TIME_COLUMN = "time_s"
MDF_META = "servodesk"  # name of the HDcomment common property and the channel comment prefix
FORMATS = ("csv", "mdf4")


@dataclass(eq=False)
class ChannelData:
    """One channel of a recording: times in seconds from the recording's ``t_ref``, raw values."""

    id: int
    name: str
    unit: str
    raw_unit: str
    scale: float
    address: str
    session: str
    source: str
    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    v: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=np.float64).reshape(-1)
        self.v = np.asarray(self.v, dtype=np.float64).reshape(-1)
        if self.t.shape != self.v.shape:
            raise ValidationError(
                f"channel {self.id} ({self.name}): {self.t.size} times for {self.v.size} values"
            )

    def meta(self) -> dict[str, Any]:
        """Everything but the samples (JSON-friendly)."""
        return {
            "id": self.id,
            "name": self.name,
            "unit": self.unit,
            "raw_unit": self.raw_unit,
            "scale": self.scale,
            "address": self.address,
            "session": self.session,
            "source": self.source,
        }


@dataclass(eq=False)
class Recording:
    """A captured window or the scope buffer: ``t_ref`` and ``trigger_time`` on the backend clock
    (``time.time()`` seconds), channel times relative to ``t_ref``."""

    t_ref: float
    trigger_time: float | None
    channels: list[ChannelData] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """The JSON the scope page opens (GET /scope/capture, POST /scope/import); NaN -> null."""

        def listed(a: FloatArray) -> list[float | None]:
            return [None if math.isnan(x) else x for x in a.tolist()]

        return {
            "t_ref": self.t_ref,
            "trigger_time": self.trigger_time,
            "channels": [{**c.meta(), "t": listed(c.t), "v": listed(c.v)} for c in self.channels],
        }


def time_bases(channels: Sequence[ChannelData]) -> list[list[int]]:
    """Indexes of the channels grouped by identical time arrays, in order of first appearance."""
    groups: list[list[int]] = []
    for i, ch in enumerate(channels):
        for g in groups:
            if np.array_equal(channels[g[0]].t, ch.t):
                g.append(i)
                break
        else:
            groups.append([i])
    return groups


def _check_exportable(rec: Recording) -> None:
    if not math.isfinite(rec.t_ref):
        raise ValidationError(f"recording t_ref {rec.t_ref!r} is not a finite time")
    if rec.trigger_time is not None and not math.isfinite(rec.trigger_time):
        raise ValidationError(f"recording trigger_time {rec.trigger_time!r} is not a finite time")
    for c in rec.channels:
        if not math.isfinite(c.scale):
            raise ValidationError(f"channel {c.id} ({c.name}): scale {c.scale!r} is not finite")
        if not bool(np.all(np.isfinite(c.t))):
            raise ValidationError(f"channel {c.id} ({c.name}): some sample times are not finite")


def _num(x: float) -> str:
    # repr() of a float is the shortest text that reads back to the same float64 (exact).
    return repr(float(x))


def _column_title(c: ChannelData) -> str:
    title = c.name or c.address or f"channel {c.id}"
    if c.raw_unit:
        title += f" [{c.raw_unit}]"
    if c.scale != 1.0 or (c.unit and c.unit != c.raw_unit):
        title += f" (1 {c.raw_unit or 'raw'} = {_num(c.scale)} {c.unit})".rstrip()
    return title


# --------------------------------------------------------------------------------------------- CSV

#: How each source's sample times come about (services/scope.py), for the ``#time_base`` rows.
_SOURCE_CLOCK = {
    "pdo": "PDO frames as received (bus timestamp on servodesk's clock)",
    "sdo": "SDO reads as answered",
    "recorder": "the drive's recorder, its sample period placed on servodesk's clock",
}


def _clock_text(channels: Sequence[ChannelData]) -> str:
    """What a time column times: servodesk's clock, whose samples (drive and source)."""
    whose = sorted(
        {f"{c.session} {_SOURCE_CLOCK.get(c.source, c.source or 'samples')}" for c in channels}
    )
    return "servodesk's clock, s from t_ref; " + "; ".join(whose)


def export_csv(rec: Recording) -> bytes:
    """The recording as CSV (layout in the module docstring), UTF-8 with BOM."""
    _check_exportable(rec)
    groups = time_bases(rec.channels)
    header: list[str] = []
    column_of: dict[int, int] = {}
    for g in groups:
        header.append(TIME_COLUMN)
        for i in g:
            column_of[i] = len(header)
            header.append(_column_title(rec.channels[i]))
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\r\n")
    w.writerow([CSV_MAGIC, CSV_VERSION])
    w.writerow(["#t_ref", _num(rec.t_ref)])
    w.writerow(["#trigger_time", "" if rec.trigger_time is None else _num(rec.trigger_time)])
    w.writerow(["#fields", *CSV_FIELDS])
    for i, c in enumerate(rec.channels):
        w.writerow(
            [
                "#channel",
                str(column_of[i]),
                str(c.id),
                c.name,
                c.unit,
                c.raw_unit,
                _num(c.scale),
                c.address,
                c.session,
                c.source,
            ]
        )
    # Which clock each time column is on (issue 48): all are seconds from t_ref on servodesk's
    # clock, so the columns align on one axis; the row says whose samples they time.
    start = 0
    for g in groups:
        w.writerow(["#time_base", str(start), _clock_text([rec.channels[i] for i in g])])
        start += 1 + len(g)
    w.writerow(header)
    # Column by column, each time base padded with empty cells to the longest one. The cells are
    # numbers (repr never contains a comma or a quote), so the rows are joined without csv quoting.
    rows = max((rec.channels[g[0]].t.size for g in groups), default=0)
    columns: list[list[str]] = []
    for g in groups:
        pad = [""] * (rows - rec.channels[g[0]].t.size)
        columns.append([*map(repr, rec.channels[g[0]].t.tolist()), *pad])
        columns.extend([*map(repr, rec.channels[i].v.tolist()), *pad] for i in g)
    for line in zip(*columns, strict=True):
        out.write(",".join(line))
        out.write("\r\n")
    return out.getvalue().encode("utf-8-sig")


def _float(text: str, what: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValidationError(f"CSV {what}: {text!r} is not a number") from None


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


_TITLE_UNIT = re.compile(r"^(?P<name>.*?)\s*\[(?P<unit>[^\]]*)\]")


def import_csv(data: bytes) -> Recording:
    """Read a CSV written by :func:`export_csv` (or a plain ``time_s, a [unit], ...`` table)."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValidationError(
            f"CSV is not UTF-8 text (byte {exc.start}); export it again from servodesk "
            "or save it as 'CSV UTF-8'"
        ) from None
    rows = list(csv.reader(io.StringIO(text, newline="")))
    line = 0
    meta: dict[str, list[str]] = {}
    channel_rows: list[tuple[int, list[str]]] = []
    while line < len(rows) and (not rows[line] or rows[line][0].startswith("#")):
        row = rows[line]
        line += 1
        if not row:
            continue
        if row[0] == "#channel":
            channel_rows.append((line, row[1:]))
        else:
            meta[row[0]] = row[1:]
    if line >= len(rows):
        raise ValidationError("CSV has no table: expected a header row starting with time_s")
    header = [h.strip() for h in rows[line]]
    header_line = line + 1
    line += 1
    if not header or header[0] != TIME_COLUMN:
        raise ValidationError(
            f"CSV line {header_line}: the table must start with a {TIME_COLUMN} column, "
            f"found {header[0] if header else 'nothing'!r}"
        )
    ncol = len(header)
    # Each channel column takes its times from the nearest time_s column on its left.
    time_col = [0] * ncol
    for j in range(ncol):
        time_col[j] = j if header[j] == TIME_COLUMN else time_col[j - 1]
    data_cols = [j for j in range(ncol) if header[j] != TIME_COLUMN]

    t_ref = 0.0
    trigger: float | None = None
    specs: list[tuple[int, dict[str, Any]]] = []  # (column, ChannelData kwargs)
    if CSV_MAGIC in meta:
        if meta[CSV_MAGIC][:1] != [CSV_VERSION]:
            raise ValidationError(
                f"CSV format version {meta[CSV_MAGIC][:1]} is not supported (this servodesk reads "
                f"{CSV_VERSION})"
            )
        t_ref = _float((meta.get("#t_ref") or [""])[0], "#t_ref")
        trig = (meta.get("#trigger_time") or [""])[0]
        trigger = _float(trig, "#trigger_time") if trig else None
        seen: set[int] = set()
        for at, cells in channel_rows:
            if len(cells) < len(CSV_FIELDS):
                raise ValidationError(
                    f"CSV line {at}: #channel has {len(cells)} fields, expected "
                    f"{len(CSV_FIELDS)} ({', '.join(CSV_FIELDS)})"
                )
            f = dict(zip(CSV_FIELDS, cells, strict=False))
            try:
                col, cid = int(f["column"]), int(f["id"])
            except ValueError:
                raise ValidationError(
                    f"CSV line {at}: column {f['column']!r} and id {f['id']!r} must be integers"
                ) from None
            if col not in data_cols or col in seen:
                raise ValidationError(
                    f"CSV line {at}: column {col} is not a free channel column of the table "
                    f"(it has {ncol} columns; time_s columns are not channels)"
                )
            seen.add(col)
            specs.append(
                (
                    col,
                    {
                        "id": cid,
                        "name": f["name"],
                        "unit": f["unit"],
                        "raw_unit": f["raw_unit"],
                        "scale": _float(f["scale"], f"line {at} scale"),
                        "address": f["address"],
                        "session": f["session"],
                        "source": f["source"],
                    },
                )
            )
        if len(specs) != len(data_cols):
            raise ValidationError(
                f"CSV describes {len(specs)} channels in #channel rows but its table has "
                f"{len(data_cols)} channel columns"
            )
    else:
        for k, j in enumerate(data_cols):
            m = _TITLE_UNIT.match(header[j])
            name, unit = (m["name"], m["unit"]) if m else (header[j], "")
            specs.append(
                (
                    j,
                    {
                        "id": k,
                        "name": name,
                        "unit": unit,
                        "raw_unit": unit,
                        "scale": 1.0,
                        "address": "",
                        "session": "",
                        "source": "import",
                    },
                )
            )

    # Column by column: the cells of each column, and which of them are empty.
    table: list[tuple[int, list[str]]] = []
    for r in range(line, len(rows)):
        row = [cell.strip() for cell in rows[r]]
        if not any(row):
            continue
        if len(row) > ncol:
            raise ValidationError(
                f"CSV line {r + 1}: {len(row)} cells but the header has {ncol} columns"
            )
        table.append((r + 1, row + [""] * (ncol - len(row))))
    numbers = [n for n, _ in table]
    columns: list[tuple[str, ...]] = list(zip(*(row for _, row in table), strict=True)) or [
        () for _ in range(ncol)
    ]
    empty = [np.array([not c for c in col], dtype=bool) for col in columns]
    parsed: dict[int, FloatArray] = {}
    for j in range(ncol):
        tj = time_col[j]
        if j != tj:
            bad = np.flatnonzero(empty[j] & ~empty[tj])
            if bad.size:
                raise ValidationError(
                    f"CSV line {numbers[bad[0]]}, column {j + 1} ({header[j]}): no value although "
                    "the row has a time; write nan for a missing sample"
                )
            bad = np.flatnonzero(~empty[j] & empty[tj])
            if bad.size:
                raise ValidationError(
                    f"CSV line {numbers[bad[0]]}, column {j + 1} ({header[j]}): a value without "
                    "a time"
                )
        texts = [c for c in columns[j] if c]
        try:
            # NumPy parses decimal text to the nearest float64, like float(): repr text is exact.
            parsed[j] = np.array(texts, dtype=np.float64)
        except ValueError:
            k = next(k for k, c in enumerate(columns[j]) if c and not _is_float(c))
            raise ValidationError(
                f"CSV line {numbers[k]}, column {j + 1} ({header[j]}): {columns[j][k]!r} is not a "
                "number"
            ) from None
    channels = [ChannelData(**kw, t=parsed[time_col[j]], v=parsed[j]) for j, kw in specs]
    return Recording(t_ref=t_ref, trigger_time=trigger, channels=channels)


# -------------------------------------------------------------------------------------------- MDF4


def _hd_comment(rec: Recording) -> str:
    root = ET.Element("HDcomment")
    ET.SubElement(root, "TX").text = "servodesk scope recording"
    props = ET.SubElement(root, "common_properties")
    meta = {
        "format": "servodesk-scope",
        "version": 1,
        "t_ref": rec.t_ref,
        "trigger_time": rec.trigger_time,
        "channels": len(rec.channels),
    }
    ET.SubElement(props, "e", name=MDF_META).text = json.dumps(meta)
    return ET.tostring(root, encoding="unicode")


def _channel_comment(index: int, c: ChannelData) -> str:
    meta = {"index": index, **c.meta(), "n": int(c.v.size)}
    return (
        f"{c.address or 'object'} on session {c.session or '-'} (source {c.source}); "
        f"raw unit {c.raw_unit or '-'}, engineering = raw x {_num(c.scale)} {c.unit}\n"
        f"{MDF_META}:{json.dumps(meta)}"
    )


def preload_mdf() -> None:
    """Import asammdf now. It takes seconds (it pulls in pandas), so the service can do it in a
    worker thread at start instead of blocking the first MDF4 export or import."""
    import asammdf  # noqa: F401


def export_mdf4(rec: Recording) -> bytes:
    """The recording as an MDF 4.10 file (layout in the module docstring)."""
    _check_exportable(rec)
    from asammdf import MDF, Signal  # imported here: asammdf pulls pandas, slow to import

    mdf = MDF(version="4.10")
    try:
        mdf.header.comment = _hd_comment(rec)
        mdf.header.start_time = _dt.datetime.fromtimestamp(rec.t_ref, tz=_dt.UTC)
        for g in time_bases(rec.channels):
            signals = []
            for i in g:
                c = rec.channels[i]
                signals.append(
                    Signal(
                        samples=c.v,
                        timestamps=c.t,
                        name=c.name or c.address or f"channel {c.id}",
                        unit=c.unit,
                        conversion={"a": float(c.scale), "b": 0.0},
                        comment=_channel_comment(i, c),
                    )
                )
            first = rec.channels[g[0]]
            mdf.append(
                signals,
                acq_name=f"{first.source} {first.session}".strip(),
                comment=f"time base of {', '.join(rec.channels[i].name for i in g)}",
            )
        buf = io.BytesIO()
        mdf.save(buf)
        return buf.getvalue()
    finally:
        mdf.close()


@contextlib.contextmanager
def _half_open_mdf_guard() -> Iterator[None]:
    """asammdf 8.8.28: when ``MDF()`` fails on a damaged file, the half-built ``MDF4`` object's
    ``__del__`` raises AttributeError (it has no header yet) when it is collected. Collect it here
    and swallow exactly that one, so that the user gets our ValidationError and nothing else."""
    previous = sys.unraisablehook

    def hook(u: Any) -> None:
        if u.exc_type is AttributeError and getattr(u.object, "__qualname__", "") == "MDF4.__del__":
            return
        previous(u)

    # asammdf also logs the failure it raises; the ValidationError carries the same text.
    log = logging.getLogger("asammdf")
    level = log.level
    log.setLevel(logging.CRITICAL)
    sys.unraisablehook = hook
    try:
        yield
    finally:
        gc.collect()
        sys.unraisablehook = previous
        log.setLevel(level)


def _recording_meta(comment: str) -> dict[str, Any] | None:
    if not comment.lstrip().startswith("<"):
        return None
    try:
        root = ET.fromstring(comment)
    except ET.ParseError:
        return None
    for e in root.iter("e"):
        if e.get("name") == MDF_META and e.text:
            try:
                meta = json.loads(e.text)
            except json.JSONDecodeError as exc:
                raise ValidationError(
                    f"MDF4 header: the servodesk properties are damaged ({exc})"
                ) from None
            return meta if isinstance(meta, dict) else None
    return None


def _channel_meta(comment: str, where: str) -> dict[str, Any] | None:
    for line in comment.splitlines():
        if line.startswith(MDF_META + ":"):
            try:
                meta = json.loads(line[len(MDF_META) + 1 :])
            except json.JSONDecodeError as exc:
                raise ValidationError(
                    f"MDF4 {where}: the servodesk comment is damaged ({exc})"
                ) from None
            if not isinstance(meta, dict):
                raise ValidationError(f"MDF4 {where}: the servodesk comment is not an object")
            return meta
    return None


def import_mdf4(data: bytes) -> Recording:
    """Read an MDF file written by :func:`export_mdf4` (or by another MDF tool)."""
    if data[:8] != b"MDF     ":
        raise ValidationError(
            f"not an MDF file: it starts with {bytes(data[:8])!r} instead of b'MDF     '"
        )
    from asammdf import MDF

    problem: str | None = None
    mdf: Any = None
    with _half_open_mdf_guard():
        try:
            mdf = MDF(io.BytesIO(bytes(data)))
        except Exception as exc:  # asammdf raises struct.error, MdfException, ValueError, ...
            problem = f"{type(exc).__name__}: {exc}"
    if mdf is None:
        raise ValidationError(
            f"MDF4 file is damaged or truncated and cannot be opened ({problem}); export it again"
        )
    try:
        return _read_mdf(mdf)
    except ValidationError:
        raise
    except Exception as exc:
        raise ValidationError(
            f"MDF4 file is damaged: reading its channels failed ({type(exc).__name__}: {exc})"
        ) from None
    finally:
        with contextlib.suppress(Exception):
            mdf.close()


def _read_mdf(mdf: Any) -> Recording:
    rec_meta = _recording_meta(str(mdf.header.comment or ""))
    found: list[tuple[int, ChannelData]] = []
    for gi, group in enumerate(mdf.groups):
        for ci, ch in enumerate(group.channels):
            if ch.channel_type in (2, 3):  # ASAM MDF 4 cn_type: 2 master, 3 virtual master
                continue
            where = f"group {gi} channel {ci} ({ch.name})"
            meta = _channel_meta(str(ch.comment or ""), where)
            if meta is not None:
                sig = mdf.get(group=gi, index=ci, raw=True)
                n = int(meta.get("n", -1))
                if n != len(sig.samples) or len(sig.timestamps) != len(sig.samples):
                    raise ValidationError(
                        f"MDF4 {where} is damaged: {len(sig.samples)} samples and "
                        f"{len(sig.timestamps)} times where the file says {n}"
                    )
                try:
                    cd = ChannelData(
                        id=int(meta["id"]),
                        name=str(meta["name"]),
                        unit=str(meta["unit"]),
                        raw_unit=str(meta["raw_unit"]),
                        scale=float(meta["scale"]),
                        address=str(meta["address"]),
                        session=str(meta["session"]),
                        source=str(meta["source"]),
                        t=np.asarray(sig.timestamps, dtype=np.float64),
                        v=np.asarray(sig.samples, dtype=np.float64),
                    )
                except (KeyError, TypeError, ValueError) as exc:
                    raise ValidationError(
                        f"MDF4 {where}: the servodesk comment lacks or garbles {exc}"
                    ) from None
                found.append((int(meta.get("index", len(found))), cd))
            else:
                sig = mdf.get(group=gi, index=ci, raw=False)
                samples = np.asarray(sig.samples)
                if samples.ndim != 1 or samples.dtype.kind not in "iufb":
                    continue  # arrays, strings, bytes: nothing the scope can plot
                found.append(
                    (
                        1_000_000 + len(found),
                        ChannelData(
                            id=len(found),
                            name=str(sig.name),
                            unit=str(sig.unit or ""),
                            raw_unit=str(sig.unit or ""),
                            scale=1.0,
                            address="",
                            session="",
                            source="import",
                            t=np.asarray(sig.timestamps, dtype=np.float64),
                            v=samples.astype(np.float64),
                        ),
                    )
                )
    found.sort(key=lambda item: item[0])
    channels = [c for _, c in found]
    if rec_meta is None:
        return Recording(t_ref=0.0, trigger_time=None, channels=channels)
    want = rec_meta.get("channels")
    if want is not None and want != len(channels):
        raise ValidationError(
            f"MDF4 file is damaged: its header lists {want} channels, {len(channels)} were found"
        )
    try:
        t_ref = float(rec_meta["t_ref"])
        trig = rec_meta.get("trigger_time")
        trigger = None if trig is None else float(trig)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValidationError(
            f"MDF4 header: t_ref or trigger_time is missing or bad ({exc})"
        ) from None
    return Recording(t_ref=t_ref, trigger_time=trigger, channels=channels)


# ------------------------------------------------------------------------------------ dispatching


def export_recording(rec: Recording, fmt: str) -> tuple[bytes, str]:
    """``(file bytes, media type)`` for ``fmt`` ``csv`` or ``mdf4``."""
    if fmt == "csv":
        return export_csv(rec), "text/csv; charset=utf-8"
    if fmt == "mdf4":
        return export_mdf4(rec), "application/octet-stream"
    raise ValidationError(f"export format {fmt!r} is unknown; use csv or mdf4", field="format")


def import_recording(data: bytes, filename: str) -> Recording:
    """Read a recording by its file name's extension: ``.csv``, or ``.mf4``/``.mdf`` (MDF)."""
    name = filename.lower()
    if name.endswith(".csv"):
        return import_csv(data)
    if name.endswith((".mf4", ".mdf")):
        return import_mdf4(data)
    raise ValidationError(
        f"cannot open {filename!r}: the scope opens .csv and .mf4 files", field="filename"
    )
