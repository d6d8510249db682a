"""Pieces shared by several resources' bodies: names, free-form metadata, resource timestamps."""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    GetCoreSchemaHandler,
    Strict,
    TypeAdapter,
)
from pydantic_core import core_schema


def _not_blank(value: str) -> str:
    """Reject a name of only white space (it would show as nothing in every list)."""
    if not value.strip():
        raise ValueError("must contain a character other than white space")
    return value


Name = Annotated[
    str,
    Field(min_length=1, max_length=200, description="A human-readable name."),
    AfterValidator(_not_blank),
]
UploadFormat = Literal["json", "csv", "c3d", "forces"]
"""How demonstrations or a recording came: JSON, CSV, or (recordings) a C3D file or a CSV of plate forces."""
Integer = Annotated[int, Strict()]
"""A JSON integer: `true`, `1.0` or `"1"` are not taken for 1 (strict, unlike pydantic's default)."""
Number = Annotated[float, Strict()]
"""A JSON number (an integer or not): `true` or `"1.5"` are not taken for a number (strict)."""
FIRST_BAD_ITEM = Field(fail_fast=True)
"""On a request's list: its validation stops at the first bad item, one issue however many follow. Pydantic
keeps every error with its input: a JSON MDP of 200,000 rows of strings (5.4 MB) took an API process to 1.6 GB."""
Metadata = Annotated[
    dict[str, Any] | None,
    Field(description="Free-form JSON object kept with the resource (e.g. age, condition, session date)."),
]

METADATA_MAX_BYTES = 64 * 1024
"""Largest metadata object, as compact JSON: labels, not data (a list page of 100 resources stays under
7 MB); arrays belong in uploads, which have their own budgets."""


def _small_finite_json(value: dict[str, Any] | None) -> dict[str, Any] | None:
    """Refuse metadata over `METADATA_MAX_BYTES` or holding NaN or infinity (JSON cannot store them)."""
    if value is None:
        return None
    try:
        text = json.dumps(value, allow_nan=False, separators=(",", ":"))
    except ValueError:
        raise ValueError("must hold only finite numbers (NaN and Infinity are not JSON)") from None
    if len(text.encode()) > METADATA_MAX_BYTES:
        raise ValueError(f"is {len(text.encode()):,} bytes as JSON; at most {METADATA_MAX_BYTES:,}")
    return value


MetadataIn = Annotated[Metadata, AfterValidator(_small_finite_json)]
"""Metadata as uploaded: at most `METADATA_MAX_BYTES`, finite numbers only."""


class Body(BaseModel):
    """A request body: a field it does not know is a 422 at that field, so a misspelt optional one
    (``task_id`` for ``task_ids``) is not silently left at its default."""

    model_config = ConfigDict(extra="forbid")


class Resource(BaseModel):
    """Fields every resource has: its prefixed `id` (contract) and its creation time (ISO 8601 UTC)."""

    model_config = ConfigDict(from_attributes=True)

    id: str = Field(description="Opaque id with a type prefix.")
    created_at: datetime


@dataclass(frozen=True)
class AsSent:
    """``Annotated[T, AsSent(documented)]``: a body, or a field of one, that its route checks itself. The OpenAPI
    schema shows it as ``documented``; validation asks only that it be a ``sent`` (by default any JSON) and
    passes it on as it came, so the route can report the schema's problems together with those only it can
    find (an unknown task, a size limit), in one 422 rather than one after the other."""

    documented: Any
    sent: Any = Any

    def __get_pydantic_core_schema__(
        self, _source: Any, handler: GetCoreSchemaHandler
    ) -> core_schema.CoreSchema:
        """A validator that checks ``sent`` alone, wrapped around ``documented``'s schema (which it never runs)
        so the JSON schema is ``documented``'s own; serialised as it came."""
        check = TypeAdapter(self.sent).validate_python
        return core_schema.no_info_wrap_validator_function(
            lambda value, _documented: check(value),
            handler.generate_schema(self.documented),
            serialization=core_schema.simple_ser_schema("any"),
        )
