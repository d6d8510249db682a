"""Sending one API call with retries: exponential backoff on connection errors and timeouts, and on 429 and
503 answers for as long as their ``Retry-After`` says; every POST carries one ``Idempotency-Key`` for all its
tries, so the service creates nothing twice (docs/client.md, "Retries")."""

from __future__ import annotations

import asyncio
import random
import time
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Generic, TypeVar

import httpx
import numpy as np
from httpx._client import UseClientDefault  # the type of httpx.USE_CLIENT_DEFAULT

from metairl_client._errors import (
    APIConnectionError,
    APITimeoutError,
    InvalidRequestError,
    error_from_response,
    retry_after_s,
)

T = TypeVar("T")

RETRY_STATUSES = frozenset({429, 503})
"""Answers that mean "not now": retried after their ``Retry-After`` (or the backoff)."""
RETRY_ERRORS = (httpx.TimeoutException, httpx.NetworkError, httpx.RemoteProtocolError)
"""Transport failures worth another try (a refused or dropped connection, a timeout)."""
IDEMPOTENCY_HEADER = "Idempotency-Key"

Timeout = float | httpx.Timeout | None | UseClientDefault
"""A request's timeout: seconds, an `httpx.Timeout`, None (wait forever) or the HTTP client's default."""


@dataclass(frozen=True)
class Retries:
    """How often and how long to retry: ``max_retries`` more tries after the first, waiting ``backoff_s``,
    then twice that each time (capped at ``max_backoff_s``, with jitter), or the answer's ``Retry-After``
    when it gives one no longer than ``max_retry_after_s`` (a longer wait is raised, not slept)."""

    max_retries: int = 2
    backoff_s: float = 0.5
    max_backoff_s: float = 8.0
    max_retry_after_s: float = 60.0

    def delay(self, tries: int, response: httpx.Response | None = None) -> float | None:
        """Seconds to wait before try ``tries + 1`` after a failed one (``response`` None: no answer), or
        None when the failure is final."""
        if tries > self.max_retries:
            return None
        if response is not None:
            if response.status_code not in RETRY_STATUSES:
                return None
            asked = retry_after_s(response.headers)
            if asked is not None:
                return asked if asked <= self.max_retry_after_s else None
        backoff = min(self.max_backoff_s, self.backoff_s * 2 ** (tries - 1))
        return backoff * random.uniform(0.75, 1.0)


@dataclass(frozen=True)
class Call(Generic[T]):
    """One API operation to send: method, path, parameters and body, and how to read its answer."""

    method: str
    path: str
    parse: Callable[[httpx.Response], T]
    params: Mapping[str, Any] | None = None
    json: Any = None
    files: Mapping[str, tuple[str, bytes, str]] | None = None
    data: Mapping[str, str] | None = None
    headers: Mapping[str, str] = field(default_factory=dict)

    def with_idempotency_key(self) -> Call[T]:
        """This call with a fresh ``Idempotency-Key`` when it is a POST that has none."""
        if self.method != "POST" or IDEMPOTENCY_HEADER in self.headers:
            return self
        return replace(self, headers={**self.headers, IDEMPOTENCY_HEADER: uuid.uuid4().hex})

    def build(self, http: httpx.Client | httpx.AsyncClient, timeout: Timeout) -> httpx.Request:
        """The request, built anew for each try (a multipart body cannot always be sent twice), numpy arrays
        and numbers in a JSON body as the lists and numbers they hold (`plain`); `InvalidRequestError` for
        arguments JSON cannot carry (NaN, infinity, objects)."""
        try:
            return http.build_request(
                self.method,
                self.path,
                params=self.params,
                json=plain(self.json),
                files=self.files,
                data=self.data,
                headers=self.headers,
                timeout=timeout,
            )
        except (TypeError, ValueError) as exc:
            raise InvalidRequestError(exc, request=self.name) from exc

    @property
    def name(self) -> str:
        """``GET /v1/jobs/job_…``, as error messages name the request."""
        return f"{self.method} {self.path}"


def plain(value: Any) -> Any:
    """A JSON body with numpy arrays as (nested) lists and numpy scalars as Python numbers, everything else as
    it is: a lab's arrays go into a JSON request as they come."""
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


def _final(call: Call[T], response: httpx.Response) -> T:
    """The parsed answer, or its error raised."""
    if response.is_error:
        raise error_from_response(response)
    return call.parse(response)


def _no_answer(call: Call[Any], error: httpx.TransportError) -> APIConnectionError:
    """The client's exception for a transport failure."""
    if isinstance(error, httpx.TimeoutException):
        return APITimeoutError(error, request=call.name)
    return APIConnectionError(error, request=call.name)


def sleep(seconds: float) -> None:
    """Wait between tries (a module function so tests can record the waits instead)."""
    time.sleep(seconds)


async def async_sleep(seconds: float) -> None:
    """Wait between tries of the async client."""
    await asyncio.sleep(seconds)


def send(http: httpx.Client, call: Call[T], retries: Retries, timeout: Timeout) -> T:
    """Send ``call``, retrying as ``retries`` says; its parsed answer or a `MetairlError`."""
    call = call.with_idempotency_key()
    tries = 0
    while True:
        tries += 1
        try:
            response = http.send(call.build(http, timeout))
        except httpx.TransportError as error:
            wait = retries.delay(tries) if isinstance(error, RETRY_ERRORS) else None
            if wait is None:
                raise _no_answer(call, error) from error
        else:
            wait = retries.delay(tries, response) if response.is_error else None
            if wait is None:
                return _final(call, response)
            response.close()
        sleep(wait)


async def send_async(http: httpx.AsyncClient, call: Call[T], retries: Retries, timeout: Timeout) -> T:
    """`send` for the async client."""
    call = call.with_idempotency_key()
    tries = 0
    while True:
        tries += 1
        try:
            response = await http.send(call.build(http, timeout))
        except httpx.TransportError as error:
            wait = retries.delay(tries) if isinstance(error, RETRY_ERRORS) else None
            if wait is None:
                raise _no_answer(call, error) from error
        else:
            wait = retries.delay(tries, response) if response.is_error else None
            if wait is None:
                return _final(call, response)
            await response.aclose()
        await async_sleep(wait)
