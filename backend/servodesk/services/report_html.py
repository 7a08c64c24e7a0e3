"""The commissioning report as one self-contained HTML document (docs/report.md).

Everything is inline (CSS, the plots as SVG, the data as JSON): the page fetches nothing, so
it reads the same offline, saved, mailed or printed. Every value from a drive, a profile or
a user is escaped (``html.escape``); the embedded JSON has its ``<`` escaped so that no value
can end the script element. Values are shown raw with their raw unit and, where the profile
gives a scale, in engineering units beside them.

A report that holds a Japanese or Chinese name (a manual's, a user's reason) carries the UI's
CJK font inline (issue 48: a server or a reader without a CJK font would print empty boxes).

The footer prints the report's id and the SHA-256 of its data (services/report.py); the
title carries both too, so that a PDF printed from the page has them in its metadata.

Over 700 lines: one self-contained page, a small function per section (identity, parameters,
PDO, limits, homing, tuning, captures, alarms, audit) over the same escaping and number helpers;
the CSS and the data embedding belong to the page as a whole.
"""

from __future__ import annotations

import base64
import json
import math
import re
from collections.abc import Iterable, Sequence
from html import escape
from pathlib import Path
from typing import Any

from servodesk.services.report import canonical

#: The id of the script element that holds the report's data (``report verify`` reads it).
DATA_ID = "servodesk-report-data"

#: The UI's CJK font as the built UI ships it (frontend/public/fonts, made by
#: scripts/cjk_subset.py), and the blocks it covers: that script's CJK_RANGES
#: (tests/profiles/test_cjk_font.py checks they agree).
CJK_FONT = Path(__file__).resolve().parents[1] / "web" / "dist" / "fonts" / "servodesk-cjk.woff2"
CJK_RANGES: tuple[tuple[int, int], ...] = (
    (0x2E80, 0x2FDF),
    (0x3000, 0x30FF),
    (0x3100, 0x31FF),
    (0x3200, 0x33FF),
    (0x3400, 0x4DBF),
    (0x4E00, 0x9FFF),
    (0xF900, 0xFAFF),
    (0xFE30, 0xFE4F),
    (0xFF00, 0xFFEF),
)
_CJK = re.compile("[" + "".join(f"\\u{lo:04x}-\\u{hi:04x}" for lo, hi in CJK_RANGES) + "]")

_CSS = """
:root { color-scheme: light; font: 10pt/1.35 system-ui, -apple-system, "Segoe UI",
  "DejaVu Sans", sans-serif, "Servodesk CJK"; color: #111; }
body { margin: 0 auto; max-width: 60rem; padding: 1.5rem; }
h1 { font-size: 1.5rem; margin: 0 0 .25rem; }
h2 { font-size: 1.1rem; margin: 1.5rem 0 .4rem; border-bottom: 1px solid #999;
  break-after: avoid; }
h3 { font-size: 1rem; margin: 1rem 0 .3rem; break-after: avoid; }
table { border-collapse: collapse; width: 100%; margin: .25rem 0 .75rem; }
th, td { border: 1px solid #ccc; padding: .15rem .35rem; text-align: left;
  vertical-align: top; }
th { background: #eee; }
tr { break-inside: avoid; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.muted { color: #555; }
.bad { color: #a00; font-weight: 600; }
.kv th { width: 14rem; }
code, .mono { font-family: "DejaVu Sans Mono", Consolas, monospace, "Servodesk CJK";
  font-size: .9em; }
svg { width: 100%; height: auto; border: 1px solid #ccc; }
footer { margin-top: 2rem; border-top: 1px solid #999; padding-top: .5rem;
  font-size: .85em; word-break: break-all; }
@page { size: A4; margin: 14mm 12mm; }
@media print { body { padding: 0; max-width: none; } }
"""


def _e(value: Any) -> str:
    """A value as escaped text ("-" for nothing)."""
    if value is None or value == "":
        return "-"
    if isinstance(value, float):
        return escape(_num(value))
    return escape(str(value))


def _num(x: float) -> str:
    if not math.isfinite(x):
        return "-"
    return f"{x:.6g}"


def value_text(
    value: Any, raw_unit: str | None, engineering: Any = None, unit: str | None = None
) -> str:
    """``1500 0.01 r/min = 15 r/min``: the raw value with its raw unit, then the engineering
    value with its unit where there is one (escaped)."""
    if value is None:
        return "-"
    out = _e(value) + (f" {_e(raw_unit)}" if raw_unit else "")
    if isinstance(engineering, int | float) and not isinstance(engineering, bool) and unit:
        if not (isinstance(value, int | float) and float(value) == float(engineering)):
            out += f" = {_e(float(engineering))} {_e(unit)}"
        elif not raw_unit:
            out += f" {_e(unit)}"
    return out


def _table(head: Sequence[str], rows: Iterable[Sequence[str]], cls: str = "") -> str:
    """A table of already escaped cells."""
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    if not body:
        return '<p class="muted">none</p>'
    th = "".join(f"<th>{escape(h)}</th>" for h in head)
    c = f' class="{cls}"' if cls else ""
    return f"<table{c}><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"


def _kv(pairs: Iterable[tuple[str, str]]) -> str:
    rows = "".join(f"<tr><th>{escape(k)}</th><td>{v}</td></tr>" for k, v in pairs)
    return f'<table class="kv"><tbody>{rows}</tbody></table>'


def _error(section: Any) -> str | None:
    if isinstance(section, dict) and "error" in section and len(section) <= 3:
        hint = f" ({_e(section.get('hint'))})" if section.get("hint") else ""
        return f'<p class="bad">not available: {_e(section["error"])}{hint}</p>'
    return None


def _hex(value: Any, digits: int = 8) -> str:
    return f"0x{value:0{digits}X}" if isinstance(value, int) else "-"


# Sections ------------------------------------------------------------------------------------


def _drive(d: dict[str, Any]) -> str:
    ident = d.get("identity") or {}
    bus = d.get("bus") or {}
    approved = d.get("approved")
    drift = d.get("drift")
    pairs = [
        ("Plant tag", _e(d.get("plant_tag"))),
        ("Drive key", f"<code>{_e(d.get('drive_key'))}</code>"),
        (
            "Family (profile)",
            f"{_e(d.get('profile_name'))} ({_e(d.get('profile_id'))} "
            f"{_e(d.get('profile_version'))})",
        ),
        ("Fieldbus", _e(d.get("fieldbus"))),
        ("Vendor id (1018h:01)", _hex(ident.get("vendor_id"))),
        ("Product code (1018h:02)", _hex(ident.get("product_code"))),
        ("Revision (1018h:03)", _hex(ident.get("revision"))),
        ("Serial number (1018h:04)", _e(ident.get("serial"))),
        ("Device name", _e(ident.get("device_name"))),
        ("Hardware version", _e(ident.get("hardware_version"))),
        ("Firmware", _e(d.get("firmware"))),
        (
            "Bus",
            f"{_e(bus.get('interface'))} {_e(bus.get('channel'))}, node "
            f"{_e(bus.get('node_id'))}"
            + (f", {_e(bus.get('bitrate'))} bit/s" if bus.get("bitrate") else ""),
        ),
        ("Session", _e(d.get("session")) + (" (simulated drive)" if d.get("simulated") else "")),
    ]
    if approved:
        pairs.append(
            (
                "Approved backup",
                f"<code>{_e(approved.get('backup'))}</code> by {_e(approved.get('by'))} at "
                f"{_e(approved.get('at'))}: {_e(approved.get('reason'))}",
            )
        )
    else:
        pairs.append(("Approved backup", "none"))
    if drift:
        pairs.append(("Last drift check", f"{_e(drift.get('state'))} ({_e(drift.get('time'))})"))
    return "<h2>Drive</h2>" + _kv(pairs)


def _differences(diffs: list[dict[str, Any]], reference: str) -> str:
    rows = []
    for d in diffs:
        kind = d.get("kind")
        ref = value_text(
            d.get("reference_value"),
            d.get("raw_unit"),
            d.get("reference_engineering"),
            d.get("unit"),
        )
        now = value_text(
            d.get("drive_value"), d.get("raw_unit"), d.get("drive_engineering"), d.get("unit")
        )
        if kind == "only_a":
            now = '<span class="muted">not read</span>'
        elif kind == "only_b":
            ref = '<span class="muted">not in it</span>'
        rows.append([f"<code>{_e(d.get('address'))}</code>", _e(d.get("name")), ref, now])
    return _table(["Object", "Name", reference, "Drive"], rows)


def _parameters(p: dict[str, Any]) -> str:
    out = ["<h2>Parameters</h2>"]
    vs_def = p.get("vs_defaults") or {}
    out.append(
        f"<p>{_e(p.get('read'))} parameters read; {_e(vs_def.get('same'))} as the profile's "
        f"defaults.</p>"
    )
    out.append("<h3>Differences from the profile's defaults</h3>")
    out.append(_differences(vs_def.get("differences") or [], "Default"))
    out.append("<h3>Differences from the approved backup</h3>")
    vs = p.get("vs_approved")
    if vs is None:
        out.append('<p class="muted">no approved backup (Fleet page: approve one)</p>')
    elif "error" in vs:
        out.append(f'<p class="bad">approved backup {_e(vs.get("backup"))}: {_e(vs["error"])}</p>')
    else:
        out.append(
            f"<p>Approved backup <code>{_e(vs.get('backup'))}</code>; "
            f"{_e(vs.get('same'))} parameters the same.</p>"
        )
        out.append(_differences(vs.get("differences") or [], "Approved"))
    unreadable = p.get("unreadable") or []
    if unreadable:
        out.append("<h3>Parameters the drive did not give</h3>")
        out.append(
            _table(
                ["Object", "Name", "Abort code", "Message"],
                (
                    [
                        f"<code>{_e(u.get('address'))}</code>",
                        _e(u.get("name")),
                        _hex(u.get("code")),
                        _e(u.get("message")),
                    ]
                    for u in unreadable
                ),
            )
        )
    return "".join(out)


def _pdo(view: Any) -> str:
    out = ["<h2>PDO layout</h2>"]
    err = _error(view)
    if err:
        return out[0] + err
    if view.get("telegram") is not None:
        out.append(f"<p>Telegram {_e(view['telegram'])}</p>")
    for p in view.get("pdos") or []:
        if not p.get("entries") and not p.get("enabled"):
            continue
        state = "enabled" if p.get("enabled") else "disabled"
        out.append(
            f"<h3>{_e(p.get('name'))} ({_e(str(p.get('direction', '')).upper())}), COB-ID "
            f"{_e(p.get('cob_id_hex'))}, {state}, {_e(p.get('bits'))} bits</h3>"
        )
        out.append(
            f'<p class="muted">transmission {_e(p.get("transmission_type"))} '
            f"({_e(p.get('transmission_text'))}), inhibit time "
            f"{_e(p.get('inhibit_time_ms'))} ms, event timer {_e(p.get('event_timer'))} ms</p>"
        )
        out.append(
            _table(
                ["Byte", "Object", "Name", "Bits", "Unit"],
                (
                    [
                        _e(e.get("offset_byte")),
                        "padding" if e.get("padding") else f"<code>{_e(e.get('address'))}</code>",
                        _e(e.get("name")),
                        _e(e.get("bits")),
                        _e(e.get("unit")),
                    ]
                    for e in p.get("entries") or []
                ),
            )
        )
    return "".join(out)


_LIMITS = (
    ("position_min", "Software position limit, min", "position"),
    ("position_max", "Software position limit, max", "position"),
    ("max_velocity", "Max velocity", "velocity"),
    ("max_torque", "Max torque", "torque"),
    ("max_acceleration", "Max acceleration", "acceleration"),
    ("max_deceleration", "Max deceleration", "acceleration"),
)


def _limits(lim: Any) -> str:
    head = "<h2>Limits</h2>"
    err = _error(lim)
    if err:
        return head + err
    units = lim.get("units") or {}
    sources = lim.get("sources") or {}
    rows = []
    for key, label, kind in _LIMITS:
        u = units.get(kind) or {}
        v = lim.get(key)
        eng = (
            v * u["scale"]
            if isinstance(v, int) and isinstance(u.get("scale"), int | float)
            else None
        )
        rows.append(
            [
                escape(label),
                value_text(v, u.get("raw_unit"), eng, u.get("unit")),
                _e(sources.get(key)),
            ]
        )
    modes = lim.get("mode_names") or {}
    body = _table(["Limit", "Value", "Source"], rows)
    body += f"<p>Modes of operation: {_e(', '.join(f'{k} {v}' for k, v in modes.items()))}</p>"
    return head + body


def _homing(h: Any) -> str:
    head = "<h2>Homing</h2>"
    err = _error(h)
    if err:
        return head + err
    m = h.get("method_description") or {}
    out = [head]
    if h.get("method") is not None:
        out.append(
            f"<p>Method {_e(h['method'])}: {_e(m.get('name'))}. "
            f'<span class="muted">{_e(m.get("description"))}</span></p>'
        )
    rows = []
    for s in h.get("settings") or []:
        if "error" in s:
            val = f'<span class="bad">{_e(s["error"])}</span>'
        else:
            val = value_text(s.get("value"), s.get("raw_unit"), s.get("engineering"), s.get("unit"))
        rows.append([f"<code>{_e(s.get('address'))}</code>", _e(s.get("name")), val])
    out.append(_table(["Object", "Name", "Value"], rows))
    return "".join(out)


def _svg_lines(
    series: Sequence[tuple[str, Sequence[float | None], Sequence[float | None]]],
    *,
    title: str,
    x_label: str,
    y_label: str,
    log_x: bool = False,
) -> str:
    """A small line plot as inline SVG (the plots need no script and print as vectors)."""
    w, h, left, bottom, top, right = 640, 240, 56, 30, 22, 10
    colours = ("#1f5fbf", "#c0392b", "#2e8b57", "#8e44ad")

    def fx(x: float) -> float:
        return math.log10(x) if log_x else x

    pts = [
        (fx(x), y)
        for _, xs, ys in series
        for x, y in zip(xs, ys, strict=False)
        if x is not None and y is not None and (x > 0 or not log_x)
    ]
    if len(pts) < 2:
        return ""
    x0, x1 = min(p[0] for p in pts), max(p[0] for p in pts)
    y0, y1 = min(p[1] for p in pts), max(p[1] for p in pts)
    if x1 == x0:
        x1 = x0 + 1
    if y1 == y0:
        y1 = y0 + 1

    def sx(x: float) -> float:
        return left + (fx(x) - x0) / (x1 - x0) * (w - left - right)

    def sy(y: float) -> float:
        return h - bottom - (y - y0) / (y1 - y0) * (h - bottom - top)

    parts = [
        f'<svg viewBox="0 0 {w} {h}" xmlns="http://www.w3.org/2000/svg" role="img" '
        f'aria-label="{escape(title)}">',
        f'<text x="{left}" y="14" font-size="12">{escape(title)}</text>',
        f'<line x1="{left}" y1="{h - bottom}" x2="{w - right}" y2="{h - bottom}" stroke="#888"/>',
        f'<line x1="{left}" y1="{top}" x2="{left}" y2="{h - bottom}" stroke="#888"/>',
        f'<text x="{w - right}" y="{h - 6}" font-size="10" text-anchor="end">'
        f"{escape(x_label)} {_num(10**x0 if log_x else x0)} .. {_num(10**x1 if log_x else x1)}"
        "</text>",
        f'<text x="4" y="{top + 8}" font-size="10">{_num(y1)}</text>',
        f'<text x="4" y="{h - bottom}" font-size="10">{_num(y0)}</text>',
        f'<text x="4" y="{(h - bottom + top) / 2}" font-size="10">{escape(y_label)}</text>',
    ]
    for i, (name, xs, ys) in enumerate(series):
        line = " ".join(
            f"{sx(x):.1f},{sy(y):.1f}"
            for x, y in zip(xs, ys, strict=False)
            if x is not None and y is not None and (x > 0 or not log_x)
        )
        colour = colours[i % len(colours)]
        parts.append(
            f'<polyline fill="none" stroke="{colour}" stroke-width="1.2" points="{line}"/>'
        )
        parts.append(
            f'<text x="{w - right - 4}" y="{top + 12 * (i + 1)}" font-size="10" '
            f'text-anchor="end" fill="{colour}">{escape(name)}</text>'
        )
    parts.append("</svg>")
    return "".join(parts)


def _numbers(values: Any) -> list[float | None]:
    if not isinstance(values, list):
        return []
    return [
        float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None for v in values
    ]


def _tuning(t: dict[str, Any] | None) -> str:
    head = "<h2>Tuning</h2>"
    if t is None:
        return head + '<p class="muted">no tuning of this drive is recorded</p>'
    out = [head]
    record = t.get("record")
    if isinstance(record, dict):
        out.append(
            f'<p class="muted">from the store: tuning {_e(record.get("id"))}, ended '
            f"{_e(record.get('ended'))} on gateway {_e(record.get('gateway'))}</p>"
        )
    out += [
        _kv(
            [
                ("Kind", _e(t.get("kind"))),
                ("Status", _e(t.get("status"))),
                ("Mode", _e(t.get("mode"))),
                ("Applied", _e(t.get("applied"))),
                ("Stored to EEPROM", _e(t.get("stored"))),
                ("Loop rate", f"{_e(t.get('loop_rate_hz'))} Hz"),
            ]
        ),
    ]
    err = t.get("error")
    if isinstance(err, dict) and err:
        out.append(f'<p class="bad">{_e(err.get("message") or err)}</p>')
    m = t.get("margins") or {}
    if m:
        out.append(
            _kv(
                [
                    ("Phase margin", f"{_e(m.get('phase_margin_deg'))} deg"),
                    ("Gain margin", f"{_e(m.get('gain_margin_db'))} dB"),
                    ("Crossover", f"{_e(m.get('crossover_hz'))} Hz"),
                    ("Bandwidth", f"{_e(m.get('bandwidth_hz'))} Hz"),
                ]
            )
        )
    gains = t.get("gains") or []
    if isinstance(gains, list) and gains:
        out.append("<h3>Gains</h3>")
        out.append(
            _table(
                ["Gain", "Object", "Before", "After"],
                (
                    [
                        _e(g.get("name")),
                        f"<code>{_e(g.get('object'))}</code>",
                        f"{_e(g.get('before'))} {_e(g.get('unit'))}",
                        f"{_e(g.get('after'))} {_e(g.get('unit'))}",
                    ]
                    for g in gains
                    if isinstance(g, dict)
                ),
            )
        )
    bode = t.get("bode") or {}
    f = _numbers(bode.get("freq_hz"))
    if f:
        out.append("<h3>Frequency response (Bode)</h3>")
        out.append(
            _svg_lines(
                [
                    ("measured", f, _numbers(bode.get("measured_mag_db"))),
                    ("model", f, _numbers(bode.get("model_mag_db"))),
                ],
                title="Magnitude",
                x_label="Hz",
                y_label="dB",
                log_x=True,
            )
        )
        out.append(
            _svg_lines(
                [
                    ("measured", f, _numbers(bode.get("measured_phase_deg"))),
                    ("model", f, _numbers(bode.get("model_phase_deg"))),
                ],
                title="Phase",
                x_label="Hz",
                y_label="deg",
                log_x=True,
            )
        )
    step = t.get("step") or {}
    series = []
    metrics = []
    for name in ("before", "after"):
        s = step.get(name)
        if isinstance(s, dict) and s.get("t_s"):
            series.append((name, _numbers(s.get("t_s")), _numbers(s.get("position"))))
            mm = s.get("metrics") or {}
            metrics.append(
                [
                    escape(name),
                    _e(mm.get("settling_s")),
                    _e(mm.get("overshoot_counts")),
                    _e(mm.get("following_error_rms")),
                ]
            )
    if series:
        out.append("<h3>Verification move, before and after</h3>")
        unit = next(
            (step[n].get("unit") for n in ("before", "after") if isinstance(step.get(n), dict)), ""
        )
        out.append(_svg_lines(series, title="Position", x_label="s", y_label=str(unit or "")))
        out.append(
            _table(["Gains", "Settling (s)", "Overshoot (counts)", "Following error RMS"], metrics)
        )
    notes = t.get("notes") or []
    if notes:
        out.append("<ul>" + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>")
    return "".join(out)


#: The most points a capture's plot draws per channel: the minimum and maximum of each of
#: half as many buckets (a peak survives, as on the Scope page's per-pixel decimation); the
#: report's data keeps every sample.
PLOT_POINTS = 1200


def decimate(
    t: Sequence[float | None], y: Sequence[float | None], points: int = PLOT_POINTS
) -> tuple[list[float | None], list[float | None]]:
    """``(t, y)`` cut to at most ``points`` samples: each bucket's minimum and maximum, in
    time order; gaps (None) are dropped."""
    pairs = [(a, b) for a, b in zip(t, y, strict=False) if a is not None and b is not None]
    if len(pairs) <= points:
        return [a for a, _ in pairs], [b for _, b in pairs]
    buckets = max(1, points // 2)
    size = len(pairs) / buckets
    ts: list[float | None] = []
    ys: list[float | None] = []
    for i in range(buckets):
        chunk = pairs[int(i * size) : int((i + 1) * size)]
        if not chunk:
            continue
        lo = min(chunk, key=lambda p: p[1])
        hi = max(chunk, key=lambda p: p[1])
        for p in sorted({lo, hi}):
            ts.append(p[0])
            ys.append(p[1])
    return ts, ys


def _period(p: Any) -> str:
    if not isinstance(p, int | float) or isinstance(p, bool) or p <= 0:
        return "-"
    return f"{_num(p * 1000.0)} ms ({_num(1.0 / p)} Hz)"


def _captures(captures: Any) -> str:
    """The kept scope captures the user attached: one plot per channel, in engineering units
    (raw x the profile's scale) against seconds from the trigger (or the buffer's start)."""
    if not isinstance(captures, list) or not captures:
        return ""
    out = ["<h2>Scope captures</h2>"]
    for c in captures:
        if not isinstance(c, dict):
            continue
        trig = c.get("trigger") if isinstance(c.get("trigger"), dict) else None
        trig_text = (
            f"{_e(trig.get('mode'))} {_e(trig.get('kind'))} on channel {_e(trig.get('channel'))}"
            f", level {_e(trig.get('level'))}, {_e(trig.get('slope'))}, "
            f"window {_e(trig.get('window_s'))} s, {_e(trig.get('pre'))} before"
            if trig
            else "none (the scope's buffer)"
        )
        out.append(f"<h3>{_e(c.get('title'))}</h3>")
        out.append(
            _kv(
                [
                    ("Capture", f"<code>{_e(c.get('id'))}</code>"),
                    ("Kept", f"{_e(c.get('time'))} by {_e(c.get('by'))} on {_e(c.get('gateway'))}"),
                    ("Trigger", trig_text),
                    ("Note", _e(c.get("note")) or '<span class="muted">-</span>'),
                ]
            )
        )
        chans = [ch for ch in c.get("channels") or [] if isinstance(ch, dict)]
        out.append(
            _table(
                ["Channel", "Object", "Source", "Unit (raw)", "Scale", "Period", "Samples"],
                (
                    [
                        _e(ch.get("name")),
                        f"<code>{_e(ch.get('address'))}</code> {_e(ch.get('session'))}",
                        _e(ch.get("source")),
                        f"{_e(ch.get('unit'))} ({_e(ch.get('raw_unit'))})",
                        _e(ch.get("scale")),
                        _period(ch.get("period_s")),
                        _e(len(ch.get("t") or [])),
                    ]
                    for ch in chans
                ),
            )
        )
        for ch in chans:
            scale = ch.get("scale")
            k = float(scale) if isinstance(scale, int | float) else 1.0
            eng = [None if v is None else v * k for v in _numbers(ch.get("v"))]
            t, y = decimate(_numbers(ch.get("t")), eng)
            unit = str(ch.get("unit") or ch.get("raw_unit") or "")
            out.append(
                _svg_lines(
                    [(str(ch.get("name") or ""), t, y)],
                    title=f"{c.get('title')}: {ch.get('name')}",
                    x_label="s",
                    y_label=unit,
                )
            )
    return "".join(out)


def _alarms(a: Any) -> str:
    head = "<h2>Alarms</h2>"
    err = _error(a)
    if err:
        return head + err
    out = [head]
    cur = a.get("current")
    if cur:
        out.append(
            f'<p class="bad">Present: {_e(cur.get("code_hex") or cur.get("code"))} '
            f"{_e(cur.get('name'))}: {_e(cur.get('cause'))}</p>"
        )
    else:
        out.append(f"<p>No alarm present (state {_e(a.get('state'))}).</p>")
    out.append("<h3>Alarm history (from the drive)</h3>")
    out.append(
        _table(
            ["#", "Code", "Name", "Cause"],
            (
                [
                    _e(i + 1),
                    _e(h.get("code_hex") or h.get("code")),
                    _e(h.get("name")),
                    _e(h.get("cause")),
                ]
                for i, h in enumerate(a.get("history") or [])
                if isinstance(h, dict)
            ),
        )
    )
    out.append("<h3>Emergency messages this session</h3>")
    out.append(
        _table(
            ["Time", "Code", "Name", "Register"],
            (
                [
                    _e(m.get("time")),
                    _e(m.get("code_hex")),
                    _e(m.get("name")),
                    _hex(m.get("register"), 2),
                ]
                for m in a.get("emcy_log") or []
            ),
        )
    )
    return "".join(out)


def _audit(records: list[dict[str, Any]]) -> str:
    return "<h2>Audit extract</h2>" + _table(
        ["#", "Time (UTC)", "Who", "Event", "Result", "Message"],
        (
            [
                _e(r.get("seq")),
                _e(r.get("time")),
                _e(r.get("user")),
                _e(r.get("event")),
                _e(r.get("result")),
                _e(r.get("message")),
            ]
            for r in records
        ),
    )


def title_of(data: dict[str, Any], digest: str) -> str:
    """The document's title: a PDF printed from the page keeps it as its Title, so the id and
    the hash are in the PDF's metadata too (``report verify`` reads them there)."""
    drive = data["drive"]
    name = drive.get("plant_tag") or drive.get("drive_key")
    return f"Commissioning report {name} - {data['report']['id']} sha256:{digest}"


def cjk_face(text: str, font: Path = CJK_FONT) -> str:
    """The @font-face of the UI's CJK font, inline, where ``text`` holds a CJK character and
    the font is there (a source checkout without the built UI has none); else nothing."""
    if not _CJK.search(text) or not font.is_file():
        return ""
    data = base64.b64encode(font.read_bytes()).decode("ascii")
    return (
        "@font-face { font-family: 'Servodesk CJK'; font-weight: 400; "
        f"src: url(data:font/woff2;base64,{data}) format('woff2'); }}"
    )


def render(data: dict[str, Any], digest: str, cjk_font: Path = CJK_FONT) -> str:
    """The report as one HTML document (text; the caller encodes it as UTF-8)."""
    rep, drive = data["report"], data["drive"]
    name = drive.get("plant_tag") or drive.get("drive_key")
    # "<" as \u003c: the JSON cannot end the script element; json.loads reads it back.
    embedded = canonical(data).decode("utf-8").replace("<", "\\u003c")
    body = [
        f"<h1>Commissioning report: {_e(name)}</h1>",
        f'<p class="muted">{_e(drive.get("profile_name"))}, drive <code>'
        f"{_e(drive.get('drive_key'))}</code>; made {_e(rep.get('generated_at'))} by "
        f"{_e(rep.get('generated_by'))} with {_e(rep.get('tool'))}</p>",
        _drive(drive),
        _parameters(data["parameters"]),
        _pdo(data.get("pdo") or {}),
        _limits(data.get("limits") or {}),
        _homing(data.get("homing") or {}),
        _tuning(data.get("tuning")),
        _captures(data.get("captures")),
        _alarms(data.get("alarms") or {}),
        _audit(data.get("audit") or []),
        f'<footer>Report <span class="mono" id="report-id">{_e(rep["id"])}</span> - '
        f'SHA-256 of its data <span class="mono" id="report-sha256">{_e(digest)}</span>. '
        "Check a copy with <code>servodesk report verify FILE</code>.</footer>",
    ]
    face = cjk_face("".join(body), cjk_font)
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        # No fetch of any kind: a saved copy reads the same anywhere (and no script runs).
        '<meta http-equiv="Content-Security-Policy" content="default-src \'none\'; '
        "style-src 'unsafe-inline'; img-src data:; font-src data:\">"
        f'<meta name="servodesk-report-id" content="{_e(rep["id"])}">'
        f'<meta name="servodesk-report-sha256" content="{_e(digest)}">'
        f"<title>{_e(title_of(data, digest))}</title><style>{face}{_CSS}</style></head><body>"
        + "".join(body)
        + f'<script type="application/json" id="{DATA_ID}">{embedded}</script>'
        + "</body></html>\n"
    )


def embedded_data(html: str) -> dict[str, Any] | None:
    """The report data embedded in a report's HTML (None: none found or not JSON)."""
    start_tag = f'<script type="application/json" id="{DATA_ID}">'
    start = html.find(start_tag)
    if start < 0:
        return None
    end = html.find("</script>", start)
    if end < 0:
        return None
    try:
        data = json.loads(html[start + len(start_tag) : end])
    except ValueError:
        return None
    return data if isinstance(data, dict) else None
