"""``servodesk openapi``: print the OpenAPI schema (the frontend's types are generated from it)."""

from __future__ import annotations

import argparse
import json
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser("openapi", help="print the OpenAPI schema as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from servodesk.api.app import create_app

    print(json.dumps(create_app().openapi(), indent=2, sort_keys=True))
    return 0
