"""The OpenAPI document checked against the live server with schemathesis (bounded examples, no streams)."""

from __future__ import annotations

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from schemathesis.checks import positive_data_acceptance

from feelium.http.openapi import openapi_document

pytestmark = pytest.mark.slow

SCHEMA = schemathesis.openapi.from_dict(openapi_document())
OPERATIONS = [r.ok() for r in SCHEMA.get_all_operations()]
# Endless responses (MJPEG, SSE, WebSocket) are covered by tests/http/test_live.py instead.
FINITE = [op for op in OPERATIONS if not op.definition.raw.get("x-streaming")]
# A JPEG or WAV body's validity is not expressible in JSON Schema: random bytes are rightly refused with 400.
OPAQUE_BODIES = {"PUT /face", "POST /speech"}


@schemathesis.serializer("audio/wav")
def _wav_bytes(ctx, value):  # type: ignore[no-untyped-def]
    return value if isinstance(value, bytes) else str(value).encode()


def test_the_document_is_valid_openapi_3_1() -> None:
    from openapi_spec_validator import validate

    validate(openapi_document())
    assert len(FINITE) >= 12


@pytest.mark.parametrize("operation", FINITE, ids=[op.label for op in FINITE])
def test_live_server_matches_the_schema_and_never_answers_5xx(live, operation) -> None:  # type: ignore[no-untyped-def]
    excluded = [positive_data_acceptance] if operation.label in OPAQUE_BODIES else []

    @settings(
        max_examples=8, deadline=None, derandomize=True, database=None,
        suppress_health_check=list(HealthCheck), phases=[Phase.explicit, Phase.generate],
    )  # fmt: skip
    @given(case=operation.as_strategy())
    def check(case) -> None:  # type: ignore[no-untyped-def]
        response = case.call(base_url=live.api, headers=live.auth, timeout=10)
        case.validate_response(response, excluded_checks=excluded)

    check()
