"""The reaper: running jobs whose heartbeat stopped are re-queued, cancelled or failed; lost messages re-sent.

A worker killed outright (SIGKILL, OOM, a lost machine) cannot report anything, and its broker
message may be gone (embedded broker) or return only after the visibility timeout (Redis); the job
row's heartbeat is what tells. An attempt whose last heartbeat came after the time limit was killed by
it and fails at once instead of being re-run. A queued job can lose its message too (the API died
between commit and send, a broker lost it): when one waited ``job_requeue_after_s`` while the broker
queue was empty, its message is sent again, at most ``job_max_resends`` times. Every worker runs
`reap_once` periodically; each change is a conditional UPDATE (same status, same attempt, still older
than the cutoff), so concurrent reapers and a worker that comes back to life cannot act twice on one job.

The queries and those fenced writes are `service/jobs/reaping.py`; here are the passes, their sessions
and commits, the logging and the broker calls.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import datetime, timedelta
from functools import lru_cache

from sqlalchemy.orm import Session, sessionmaker

from service.jobs.queue import CeleryJobQueue, EnqueueFailed, JobQueue
from service.jobs.reaping import BATCH, RESENT, settle_lost, settle_stale, stale_running, waiting_queued
from service.jobs.transitions import send_or_fail
from service.settings import Settings, get_settings
from service.store.models.base import utcnow
from service.store.models.job_status import JobStatus
from worker.context import sessions

__all__ = ["BATCH", "RESENT", "Reaped", "reap", "reap_once", "resend_lost"]

log = logging.getLogger(__name__)


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
    with make_session() as session:
        stale = stale_running(session, cutoff=cutoff)
    done: list[Reaped] = []
    for row in stale:
        with make_session() as session:
            settled = settle_stale(session, row, settings, cutoff=cutoff)
            session.commit()
            if settled is None:
                continue
            status, message = settled
            log.warning("reaper: job %s → %s: %s", row.id, status.value, message)
            if status is JobStatus.QUEUED and not send_or_fail(session, queue, row.id):
                session.commit()
                status = JobStatus.FAILED
        done.append(Reaped(row.id, status, message))
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
        waiting = waiting_queued(session, cutoff=cutoff)
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
            settled = settle_lost(session, job_id, since, settings, now=now, cutoff=cutoff)
            session.commit()
            if settled is None:
                continue
            status, message = settled
            log.warning("reaper: job %s: %s", job_id, message)
            if status is JobStatus.QUEUED and not send_or_fail(session, queue, job_id):
                session.commit()
                status = JobStatus.FAILED
        done.append(Reaped(job_id, status, message))
    return done
