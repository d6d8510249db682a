"""The heartbeat of a running attempt: a thread that writes progress, reads the cancel flag, fences writes.

Started right after the claim (before torch is even imported), it writes heartbeat and the latest
progress to the job row every ``job_heartbeat_s`` (or more often, to fit ``job_event_interval_s``) from its own thread, so neither a slow import nor a
long optimisation step starves it; it appends a progress event every ``job_event_interval_s`` while the
step advances, and tells the fit to stop when a cancel was requested or another attempt took the job.
The beats fall on a fixed grid, so the events keep their rate (two a second by default) however long
each write takes. numpy-free and torch-free.
"""

from __future__ import annotations

import logging
import math
import threading
import time

from sqlalchemy import update
from sqlalchemy.orm import Session, sessionmaker

from metairl_engine.results import Progress
from service.jobs.transitions import owned_by
from service.settings import Settings
from service.store.models.base import utcnow
from service.store.models.job_status import JobStatus
from service.store.models.jobs import PROGRESS_FIELDS, Job, JobEvent

log = logging.getLogger(__name__)


def progress_values(p: Progress | None) -> dict[str, object]:
    """A progress sample as job/event column values (empty before the first step)."""
    return {} if p is None else {name: getattr(p, name) for name in PROGRESS_FIELDS}


def beat_grid(heartbeat_s: float, event_interval_s: float) -> tuple[float, int]:
    """The monitor's period and the beats per progress event: a beat at least every heartbeat (and every
    second), on a grid that divides the event interval, so an event falls due exactly once per interval."""
    most = min(heartbeat_s, 1.0)
    if event_interval_s <= 0:
        return most, 1
    beats = max(1, math.ceil(event_interval_s / most - 1e-9))
    return event_interval_s / beats, beats


class Monitor(threading.Thread):
    """Heartbeat, progress writer and cancel reader of one running attempt (a daemon thread)."""

    def __init__(self, make_session: sessionmaker[Session], job_id: str, attempt: int, settings: Settings):
        super().__init__(name=f"monitor-{job_id}", daemon=True)
        self._make_session, self._job_id, self._attempt = make_session, job_id, attempt
        self._period, self._beats_per_event = beat_grid(
            settings.job_heartbeat_s, settings.job_event_interval_s
        )
        self._latest: Progress | None = None
        self._logged_step: int | None = None
        self._beats_since_event = 0
        self._stop_requested = threading.Event()
        self._closing = threading.Event()
        self.lost = False
        """True once another attempt (or the reaper) took the job: this attempt must stop writing."""

    def report(self, p: Progress) -> None:
        """The fit's progress callback: keep the newest sample for the next write (no I/O here)."""
        self._latest = p

    def should_stop(self) -> bool:
        """The fit's stop check: cancel requested, or the job is no longer this attempt's."""
        return self._stop_requested.is_set()

    def run(self) -> None:
        """Beat on a grid of the period until closed (a write's own time does not push the next one back);
        a failed write is logged and retried next period; after a beat longer than the period the grid
        starts again from then."""
        next_beat = time.monotonic() + self._period
        while not self._closing.wait(max(0.0, next_beat - time.monotonic())):
            try:
                self.beat()
            except Exception:
                log.exception("job %s: heartbeat failed; retrying", self._job_id)
            next_beat = max(next_beat + self._period, time.monotonic())

    def close(self) -> None:
        """Stop the thread and write the last progress sample (once; later calls do nothing)."""
        if self._closing.is_set():
            return
        self._closing.set()
        self.join()
        self.beat(final=True)

    def beat(self, *, final: bool = False) -> None:
        """One heartbeat: progress and heartbeat time to the row (fenced), cancel flag back, maybe an event."""
        latest = self._latest
        with self._make_session() as session:
            cancel = session.execute(
                update(Job)
                .where(
                    Job.id == self._job_id, Job.status == JobStatus.RUNNING.value, *owned_by(self._attempt)
                )
                .values(heartbeat_at=utcnow(), **progress_values(latest))
                .returning(Job.cancel_requested)
                .execution_options(synchronize_session=False)
            ).scalar_one_or_none()
            if cancel is None:
                self.lost = True
            if cancel is None or cancel:
                self._stop_requested.set()
            self._beats_since_event += 1
            due = final or self._logged_step is None or self._beats_since_event >= self._beats_per_event
            if cancel is not None and latest is not None and latest.step != self._logged_step and due:
                session.add(
                    JobEvent(
                        job_id=self._job_id, kind="progress", attempt=self._attempt, **progress_values(latest)
                    )
                )
                self._logged_step, self._beats_since_event = latest.step, 0
            session.commit()
