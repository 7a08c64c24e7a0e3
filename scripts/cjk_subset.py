"""Build the UI's CJK font: Noto Sans CJK cut down to the characters the UI can show.

The profiles of the Japanese and Chinese manuals' families carry their names in the manuals'
own script (``name_local``, group subtitles, alarm texts). A machine without a CJK font draws
them as empty boxes (issue 48), so the UI ships this subset as the "Servodesk CJK" web font
(frontend/src/styles.css), after the system fonts: a machine with CJK fonts keeps its own.

    PYTHONPATH=backend .venv/bin/python scripts/cjk_subset.py [--source NotoSansCJK-Regular.ttc]

The source is Debian's ``fonts-noto-cjk`` (``apt-get install fonts-noto-cjk``; SIL OFL 1.1),
face 0 of the collection (Noto Sans CJK JP: the Japanese glyph forms; the Chinese manuals'
characters are in it too). Written under frontend/public/fonts/ (vite copies public/ into the
built UI, so the wheel carries it): the font, the OFL with the font's copyright line, and
SOURCE.md naming the source version. Re-run it when a profile gains a character:
tests/profiles/test_cjk_font.py fails until then.

Needs the development dependencies fonttools and brotli (WOFF2), both pinned in uv.lock.
"""

from __future__ import annotations

import argparse
import gzip
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT_DIR = REPO / "frontend/public/fonts"
FONT = OUT_DIR / "servodesk-cjk.woff2"
FAMILY = "Servodesk CJK"
DEFAULT_SOURCE = Path("/usr/share/fonts/opentype/noto/NotoSansCJK-Regular.ttc")
DEBIAN_COPYRIGHT = Path("/usr/share/doc/fonts-noto-cjk/copyright")

#: The Unicode blocks a CJK name can draw on; the same list is the @font-face unicode-range in
#: frontend/src/styles.css, so Latin text never downloads the font.
CJK_RANGES: tuple[tuple[int, int], ...] = (
    (0x2E80, 0x2FDF),  # CJK radicals, Kangxi radicals
    (0x3000, 0x30FF),  # CJK symbols and punctuation, hiragana, katakana
    (0x3100, 0x31FF),  # bopomofo, kanbun, katakana phonetic extensions
    (0x3200, 0x33FF),  # enclosed CJK letters, CJK compatibility (㎜, ㎏)
    (0x3400, 0x4DBF),  # CJK unified ideographs extension A
    (0x4E00, 0x9FFF),  # CJK unified ideographs
    (0xF900, 0xFAFF),  # CJK compatibility ideographs
    (0xFE30, 0xFE4F),  # CJK compatibility forms
    (0xFF00, 0xFFEF),  # halfwidth and fullwidth forms
)

#: Shipped whatever the profiles hold, for text typed into the UI's search boxes and names a
#: manual may gain: the ideographic space and punctuation (U+3000-303F) and the fullwidth
#: ASCII forms and yen/pound signs the Japanese manuals set (U+FF01-FF5E, U+FFE0-FFE6).
ALWAYS: frozenset[str] = frozenset(
    chr(c)
    for lo, hi in ((0x3000, 0x303F), (0xFF01, 0xFF5E), (0xFFE0, 0xFFE6))
    for c in range(lo, hi + 1)
)

_CJK = re.compile("[" + "".join(f"\\u{lo:04x}-\\u{hi:04x}" for lo, hi in CJK_RANGES) + "]")


def cjk_characters(text: str) -> set[str]:
    """The characters of ``text`` in the CJK ranges."""
    return set(_CJK.findall(text))


def shown_characters(repo: Path = REPO) -> set[str]:
    """Every CJK character the UI can show: the profiles' text and the UI's own sources."""
    chars: set[str] = set()
    for path in sorted(repo.glob("profiles/*/profile.yaml")):
        chars |= cjk_characters(path.read_text("utf-8"))
    for path in sorted((repo / "frontend/src").rglob("*")):
        if path.suffix in {".ts", ".tsx", ".css"} and ".test." not in path.name:
            chars |= cjk_characters(path.read_text("utf-8"))
    return chars


def css_unicode_range() -> str:
    """CJK_RANGES as a CSS unicode-range value."""
    return ", ".join(f"U+{lo:04X}-{hi:04X}" for lo, hi in CJK_RANGES)


def _ofl_text() -> str:
    """The SIL OFL 1.1 text as Debian ships it with the font (its copyright file)."""
    raw = DEBIAN_COPYRIGHT.read_bytes()
    text = (gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw).decode("utf-8")
    block = text.split("License: SIL-1.1\n", 2)[2].split("\nLicense:", 1)[0]
    lines = [line[1:] if line.startswith(" ") else line for line in block.splitlines()]
    return "\n".join("" if line == "." else line for line in lines).strip() + "\n"


def _debian_version() -> str:
    """The installed fonts-noto-cjk package's version, for the source note."""
    try:
        out = subprocess.run(
            ["dpkg-query", "-W", "-f=${Version}", "fonts-noto-cjk"],
            capture_output=True,
            text=True,
            check=True,
        )
    except (OSError, subprocess.CalledProcessError):
        return "(version unknown)"
    return out.stdout.strip()


def build(source: Path, out_dir: Path = OUT_DIR) -> tuple[Path, int, str]:
    """Write the subset font, its licence and its source note; the font's path, its number of
    characters and the source's version string."""
    from fontTools import subset

    options = subset.Options()
    options.flavor = "woff2"
    # Horizontal text only: the vertical metrics (vhea/vmtx/VORG) and the BASE table serve
    # vertical CJK layout, which the UI never uses; dropping them keeps the download small.
    options.drop_tables += ["vhea", "vmtx", "VORG", "BASE"]
    options.hinting = False  # The CFF hints; browsers at UI sizes render CJK as well without.
    # No OpenType layout features: they map the kept characters to alternates the UI never
    # asks for (vertical forms, proportional kana, other locales' glyphs) and would double
    # the file; the default glyph of each character is what a plain horizontal label uses.
    options.layout_features = []
    # Flat charstrings compress better under WOFF2's Brotli than CFF subroutines (measured:
    # 81 kB with them, 76 kB without).
    options.desubroutinize = True
    # The copyright, names, version, trademark and licence records (OFL 1.1 condition 2).
    options.name_IDs = [0, 1, 2, 3, 4, 5, 6, 7, 13, 14]
    options.font_number = 0  # Noto Sans CJK JP in the collection
    font = subset.load_font(str(source), options)
    font.recalcTimestamp = False  # The source's date: the same input gives the same bytes.
    name = font["name"]
    copyright_line = name.getDebugName(0) or ""
    version = name.getDebugName(5) or "unknown"
    source_family = name.getDebugName(1) or source.name
    have = {chr(c) for c in font.getBestCmap()}
    missing = sorted(shown_characters() - have)
    if missing:
        raise SystemExit(f"cjk_subset: {source} lacks {''.join(missing)}")
    chars = (shown_characters() | ALWAYS) & have
    subsetter = subset.Subsetter(options)
    subsetter.populate(unicodes=sorted(ord(c) for c in chars))
    subsetter.subset(font)
    # OFL 1.1 §3: a Modified Version does not keep the Reserved Font Name ("Source", the
    # Source Han Sans origin Noto CJK declares) as its primary name; renamed to our family.
    postscript = FAMILY.replace(" ", "")
    for record in font["name"].names:
        if record.nameID in (1, 4, 16):
            record.string = FAMILY
        elif record.nameID == 3:
            record.string = f"{postscript}-Regular;subset of {source_family} {version}"
        elif record.nameID == 6:
            record.string = f"{postscript}-Regular"
    out_dir.mkdir(parents=True, exist_ok=True)
    font_path = out_dir / FONT.name
    subset.save_font(font, str(font_path), options)
    (out_dir / "OFL.txt").write_text(f"{copyright_line}\n\n{_ofl_text()}", "utf-8")
    (out_dir / "SOURCE.md").write_text(
        f"# {FONT.name}\n\n"
        f"A subset of {source_family} ({version}), face 0 of `{source.name}` from Debian's "
        f"`fonts-noto-cjk` {_debian_version()} (upstream https://github.com/googlefonts/noto-cjk), "
        f"renamed {FAMILY!r}. Licence: SIL Open Font License 1.1 (OFL.txt beside it).\n\n"
        f"It holds {len(chars)} characters: the {len(shown_characters())} CJK characters the UI "
        "can show from profiles/ and frontend/src, and CJK punctuation and the fullwidth forms. "
        "Regenerate with "
        "`PYTHONPATH=backend .venv/bin/python scripts/cjk_subset.py` (docs/ui.md).\n",
        "utf-8",
    )
    return font_path, len(chars), version


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--source", type=Path, default=DEFAULT_SOURCE, help="Noto Sans CJK .ttc")
    args = parser.parse_args(argv)
    if not args.source.is_file() or not DEBIAN_COPYRIGHT.is_file():
        print(
            f"cjk_subset: {args.source} or {DEBIAN_COPYRIGHT} not found: "
            "apt-get install --no-install-recommends fonts-noto-cjk",
            file=sys.stderr,
        )
        return 2
    # fontTools writes WOFF2 with brotli; both are development dependencies (uv.lock).
    absent = [m for m in ("fontTools", "brotli") if importlib.util.find_spec(m) is None]
    if absent:
        print(f"cjk_subset: {', '.join(absent)} not installed: run make setup", file=sys.stderr)
        return 2
    path, count, version = build(args.source)
    size = path.stat().st_size
    print(f"cjk_subset: {path.relative_to(REPO)}: {count} characters, {size} bytes ({version})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
