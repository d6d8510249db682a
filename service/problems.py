"""The service's one exception hierarchy and the handlers that render every error as RFC 9457 problem+json."""

from __future__ import annotations

import csv
import logging
import math
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ValidationError
from sqlalchemy.exc import OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeout
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from metairl_engine.errors import InvalidInput, Issue

M = TypeVar("M", bound=BaseModel)
T = TypeVar("T")
PROBLEM_JSON = "application/problem+json"
HTTP_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")
log = logging.getLogger(__name__)


class ApiError(Exception):
    """An error with an HTTP status; `errors` lists `{pointer, message}` for validation problems."""

    status = 500
    type = "internal"
    title = "Internal server error"

    def __init__(
        self, detail: str, *, errors: Sequence[dict[str, str]] = (), headers: dict[str, str] | None = None
    ):
        super().__init__(detail)
        self.detail = detail
        self.errors = list(errors)
        self.headers = headers or {}

    def body(self) -> dict[str, Any]:
        """The problem document (RFC 9457 members plus `errors` when there are any)."""
        out: dict[str, Any] = {
            "type": problem_type(self.type),
            "title": self.title,
            "status": self.status,
            "detail": self.detail,
        }
        if self.errors:
            out["errors"] = self.errors
        return out


class Unauthorized(ApiError):
    """No API key, or one that is unknown or revoked."""

    status, type, title = 401, "unauthorized", "Missing or invalid API key"


class NotFound(ApiError):
    """No such resource in the caller's lab (another lab's resources are reported the same way)."""

    status, type, title = 404, "not-found", "Not found"


class Conflict(ApiError):
    """The request cannot be done in the resource's current state."""

    status, type, title = 409, "conflict", "Conflict"


class PayloadTooLarge(ApiError):
    """The request body is larger than the configured limit."""

    status, type, title = 413, "payload-too-large", "Request body too large"


class UnsupportedMediaType(ApiError):
    """The body's Content-Type is not one the endpoint accepts."""

    status, type, title = 415, "unsupported-media-type", "Unsupported media type"


class Unprocessable(ApiError):
    """The body is well-formed but invalid; `errors` names each offending field, trajectory and step."""

    status, type, title = 422, "validation", "Invalid input"


class TooManyRequests(ApiError):
    """A rate limit was reached (per API key, or failed authentications per address); `Retry-After` says when
    to retry."""

    status, type, title = 429, "rate-limited", "Too many requests"


class DatabaseUnavailable(ApiError):
    """The database could not be reached or dropped the connection (e.g. it restarted): retry shortly."""

    status, type, title = 503, "database-unavailable", "Database unavailable"


class BrokerUnavailable(ApiError):
    """The job broker could not take a job's message: nothing was stored, so the same request can be retried."""

    status, type, title = 503, "broker-unavailable", "Job broker unavailable"


BROKER_RETRY_AFTER_S = 5
"""`Retry-After` of a refused submission: long enough for a restarting broker, short for a blip."""


def database_unavailable() -> DatabaseUnavailable:
    """The 503 of a lost or refused database connection, with ``Retry-After: 1``."""
    return DatabaseUnavailable(
        "The database could not be reached; retry in a moment.", headers={"Retry-After": "1"}
    )


def problem_type(slug: str) -> str:
    """The `type` URI of a problem (relative, resolved against the service's address)."""
    return f"/problems/{slug}"


def problem_response(error: ApiError) -> JSONResponse:
    """Render `error` as application/problem+json."""
    return JSONResponse(
        error.body(), status_code=error.status, media_type=PROBLEM_JSON, headers=error.headers
    )


def from_invalid_input(error: InvalidInput, *, detail: str = "The input is invalid.") -> Unprocessable:
    """The engine's `InvalidInput` as a 422 whose errors are its issues."""
    issues = [{"pointer": i.pointer, "message": i.message} for i in error.issues]
    first = error.issues[0] if error.issues else None
    more = f" {first.pointer or '/'}: {first.message}" if first else ""
    return Unprocessable(f"{detail}{more}", errors=issues)


def pointer_from_loc(loc: Sequence[str | int], body: Any) -> str:
    """An RFC 6901 pointer into `body` for a pydantic error location, skipping union tags and the
    leading ``body``: steps that do not exist in the input are dropped, except the last (a missing field)."""
    parts = list(loc[1:] if loc and loc[0] == "body" else loc)
    out: list[str] = []
    node = body
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        found, child = _child(node, part)
        if found:
            node = child
        elif not last:
            continue
        out.append(str(part).replace("~", "~0").replace("/", "~1"))
    return "".join(f"/{p}" for p in out)


def _tag_field(error: Any) -> tuple[str, ...]:
    """The discriminator field (``kind``) of a tagged union's error, which pydantic locates at the union
    itself, so the pointer names the field that picks the variant."""
    if error.get("type") not in ("union_tag_invalid", "union_tag_not_found"):
        return ()
    name = str((error.get("ctx") or {}).get("discriminator", "")).strip("'")
    return (name,) if name.isidentifier() else ()


def _child(node: Any, part: str | int) -> tuple[bool, Any]:
    """Whether `node` (parsed JSON) has the key or index `part`, and the value there."""
    if isinstance(node, dict) and part in node:
        return True, node[part]
    if isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
        return True, node[part]
    return False, None


def _message(error: Any) -> str:
    """What a 422 says of one pydantic error: pydantic's message, but a missing union tag is required, an unknown
    field maybe misspelt, and NaN or infinity not finite (it fails every bound)."""
    if error.get("type") == "union_tag_not_found":
        return "is required"
    if error.get("type") == "extra_forbidden":
        return "is not a field of this body (a misspelt name?); see the schema at /openapi.json"
    value = error.get("input")
    if isinstance(value, float) and not math.isfinite(value):
        return f"must be a finite number, not {value}"
    return str(error.get("msg", "is invalid"))


def body_issues(error: ValidationError, body: Any) -> list[Issue]:
    """Pydantic's errors of a body, or part of one, that a route validates itself, as issues with pointers into
    ``body`` worded as `validation_errors` words them: they join the route's own issues in one 422."""
    return [
        Issue(pointer_from_loc(tuple(e["loc"]) + _tag_field(e), body), _message(e))
        for e in error.errors(include_url=False)
    ]


def gathering(issues: list[Issue], stage: Callable[[], T]) -> T | None:
    """``stage()``, or None with its `InvalidInput`'s issues added to ``issues``: a later stage still runs, so
    a request's problems come in one answer rather than one stage at a time."""
    try:
        return stage()
    except InvalidInput as exc:
        issues.extend(exc.issues)
        return None


def validated(model: type[M], body: Any) -> M:
    """``body`` as a ``model``, or `InvalidInput` with an issue per problem (`body_issues`)."""
    try:
        return model.model_validate(body)
    except ValidationError as exc:
        raise InvalidInput(body_issues(exc, body)) from None


def valid_fields(model: type[BaseModel], body: Any) -> dict[str, Any]:
    """The fields of ``body`` (a JSON object) that pass ``model``'s schema each on its own, validated, and the
    defaults of optional ones not sent: what a route's later checks may still read of a body the schema refuses
    (`validated` says why). A field that fails, and a required one not sent, is absent. For models without
    model validators (each field is validated as an assignment to an otherwise empty model)."""
    if not isinstance(body, dict):
        return {}
    defaults = model.model_construct()
    out: dict[str, Any] = {}
    for name, field in model.model_fields.items():
        if name not in body:
            if not field.is_required():
                out[name] = getattr(defaults, name)
            continue
        try:
            one = model.__pydantic_validator__.validate_assignment(model.model_construct(), name, body[name])
        except ValidationError:
            continue
        out[name] = getattr(one, name)
    return out


def validation_errors(errors: Sequence[Any], body: Any) -> Unprocessable:
    """Pydantic errors as a 422: body errors get pointers, query/path/header errors name the parameter."""
    items: list[dict[str, str]] = []
    for e in errors:
        loc = tuple(e.get("loc", ())) + _tag_field(e)
        message = _message(e)
        if loc and loc[0] in ("query", "path", "header", "cookie"):
            name = str(loc[1]) if len(loc) > 1 else ""  # a repeated parameter's item adds its index
            items.append(
                {
                    "pointer": "",
                    "parameter": name,
                    "message": f"{loc[0]} parameter {name}: {message}",
                }
            )
        else:
            items.append({"pointer": pointer_from_loc(loc, body), "message": message})
    first = items[0] if items else {"pointer": "", "message": "invalid"}
    where = f"{first['pointer']}: " if first["pointer"] else ""
    return Unprocessable(f"The request is invalid. {where}{first['message']}", errors=items)


def not_utf8_json() -> Unprocessable:
    """422 for a JSON body whose bytes are not UTF-8 (JSON must be, RFC 8259)."""
    return Unprocessable(
        "The body is not valid JSON: it must be UTF-8 encoded text (RFC 8259).",
        errors=[{"pointer": "", "message": "is not UTF-8 encoded JSON text"}],
    )


def _media_type(request: Request) -> str:
    """The request's media type without parameters, lower case ("" when absent)."""
    return request.headers.get("content-type", "").partition(";")[0].strip().lower()


def _is_json(kind: str) -> bool:
    """Whether a media type is JSON (``application/json`` or ``…+json``)."""
    return kind == "application/json" or kind.endswith("+json")


def _json_syntax_error(error: Any, body: Any) -> Unprocessable:
    """A JSON syntax error as a 422 for the whole body (pointer ""), naming the line and column."""
    position = tuple(error.get("loc", ()))[-1]
    reason = str((error.get("ctx") or {}).get("error") or error.get("msg") or "JSON decode error")
    where = ""
    if isinstance(position, int) and isinstance(body, str | bytes):
        text = body if isinstance(body, str) else body.decode("utf-8", "replace")
        line = text.count("\n", 0, position) + 1
        column = position - (text.rfind("\n", 0, position) + 1) + 1
        where = f" at line {line} column {column}"
    message = f"is not valid JSON: {reason}{where}"
    return Unprocessable(f"The body {message}.", errors=[{"pointer": "", "message": message}])


def _allowed_methods(request: Request) -> list[str]:
    """Every method some route of the app takes at this request's path (the ``Allow`` of a 405): each
    standard method is matched against the app's routes as a request of that method would be."""
    routes = request.app.router.routes
    allowed = [
        method
        for method in HTTP_METHODS
        if any(route.matches({**request.scope, "method": method})[0] == Match.FULL for route in routes)
    ]
    return allowed


def install_handlers(app: FastAPI) -> None:
    """Map every error the app can raise to problem+json; unexpected exceptions become an opaque 500."""

    @app.exception_handler(ApiError)
    async def _api_error(_request: Request, exc: ApiError) -> JSONResponse:
        """Our own errors carry their status and problem fields."""
        return problem_response(exc)

    @app.exception_handler(InvalidInput)
    async def _invalid_input(_request: Request, exc: InvalidInput) -> JSONResponse:
        """The engine's validation errors: 422 with its issues."""
        return problem_response(from_invalid_input(exc))

    @app.exception_handler(csv.Error)
    async def _csv_error(_request: Request, exc: csv.Error) -> JSONResponse:
        """A CSV the parsers did not catch an error of (a header line past the cell limit): 422 at /file."""
        return problem_response(
            Unprocessable(
                f"The uploaded CSV cannot be read: {exc}.",
                errors=[{"pointer": "/file", "message": f"is not a readable CSV ({exc})"}],
            )
        )

    @app.exception_handler(RequestValidationError)
    async def _request_validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        """FastAPI's parameter and body validation: 422 with pointers; 415 for a body that is not JSON; a
        JSON syntax error points at the body as a whole and names its line and column."""
        errors = exc.errors()
        body_errors = [e for e in errors if tuple(e.get("loc", ()))[:1] == ("body",)]
        kind = _media_type(request)
        if body_errors and kind and not _is_json(kind):
            return problem_response(
                UnsupportedMediaType(f"Content-Type {kind!r} is not accepted; send application/json.")
            )
        syntax = [e for e in body_errors if e.get("type") == "json_invalid"]
        if syntax:
            return problem_response(_json_syntax_error(syntax[0], exc.body))
        return problem_response(validation_errors(errors, exc.body))

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        """Starlette's HTTP errors (unknown route, wrong method) as problems; a 405's ``Allow`` and detail list
        every method of the path, a 404's detail where the routes are; a JSON body that is not UTF-8 is a 422
        like any other malformed JSON."""
        if exc.status_code == 400 and _is_json(_media_type(request)):
            return problem_response(not_utf8_json())
        headers = dict(exc.headers or {})
        detail = str(exc.detail)
        if exc.status_code == 405:
            allowed = _allowed_methods(request)
            headers["Allow"] = ", ".join(allowed)
            detail = f"{request.method} is not allowed on {request.url.path}: it takes {', '.join(allowed)}."
        elif exc.status_code == 404:
            detail = f"Nothing is at {request.url.path}: /docs lists the API's routes, each under /v1."
        error = ApiError(detail, headers=headers)
        error.status, error.type, error.title = exc.status_code, f"http-{exc.status_code}", str(exc.detail)
        return problem_response(error)

    @app.exception_handler(OperationalError)
    async def _database_unavailable(request: Request, exc: OperationalError) -> JSONResponse:
        """A lost or refused database connection (the API does not ping connections before use): 503."""
        log.warning("database unavailable on %s %s: %s", request.method, request.url.path, exc.orig)
        return problem_response(database_unavailable())

    @app.exception_handler(PoolTimeout)
    async def _database_busy(request: Request, exc: PoolTimeout) -> JSONResponse:
        """Every pooled connection stayed busy for ``db_pool_timeout_s``: 503, retry shortly (never a 500)."""
        log.warning("no database connection free on %s %s: %s", request.method, request.url.path, exc)
        return problem_response(
            DatabaseUnavailable(
                "Every database connection of this API process is busy; retry in a moment.",
                headers={"Retry-After": "1"},
            )
        )

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        """Anything else: logged, and an opaque 500 problem."""
        log.exception("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
        return problem_response(ApiError("An unexpected error occurred; it has been logged."))
