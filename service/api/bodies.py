"""Reading request bodies that may be JSON or a multipart upload, with errors as problem+json."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypeVar

from fastapi import Request
from pydantic import TypeAdapter, ValidationError
from starlette.datastructures import FormData, UploadFile
from starlette.exceptions import HTTPException

from service.json_input import NUL, JsonTooDeep, nul_refused, parse_json
from service.problems import ApiError, Unprocessable, UnsupportedMediaType, not_utf8_json, validation_errors
from service.sizes import check_request_memory

T = TypeVar("T")
JSON_EXPANSION = 24
"""Peak memory of a JSON upload while it is validated and turned into arrays, per byte of body (measured:
6.6 for COP samples, 11.6 for trajectories of large state indices, 22.5 for trajectories of one-digit
states: a Python object or pointer for every number)."""
MAX_FORM_FIELDS = 50


def media_type(request: Request) -> str:
    """The request's media type without parameters, lower case."""
    return request.headers.get("content-type", "").partition(";")[0].strip().lower()


async def json_body(request: Request, adapter: TypeAdapter[T]) -> T:
    """Parse and validate a JSON body; 422 with pointers into the body on any problem, and before parsing if
    its parsed form would not fit the per-request memory budget."""
    raw = await request.body()
    check_request_memory(
        f"parsing the {len(raw) / 2**20:,.1f} MiB JSON body",
        len(raw) * JSON_EXPANSION,
        request.app.state.settings,
        pointer="",
    )
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
        raise validation_errors(exc.errors(include_url=False), parsed) from exc


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


async def json_or_upload(request: Request, adapter: TypeAdapter[T], *, accepted: str) -> T | Upload:
    """The body of a route that takes JSON or a file: JSON validated by ``adapter``, or the multipart form with
    its file (`form_body`); 415 naming ``accepted`` for any other media type."""
    kind = media_type(request)
    if kind == "multipart/form-data":
        return Upload(*await form_body(request))
    if kind == "application/json":
        return await json_body(request, adapter)
    raise unsupported(request, accepted=accepted)


def unsupported(request: Request, *, accepted: str) -> UnsupportedMediaType:
    """415 for a body of a media type the endpoint does not take."""
    return UnsupportedMediaType(
        f"Content-Type {media_type(request) or '(none)'!r} is not accepted; send {accepted}."
    )
