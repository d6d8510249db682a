"""The heartbeat of a running attempt: a thread that writes progress, reads the cancel flag, fences writes.

Started right after the claim (before torch is even imported), it writes heartbeat and the latest
progress to the job row every ``job_heartbeat_s`` (or ``job_event_interval_s`` when shorter) from its own thread, so neither a slow import nor a
long optimisation step starves it; it appends throttled progress events, and tells the fit to stop
when a cancel was requested or another attempt took the job. numpy-free and torch-free.
"""

from __future__ import annotations

import logging
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


class Monitor(threading.Thread):
    """Heartbeat, progress writer and cancel reader of one running attempt (a daemon thread)."""

    def __init__(self, make_session: sessionmaker[Session], job_id: str, attempt: int, settings: Settings):
        super().__init__(name=f"monitor-{job_id}", daemon=True)
        self._make_session, self._job_id, self._attempt = make_session, job_id, attempt
        self._period = min(settings.job_heartbeat_s, settings.job_event_interval_s, 1.0)
        self._event_interval = settings.job_event_interval_s
        self._latest: Progress | None = None
        self._logged_step: int | None = None
        self._last_event = 0.0
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
        """Write a heartbeat every period until closed; a failed write is logged and retried next period."""
        while not self._closing.wait(self._period):
            try:
                self.beat()
            except Exception:
                log.exception("job %s: heartbeat failed; retrying", self._job_id)

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
            due = time.monotonic() - self._last_event >= self._event_interval or final
            if cancel is not None and latest is not None and latest.step != self._logged_step and due:
                session.add(
                    JobEvent(
                        job_id=self._job_id, kind="progress", attempt=self._attempt, **progress_values(latest)
                    )
                )
                self._logged_step, self._last_event = latest.step, time.monotonic()
            session.commit()
