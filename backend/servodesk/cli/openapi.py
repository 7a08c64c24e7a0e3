"""``servodesk openapi``: print the OpenAPI schema (the frontend's types are generated from it)."""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser("openapi", help="print the OpenAPI schema as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from servodesk.api.app import create_app
    from servodesk.settings import Settings

    # The schema depends on the code only. The application is built on a throw-away data
    # directory and the default SQLite store: printing it must neither open the user's store
    # (a store made by a newer servodesk refused an older one's `openapi`; a
    # SERVODESK_STORE_URL would have been connected to) nor leave files behind.
    with tempfile.TemporaryDirectory(prefix="servodesk-openapi-") as d:
        settings = Settings(data_dir=Path(d), store_url="", viewer_port=0)
        print(json.dumps(create_app(settings).openapi(), indent=2, sort_keys=True))
    return 0
