"""Property-based run over the OpenAPI schema against a live ``serve --sim``.

Every operation gets generated requests (bounded); no answer may be a 5xx or violate the
documented schema. (Driven through schemathesis' Python API: its pytest plugin does not
support the pytest version pinned here.)
"""

from __future__ import annotations

import schemathesis
from hypothesis import HealthCheck, given, settings

from tests.live import live_server


def test_no_5xx_and_answers_match_the_schema() -> None:
    # A short SDO time-out keeps requests to absent nodes quick; only the generic drive runs.
    env = {"SERVODESK_SDO_TIMEOUT": "0.1", "SERVODESK_SIM_PROFILES": "cia402-generic"}
    with live_server(env=env) as base:
        schema = schemathesis.openapi.from_url(f"{base}/openapi.json")
        operations = [r.ok() for r in schema.get_all_operations()]
        assert len(operations) >= 11
        for op in operations:
            # A bus scan waits its whole time-out; fewer examples keep the run bounded.
            n = 5 if "scan" in op.path else 15

            @given(case=op.as_strategy())
            @settings(
                max_examples=n,
                deadline=None,
                suppress_health_check=list(HealthCheck),
                database=None,
            )
            def check(case: schemathesis.Case) -> None:
                case.call_and_validate()

            check()
