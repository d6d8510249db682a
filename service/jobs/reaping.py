"""The reaper's queries: running jobs whose heartbeat stopped, queued jobs whose message may be lost.

Each function takes a session, reads or applies one fenced transition (`service/jobs/transitions.py`: same
status, same attempt, still older than the cutoff) and never commits; the reaper (`worker/reaper.py`)
opens the sessions, commits, logs and talks to the broker.
"""

from __future__ import annotations

from datetime import datetime, timedelta
from typing import NamedTuple

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from service.jobs.transitions import owned_by, touch_queued, transition
from service.settings import Settings
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, JobEvent

BATCH = 100
"""Most jobs handled in one pass (the next pass takes the rest)."""

RESENT = "message sent again"
"""How the status event of a re-send begins; counting these events counts a job's re-sends."""


class StaleJob(NamedTuple):
    """A running job whose heartbeat stopped, as `stale_running` reads it."""

    id: str
    attempts: int
    max_attempts: int
    cancel_requested: bool
    started_at: datetime | None
    heartbeat_at: datetime | None


class WaitingJob(NamedTuple):
    """A queued job unclaimed since ``updated_at``, as `waiting_queued` reads it."""

    id: str
    updated_at: datetime


def stale_running(session: Session, *, cutoff: datetime) -> list[StaleJob]:
    """Running jobs whose last heartbeat is older than ``cutoff``, oldest first (at most `BATCH`): id,
    attempts, max_attempts, cancel_requested, started_at, heartbeat_at."""
    rows = session.execute(
        select(Job.id, Job.attempts, Job.max_attempts, Job.cancel_requested, Job.started_at, Job.heartbeat_at)
        .where(Job.status == JobStatus.RUNNING.value, Job.heartbeat_at < cutoff)
        .order_by(Job.heartbeat_at)
        .limit(BATCH)
    ).all()
    return [StaleJob(*row) for row in rows]


def settle_stale(
    session: Session, stale: StaleJob, settings: Settings, *, cutoff: datetime
) -> tuple[JobStatus, str] | None:
    """Cancel, fail or re-queue one row of `stale_running`, fenced by its attempt and heartbeat; the new
    status and the event's message, or None when another actor changed the job first."""
    job_id, attempts, max_attempts, cancel_requested, started_at, heartbeat_at = stale
    lost = f"the worker running attempt {attempts} stopped sending heartbeats (last at {heartbeat_at:%H:%M:%S} UTC)"
    values: dict[str, object] = {"heartbeat_at": None}
    if cancel_requested:
        status, message = JobStatus.CANCELLED, f"cancelled on request; {lost}"
    elif (
        started_at is not None
        and heartbeat_at is not None
        and heartbeat_at - started_at >= timedelta(seconds=settings.job_time_limit_s)
    ):
        # Alive past the soft limit: the hard limit killed the pool process, and would kill a re-run too.
        status = JobStatus.FAILED
        message = (
            f"The job ran longer than the limit of {settings.job_time_limit_s} s and did not stop when asked, "
            "so its worker process was killed; lower config.max_steps, fit fewer or smaller tasks, or ask "
            "the operator to raise METAIRL_JOB_TIME_LIMIT_S."
        )
        values["error"] = message
    elif attempts < max_attempts:
        status, message = JobStatus.QUEUED, f"{lost}; re-queued for attempt {attempts + 1} of {max_attempts}"
    else:
        status = JobStatus.FAILED
        message = (
            f"The job was started {attempts} times and each time its worker stopped responding ({lost}); "
            "workers die like this when killed or out of memory: try fewer states, smaller config.hidden "
            "or fewer tasks, or ask the operator to check the workers, then submit it again."
        )
        values["error"] = message
    changed = transition(
        session,
        job_id,
        JobStatus.RUNNING,
        status,
        where=(*owned_by(attempts), Job.heartbeat_at < cutoff),
        values=values,
        message=message,
    )
    return None if changed is None else (status, message)


def waiting_queued(session: Session, *, cutoff: datetime) -> list[WaitingJob]:
    """Queued jobs not submitted, re-queued or re-sent since ``cutoff``, oldest first (at most `BATCH`):
    id, updated_at."""
    rows = session.execute(
        select(Job.id, Job.updated_at)
        .where(Job.status == JobStatus.QUEUED.value, Job.updated_at < cutoff)
        .order_by(Job.updated_at)
        .limit(BATCH)
    ).all()
    return [WaitingJob(*row) for row in rows]


def resend_count(session: Session, job_id: str) -> int:
    """How many times the reaper sent the job's message again (its `RESENT` status events)."""
    return session.execute(
        select(func.count())
        .select_from(JobEvent)
        .where(JobEvent.job_id == job_id, JobEvent.kind == "status", JobEvent.message.startswith(RESENT))
    ).scalar_one()


def settle_lost(
    session: Session, job_id: str, since: datetime, settings: Settings, *, now: datetime, cutoff: datetime
) -> tuple[JobStatus, str] | None:
    """Mark a queued job whose message may be lost (the broker queue was empty) as sent again — or failed
    after ``job_max_resends`` re-sends — fenced by ``updated_at < cutoff``; the status (`QUEUED`: send its
    message again) and the event's message, or None when another actor changed the job first."""
    resends = resend_count(session, job_id)
    unclaimed = (
        f"no worker claimed the job for {(now - since).total_seconds():.0f} s and the broker queue was empty"
    )
    if resends >= settings.job_max_resends:
        status = JobStatus.FAILED
        message = (
            f"The job's message was sent {resends + 1} times but never reached a worker ({unclaimed}); "
            f"check that a worker runs on queue {settings.queue_name!r} and that the broker keeps its "
            "messages, then submit the job again."
        )
        changed = transition(
            session,
            job_id,
            JobStatus.QUEUED,
            status,
            where=(Job.updated_at < cutoff,),
            values={"error": message},
            message=message,
        )
    else:
        status = JobStatus.QUEUED
        message = f"{RESENT} ({resends + 1} of {settings.job_max_resends}): {unclaimed}"
        changed = touch_queued(session, job_id, waiting_since_before=cutoff, now=now, message=message)
    return None if changed is None else (status, message)
