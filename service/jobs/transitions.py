"""Conditional writes to job rows shared by the API, the worker and the reaper.

Every status change is one `UPDATE … WHERE id = ? AND status = <from> [AND …]` checked against
`JobStatus.can_become`, so concurrent actors (two reapers, a cancel racing a finish, a zombie worker)
cannot both win: the loser's UPDATE matches no row. Nothing here commits: the caller that opened the
session does (a route, a worker task, the reaper).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import ColumnElement, update
from sqlalchemy.orm import Session

from service.jobs.queue import EnqueueFailed, JobQueue
from service.jobs.webhooks import notify_job_end
from service.problems import Conflict
from service.store.models.base import utcnow
from service.store.models.job_status import JobStatus
from service.store.models.jobs import PROGRESS_FIELDS, Job, JobEvent


def transition(
    session: Session,
    job_id: str,
    old: JobStatus,
    new: JobStatus,
    *,
    where: tuple[ColumnElement[bool], ...] = (),
    values: dict[str, Any] | None = None,
    message: str | None = None,
) -> int | None:
    """Move the job from ``old`` to ``new`` if it is still ``old`` (and ``where`` holds); log a status event.

    Returns the job's attempt number after the change, or None when the row no longer matched.
    Raises `IllegalTransition` for an edge the lifecycle does not have.
    """
    old.check(new)
    now = utcnow()
    changes: dict[str, Any] = {"status": new.value, "updated_at": now, **(values or {})}
    if new.is_terminal:
        changes.setdefault("finished_at", now)
    attempt = session.execute(
        update(Job)
        .where(Job.id == job_id, Job.status == old.value, *where)
        .values(changes)
        .returning(Job.attempts)
        .execution_options(synchronize_session=False)
    ).scalar_one_or_none()
    if attempt is not None:
        session.add(
            JobEvent(job_id=job_id, at=now, kind="status", attempt=attempt, status=new, message=message)
        )
        if new.is_terminal:  # the webhooks' deliveries commit (or roll back) with the final status
            notify_job_end(session, job_id, new)
    return attempt


def claim(session: Session, job_id: str) -> int | None:
    """Start the next attempt of a queued job: running, attempts + 1, fresh heartbeat, no progress yet (an
    earlier attempt's last step must not show as this one's); None if not queued."""
    now = utcnow()
    return transition(
        session,
        job_id,
        JobStatus.QUEUED,
        JobStatus.RUNNING,
        values={
            "attempts": Job.attempts + 1,
            "started_at": now,
            "heartbeat_at": now,
            "error": None,
            **dict.fromkeys(PROGRESS_FIELDS),
        },
        message="a worker started the job",
    )


def touch_queued(
    session: Session, job_id: str, *, waiting_since_before: datetime, now: datetime, message: str
) -> int | None:
    """Restart the wait of a job still queued since before the given time (its message is sent again); log why.

    Not a status change: ``updated_at`` (when the job last entered the queue or was re-sent) becomes ``now``,
    so of concurrent reapers only the first matches. Returns the job's attempt, or None if it no longer matched.
    """
    attempt = session.execute(
        update(Job)
        .where(Job.id == job_id, Job.status == JobStatus.QUEUED.value, Job.updated_at < waiting_since_before)
        .values(updated_at=now)
        .returning(Job.attempts)
        .execution_options(synchronize_session=False)
    ).scalar_one_or_none()
    if attempt is not None:
        session.add(
            JobEvent(
                job_id=job_id,
                at=now,
                kind="status",
                attempt=attempt,
                status=JobStatus.QUEUED,
                message=message,
            )
        )
    return attempt


def owned_by(attempt: int) -> tuple[ColumnElement[bool], ...]:
    """The fence of attempt ``attempt``: only while the row still records this attempt may it write."""
    return (Job.attempts == attempt,)


def send_or_fail(session: Session, queue: JobQueue, job_id: str) -> bool:
    """Hand a committed queued job to the workers; if the broker refuses, fail the job saying why.

    Returns whether the message was sent; when not, the caller commits the failure."""
    try:
        queue.enqueue(job_id)
    except EnqueueFailed as exc:
        reason = (
            f"The job could not be handed to a worker ({exc}). "
            "Check that the broker is running and reachable, then submit the job again."
        )
        transition(
            session, job_id, JobStatus.QUEUED, JobStatus.FAILED, values={"error": reason}, message=reason
        )
        return False
    return True


def cancel(session: Session, job: Job) -> None:
    """Cancel a queued job at once, or ask a running one to stop (`cancel_requested`); 409 once it finished.

    The job may change status between our reads; each step is a conditional write, retried a few times.
    """
    for _ in range(3):
        cancelled = transition(
            session, job.id, JobStatus.QUEUED, JobStatus.CANCELLED, message="cancelled on request"
        )
        if cancelled is not None:  # the attempt number, 0 before any worker claimed the job
            return
        flagged = session.execute(
            update(Job)
            .where(Job.id == job.id, Job.status == JobStatus.RUNNING.value)
            .values(cancel_requested=True)
            .execution_options(synchronize_session=False)
        )
        if flagged.rowcount:  # type: ignore[attr-defined]
            return
        session.refresh(job)
        if JobStatus(job.status).is_terminal:
            raise Conflict(f"Job {job.id} already finished ({job.status}); there is nothing to cancel.")
