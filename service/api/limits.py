"""Request size limits as ASGI middleware: 413 by Content-Length, or while counting streamed bytes."""

from __future__ import annotations

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.problems import PayloadTooLarge, problem_response
from service.settings import Settings


def _limit_for(scope: Scope, settings: Settings) -> int:
    """The byte limit of a request: the upload limit for multipart bodies, the JSON limit otherwise."""
    content_type = dict(scope.get("headers", [])).get(b"content-type", b"")
    if content_type.startswith(b"multipart/"):
        return settings.max_upload_bytes
    return settings.max_json_bytes


def too_large(limit: int) -> PayloadTooLarge:
    """The 413 problem naming the configured limit."""
    return PayloadTooLarge(f"The request body exceeds the limit of {limit} bytes ({limit / 2**20:.4g} MiB).")


class BodySizeLimit:
    """Reject bodies over the limit: by Content-Length up front, and by counting bytes as they arrive."""

    def __init__(self, app: ASGIApp, *, settings: Settings):
        self.app = app
        self.settings = settings

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Pass the request on with a counting `receive`; answer 413 instead if the body is too big."""
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = _limit_for(scope, self.settings)
        length = dict(scope["headers"]).get(b"content-length")
        if length is not None and length.isdigit() and int(length) > limit:
            await problem_response(too_large(limit))(scope, receive, send)
            return
        received = 0
        exceeded = False
        started = False

        async def counting_receive() -> Message:
            """The next body chunk, counted; raises 413 once the total passes the limit."""
            nonlocal received, exceeded
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    exceeded = True
                    raise too_large(limit)
            return message

        async def guarded_send(message: Message) -> None:
            """Forward the app's response unless the body was too large (then ours is sent instead)."""
            nonlocal started
            if exceeded:
                return
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, counting_receive, guarded_send)
        except Exception:
            if not exceeded:
                raise
        if exceeded and not started:
            await problem_response(too_large(limit))(scope, receive, send)
