"""Following one job to its end: the state as events arrive, a tqdm bar of its steps, the deadline.

The I/O (stream, polls, sleeps) is the clients'; this is what both do with what arrives."""

from __future__ import annotations

import time
from dataclasses import replace
from types import TracebackType
from typing import IO, Any

import httpx
from tqdm import tqdm

from metairl_client._models import JobState, when
from metairl_client._sse import STREAM_HEADERS

STREAM_FAILURES = 3
"""Broken stream connections in a row after which the client polls instead."""
LAST_STRETCH_S = 12.0
"""How close to its ``timeout_s`` a wait stops following the stream and polls every ``poll_s`` instead: a quiet
stream shows life only by its keep-alive comments (the service sends one every 10 s), too seldom to stop on
time."""
REFUSED_STREAM_STATUSES = frozenset({429, 503})
"""Answers to the stream request after which the client polls instead (too many streams open for the key, the
service busy): the polls are retried as every other request is."""


class NoStream(Exception):
    """The server did not answer with an event stream (an older server), or it kept failing: poll instead."""


class Waiter:
    """A job being waited for: its latest state, the last event id seen and the progress bar."""

    def __init__(self, job_id: str, *, timeout_s: float | None, progress: bool, stream: IO[str] | None):
        self.job_id = job_id
        self.timeout_s = timeout_s
        self.deadline = None if timeout_s is None else time.monotonic() + timeout_s
        self.state: JobState | None = None
        self.last_event_id: str | None = None
        self.bar = tqdm(desc=job_id, file=stream, disable=not progress, unit="step", dynamic_ncols=True)

    def __enter__(self) -> Waiter:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.bar.close()

    @property
    def current(self) -> JobState:
        """The latest state (after the first `show`)."""
        assert self.state is not None, "show the job's state first"
        return self.state

    @property
    def finished(self) -> bool:
        """Whether the job has reached a final status."""
        return self.state is not None and self.state.finished

    def show(self, state: JobState) -> None:
        """Take a new state and draw it."""
        self.state = state
        if state.status == "succeeded" and state.step:
            self.bar.total = state.step  # stopped early, as most fits do: it needed no more steps
        elif state.max_steps and self.bar.total != state.max_steps:
            self.bar.total = state.max_steps  # not `reset`: its clock, and so the rate it shows, runs on
        self.bar.set_description_str(f"{state.id} {state.status}", refresh=False)
        self.bar.n = state.step or 0
        self.bar.refresh()

    def check_deadline(self) -> None:
        """`TimeoutError` once ``timeout_s`` has passed."""
        if self.deadline is not None and time.monotonic() > self.deadline:
            raise TimeoutError(f"job {self.job_id} is still {self.current.status} after {self.timeout_s} s")

    def remaining_s(self) -> float | None:
        """Seconds left before ``timeout_s`` runs out (None: no deadline)."""
        return None if self.deadline is None else max(0.0, self.deadline - time.monotonic())

    def tick(self) -> None:
        """Called as each chunk of the stream arrives: `TimeoutError` past the deadline, `NoStream` (poll for the
        rest) within `LAST_STRETCH_S` of it."""
        self.check_deadline()
        remaining = self.remaining_s()
        if remaining is not None and remaining < LAST_STRETCH_S:
            raise NoStream

    def stream_timeout(self, timeout: httpx.Timeout) -> httpx.Timeout:
        """The stream request's timeout: the client's, its read timeout cut to the time left, so that a stream
        silent until the deadline (no keep-alive either) ends there."""
        remaining = self.remaining_s()
        if remaining is None:
            return timeout
        read = remaining if timeout.read is None else min(timeout.read, remaining)
        return httpx.Timeout(
            connect=timeout.connect, read=max(read, 0.001), write=timeout.write, pool=timeout.pool
        )

    def pause(self, seconds: float) -> float:
        """``seconds``, or the time left when that is shorter (a wait never sleeps past its deadline)."""
        remaining = self.remaining_s()
        return seconds if remaining is None else min(seconds, remaining)

    def refuses_stream(self, response: httpx.Response) -> bool:
        """Whether an error answer to the stream request means "poll instead" (429, 503)."""
        return response.status_code in REFUSED_STREAM_STATUSES

    def stream_headers(self) -> dict[str, str]:
        """The headers that open (or resume, after the last event seen) the job's event stream."""
        resume = {"Last-Event-ID": self.last_event_id} if self.last_event_id else {}
        return STREAM_HEADERS | resume

    def on_event(self, event_id: str | None, kind: str, data: dict[str, Any]) -> bool:
        """Apply one streamed event; True when it says the job finished (read its final row then)."""
        self.check_deadline()
        self.last_event_id = event_id or self.last_event_id
        state = self.current
        if state.already_shows(kind, data):
            return False  # history the stream replays: drawing it would move the bar back
        attempt = int(data.get("attempt", state.attempt))
        if kind == "progress":
            state = replace(
                state,
                step=data.get("step"),
                max_steps=data.get("max_steps"),
                attempt=attempt,
                loss=data.get("loss"),
                irl_loss=data.get("irl_loss"),
                sharing_loss=data.get("sharing_loss"),
                heldout_nll=data.get("heldout_nll"),
                elapsed_s=data.get("elapsed_s"),
            )
        elif kind == "status":
            state = replace(
                state, status=str(data.get("status")), attempt=attempt, updated_at=when(data.get("at"))
            )
        else:
            return False
        self.show(state)
        return state.finished
