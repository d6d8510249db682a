"""Reading request bodies that may be JSON or a multipart upload, with errors as problem+json."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from fastapi import Request
from pydantic import TypeAdapter, ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import FormData, UploadFile
from starlette.exceptions import HTTPException

from metairl_engine.errors import Issue
from service.json_input import NUL, JsonTooDeep, nul_refused, parse_json
from service.problems import (
    ApiError,
    PayloadTooLarge,
    Unprocessable,
    UnsupportedMediaType,
    not_utf8_json,
    validation_errors,
)
from service.settings import Settings

T = TypeVar("T")
JSON_EXPANSION = 24
"""Peak memory of a JSON upload while it is validated and turned into arrays, per byte of body (measured:
6.6 for COP samples, 11.6 for trajectories of large state indices, 22.5 for trajectories of one-digit
states: a Python object or pointer for every number)."""
MAX_FORM_FIELDS = 50


def media_type(request: Request) -> str:
    """The request's media type without parameters, lower case."""
    return request.headers.get("content-type", "").partition(";")[0].strip().lower()


LaterChecks = Callable[[Any], list[Issue]]
"""A route's checks after the schema, run (in the thread pool) on the parsed JSON of a body the schema refuses:
the problems they find in the parts that pass it join the schema's in one 422."""


async def json_body(request: Request, adapter: TypeAdapter[T], *, later: LaterChecks | None = None) -> T:
    """Parse and validate a JSON body; 422 with pointers into the body on any problem (with those ``later``
    finds), and before parsing a 413 naming the largest JSON body the per-request memory budget holds if its
    parsed form would not fit. A valid body is validated straight from its bytes, never parsed twice."""
    raw = await request.body()
    check_json_size(len(raw), request.app.state.settings)
    try:
        return adapter.validate_json(raw)
    except ValidationError as exc:
        if any(e["type"] == "json_invalid" for e in exc.errors()):
            try:
                raw.decode("utf-8")
            except UnicodeDecodeError:
                raise not_utf8_json() from exc
        try:
            parsed: Any = parse_json(raw)
        except JsonTooDeep as deep:
            raise deep from exc
        except ApiError:
            parsed = None
        problem = validation_errors(exc.errors(include_url=False), parsed)
        if later is not None and parsed is not None:
            found = await run_in_threadpool(later, parsed)
            problem.errors += [{"pointer": i.pointer, "message": i.message} for i in found]
        raise problem from exc


def check_json_size(n_bytes: int, settings: Settings) -> None:
    """413 if a JSON body of ``n_bytes`` would take more than ``api_max_request_memory_mb`` to parse (about
    JSON_EXPANSION bytes per byte of body), naming the largest that fits: a body too large for this server,
    however small the arrays it describes."""
    budget_mb = settings.api_max_request_memory_mb
    largest = budget_mb * 2**20 / JSON_EXPANSION
    if n_bytes > largest:
        raise PayloadTooLarge(
            f"The {n_bytes / 2**20:,.1f} MiB JSON body would take about {n_bytes * JSON_EXPANSION / 2**20:,.0f} "
            f"MiB of memory to parse; JSON bodies up to {largest / 2**20:,.1f} MiB fit the per-request budget of "
            f"{budget_mb:,} MiB (METAIRL_API_MAX_REQUEST_MEMORY_MB). Send large arrays as an .npz or CSV file.",
            errors=[
                {
                    "pointer": "",
                    "message": f"at most {largest / 2**20:,.1f} MiB of JSON (METAIRL_API_MAX_REQUEST_MEMORY_MB)",
                }
            ],
        )


async def form_body(request: Request) -> tuple[FormData, UploadFile]:
    """A multipart form and its single file (whatever the field's name); 422 if there is no file, if a field
    or file name holds a NUL character, or if the body is not well-formed multipart or has too many parts
    (Starlette's 400, like malformed JSON's 422)."""
    try:
        form = await request.form(max_files=1, max_fields=MAX_FORM_FIELDS)
    except HTTPException as exc:
        if exc.status_code != 400:
            raise
        raise Unprocessable(
            f"The multipart body is invalid: {exc.detail}",
            errors=[{"pointer": "", "message": f"is not a valid multipart form: {exc.detail}"}],
        ) from exc
    for key, value in form.multi_items():
        text = value if isinstance(value, str) else value.filename or ""
        if NUL in key or NUL in text:
            raise nul_refused(f"/{key.replace(NUL, '')}", parameter=key.replace(NUL, "") or "form")
    files = [v for v in form.values() if isinstance(v, UploadFile)]
    if not files:
        raise validation_errors([{"loc": ("file",), "msg": "a file part is required"}], None)
    return form, files[0]


@dataclass(frozen=True)
class Upload:
    """A multipart body: its form fields and its one file."""

    form: FormData
    file: UploadFile


async def json_or_upload(
    request: Request, adapter: TypeAdapter[T], *, accepted: str, later: LaterChecks | None = None
) -> T | Upload:
    """The body of a route that takes JSON or a file: JSON validated by ``adapter`` (a refused one with what
    ``later`` finds, `json_body`), or the multipart form with its file (`form_body`); 415 naming ``accepted``
    for any other media type."""
    kind = media_type(request)
    if kind == "multipart/form-data":
        return Upload(*await form_body(request))
    if kind == "application/json":
        return await json_body(request, adapter, later=later)
    raise unsupported(request, accepted=accepted)


def unsupported(request: Request, *, accepted: str) -> UnsupportedMediaType:
    """415 for a body of a media type the endpoint does not take."""
    return UnsupportedMediaType(
        f"Content-Type {media_type(request) or '(none)'!r} is not accepted; send {accepted}."
    )
