"""Helpers shared by the PDO tests."""

from __future__ import annotations

from typing import Any


def layout_of(proposal: dict[str, Any]) -> dict[str, Any]:
    """The body of ``POST .../pdo/apply`` for a template's proposal
    (``POST .../pdo/templates/{id}``): its PDOs' entries, telegram and assignment."""
    return {
        "pdos": [
            {
                "direction": p["direction"],
                "number": p["number"],
                "entries": [
                    {"index": e["index"], "subindex": e["subindex"], "bits": e["bits"]}
                    for e in p["entries"]
                ],
            }
            for p in proposal["pdos"]
        ],
        "telegram": proposal["telegram"],
        "assignment": proposal["assignment"],
    }
