"""A job's Server-Sent Events, parsed by httpx-sse: (id, event name, JSON data) per message with data."""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable, Iterator
from typing import Any

import httpx
from httpx_sse import EventSource, ServerSentEvent

STREAM_HEADERS = {"Accept": "text/event-stream", "Cache-Control": "no-store"}
"""What asks the events route for the stream instead of the JSON list."""

Event = tuple[str | None, str, dict[str, Any]]
"""(the event id to resume after, the event name, its JSON data)."""


class Watched(httpx.SyncByteStream, httpx.AsyncByteStream):
    """A response body that calls ``tick`` as each chunk arrives, keep-alive comments included: the only
    sign of life of a quiet stream, so that a deadline is checked while no event comes."""

    def __init__(self, stream: Any, tick: Callable[[], None]):
        self.stream, self.tick = stream, tick

    def __iter__(self) -> Iterator[bytes]:
        for chunk in self.stream:
            self.tick()
            yield chunk

    async def __aiter__(self) -> AsyncIterator[bytes]:
        async for chunk in self.stream:
            self.tick()
            yield chunk

    def close(self) -> None:
        self.stream.close()

    async def aclose(self) -> None:
        await self.stream.aclose()


def is_event_stream(response: httpx.Response) -> bool:
    """Whether the answer is an event stream (an older server answers the JSON list)."""
    return response.headers.get("content-type", "").startswith("text/event-stream")


def _event(sse: ServerSentEvent) -> Event | None:
    """The message as an `Event`; None for one without data (a retry hint or keep-alive)."""
    if not sse.data:
        return None
    return sse.id or None, sse.event, dict(sse.json())


def events(response: httpx.Response, tick: Callable[[], None] = lambda: None) -> Iterator[Event]:
    """The stream's messages, as they arrive; ``tick`` is called at every chunk (it may raise to stop)."""
    response.stream = Watched(response.stream, tick)
    for sse in EventSource(response).iter_sse():
        if (event := _event(sse)) is not None:
            yield event


async def aevents(response: httpx.Response, tick: Callable[[], None] = lambda: None) -> AsyncIterator[Event]:
    """The stream's messages, as they arrive (async); ``tick`` as for `events`."""
    response.stream = Watched(response.stream, tick)
    async for sse in EventSource(response).aiter_sse():
        if (event := _event(sse)) is not None:
            yield event
