"""The reaper: running jobs whose heartbeat stopped are re-queued, cancelled or failed; lost messages re-sent.

A worker killed outright (SIGKILL, OOM, a lost machine) cannot report anything, and its broker
message may be gone (embedded broker) or return only after the visibility timeout (Redis); the job
row's heartbeat is what tells. An attempt whose last heartbeat came after the time limit was killed by
it and fails at once instead of being re-run. A queued job can lose its message too (the API died
between commit and send, a broker lost it): when one waited ``job_requeue_after_s`` while the broker
queue was empty, its message is sent again, at most ``job_max_resends`` times. Every worker runs
`reap_once` periodically; each change is a conditional UPDATE (same status, same attempt, still older
than the cutoff), so concurrent reapers and a worker that comes back to life cannot act twice on one job.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import datetime, timedelta
from functools import lru_cache

from sqlalchemy import func, select
from sqlalchemy.orm import Session, sessionmaker

from service.jobstatus import JobStatus
from service.jobstore import owned_by, send_or_fail, touch_queued, transition
from service.models.base import utcnow
from service.models.jobs import Job, JobEvent
from service.queue import CeleryJobQueue, EnqueueFailed, JobQueue
from service.settings import Settings, get_settings
from worker.context import sessions

log = logging.getLogger(__name__)

BATCH = 100
"""Most stale jobs handled in one pass (the next pass takes the rest)."""

RESENT = "message sent again"
"""How the status event of a re-send begins; counting these events counts a job's re-sends."""


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
    """One pass over this process's configured database and broker: stale running jobs, then lost messages."""
    settings, queue = get_settings(), default_queue()
    return reap(sessions(), settings, queue) + resend_lost(sessions(), settings, queue)


def reap(
    make_session: sessionmaker[Session], settings: Settings, queue: JobQueue, *, now: datetime | None = None
) -> list[Reaped]:
    """Re-queue, cancel or fail every running job whose last heartbeat is older than ``job_stale_after_s``."""
    cutoff = (now or utcnow()) - timedelta(seconds=settings.job_stale_after_s)
    limit = timedelta(seconds=settings.job_time_limit_s)
    with make_session() as session:
        stale = session.execute(
            select(
                Job.id, Job.attempts, Job.max_attempts, Job.cancel_requested, Job.started_at, Job.heartbeat_at
            )
            .where(Job.status == JobStatus.RUNNING.value, Job.heartbeat_at < cutoff)
            .order_by(Job.heartbeat_at)
            .limit(BATCH)
        ).all()
    done: list[Reaped] = []
    for job_id, attempts, max_attempts, cancel_requested, started_at, heartbeat_at in stale:
        lost = f"the worker running attempt {attempts} stopped sending heartbeats (last at {heartbeat_at:%H:%M:%S} UTC)"
        values: dict[str, object] = {"heartbeat_at": None}
        if cancel_requested:
            status, message = JobStatus.CANCELLED, f"cancelled on request; {lost}"
        elif started_at is not None and heartbeat_at is not None and heartbeat_at - started_at >= limit:
            # Alive past the soft limit: the hard limit killed the pool process, and would kill a re-run too.
            status = JobStatus.FAILED
            message = (
                f"The job ran longer than the limit of {settings.job_time_limit_s} s and did not stop when asked, "
                "so its worker process was killed; lower config.max_steps, fit fewer or smaller tasks, or ask "
                "the operator to raise METAIRL_JOB_TIME_LIMIT_S."
            )
            values["error"] = message
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


def resend_lost(
    make_session: sessionmaker[Session], settings: Settings, queue: JobQueue, *, now: datetime | None = None
) -> list[Reaped]:
    """Send again the message of each job queued longer than ``job_requeue_after_s`` while the broker queue is empty.

    An empty queue means no message waits for these jobs (one still in it may just be behind busy
    workers, so nothing is re-sent then). After ``job_max_resends`` re-sends the job is failed instead.
    """
    now = now or utcnow()
    cutoff = now - timedelta(seconds=settings.job_requeue_after_s)
    with make_session() as session:
        waiting = session.execute(
            select(Job.id, Job.updated_at)
            .where(Job.status == JobStatus.QUEUED.value, Job.updated_at < cutoff)
            .order_by(Job.updated_at)
            .limit(BATCH)
        ).all()
    if not waiting:
        return []
    try:
        if queue.waiting():
            return []
    except EnqueueFailed as exc:
        log.warning("reaper: cannot tell whether queued jobs lost their messages: %s", exc)
        return []
    done: list[Reaped] = []
    for job_id, since in waiting:
        with make_session() as session:
            resends = session.execute(
                select(func.count())
                .select_from(JobEvent)
                .where(
                    JobEvent.job_id == job_id, JobEvent.kind == "status", JobEvent.message.startswith(RESENT)
                )
            ).scalar_one()
            unclaimed = f"no worker claimed the job for {(now - since).total_seconds():.0f} s and the broker queue was empty"
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
            session.commit()
            if changed is None:
                continue
            log.warning("reaper: job %s: %s", job_id, message)
            if status is JobStatus.QUEUED and not send_or_fail(session, queue, job_id):
                status = JobStatus.FAILED
        done.append(Reaped(job_id, status, message))
    return done
