"""A report's PDF, printed by the system's headless Chromium, and finding a report's id and
hash in a PDF again (docs/report.md).

Chromium is found as the browser tests find it (tests/browser/harness.py):
``SERVODESK_CHROMIUM``, else ``chromium`` on PATH. It prints the report's own HTML from a
private temporary directory, with a fresh profile and no background network, and is killed
after :data:`TIMEOUT_S`. The page runs no script and fetches nothing: its
Content-Security-Policy is ``default-src 'none'`` (JavaScript cannot be switched off by flag:
``--blink-settings=scriptEnabled=false`` makes Chromium 156 print no PDF at all).

The page's ``<title>`` carries the report id and hash; Chromium writes the title as the PDF's
``/Title`` (PDF 32000-1 §14.3.3, the document information dictionary), where
:func:`find_in_pdf` reads it back.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path

from servodesk.errors import ToolMissing, WorkerFailed

#: The longest a print may take, s (a report of a few hundred rows prints in 1-4 s).
TIMEOUT_S = 60.0

#: Chromiums printing at once (each takes a few hundred MB; the machine has other work).
_PRINTERS = threading.BoundedSemaphore(2)

#: What the title (and the HTML footer) says: ``<report id> sha256:<64 hex>``.
ID_HASH_RE = re.compile(r"(report-[a-z0-9._-]{1,56}) sha256:([0-9a-f]{64})")


def chromium() -> str:
    """The Chromium to print with; ToolMissing (503) saying what to install when none."""
    path = os.environ.get("SERVODESK_CHROMIUM") or shutil.which("chromium")
    if not path or not Path(path).is_file():
        raise ToolMissing(
            "printing a report as PDF needs Chromium, which is not installed on the server",
            hint="install it (Debian: apt-get install chromium) or name it with "
            "SERVODESK_CHROMIUM=/path/to/chromium; the HTML report works without it",
        )
    return path


def print_pdf(html: bytes, timeout_s: float = TIMEOUT_S) -> bytes:
    """``html`` printed to PDF (A4, the page's own @page margins, no header or footer).

    Blocking: run it in a thread (``asyncio.to_thread``)."""
    exe = chromium()
    with _PRINTERS, tempfile.TemporaryDirectory(prefix="servodesk-report-") as tmp:
        page, out = Path(tmp) / "report.html", Path(tmp) / "report.pdf"
        page.write_bytes(html)
        args = [
            exe,
            "--headless=new",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            f"--user-data-dir={Path(tmp) / 'profile'}",
            "--no-pdf-header-footer",
            f"--print-to-pdf={out}",
        ]
        if os.geteuid() == 0:
            args.append("--no-sandbox")  # Chromium refuses to run as root with its sandbox.
        args.append(page.as_uri())
        try:
            done = subprocess.run(args, capture_output=True, timeout=timeout_s, check=False)
        except subprocess.TimeoutExpired:
            raise WorkerFailed(
                f"Chromium did not print the report within {timeout_s:.0f} s",
                hint="try again; a loaded server may need longer",
            ) from None
        except OSError as exc:
            raise ToolMissing(
                f"cannot start Chromium ({exe}): {exc.strerror or exc}",
                hint="check SERVODESK_CHROMIUM, or install Chromium (apt-get install chromium)",
            ) from exc
        if not out.is_file() or out.stat().st_size == 0:
            tail = done.stderr.decode("utf-8", "replace").strip().splitlines()[-3:]
            raise WorkerFailed(
                f"Chromium printed no PDF (exit code {done.returncode})",
                hint="; ".join(tail) or "see the server log",
            )
        return out.read_bytes()


def _pdf_strings(data: bytes) -> list[str]:
    """The texts of a PDF's /Title entries: literal ``(...)`` strings and UTF-16 hex
    ``<FEFF...>`` strings (PDF 32000-1 §7.9.2.2: text strings)."""
    out: list[str] = []
    for m in re.finditer(rb"/Title\s*\(((?:[^()\\]|\\.)*)\)", data):
        out.append(re.sub(rb"\\(.)", rb"\1", m.group(1)).decode("latin-1"))
    for m in re.finditer(rb"/Title\s*<([0-9A-Fa-f\s]*)>", data):
        raw = bytes.fromhex(re.sub(rb"\s", b"", m.group(1)).decode("ascii"))
        if raw.startswith(b"\xfe\xff"):
            out.append(raw[2:].decode("utf-16-be", "replace"))
        else:
            out.append(raw.decode("latin-1"))
    return out


def find_in_pdf(data: bytes) -> tuple[str, str] | None:
    """The report id and hash a report's PDF names in its metadata (None: none there)."""
    for text in _pdf_strings(data):
        m = ID_HASH_RE.search(text)
        if m:
            return m.group(1), m.group(2)
    return None


def find_in_html(text: str) -> tuple[str, str] | None:
    """The report id and hash a report's HTML names in its title (None: none there)."""
    m = re.search(r"<title>([^<]*)</title>", text)
    if m:
        found = ID_HASH_RE.search(m.group(1))
        if found:
            return found.group(1), found.group(2)
    return None
