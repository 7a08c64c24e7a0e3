"""Object dictionary addresses (CiA 301 §7.4.1: 16-bit index, 8-bit subindex)."""

from __future__ import annotations

import re
from dataclasses import dataclass

from servodesk.errors import ValidationError

_ADDR = re.compile(r"^\s*(?:0x)?([0-9a-f]{1,4})h?\s*(?:[:.]\s*(?:0x)?([0-9a-f]{1,2})h?)?\s*$", re.I)
_PNU = re.compile(r"^\s*P(\d{1,5})(?:\s*[:.\[]\s*(\d{1,3})\]?)?\s*$", re.I)


@dataclass(frozen=True, order=True, slots=True)
class ObjectAddress:
    """One object dictionary entry: ``index`` 0..0xFFFF, ``subindex`` 0..0xFF."""

    index: int
    subindex: int = 0

    def __post_init__(self) -> None:
        if not 0 <= self.index <= 0xFFFF:
            raise ValidationError(f"index {self.index:#x} is outside 0x0000..0xFFFF")
        if not 0 <= self.subindex <= 0xFF:
            raise ValidationError(f"subindex {self.subindex} is outside 0..255")

    def __str__(self) -> str:
        return f"0x{self.index:04X}:{self.subindex:02X}"

    @property
    def pnu(self) -> int:
        """PROFIdrive parameter number: the CiA index in decimal (LECSN manual §20.2)."""
        return self.index

    @classmethod
    def parse(cls, text: str, *, default_subindex: int = 0) -> ObjectAddress:
        """Parse ``0x6040``, ``0x6040:00``, ``6040h.1``, ``6040`` or a PNU ``P24640[0]``.

        A bare number is read as hex (the way manuals print indices); a PNU is decimal.
        """
        m = _PNU.match(text)
        if m:
            sub = int(m.group(2)) if m.group(2) else default_subindex
            return cls(int(m.group(1)), sub)
        m = _ADDR.match(text)
        if not m:
            raise ValidationError(
                f"{text!r} is not an object address",
                hint="write it as 0x6040, 0x6040:00, 6040h.0 or (PROFINET) P24640",
            )
        sub = int(m.group(2), 16) if m.group(2) else default_subindex
        return cls(int(m.group(1), 16), sub)
