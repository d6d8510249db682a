"""The one way JSON from a client is parsed outside pydantic models: nesting limited, NUL characters found.

Bodies, multipart form fields that hold JSON, and the Idempotency-Key fingerprint all parse with
`parse_json` (pydantic-core's parser: no recursion of the interpreter, at most `MAX_JSON_DEPTH` levels), so
a document nested 100,000 levels deep is a 422 naming where it came from, never a `RecursionError`.
PostgreSQL cannot store NUL in text, so `nul_pointer` finds one anywhere in a parsed document.
"""

from __future__ import annotations

from typing import Any

from pydantic_core import from_json

from service.problems import Unprocessable

MAX_JSON_DEPTH = 200
"""Deepest nesting of arrays and objects accepted (pydantic-core's parser refuses deeper documents)."""
NUL = "\x00"


class JsonTooDeep(Unprocessable):
    """422: a JSON document nested deeper than `MAX_JSON_DEPTH`."""


def parse_json(raw: bytes | str, *, pointer: str = "", what: str = "The body") -> Any:
    """The parsed document; 422 at `pointer` when it is not JSON or nested deeper than `MAX_JSON_DEPTH`."""
    try:
        return from_json(raw)
    except ValueError as exc:
        reason = str(exc)
        deep = "recursion limit" in reason
        if deep:
            reason = f"it is nested deeper than {MAX_JSON_DEPTH} levels ({reason})"
        error = JsonTooDeep if deep else Unprocessable
        raise error(
            f"{what} is not valid JSON: {reason}.",
            errors=[{"pointer": pointer, "message": f"is not valid JSON: {reason}"}],
        ) from exc


def may_be_too_deep(raw: bytes) -> bool:
    """Whether `raw` has enough brackets to nest past `MAX_JSON_DEPTH` (cheap: two byte counts)."""
    return raw.count(b"[") + raw.count(b"{") > MAX_JSON_DEPTH


def nul_pointer(value: Any, pointer: str = "") -> str | None:
    """The JSON pointer of the first string holding a NUL character (of its object for a key), or None."""
    if isinstance(value, str):
        return pointer if NUL in value else None
    if isinstance(value, dict):
        for key, item in value.items():
            if NUL in str(key):  # the key itself cannot be named: point at its object
                return pointer
            found = nul_pointer(item, f"{pointer}/{str(key).replace('~', '~0').replace('/', '~1')}")
            if found is not None:
                return found
    elif isinstance(value, list):
        for index, item in enumerate(value):
            found = nul_pointer(item, f"{pointer}/{index}")
            if found is not None:
                return found
    return None


def nul_refused(pointer: str = "", *, parameter: str | None = None) -> Unprocessable:
    """422: a NUL character where text is expected (named by `pointer` or `parameter`)."""
    where = f"the {parameter} parameter" if parameter else (pointer or "the body")
    error: dict[str, str] = {"pointer": pointer, "message": "contains a NUL character (\\u0000)"}
    if parameter:
        error["parameter"] = parameter
    return Unprocessable(
        f"{where} contains a NUL character (\\u0000), which text may not hold.", errors=[error]
    )
