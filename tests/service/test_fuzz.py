"""Schemathesis against the API's own OpenAPI document: every operation, generated requests, all
of schemathesis's checks (status codes, content types, headers and bodies against the documented responses,
not only server errors).

The app runs on SQLite and on PostgreSQL with the fuzzer's lab holding one resource of every kind; a path parameter naming a
resource gets that resource's id, so generated bodies reach the validation behind the lookups instead of
stopping at a 404. Each operation gets `FUZZ_EXAMPLES` requests, schema-valid and schema-violating mixed;
then the stateful phase chains calls along the links schemathesis infers, each scenario in an empty lab of
its own. Both together take one to one and a half minutes per backend on two cores. (The tests drive hypothesis themselves: `schemathesis.pytest.from_fixture` fails on pytest 9.)
"""

from __future__ import annotations

import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi import FastAPI
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from schemathesis.generation import GenerationMode
from schemathesis.specs.openapi.checks import positive_data_acceptance

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings
from tests.service.helpers import owned_resource_ids

FUZZ_EXAMPLES = 60
"""Generated requests per operation (hypothesis's `max_examples`)."""

EXCLUDED = [
    # A request valid by the schema can still break a rule across fields or against stored resources (a
    # transition table's shape, a trajectory's states in its MDP): the API answers those with a documented 422.
    positive_data_acceptance,
]


@pytest.fixture(scope="module")
def fuzz_app(tmp_path_factory: pytest.TempPathFactory, database_url: str) -> Iterator[FastAPI]:
    """The app on the session's database of each backend (SQLite and PostgreSQL: a NUL in a string is only
    refused by the latter's driver), rate limits off: the fuzzer is one key flooding it, and its requests
    without or with a wrong key would trip the per-address limit on failed authentications (429 instead of
    the 401 its auth checks expect; `tests/service/test_rate_limits.py` covers the limits)."""
    folder: Path = tmp_path_factory.mktemp("fuzz")
    settings = Settings(
        data_dir=folder / "var", database_url=database_url, rate_limit_per_key=0, rate_limit_per_ip=0
    )
    application = create_app(settings)
    yield application
    application.state.engine.dispose()


def new_lab_auth(app: FastAPI) -> dict[str, str]:
    """Authorization headers of a new, empty lab."""
    with app.state.sessionmaker() as session:
        return {"Authorization": f"Bearer {create_key(session, f'lab-fuzz-{secrets.token_hex(4)}')}"}


@pytest.fixture(scope="module")
def fuzz_auth(fuzz_app: FastAPI) -> dict[str, str]:
    """Authorization headers of the fuzzer's lab."""
    return new_lab_auth(fuzz_app)


@pytest.fixture(scope="module")
def fuzz_ids(fuzz_app: FastAPI, fuzz_auth: dict[str, str]) -> dict[str, str]:
    """One resource of every kind in the fuzzer's lab, keyed by the path parameter naming it."""
    with TestClient(fuzz_app) as client:
        return owned_resource_ids(fuzz_app, client, fuzz_auth)


def _schema_with_key(app: FastAPI, key: dict[str, str]) -> Any:
    """The API's OpenAPI document, called in-process through ASGI, authorised by `key["Authorization"]` as it is
    at each call (so that schemathesis knows the key is real: its auth checks then also try the request without
    it and with a bad one)."""
    api = schemathesis.openapi.from_asgi("/openapi.json", app)

    @api.auth(refresh_interval=None)
    class BearerKey:
        def get(self, case: Any, context: Any) -> str:
            return key["Authorization"]

        def set(self, case: Any, data: str, context: Any) -> None:
            case.headers = {**(case.headers or {}), "Authorization": data}

    return api


@pytest.fixture(scope="module")
def api_schema(fuzz_app: FastAPI, fuzz_auth: dict[str, str]) -> Any:
    """The OpenAPI document, called with the fuzzer's key."""
    return _schema_with_key(fuzz_app, fuzz_auth)


def test_every_operation_answers_as_its_openapi_document_says(
    api_schema: Any, fuzz_auth: dict[str, str], fuzz_ids: dict[str, str]
) -> None:
    # Each operation gets its own hypothesis run; all operations' failures are reported together.
    failures = []
    for result in api_schema.get_all_operations():
        operation = result.ok()
        ids = {name: value for name, value in fuzz_ids.items() if f"{{{name}}}" in operation.path}
        cases = st.one_of(
            [
                operation.as_strategy(mode, path_parameters=ids)
                for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE)
            ]
        )

        @given(case=cases)
        @settings(
            max_examples=FUZZ_EXAMPLES,
            deadline=None,
            database=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
        )
        def answers_as_documented(case: Any) -> None:
            case.call_and_validate(excluded_checks=EXCLUDED)

        try:
            answers_as_documented()
        except (Exception, BaseExceptionGroup) as exc:
            failures.append(f"{operation.label}: {exc}")
    assert not failures, "\n\n".join(failures)


STATEFUL_SCENARIOS = 40
"""Scenarios of the stateful phase (each up to `STATEFUL_STEPS` calls chained by the links schemathesis infers:
an id a response returned is the path parameter of a later call)."""
STATEFUL_STEPS = 10


def test_chained_calls_answer_as_the_openapi_document_says(fuzz_app: FastAPI) -> None:
    # Every scenario starts in a lab of its own, empty: what a call answers then depends only on the calls
    # before it in that scenario, so hypothesis replaying a scenario's prefix draws the same next call (with
    # one lab for all, stored resources and quotas carry over and hypothesis stops on "inconsistent data
    # generation").
    key: dict[str, str] = {}

    class Workflow(_schema_with_key(fuzz_app, key).as_state_machine()):  # type: ignore[misc]
        def setup(self) -> None:
            key.update(new_lab_auth(fuzz_app))

        def validate_response(
            self, response: Any, case: Any, additional_checks: Any = None, **kwargs: Any
        ) -> None:
            case.validate_response(
                response,
                additional_checks=additional_checks,
                excluded_checks=EXCLUDED,
                transport_kwargs=kwargs or None,
                recorder=self.recorder,
            )

    Workflow.run(
        settings=settings(
            max_examples=STATEFUL_SCENARIOS,
            stateful_step_count=STATEFUL_STEPS,
            deadline=None,
            database=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
        )
    )
