"""The reaper: running jobs whose heartbeat stopped are re-queued (attempts left), cancelled or failed.

A worker killed outright (SIGKILL, OOM, a lost machine) cannot report anything, and its broker
message may be gone (embedded broker) or return only after the visibility timeout (Redis); the job
row's heartbeat is what tells. Every worker runs `reap_once` periodically; each change is a conditional
UPDATE on (status running, same attempt, heartbeat still older than the cutoff), so concurrent reapers
and a worker that comes back to life cannot act twice on one job.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import datetime, timedelta
from functools import lru_cache

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from service.jobstatus import JobStatus
from service.jobstore import owned_by, send_or_fail, transition
from service.models.base import utcnow
from service.models.jobs import Job
from service.queue import CeleryJobQueue, JobQueue
from service.settings import Settings, get_settings
from worker.context import sessions

log = logging.getLogger(__name__)

BATCH = 100
"""Most stale jobs handled in one pass (the next pass takes the rest)."""


@dataclass(frozen=True)
class Reaped:
    """What the reaper did to one job."""

    job_id: str
    status: JobStatus
    message: str


@lru_cache(maxsize=1)
def default_queue() -> CeleryJobQueue:
    """The queue re-queued jobs are sent to: this process's configured broker."""
    return CeleryJobQueue(get_settings())


def reap_once() -> list[Reaped]:
    """One pass over this process's configured database and broker."""
    return reap(sessions(), get_settings(), default_queue())


def reap(
    make_session: sessionmaker[Session], settings: Settings, queue: JobQueue, *, now: datetime | None = None
) -> list[Reaped]:
    """Re-queue, cancel or fail every running job whose last heartbeat is older than ``job_stale_after_s``."""
    cutoff = (now or utcnow()) - timedelta(seconds=settings.job_stale_after_s)
    with make_session() as session:
        stale = session.execute(
            select(Job.id, Job.attempts, Job.max_attempts, Job.cancel_requested, Job.heartbeat_at)
            .where(Job.status == JobStatus.RUNNING.value, Job.heartbeat_at < cutoff)
            .order_by(Job.heartbeat_at)
            .limit(BATCH)
        ).all()
    done: list[Reaped] = []
    for job_id, attempts, max_attempts, cancel_requested, heartbeat_at in stale:
        lost = f"the worker running attempt {attempts} stopped sending heartbeats (last at {heartbeat_at:%H:%M:%S} UTC)"
        values: dict[str, object] = {"heartbeat_at": None}
        if cancel_requested:
            status, message = JobStatus.CANCELLED, f"cancelled on request; {lost}"
        elif attempts < max_attempts:
            status, message = (
                JobStatus.QUEUED,
                f"{lost}; re-queued for attempt {attempts + 1} of {max_attempts}",
            )
        else:
            status = JobStatus.FAILED
            message = (
                f"The job was started {attempts} times and each time its worker stopped responding ({lost}); "
                "workers die like this when killed or out of memory: try fewer states, smaller config.hidden "
                "or fewer tasks, or ask the operator to check the workers, then submit it again."
            )
            values["error"] = message
        with make_session() as session:
            changed = transition(
                session,
                job_id,
                JobStatus.RUNNING,
                status,
                where=(*owned_by(attempts), Job.heartbeat_at < cutoff),
                values=values,
                message=message,
            )
            session.commit()
            if changed is None:
                continue
            log.warning("reaper: job %s → %s: %s", job_id, status.value, message)
            if status is JobStatus.QUEUED and not send_or_fail(session, queue, job_id):
                status = JobStatus.FAILED
        done.append(Reaped(job_id, status, message))
    return done
