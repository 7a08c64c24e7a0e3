"""Schemathesis over the whole OpenAPI as each role (issue 45, "Measure and test").

One server with an account per role (docs/security.md, Roles), each request sent with that
account's API token: no answer is a 5xx, and an answer is 403 ``Forbidden`` exactly where the
role lacks the right the route needs (api/rights.py's table, domain/roles.py's rights). The
rights are checked before the body is validated, so every generated request, valid or not,
says which it is. tests/security/test_rights.py walks one route per right with real bodies;
this run covers every route with generated ones.
"""

from __future__ import annotations

from typing import Any

import schemathesis
from hypothesis import HealthCheck, Phase, given, settings

from servodesk.api.rights import right_for
from servodesk.domain.roles import Role, rights_of
from tests.api.test_schemathesis import _offline_bus
from tests.security.server import serve

#: One account per role (the administrator first: it is the one the server's fixture uses).
ACCOUNTS = {f"sd-{r.value}": r.value for r in Role}


def _run(op: Any, token: str, role: str, seen: dict[str, int]) -> None:
    right = right_for(op.definition.raw.get("operationId"))
    allowed = right is None or right in rights_of(role)
    # A refusal is decided from the route alone, before the body is read (api/rights.py), so
    # one example shows it; a role that has the right gets three, to see no input is refused
    # as "Forbidden". A bus scan waits its whole time-out: one example is enough there.
    n = 1 if "scan" in op.path or not allowed else 3

    @given(case=op.as_strategy().map(_offline_bus))
    @settings(
        max_examples=n,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        database=None,
        phases=[Phase.explicit, Phase.generate],
    )
    def check(case: schemathesis.Case) -> None:
        if "/ws" in case.path:  # WebSockets are not HTTP requests (test_rights.py has them).
            return
        case.headers = {**(case.headers or {}), "Authorization": f"Bearer {token}"}
        r = case.call(timeout=30)
        where = f"{role}: {case.method} {case.formatted_path} -> {r.status_code}"
        assert r.status_code < 500, f"{where}: {r.text[:300]}"
        if allowed:
            assert r.status_code != 403 or r.json().get("error") != "Forbidden", (
                f"{where}: refused although {role} has {right}: {r.text[:200]}"
            )
        else:
            assert r.status_code == 403 and r.json().get("error") == "Forbidden", (
                f"{where}: not refused although {role} lacks {right}: {r.text[:200]}"
            )
            assert r.json()["right"] == right.value  # type: ignore[union-attr]
        seen[role] = seen.get(role, 0) + 1

    check()


def test_every_route_answers_403_exactly_where_the_role_lacks_its_right() -> None:
    env = {"SERVODESK_SDO_TIMEOUT": "0.1", "SERVODESK_LOG_LEVEL": "warning"}
    with serve(accounts=ACCOUNTS, env=env) as srv:
        schema = schemathesis.openapi.from_url(
            f"{srv.base}/openapi.json", headers={"Authorization": f"Bearer {srv.token}"}
        )
        operations = [r.ok() for r in schema.get_all_operations()]
        assert len(operations) >= 60
        seen: dict[str, int] = {}
        # The guest first and the administrator last: a generated request of the
        # administrator's (a new account, an ended session) must not change the others' run.
        for role in reversed(list(Role)):
            token = srv.tokens[f"sd-{role.value}"]
            for op in operations:
                _run(op, token, role.value, seen)
        assert all(seen.get(r.value, 0) >= len(operations) for r in Role), seen
