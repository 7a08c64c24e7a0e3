"""What every part of the device profile model shares: the strict model configuration and the
validators of authored data types and object addresses (domain/profile.py and its parts
profile_pdo.py, profile_tuning.py, profile_network.py)."""

from __future__ import annotations

from typing import Any

from pydantic import ConfigDict

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.errors import ServodeskError

#: Unknown keys are refused (a typo in profile.yaml is an error, not a silent default).
STRICT = ConfigDict(extra="forbid", frozen=True, use_enum_values=False)


def parse_data_type(v: Any) -> Any:
    """A data type as authored (``"UNSIGNED16"``) -> :class:`DataType`."""
    if isinstance(v, str):
        try:
            return DataType.from_name(v)
        except ServodeskError as exc:  # pydantic reports ValueErrors with their place.
            raise ValueError(f"{exc.message} ({exc.hint})") from None
    return v


def check_address(v: str) -> str:
    """An object address as authored (``"0x2101:00"``, ``"P922"``); kept as written."""
    try:
        ObjectAddress.parse(v)
    except ServodeskError as exc:  # pydantic reports ValueErrors with their place.
        raise ValueError(exc.message) from exc
    return v
