"""A job's event log as Server-Sent Events (docs/api.md, "Following a job live").

The stream polls the database every ``events_poll_s`` (each read runs in the thread pool, the event loop
only sleeps between them), sends each new event as ``id:``/``event:``/``data:`` (JSON, the same object as
the JSON list's items), and ends after the job's terminal status event — or, when resumed after it with
``Last-Event-ID``, at once. A stream stays open at most ``events_stream_max_s``; the client then
reconnects with the last id it saw. A comment line every few seconds keeps proxies from closing it.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator

from sqlalchemy.orm import Session, sessionmaker
from starlette.concurrency import run_in_threadpool

from service.domain.jobs import JobEventOut
from service.store import jobs
from service.store.models.job_status import JobStatus

MEDIA_TYPE = "text/event-stream"
BATCH = 500
"""Most events read in one poll (a long log streams in several reads)."""
KEEPALIVE_S = 10.0
"""A comment line after this long without an event."""
RETRY_MS = 2000
"""The reconnection delay suggested to browsers (the ``retry:`` field)."""


def wants_stream(accept: str | None) -> bool:
    """Whether the ``Accept`` header asks for Server-Sent Events."""
    return accept is not None and MEDIA_TYPE in accept.lower()


def parse_last_event_id(value: str | None) -> int:
    """The event id to resume after (0: from the start); a malformed id starts from the start."""
    try:
        return max(0, int((value or "0").strip()))
    except ValueError:
        return 0


def format_event(event: JobEventOut) -> str:
    """One SSE message: ``id``, ``event`` (``status`` or ``progress``) and the event as JSON ``data``."""
    data = json.dumps(event.model_dump(mode="json", exclude_none=True), separators=(",", ":"))
    return f"id: {event.id}\nevent: {event.kind}\ndata: {data}\n\n"


def _read(
    make_session: sessionmaker[Session], job_id: str, after_id: int
) -> tuple[JobStatus | None, list[JobEventOut]]:
    """The job's status, then its events after ``after_id`` (status first: a terminal status read here means
    its terminal event, written in the same transaction, is among the events read after)."""
    with make_session() as session:
        status = jobs.job_status(session, job_id)
        rows = jobs.events_after(session, job_id, after_id=after_id, limit=BATCH)
        return status, [JobEventOut.of(row) for row in rows]


async def job_events(
    make_session: sessionmaker[Session], job_id: str, *, after_id: int, poll_s: float, max_s: float
) -> AsyncIterator[str]:
    """The SSE text of the job's events after ``after_id``, until its terminal status (or ``max_s``)."""
    yield f"retry: {RETRY_MS}\n\n"
    deadline = time.monotonic() + max_s
    quiet_since = time.monotonic()
    while True:
        status, events = await run_in_threadpool(_read, make_session, job_id, after_id)
        for event in events:
            yield format_event(event)
            after_id = event.id
            if event.kind == "status" and event.status is not None and JobStatus(event.status).is_terminal:
                return
        if events:
            quiet_since = time.monotonic()
            if len(events) == BATCH:
                continue  # more are waiting: read on without sleeping
        if status is None or (status.is_terminal and not events):
            return  # deleted, or resumed after the terminal event
        if time.monotonic() >= deadline:
            return
        if time.monotonic() - quiet_since >= KEEPALIVE_S:
            quiet_since = time.monotonic()
            yield ": keep-alive\n\n"
        await asyncio.sleep(poll_s)
