"""The exceptions the client raises: `MetairlError` at the root, one class per kind of failure below it.

An error answer becomes the `APIStatusError` subclass of its status (404 `NotFoundError`, 429
`RateLimitError`, …) carrying the problem+json (RFC 9457); no answer at all becomes `APIConnectionError`
(`APITimeoutError` when it timed out). Catch `MetairlError` for all of them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from email.utils import parsedate_to_datetime
from typing import Any

import httpx


class MetairlError(Exception):
    """Any failure of a request: ``status`` (None when no answer came), ``title``, ``detail``, ``errors``
    (``[{"pointer" or "parameter", "message"}]``), the whole problem+json as ``problem`` and the ``request``."""

    def __init__(
        self,
        *,
        status: int | None = None,
        title: str,
        detail: str = "",
        errors: Sequence[Mapping[str, Any]] = (),
        request: str = "",
        problem: Mapping[str, Any] | None = None,
    ):
        self.status, self.title, self.detail = status, title, detail
        self.errors = [dict(e) for e in errors]
        self.request = request
        self.problem: dict[str, Any] = dict(problem or {"status": status, "title": title, "detail": detail})
        super().__init__(self.describe())

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle the error whole (a process pool hands a worker's error back pickled): rebuilt from its
        attributes, since the constructors take other arguments than the ones they keep."""
        return _rebuild, (type(self), self.args, self.__dict__)

    @classmethod
    def from_response(cls, response: httpx.Response) -> APIStatusError:
        """The error of a non-2xx response: the `APIStatusError` subclass of its status."""
        return error_from_response(response)

    def describe(self) -> str:
        """``HTTP 422 Invalid input (POST /v1/mdps): detail`` and one indented line per field error, unless the
        detail already names the only one."""
        where = f" ({self.request})" if self.request else ""
        head = (
            f"HTTP {self.status} {self.title}{where}" if self.status is not None else f"{self.title}{where}"
        )
        lines = [f"{head}: {self.detail}" if self.detail else head]
        listed = [
            f"  - {e.get('pointer') or e.get('parameter') or '/'}: {e.get('message', '')}"
            for e in self.errors
        ]
        if len(self.errors) == 1 and str(self.errors[0].get("message", "")) in (self.detail or ""):
            listed = []  # the service's detail already names its one field error
        return "\n".join(lines + listed)


class InvalidRequestError(MetairlError):
    """A request the client could not build from its arguments (a NaN in a JSON body): nothing was sent."""

    TITLE = "The request cannot be sent"

    def __init__(self, error: Exception, *, request: str = ""):
        super().__init__(title=self.TITLE, detail=f"{error}; nothing was sent", request=request)


class APIConnectionError(MetairlError):
    """No answer: the service could not be reached, or the connection broke (after the retries)."""

    TITLE = "Cannot reach the service"

    def __init__(self, error: httpx.TransportError, *, request: str = ""):
        super().__init__(title=self.TITLE, detail=str(error) or type(error).__name__, request=request)


class APITimeoutError(APIConnectionError):
    """No answer within the client's timeout (after the retries)."""

    TITLE = "The service did not answer in time"


class APIStatusError(MetairlError):
    """An error answer (4xx or 5xx), with its ``headers``; `retry_after_s` when the service said to wait."""

    def __init__(self, *, headers: Mapping[str, str] | None = None, **problem: Any):
        self.headers = httpx.Headers(headers or {})
        super().__init__(**problem)

    @property
    def retry_after_s(self) -> float | None:
        """The answer's ``Retry-After`` in seconds (None when absent)."""
        return retry_after_s(self.headers)


class BadRequestError(APIStatusError):
    """400: the request is malformed."""


class AuthenticationError(APIStatusError):
    """401: no API key, or an unknown or revoked one."""


class PermissionDeniedError(APIStatusError):
    """403: the key may not do this."""


class NotFoundError(APIStatusError):
    """404: no such resource in this lab."""


class ConflictError(APIStatusError):
    """409: the resource's state forbids it (a job still running, results not ready, a key in use)."""


class RequestTooLargeError(APIStatusError):
    """413: the body is over the service's limit (named in ``detail``)."""


class UnprocessableEntityError(APIStatusError):
    """422: a field is invalid; ``errors`` names each one."""


class RateLimitError(APIStatusError):
    """429: too many requests; `retry_after_s` says when to try again."""


class InternalServerError(APIStatusError):
    """5xx: the service failed."""


class ServiceUnavailableError(InternalServerError):
    """503: the service is up but cannot serve now (database or broker down); `retry_after_s` says when."""


STATUS_ERRORS: dict[int, type[APIStatusError]] = {
    400: BadRequestError,
    401: AuthenticationError,
    403: PermissionDeniedError,
    404: NotFoundError,
    409: ConflictError,
    413: RequestTooLargeError,
    422: UnprocessableEntityError,
    429: RateLimitError,
    503: ServiceUnavailableError,
}


def _rebuild(kind: type[MetairlError], args: tuple[Any, ...], state: dict[str, Any]) -> MetairlError:
    """An unpickled error: its class, message and attributes as they were."""
    error = kind.__new__(kind)
    error.args = args
    error.__dict__.update(state)
    return error


def error_class(status: int) -> type[APIStatusError]:
    """The exception class of an error status: its own, else its family's (5xx), else `APIStatusError`."""
    if status in STATUS_ERRORS:
        return STATUS_ERRORS[status]
    return InternalServerError if status >= 500 else APIStatusError


def error_from_response(response: httpx.Response) -> APIStatusError:
    """Read a problem+json body (or, failing that, the raw text) of a non-2xx response."""
    request = f"{response.request.method} {response.request.url.path}"
    kind = error_class(response.status_code)
    try:
        body = response.json()
    except ValueError:
        body = None
    if not isinstance(body, dict):
        return kind(
            status=response.status_code,
            title=response.reason_phrase or "Error",
            detail=response.text.strip()[:500],
            request=request,
            headers=response.headers,
        )
    return kind(
        status=int(body.get("status", response.status_code)),
        title=str(body.get("title", response.reason_phrase)),
        detail=str(body.get("detail", "")),
        errors=[e for e in body.get("errors") or [] if isinstance(e, dict)],
        request=request,
        problem=body,
        headers=response.headers,
    )


def retry_after_s(headers: httpx.Headers) -> float | None:
    """``Retry-After`` as seconds: a number, or an HTTP date from now; None when absent or unreadable."""
    value = headers.get("retry-after")
    if value is None:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:
        when = parsedate_to_datetime(value)
    except (TypeError, ValueError):
        return None
    return max(0.0, (when - datetime.now(UTC)).total_seconds())
