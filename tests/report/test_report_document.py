"""The report's pure parts (docs/report.md): the canonical hash, the HTML's escaping and
units, and finding a report's id and hash in a PDF's metadata."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from servodesk.services.report import canonical, content_hash
from servodesk.services.report_html import embedded_data, render, value_text
from servodesk.services.report_pdf import find_in_html, find_in_pdf

RID = "report-20261207t142600z-a1b2c3"


def _data(**drive: Any) -> dict[str, Any]:
    return {
        "format": "servodesk.report/1",
        "report": {"id": RID, "generated_at": "t", "generated_by": "eng", "tool": "servodesk"},
        "drive": {"drive_key": "k", "plant_tag": None, **drive},
        "parameters": {"read": 0, "vs_defaults": {"differences": [], "same": 0}},
    }


def test_the_hash_does_not_depend_on_key_order_and_json_has_no_nan() -> None:
    a = {"b": 1, "a": [1.5, (2, 3)], "x": math.nan}
    b = {"x": None, "a": [1.5, [2, 3]], "b": 1}
    assert canonical(a) == canonical(b) == b'{"a":[1.5,[2,3]],"b":1,"x":null}'
    assert content_hash(a) == content_hash(b)
    assert content_hash({**a, "b": 2}) != content_hash(a)


def test_every_value_is_escaped_and_the_data_cannot_end_its_script() -> None:
    data = _data(profile_name="</script><img src=x onerror=alert(1)>")
    digest = content_hash(data)
    html = render(data, digest)
    assert "<img src=x" not in html and "&lt;img src=x onerror=alert(1)&gt;" in html
    assert html.count("</script>") == 1  # only the data element's own end
    assert embedded_data(html) == data and find_in_html(html) == (RID, digest)


def test_values_show_the_raw_unit_and_the_engineering_unit() -> None:
    assert value_text(1500, "0.01 r/min", 15.0, "r/min") == "1500 0.01 r/min = 15 r/min"
    assert value_text(3, None, 3.0, "ms") == "3 ms"
    assert value_text(None, "inc", None, None) == "-"


def test_the_id_and_hash_are_found_in_a_pdf_title_literal_or_utf16() -> None:
    digest = "0f" * 32
    title = f"Commissioning report Ä - {RID} sha256:{digest}"
    literal = b"%PDF-1.4\n<</Title (" + title.encode("latin-1") + b")>>"
    utf16 = b"%PDF-1.4\n<</Title <FEFF" + title.encode("utf-16-be").hex().encode() + b">>>"
    assert find_in_pdf(literal) == find_in_pdf(utf16) == (RID, digest)
    assert find_in_pdf(b"%PDF-1.4\n<</Title (something else)>>") is None


def test_a_tuning_result_shows_margins_gains_bode_and_steps() -> None:
    step = {"t_s": [0.0, 0.1, 0.2], "position": [0.0, 90.0, 100.0], "unit": "counts"}
    tuning = {
        "kind": "gains",
        "status": "done",
        "margins": {"phase_margin_deg": 47.5, "gain_margin_db": 9.1, "crossover_hz": 80.0},
        "gains": [
            {"name": "kv", "object": "0x2101:00", "unit": "A/(rad/s)", "before": 1, "after": 2}
        ],
        "bode": {
            "freq_hz": [10.0, 100.0, 1000.0],
            "measured_mag_db": [0.0, -20.0, None],
            "model_mag_db": [0.0, -21.0, -40.0],
            "measured_phase_deg": [-90.0, -120.0, -170.0],
            "model_phase_deg": [-90.0, -125.0, -175.0],
        },
        "step": {
            "before": step | {"metrics": {"settling_s": 0.2}},
            "after": step | {"metrics": {"settling_s": 0.1}},
        },
    }
    html = render({**_data(), "tuning": tuning}, "00" * 32)
    assert "47.5 deg" in html and "9.1 dB" in html and "0x2101:00" in html
    assert html.count("<svg") == 3  # magnitude, phase, the steps before and after


def test_a_report_with_a_japanese_name_carries_the_cjk_font_inline() -> None:
    """A report prints the same on a server and a reader without a CJK font (issue 48): the
    UI's font is inside it where it holds a CJK character, and only then."""
    font = Path(__file__).resolve().parents[2] / "frontend/public/fonts/servodesk-cjk.woff2"
    japanese = _data(profile_name="速度・加減速")
    html = render(japanese, content_hash(japanese), cjk_font=font)
    assert "font-family: 'Servodesk CJK'" in html and "data:font/woff2;base64," in html
    assert "font-src data:" in html  # The page's own CSP lets the inline font in, nothing more.
    latin = _data(profile_name="CiA 402 generic")
    assert "data:font/woff2" not in render(latin, content_hash(latin), cjk_font=font)
