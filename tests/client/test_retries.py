"""Retries, backoff, ``Retry-After``, idempotency keys and error classes, against `httpx.MockTransport`."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterator

import httpx
import pytest

from metairl_client import (
    APIConnectionError,
    APIStatusError,
    APITimeoutError,
    AsyncClient,
    AuthenticationError,
    BadRequestError,
    Client,
    ConflictError,
    InternalServerError,
    MetairlError,
    NotFoundError,
    PermissionDeniedError,
    RateLimitError,
    RequestTooLargeError,
    ServiceUnavailableError,
    UnprocessableEntityError,
    _transport,
)

BASE = "http://metairl.test"
JOB = {"id": "job_1", "status": "queued", "progress": None, "error": None}
Handler = Callable[[httpx.Request], httpx.Response]


def problem(status: int, **headers: str) -> httpx.Response:
    """A problem+json answer of ``status``."""
    body = {"type": "about:blank", "title": "Nope", "status": status, "detail": f"status {status}"}
    return httpx.Response(status, json=body, headers={"content-type": "application/problem+json", **headers})


def scripted(*answers: httpx.Response | Exception) -> tuple[Handler, list[httpx.Request]]:
    """A handler giving ``answers`` in turn (an exception is raised), and the requests it saw."""
    seen: list[httpx.Request] = []
    queue: Iterator[httpx.Response | Exception] = iter(answers)

    def handle(request: httpx.Request) -> httpx.Response:
        seen.append(request)
        answer = next(queue)
        if isinstance(answer, Exception):
            raise answer
        return answer

    return handle, seen


@pytest.fixture
def waits(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The seconds the client waited between tries (recorded, not slept)."""
    recorded: list[float] = []

    async def async_record(seconds: float) -> None:
        recorded.append(seconds)

    monkeypatch.setattr(_transport, "sleep", recorded.append)
    monkeypatch.setattr(_transport, "async_sleep", async_record)
    return recorded


def lab(handler: Handler) -> Client:
    """A client whose requests ``handler`` answers."""
    return Client(httpx.Client(transport=httpx.MockTransport(handler), base_url=BASE))


def test_a_429_is_retried_after_its_retry_after(waits: list[float]) -> None:
    handler, seen = scripted(problem(429, **{"Retry-After": "3"}), httpx.Response(200, json=JOB))
    assert lab(handler).get_job("job_1").status == "queued"
    assert (len(seen), waits) == (2, [3.0])


def test_a_503_without_retry_after_backs_off_exponentially(waits: list[float]) -> None:
    handler, seen = scripted(problem(503), problem(503), httpx.Response(200, json=JOB))
    assert lab(handler).get_job("job_1").id == "job_1"
    assert len(seen) == 3
    assert 0.375 <= waits[0] <= 0.5 and 0.75 <= waits[1] <= 1.0


def test_a_connection_error_is_retried_then_succeeds(waits: list[float]) -> None:
    handler, seen = scripted(httpx.ConnectError("refused"), httpx.Response(200, json=JOB))
    assert lab(handler).get_job("job_1").id == "job_1"
    assert len(seen) == 2 and len(waits) == 1


def test_every_try_of_one_post_carries_the_same_idempotency_key(waits: list[float]) -> None:
    handler, seen = scripted(
        httpx.ReadError("reset"), problem(503, **{"Retry-After": "0"}), httpx.Response(202, json=JOB)
    )
    client = lab(handler)
    assert client.submit_job("dem_1").id == "job_1"
    keys = {request.headers["Idempotency-Key"] for request in seen}
    assert len(seen) == 3 and len(keys) == 1
    handler_2, seen_2 = scripted(httpx.Response(202, json=JOB))
    lab(handler_2).submit_job("dem_1")
    assert seen_2[0].headers["Idempotency-Key"] not in keys  # a new call, a new key


def test_gets_carry_no_idempotency_key() -> None:
    handler, seen = scripted(httpx.Response(200, json=JOB))
    lab(handler).get_job("job_1")
    assert "Idempotency-Key" not in seen[0].headers


def test_retries_run_out_into_the_error_of_the_last_answer(waits: list[float]) -> None:
    handler, seen = scripted(*[problem(503, **{"Retry-After": "1"})] * 3)
    with pytest.raises(ServiceUnavailableError) as caught:
        lab(handler).get_job("job_1")
    assert len(seen) == 3 and waits == [1.0, 1.0]
    assert caught.value.retry_after_s == 1.0 and caught.value.problem["detail"] == "status 503"


def test_a_retry_after_longer_than_the_limit_is_raised_not_slept(waits: list[float]) -> None:
    handler, seen = scripted(problem(429, **{"Retry-After": "3600"}))
    with pytest.raises(RateLimitError) as caught:
        lab(handler).get_job("job_1")
    assert (len(seen), waits, caught.value.retry_after_s) == (1, [], 3600.0)


def test_with_options_max_retries_zero_sends_once(waits: list[float]) -> None:
    handler, seen = scripted(problem(503))
    with pytest.raises(ServiceUnavailableError):
        lab(handler).with_options(max_retries=0).get_job("job_1")
    assert len(seen) == 1 and waits == []


def test_no_answer_raises_a_connection_error_and_a_timeout_its_own(waits: list[float]) -> None:
    handler, _ = scripted(*[httpx.ConnectError("refused")] * 3)
    with pytest.raises(APIConnectionError, match=r"Cannot reach the service \(GET /v1/jobs/job_1\): refused"):
        lab(handler).get_job("job_1")
    handler, _ = scripted(*[httpx.ReadTimeout("slow")] * 3)
    with pytest.raises(APITimeoutError) as caught:
        lab(handler).get_job("job_1")
    assert isinstance(caught.value, MetairlError) and caught.value.status is None


@pytest.mark.parametrize(
    ("status", "kind"),
    [
        (400, BadRequestError),
        (401, AuthenticationError),
        (403, PermissionDeniedError),
        (404, NotFoundError),
        (409, ConflictError),
        (413, RequestTooLargeError),
        (418, APIStatusError),
        (422, UnprocessableEntityError),
        (500, InternalServerError),
        (502, InternalServerError),
    ],
)
def test_each_error_status_raises_its_class_carrying_the_problem(
    status: int, kind: type[APIStatusError]
) -> None:
    handler, seen = scripted(problem(status))
    with pytest.raises(kind) as caught:
        lab(handler).get_job("job_1")
    assert type(caught.value) is kind and isinstance(caught.value, MetairlError)
    assert caught.value.status == status and caught.value.problem["detail"] == f"status {status}"
    assert len(seen) == 1  # not retried


def test_the_async_client_retries_the_same_way(waits: list[float]) -> None:
    handler, seen = scripted(
        httpx.ConnectError("refused"), problem(429, **{"Retry-After": "2"}), httpx.Response(202, json=JOB)
    )

    async def submit() -> str:
        transport = httpx.MockTransport(handler)
        async with AsyncClient(httpx.AsyncClient(transport=transport, base_url=BASE)) as client:
            return (await client.submit_job("dem_1")).id

    assert asyncio.run(submit()) == "job_1"
    assert len(seen) == 3 and waits[1] == 2.0
    assert len({request.headers["Idempotency-Key"] for request in seen}) == 1
