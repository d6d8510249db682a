"""A job's event log as Server-Sent Events (docs/api.md, "Following a job live"), sent by sse-starlette.

`job_events` polls the database every ``events_poll_s`` (each read runs in the thread pool, the event loop
only sleeps between them) and yields each new event with its ``id``, ``event`` and JSON ``data`` (the same
object as the JSON list's items); it ends after the job's terminal status event — or, when resumed after it
with ``Last-Event-ID``, at once. A stream stays open at most ``events_stream_max_s``; the client then
reconnects with the last id it saw. `stream_response` wraps it in sse-starlette's `EventSourceResponse`,
which writes the messages, sends a ``: keep-alive`` comment every `KEEPALIVE_S`, ends the generator as soon
as the client disconnects, and on the server's shutdown sets an event the generator ends on (within
`SHUTDOWN_GRACE_S`), so the response ends complete and the client resumes elsewhere.

A stream holds no database connection between its polls (each poll checks one out and returns it), and
each API key may hold at most ``events_max_streams_per_key`` streams open in one process (`StreamSlots`);
a poll that finds the database gone or every connection busy ends the stream, and the client resumes.
"""

from __future__ import annotations

import hashlib
import json
import threading
import time
from collections import Counter
from collections.abc import AsyncIterator

import anyio
from sqlalchemy.exc import OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeout
from sqlalchemy.orm import Session, sessionmaker
from sse_starlette import EventSourceResponse, ServerSentEvent
from starlette.background import BackgroundTask
from starlette.concurrency import run_in_threadpool

from service.domain.jobs import JobEventOut
from service.problems import TooManyRequests
from service.store import jobs
from service.store.models.job_status import JobStatus

MEDIA_TYPE = "text/event-stream"
BATCH = 500
"""Most events read in one poll (a long log streams in several reads)."""
KEEPALIVE_S = 10.0
"""A comment line this often, so proxies keep a quiet stream open."""
RETRY_MS = 2000
"""The reconnection delay suggested to browsers (the ``retry:`` field)."""
SHUTDOWN_GRACE_S = 2.0
"""How long a stream may take to end by itself once the server shuts down, before it is cancelled."""
SEP = "\n"
"""The line separator of the messages (sse-starlette's default is CRLF; the documented examples use LF)."""


class Slot:
    """One open stream of a key; `release` gives it back (once, however often it is called)."""

    def __init__(self, slots: StreamSlots, key: str):
        self.slots, self.key, self.released = slots, key, False

    def release(self) -> None:
        """Give the slot back (idempotent: called when the stream ends and again after the response)."""
        with self.slots.lock:
            if not self.released:
                self.released = True
                self.slots.open[self.key] -= 1


class StreamSlots:
    """Open event streams per API key in this process: at most `cap` each, one more is a 429."""

    def __init__(self, cap: int):
        self.cap = cap
        self.open: Counter[str] = Counter()
        self.lock = threading.Lock()

    def take(self, authorization: str) -> Slot:
        """A slot for the key in the ``Authorization`` header; 429 with ``Retry-After`` if it holds `cap`."""
        key = hashlib.sha256(authorization.encode()).hexdigest()
        with self.lock:
            if self.open[key] >= self.cap:
                raise TooManyRequests(
                    f"This API key already holds {self.cap} open event streams in this process, the most "
                    "allowed (METAIRL_EVENTS_MAX_STREAMS_PER_KEY); close one, or poll the JSON log instead.",
                    headers={"Retry-After": str(max(1, round(RETRY_MS / 1000)))},
                )
            self.open[key] += 1
        return Slot(self, key)


def wants_stream(accept: str | None) -> bool:
    """Whether the ``Accept`` header asks for Server-Sent Events."""
    return accept is not None and MEDIA_TYPE in accept.lower()


def parse_last_event_id(value: str | None) -> int:
    """The event id to resume after (0: from the start); a malformed id starts from the start."""
    try:
        return max(0, int((value or "0").strip()))
    except ValueError:
        return 0


def message(event: JobEventOut) -> ServerSentEvent:
    """One SSE message: ``id``, ``event`` (``status`` or ``progress``) and the event as JSON ``data``."""
    data = json.dumps(event.model_dump(mode="json", exclude_none=True), separators=(",", ":"))
    return ServerSentEvent(data, id=str(event.id), event=event.kind, sep=SEP)


def keep_alive() -> ServerSentEvent:
    """The comment line sent while the stream is quiet."""
    return ServerSentEvent(comment="keep-alive", sep=SEP)


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
    make_session: sessionmaker[Session],
    job_id: str,
    *,
    after_id: int,
    poll_s: float,
    max_s: float,
    shutdown: anyio.Event,
    slot: Slot | None = None,
) -> AsyncIterator[ServerSentEvent]:
    """The messages of the job's events after ``after_id``, until its terminal status (or ``max_s``, a
    database failure or ``shutdown``: the client reconnects after ``retry``); `slot` is released when it ends."""
    try:
        yield ServerSentEvent(retry=RETRY_MS, sep=SEP)
        deadline = time.monotonic() + max_s
        while True:
            try:
                status, events = await run_in_threadpool(_read, make_session, job_id, after_id)
            except (OperationalError, PoolTimeout):
                return  # the database is gone or busy: end here, the client resumes with Last-Event-ID
            for event in events:
                yield message(event)
                after_id = event.id
                if (
                    event.kind == "status"
                    and event.status is not None
                    and JobStatus(event.status).is_terminal
                ):
                    return
            if len(events) == BATCH:
                continue  # more are waiting: read on without sleeping
            if status is None or (status.is_terminal and not events):
                return  # deleted, or resumed after the terminal event
            if time.monotonic() >= deadline:
                return
            with anyio.move_on_after(poll_s):
                await shutdown.wait()
            if shutdown.is_set():
                return  # the server is shutting down
    finally:
        if slot is not None:
            slot.release()


def stream_response(
    make_session: sessionmaker[Session],
    job_id: str,
    *,
    after_id: int,
    poll_s: float,
    max_s: float,
    slot: Slot,
) -> EventSourceResponse:
    """The job's event stream as a response; the slot is given back when it ends, however it ends."""
    shutdown = anyio.Event()
    events = job_events(
        make_session, job_id, after_id=after_id, poll_s=poll_s, max_s=max_s, slot=slot, shutdown=shutdown
    )
    return EventSourceResponse(
        events,
        shutdown_event=shutdown,
        shutdown_grace_period=SHUTDOWN_GRACE_S,
        headers={"Cache-Control": "no-cache"},
        ping=KEEPALIVE_S,
        ping_message_factory=keep_alive,
        sep=SEP,
        background=BackgroundTask(slot.release),
    )
