"""Input refused at the edge, before any route or database sees it, as a 422 naming the field.

- A NUL character in a path parameter, a query parameter or a string (or key) of a JSON body: PostgreSQL
  text cannot hold one (it answered 500), and no name, id or URL of ours contains one, so every backend
  refuses it the same way. Multipart fields and CSV cells are checked where they are parsed
  (`service.api.bodies`, `service.files.csv_rows`).
- A JSON body nested deeper than `MAX_JSON_DEPTH` (the routes whose models FastAPI parses would otherwise
  hand it to the interpreter's recursive parser). Only bodies up to `SCREENED_BYTES` are parsed here; the
  upload routes parse larger ones themselves with the same depth limit (`service.api.bodies.json_body`).
"""

from __future__ import annotations

from urllib.parse import parse_qsl

from starlette.routing import compile_path
from starlette.types import ASGIApp, Receive, Scope, Send

from service.api.idempotency import read_body, replaying_receive
from service.json_input import NUL, JsonTooDeep, may_be_too_deep, nul_pointer, nul_refused, parse_json
from service.problems import ApiError, problem_response

SCREENED_BYTES = 1 << 20
"""JSON bodies up to this size are parsed here when they have enough brackets to be too deep."""
NUL_ESCAPE = b"\\u0000"


class InputGuard:
    """Answer 422 to a NUL character in the path, query or JSON body, or to JSON nested too deep."""

    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Check the path and query, then (JSON bodies) the body; pass the request on, or answer 422."""
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        error = _path_or_query_error(scope)
        if error is None and _is_json(scope):
            body = await read_body(receive)
            error = _body_error(body)
            receive = replaying_receive(body, receive)
        if error is not None:
            await problem_response(error)(scope, receive, send)
            return
        await self.app(scope, receive, send)


def _is_json(scope: Scope) -> bool:
    """Whether the request carries a JSON body (by its media type)."""
    if scope["method"] not in ("POST", "PUT", "PATCH"):
        return False
    media = dict(scope["headers"]).get(b"content-type", b"").partition(b";")[0].strip().lower()
    return media == b"application/json" or media.endswith(b"+json")


def _path_or_query_error(scope: Scope) -> ApiError | None:
    """The 422 for a NUL in a path parameter (named by the route that matches) or a query parameter."""
    if NUL in scope["path"]:
        return nul_refused(parameter=_path_parameter(scope))
    query = scope.get("query_string", b"")
    if b"%00" in query or b"\x00" in query:
        for name, value in parse_qsl(query.decode("latin-1"), keep_blank_values=True):
            if NUL in name or NUL in value:
                return nul_refused(parameter=name.replace(NUL, "") or "query")
    return None


def _path_parameter(scope: Scope) -> str:
    """The name of the path parameter holding the NUL, from the documented path the request matches ("path"
    if none does)."""
    app = scope["app"]
    for template in app.openapi()["paths"]:
        match = compile_path(template)[0].match(scope["path"])
        if match is not None:
            for name, value in match.groupdict().items():
                if NUL in value:
                    return name
    return "path"


def _body_error(body: bytes) -> ApiError | None:
    """The 422 for a JSON body nested too deep or holding a NUL in a string; None if it passes (a body that
    is not JSON at all is left to the route's own 422)."""
    if NUL_ESCAPE not in body and not (len(body) <= SCREENED_BYTES and may_be_too_deep(body)):
        return None
    try:
        document = parse_json(body)
    except JsonTooDeep as exc:
        return exc
    except ApiError:
        return None
    pointer = nul_pointer(document)
    return None if pointer is None else nul_refused(pointer)
