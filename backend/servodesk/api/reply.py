"""The base of the response models that a route builds from a service's dict (issue 51 item 1).

The PDO, scope and tuning services answer with dicts built where the data is
(services/pdo.py, services/cyclic.py, services/scope.py, services/tuning/); their routes turn
each into its response model with ``Model.model_validate(d)``. A missing key or a value of
another type then fails the request, but a key the model does not declare would be dropped
from the answer without a word (pydantic ignores undeclared keys), and the UI would lose it.
Under the test suite (``SERVODESK_STRICT_REPLIES=1``, set by tests/conftest.py) such a key
fails the request too, naming it. Served, it is left out: a 500 for a key the page does not
know yet would take a working page down.

A key a service sends only sometimes is a field with a default; its route says
``response_model_exclude_unset=True`` so that the answer has the keys the service gave, no
more (the key is optional in the OpenAPI schema, ``?:`` in schema.ts).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, model_validator

#: The environment variable that turns an undeclared key into an error (tests/conftest.py).
STRICT_ENV = "SERVODESK_STRICT_REPLIES"


class Reply(BaseModel):
    """A response model; under SERVODESK_STRICT_REPLIES=1 an undeclared key is an error."""

    # The tuning's Bode plot has keys "model_mag_db" and "model_phase_deg": not pydantic's.
    model_config = ConfigDict(protected_namespaces=())

    @model_validator(mode="before")
    @classmethod
    def _declared_only(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and os.environ.get(STRICT_ENV) == "1":
            undeclared = sorted(str(k) for k in data if k not in cls.model_fields)
            if undeclared:
                raise ValueError(
                    f"{cls.__name__} does not declare {', '.join(undeclared)}: "
                    "the answer would drop them"
                )
        return data
