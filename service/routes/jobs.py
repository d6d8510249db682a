"""`/v1/jobs` (API.md §5): submit, read, list, follow the event log, cancel.

The job row is committed before its message is sent; if the broker refuses the message the job is
marked failed with the reason (never lost silently).
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query, Request, Response, status
from sqlalchemy import select, update

from service.auth import LabDep
from service.deps import SessionDep, SettingsDep
from service.jobstatus import JobStatus
from service.jobstore import send_or_fail, transition
from service.jobsubmit import create_job
from service.models.jobs import Job, JobEvent
from service.pagination import Page, PageDep, paginate
from service.problems import Conflict, NotFound, Unprocessable
from service.queue import JobQueue
from service.schemas.jobs import JobEventOut, JobIn, JobOut

router = APIRouter(tags=["jobs"])

NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"description": "No such job in your lab."}}


def job_queue(request: Request) -> JobQueue:
    """The queue jobs are sent to (set on the app by `create_app`)."""
    queue: JobQueue = request.app.state.job_queue
    return queue


QueueDep = Annotated[JobQueue, Depends(job_queue)]


def get_job(session: SessionDep, lab: LabDep, job_id: str) -> Job:
    """The lab's job ``job_id``; 404 if it does not exist or belongs to another lab."""
    job = session.get(Job, job_id)
    if job is None or job.lab_id != lab.id:
        raise NotFound(f"No job {job_id} in your lab.")
    return job


JobDep = Annotated[Job, Depends(get_job)]


@router.post(
    "/jobs",
    status_code=status.HTTP_202_ACCEPTED,
    summary="Submit a job",
    responses={422: {"description": "Bad config or inputs; `errors` names each field."}},
)
def submit_job(
    body: JobIn, response: Response, session: SessionDep, lab: LabDep, settings: SettingsDep, queue: QueueDep
) -> JobOut:
    """Queue a fit of the demonstrator's tasks; poll `Location` for status and progress.

    If the job broker cannot be reached the job is returned already `failed`, with the reason in `error`.
    """
    job = create_job(session, lab_id=lab.id, body=body, max_attempts=settings.job_max_attempts)
    send_or_fail(session, queue, job.id)
    session.refresh(job)
    response.headers["Location"] = f"/v1/jobs/{job.id}"
    return JobOut.of(job)


@router.get("/jobs", summary="List jobs")
def list_jobs(
    session: SessionDep,
    lab: LabDep,
    page: PageDep,
    status_: Annotated[
        JobStatus | None, Query(alias="status", description="Only jobs in this status.")
    ] = None,
    demonstrator_id: Annotated[str | None, Query(description="Only jobs of this demonstrator.")] = None,
) -> Page[JobOut]:
    """The lab's jobs, newest first, optionally filtered by status and demonstrator."""
    query = select(Job).where(Job.lab_id == lab.id)
    if status_ is not None:
        query = query.where(Job.status == status_.value)
    if demonstrator_id is not None:
        query = query.where(Job.demonstrator_id == demonstrator_id)
    return paginate(session, query, Job, page, JobOut.of)


@router.get("/jobs/{job_id}", summary="Get a job's status and progress", responses=NOT_FOUND)
def read_job(job: JobDep) -> JobOut:
    """Status (contract values), progress, error when failed, attempts, timestamps and the config used."""
    return JobOut.of(job)


@router.get("/jobs/{job_id}/events", summary="A job's progress log", responses=NOT_FOUND)
def list_events(job: JobDep, session: SessionDep, page: PageDep) -> Page[JobEventOut]:
    """Status changes and (throttled) progress samples, oldest first; `next_cursor` continues the log."""
    after = _event_cursor(page.cursor)
    rows = list(
        session.execute(
            select(JobEvent)
            .where(JobEvent.job_id == job.id, JobEvent.id > after)
            .order_by(JobEvent.id)
            .limit(page.limit + 1)
        ).scalars()
    )
    has_more = len(rows) > page.limit
    rows = rows[: page.limit]
    return Page[JobEventOut](
        data=[JobEventOut.of(r) for r in rows],
        has_more=has_more,
        next_cursor=str(rows[-1].id) if has_more else None,
    )


def _event_cursor(cursor: str | None) -> int:
    """The event id a page starts after (0 for the first page); 422 for a cursor this list never made."""
    if cursor is None:
        return 0
    if not cursor.isdigit():
        raise Unprocessable(
            "The cursor is not valid; pass next_cursor from a previous page unchanged.",
            errors=[{"pointer": "", "parameter": "cursor", "message": "is not a cursor of this list"}],
        )
    return int(cursor)


@router.post(
    "/jobs/{job_id}/cancel",
    status_code=status.HTTP_202_ACCEPTED,
    summary="Cancel a job",
    responses={**NOT_FOUND, 409: {"description": "The job already finished."}},
)
def cancel_job(job: JobDep, session: SessionDep) -> JobOut:
    """A queued job is cancelled at once; a running one stops within a few seconds (`cancel_requested`)."""
    for _ in range(3):  # the job may change status between our reads; each step is a conditional write
        cancelled = transition(
            session, job.id, JobStatus.QUEUED, JobStatus.CANCELLED, message="cancelled on request"
        )
        if cancelled is not None:
            break
        flagged = session.execute(
            update(Job)
            .where(Job.id == job.id, Job.status == JobStatus.RUNNING.value)
            .values(cancel_requested=True)
            .execution_options(synchronize_session=False)
        )
        if flagged.rowcount:  # type: ignore[attr-defined]
            break
        session.refresh(job)
        if JobStatus(job.status).is_terminal:
            raise Conflict(f"Job {job.id} already finished ({job.status}); there is nothing to cancel.")
    session.commit()
    session.refresh(job)
    return JobOut.of(job)
