"""OpenAPI for routes that read their own body (one path taking JSON or a multipart upload)."""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic import TypeAdapter

REF_TEMPLATE = "#/components/schemas/{model}"
_schemas: dict[str, Any] = {}
"""Component schemas referenced by `request_body`, merged into the document by `install_openapi`."""

PROBLEM_RESPONSES: dict[int | str, dict[str, Any]] = {
    401: {"description": "Missing or invalid API key (problem+json)."},
    404: {"description": "No such resource in your lab (problem+json)."},
    413: {"description": "Body larger than the configured limit; `detail` names it (problem+json)."},
    415: {"description": "A body of a media type the route does not take (problem+json)."},
    422: {
        "description": "Invalid input; `errors` lists `{pointer, message}` (problem+json).",
        "content": {
            "application/problem+json": {
                "example": {
                    "type": "/problems/validation",
                    "title": "Invalid input",
                    "status": 422,
                    "detail": "The input is invalid. /trajectories/0/states/3: action 1 from state 2 cannot lead to state 7",
                    "errors": [
                        {
                            "pointer": "/trajectories/0/states/3",
                            "message": "trajectory 0 step 2: action 1 from state 2 cannot lead to state 7 "
                            "(transition probability 0)",
                        }
                    ],
                }
            }
        },
    },
    429: {
        "description": "Too many requests with this API key, or too many failed authentications from this "
        "address; `Retry-After` gives the seconds to wait (problem+json).",
        "headers": {"Retry-After": {"description": "Seconds to wait.", "schema": {"type": "integer"}}},
    },
    503: {
        "description": "The database cannot be reached or dropped the connection (it is restarting); "
        "`Retry-After` gives the seconds to wait (problem+json).",
        "headers": {"Retry-After": {"description": "Seconds to wait.", "schema": {"type": "integer"}}},
    },
}
"""Error responses documented on every `/v1` route."""


def request_body(
    json_type: Any, *, json_examples: dict[str, Any], multipart: dict[str, Any] | None = None
) -> dict[str, Any]:
    """`openapi_extra` documenting a JSON body of `json_type` (with named examples) and optionally a
    multipart form described by the JSON schema `multipart`."""
    schema = TypeAdapter(json_type).json_schema(ref_template=REF_TEMPLATE)
    _schemas.update(schema.pop("$defs", {}))
    content: dict[str, Any] = {"application/json": {"schema": schema, "examples": json_examples}}
    if multipart is not None:
        content["multipart/form-data"] = {"schema": multipart}
    return {"requestBody": {"required": True, "content": content}}


def install_openapi(app: FastAPI) -> None:
    """Make `app.openapi()` include the component schemas `request_body` referenced."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            document = get_openapi(
                title=app.title,
                version=app.version,
                description=app.description,
                routes=app.routes,
                tags=app.openapi_tags,
            )
            document.setdefault("components", {}).setdefault("schemas", {}).update(
                {k: v for k, v in _schemas.items() if k not in document["components"]["schemas"]}
            )
            app.openapi_schema = document
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
