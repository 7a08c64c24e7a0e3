"""The UI's CJK font draws every Japanese and Chinese character of the profiles (issue 48).

A machine without CJK fonts shows the manuals' names (name_local, group subtitles, alarm
texts) only through "Servodesk CJK", a subset of Noto Sans CJK cut to the characters the UI
can show (scripts/cjk_subset.py). A profile that gains a character the subset lacks would show
an empty box there: this fails until the script is re-run.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

from fontTools.ttLib import TTFont

REPO = Path(__file__).resolve().parents[2]
FONT = REPO / "frontend/public/fonts/servodesk-cjk.woff2"
STYLES = REPO / "frontend/src/styles.css"


def cjk_subset() -> ModuleType:
    spec = importlib.util.spec_from_file_location("cjk_subset", REPO / "scripts/cjk_subset.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["cjk_subset"] = module
    spec.loader.exec_module(module)
    return module


def font_characters() -> set[str]:
    return {chr(c) for c in TTFont(FONT).getBestCmap()}


def test_every_cjk_character_of_the_profiles_is_in_the_shipped_font() -> None:
    script = cjk_subset()
    missing = sorted(script.shown_characters() - font_characters())
    assert not missing, (
        f"{FONT.relative_to(REPO)} lacks {''.join(missing)} (U+"
        + ", U+".join(f"{ord(c):04X}" for c in missing)
        + "), which the profiles or the UI show: run "
        "`PYTHONPATH=backend .venv/bin/python scripts/cjk_subset.py` "
        "(apt-get install fonts-noto-cjk first) and commit frontend/public/fonts/"
    )


def test_the_profiles_japanese_names_are_found() -> None:
    """The collection sees the profiles' text: a group subtitle and an alarm of two families."""
    chars = cjk_subset().shown_characters()
    assert set("ホーミング") <= chars  # CTMM04x homing (003 §4-4-7)
    assert set("信号を受信しました") <= chars  # HIWIN E alarm 9A1h
    assert len(chars) > 400


def test_the_font_holds_only_cjk() -> None:
    """Latin text never needs it, so it neither carries Latin glyphs nor is fetched for them."""
    script = cjk_subset()
    extra = sorted(c for c in font_characters() if not script.cjk_characters(c))
    assert not extra, f"non-CJK characters in the font: {extra}"


def test_the_css_unicode_range_is_the_scripts() -> None:
    """The @font-face's unicode-range lists the script's ranges, no wider (Latin text would
    download the font) and no narrower (a character in the font would never be used)."""
    css = STYLES.read_text("utf-8")
    face = re.search(r"@font-face\s*\{[^}]*'Servodesk CJK'[^}]*\}", css)
    assert face is not None, "styles.css has no @font-face for 'Servodesk CJK'"
    found = re.search(r"unicode-range:\s*([^;]+);", face.group(0))
    assert found is not None
    assert " ".join(found.group(1).split()) == cjk_subset().css_unicode_range()


def test_the_reports_cjk_ranges_are_the_scripts() -> None:
    """A commissioning report embeds the font where it holds a character of these ranges
    (services/report_html.py): the same as the font's."""
    from servodesk.services.report_html import CJK_RANGES

    assert cjk_subset().CJK_RANGES == CJK_RANGES
