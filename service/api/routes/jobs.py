"""`/v1/jobs` (docs/api.md, "Jobs"): submit, read, list, follow the event log, read the loss curve, cancel.

The job row is committed before its message is sent; if the broker refuses the message the job is
marked failed with the reason (never lost silently).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Query, Request, Response, status
from sse_starlette import EventSourceResponse

from service.api.auth import BearerDep, authorised_row
from service.api.deps import JobDep, LabDep, QueueDep, SessionDep, SettingsDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.pagination import Page, PageDep
from service.api.responses import DELETED, NO_SUCH_JOB
from service.api.sse import MEDIA_TYPE, parse_last_event_id, stream_response, wants_stream
from service.domain.jobs import JobEventOut, JobHistory, JobOut, JobSubmission
from service.jobs.queue import EnqueueFailed
from service.jobs.submit import create_job
from service.jobs.transitions import cancel
from service.problems import BROKER_RETRY_AFTER_S, BrokerUnavailable
from service.store import jobs
from service.store.deletion import commit_deletion, discard_unsent_job
from service.store.deletion import delete_job as delete_job_rows
from service.store.histories import step_history
from service.store.models.job_status import JobStatus
from service.store.owned import not_found

router = APIRouter(tags=["jobs"], responses=PROBLEM_RESPONSES)


@router.post(
    "/jobs",
    status_code=status.HTTP_202_ACCEPTED,
    summary="Submit a job",
    responses={422: {"description": "Bad config or inputs; `errors` names each field."}},
)
def submit_job(
    body: JobSubmission,
    response: Response,
    session: SessionDep,
    lab: LabDep,
    settings: SettingsDep,
    queue: QueueDep,
) -> JobOut:
    """Queue a fit of the demonstrator's tasks; poll `Location` for status and progress.

    If the job broker cannot be reached the answer is 503 with `Retry-After` and no job is stored, so the same
    request (same `Idempotency-Key`) can simply be sent again.
    """
    job = create_job(session, lab_id=lab.id, body=body, settings=settings)
    session.commit()  # before the message: a worker never receives a job that is not in the database
    try:
        queue.enqueue(job.id)
    except EnqueueFailed as exc:
        discard_unsent_job(session, job.id)
        session.commit()
        raise BrokerUnavailable(
            f"The job could not be handed to a worker ({exc}); nothing was stored. Retry once the broker is back.",
            headers={"Retry-After": str(BROKER_RETRY_AFTER_S)},
        ) from exc
    session.refresh(job)
    response.headers["Location"] = f"/v1/jobs/{job.id}"
    return JobOut.of(job)


@router.get("/jobs", summary="List jobs")
def list_jobs(
    session: SessionDep,
    lab: LabDep,
    page: PageDep,
    status_: Annotated[
        list[JobStatus] | None,
        Query(
            alias="status",
            description="Only jobs in this status; repeat it for several (`?status=queued&status=running`).",
        ),
    ] = None,
    demonstrator_id: Annotated[str | None, Query(description="Only jobs of this demonstrator.")] = None,
) -> Page[JobOut]:
    """The lab's jobs, newest first, optionally filtered by status and demonstrator."""
    rows = jobs.list_jobs(session, lab_id=lab.id, page=page, status=status_, demonstrator_id=demonstrator_id)
    return Page[JobOut].of(rows, JobOut.of)


@router.get("/jobs/{job_id}", summary="Get a job's status and progress", responses=NO_SUCH_JOB)
async def read_job(job_id: str, request: Request, credentials: BearerDep) -> JobOut:
    """Status (contract values), progress, error when failed, attempts, timestamps and the config used."""
    # Polled hard: the key check and the job are one statement on the event loop (service/api/async_db.py).
    row = await authorised_row(request, credentials, jobs.KEYED_JOB, job_id=job_id)
    if row.id is None:
        raise not_found("job", job_id)
    return JobOut.of(row)


SSE_EXAMPLE = (
    "retry: 2000\n\n"
    'id: 7\nevent: progress\ndata: {"id":7,"at":"2026-01-05T10:05:06Z","kind":"progress","attempt":1,'
    '"step":120,"max_steps":500,"loss":1.204,"irl_loss":1.187,"sharing_loss":0.017,"elapsed_s":14.2}\n\n'
    'id: 9\nevent: status\ndata: {"id":9,"at":"2026-01-05T10:06:02Z","kind":"status","attempt":1,'
    '"status":"succeeded","message":"finished after 380 steps (kept step 280)"}\n\n'
)


@router.get(
    "/jobs/{job_id}/events",
    summary="A job's progress log (JSON pages, or live as Server-Sent Events)",
    response_model=Page[JobEventOut],
    responses={
        **NO_SUCH_JOB,
        200: {
            "description": "The log as a JSON page; with `Accept: text/event-stream`, a live SSE stream.",
            "content": {MEDIA_TYPE: {"schema": {"type": "string"}, "example": SSE_EXAMPLE}},
        },
    },
)
def list_events(
    job: JobDep,
    session: SessionDep,
    page: PageDep,
    request: Request,
    accept: Annotated[str | None, Header(include_in_schema=False)] = None,
    last_event_id: Annotated[
        str | None,
        Header(description="SSE only: resume after this event id (sent by browsers when they reconnect)."),
    ] = None,
) -> Page[JobEventOut] | EventSourceResponse:
    """Status changes and (throttled) progress samples, oldest first; `next_cursor` continues the log.

    With `Accept: text/event-stream` the log streams as Server-Sent Events instead: each stored event once
    (`event: progress` or `event: status`, `id:` the event id, `data:` the event as JSON), new ones as they
    are written, and the stream ends after the job's final status. `Last-Event-ID` resumes after an event.
    """
    if not wants_stream(accept):
        return Page[JobEventOut].of(jobs.list_events(session, job, page=page), JobEventOut.of)
    session.close()  # the stream reads with a session per poll: hold no connection while it is open
    settings = request.app.state.settings
    slot = request.app.state.stream_slots.take(request.headers.get("authorization", ""))
    return stream_response(
        request.app.state.sessionmaker,
        job.id,
        after_id=parse_last_event_id(last_event_id),
        poll_s=settings.events_poll_s,
        max_s=settings.events_stream_max_s,
        slot=slot,
    )


@router.get(
    "/jobs/{job_id}/history", summary="A job's loss curve", response_model=JobHistory, responses=NO_SUCH_JOB
)
def read_history(job: JobDep, session: SessionDep) -> JobHistory | Response:
    """Loss, IRL loss, sharing loss and held-out NLL by step: every step of a succeeded fit (`source`
    `steps`), else the progress samples of the latest attempt (`samples`), which the event stream's
    `progress` events extend live."""
    stored = step_history(session, job)
    if stored is not None:
        body = JobHistory.steps_json(
            job, attempt=stored.attempt, max_steps=stored.max_steps, columns=stored.columns
        )
        return Response(body, media_type="application/json")
    return JobHistory.of(job, jobs.progress_history(session, job))


@router.post(
    "/jobs/{job_id}/cancel",
    status_code=status.HTTP_202_ACCEPTED,
    summary="Cancel a job",
    responses={**NO_SUCH_JOB, 409: {"description": "The job already finished."}},
)
def cancel_job(job: JobDep, session: SessionDep) -> JobOut:
    """A queued job is cancelled at once; a running one stops within a few seconds (`cancel_requested`)."""
    cancel(session, job)
    session.commit()
    session.refresh(job)
    return JobOut.of(job)


@router.delete(
    "/jobs/{job_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    summary="Delete a finished job",
    responses={**NO_SUCH_JOB, **DELETED},
)
def delete_job(job: JobDep, session: SessionDep) -> Response:
    """Removes a finished job with its events and learned rewards (values, policies) and their stored
    arrays; 409 while it is queued or running (cancel it first)."""
    delete_job_rows(session, job)
    commit_deletion(session)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
