"""Pieces shared by several resources' bodies: names, free-form metadata, resource timestamps."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, Strict


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
Metadata = Annotated[
    dict[str, Any] | None,
    Field(description="Free-form JSON object kept with the resource (e.g. age, condition, session date)."),
]


class Resource(BaseModel):
    """Fields every resource has: its prefixed `id` (contract) and its creation time (ISO 8601 UTC)."""

    model_config = ConfigDict(from_attributes=True)

    id: str = Field(description="Opaque id with a type prefix.")
    created_at: datetime
