"""Reading a lab's jobs and a job's event log (the writes are `service.jobs`: submit and transitions)."""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import and_, bindparam, select
from sqlalchemy.orm import Session

from service.store.keys import KeyedQuery, in_key_lab, key_select
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, JobEvent
from service.store.owned import get_owned
from service.store.paging import PageParams, RowPage, paginate


def get_job(session: Session, job_id: str, *, lab_id: str) -> Job:
    """The lab's job, or 404."""
    return get_owned(session, Job, job_id, lab_id=lab_id, what="job")


KEYED_JOB: KeyedQuery = (
    key_select()
    .add_columns(*Job.__table__.columns)
    .outerjoin(Job, and_(Job.id == bindparam("job_id"), in_key_lab(Job.lab_id)))
)
"""The key check (`service.store.keys.key_select`) and job ``:job_id`` in one statement: every column of the
job under its own name, all NULL unless the job is in the key's lab."""


def list_jobs(
    session: Session,
    *,
    lab_id: str,
    page: PageParams,
    status: Sequence[JobStatus] | None = None,
    demonstrator_id: str | None = None,
) -> RowPage[Job]:
    """One page of the lab's jobs, newest first, optionally only those in one of `status` or of one
    demonstrator."""
    query = select(Job).where(Job.lab_id == lab_id)
    if status:
        query = query.where(Job.status.in_([s.value for s in status]))
    if demonstrator_id is not None:
        query = query.where(Job.demonstrator_id == demonstrator_id)
    return paginate(session, query, page, key=(Job.created_at, Job.id))


def list_events(session: Session, job: Job, *, page: PageParams) -> RowPage[JobEvent]:
    """One page of the job's event log, oldest first."""
    query = select(JobEvent).where(JobEvent.job_id == job.id)
    return paginate(session, query, page, key=(JobEvent.id,), newest_first=False)


HISTORY_MAX_POINTS = 2000
"""The most points a job's loss history returns: a longer log is thinned evenly (first and last kept)."""


def progress_history(session: Session, job: Job) -> list[JobEvent]:
    """The progress samples of the job's latest attempt, by step, thinned to `HISTORY_MAX_POINTS`."""
    query = (
        select(JobEvent)
        .where(JobEvent.job_id == job.id, JobEvent.kind == "progress", JobEvent.attempt == job.attempts)
        .order_by(JobEvent.step, JobEvent.id)
    )
    samples = list(session.execute(query).scalars())
    if len(samples) <= HISTORY_MAX_POINTS:
        return samples
    stride = (len(samples) - 1) / (HISTORY_MAX_POINTS - 1)
    return [samples[round(i * stride)] for i in range(HISTORY_MAX_POINTS)]


def events_after(session: Session, job_id: str, *, after_id: int, limit: int) -> list[JobEvent]:
    """Up to ``limit`` events of the job with an id above ``after_id``, oldest first (the event stream)."""
    query = (
        select(JobEvent)
        .where(JobEvent.job_id == job_id, JobEvent.id > after_id)
        .order_by(JobEvent.id)
        .limit(limit)
    )
    return list(session.execute(query).scalars())


def job_status(session: Session, job_id: str) -> JobStatus | None:
    """The job's status now (None if it was deleted meanwhile)."""
    value = session.execute(select(Job.status).where(Job.id == job_id)).scalar_one_or_none()
    return None if value is None else JobStatus(value)
