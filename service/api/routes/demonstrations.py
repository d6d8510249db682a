"""`/v1/tasks/{task_id}/demonstrations`: append trajectories (JSON or CSV upload), list upload batches, read one
back (JSON or CSV) or delete it."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request, Response, status
from pydantic import TypeAdapter
from starlette.concurrency import run_in_threadpool

from metairl_engine import InvalidInput, Trajectory
from service.api.auth import LabDep
from service.api.bodies import Upload, json_or_upload
from service.api.deps import SessionDep
from service.api.openapi import PROBLEM_RESPONSES, request_body
from service.api.pagination import Page, PageDep
from service.api.responses import DELETED, file_response
from service.domain.demonstrations import (
    EXAMPLE_IN,
    BatchFormat,
    DemonstrationBatchOut,
    DemonstrationOut,
    DemonstrationsIn,
)
from service.files.csv_demonstrations import COLUMNS, parse_csv
from service.problems import from_invalid_input
from service.results import downloads
from service.store import demonstrations
from service.store.deletion import commit_deletion, delete_demonstration
from service.store.loaders import batch_trajectories
from service.store.tasks import get_task

router = APIRouter(tags=["demonstrations"], responses=PROBLEM_RESPONSES)
DEMOS_IN = TypeAdapter(DemonstrationsIn)
CSV_FORM = {
    "type": "object",
    "required": ["file"],
    "properties": {
        "file": {
            "type": "string",
            "format": "binary",
            "description": f"CSV with header {','.join(COLUMNS)}; the final state's row may leave action empty.",
        }
    },
}


@router.post(
    "/tasks/{task_id}/demonstrations",
    status_code=201,
    summary="Add demonstrations to a task",
    description="JSON trajectories, or a CSV file as multipart/form-data. Every index is checked against the "
    "task's MDP and every step against its transitions; nothing is stored unless all of it is valid.",
    openapi_extra=request_body(
        DemonstrationsIn,
        json_examples={
            "two trajectories": {"summary": "The second without a final state", "value": EXAMPLE_IN}
        },
        multipart=CSV_FORM,
    ),
)
async def add_demonstrations(
    task_id: str, request: Request, response: Response, lab: LabDep, session: SessionDep
) -> DemonstrationOut:
    """Validate and append one batch of trajectories."""
    task = await run_in_threadpool(get_task, session, task_id, lab_id=lab.id)
    body = await json_or_upload(request, DEMOS_IN, accepted="application/json or multipart/form-data (CSV)")
    if isinstance(body, Upload):
        parsed = await run_in_threadpool(parse_csv, await body.file.read(), request.app.state.settings)
        try:
            created = await run_in_threadpool(
                demonstrations.add_demonstrations, session, task, parsed.trajectories, fmt="csv"
            )
        except InvalidInput as exc:
            raise parsed.locate(exc) from exc
    else:
        trajectories = [Trajectory.of(t.states, t.actions) for t in body.trajectories]
        try:
            created = await run_in_threadpool(
                demonstrations.add_demonstrations, session, task, trajectories, fmt="json"
            )
        except InvalidInput as exc:
            raise from_invalid_input(exc, detail="The demonstrations are invalid.") from exc
    await run_in_threadpool(session.commit)
    response.headers["Location"] = f"/v1/tasks/{task.id}/demonstrations"
    return DemonstrationOut.of(created)


@router.get("/tasks/{task_id}/demonstrations", summary="List a task's demonstration uploads")
def list_demonstrations(
    task_id: str, lab: LabDep, session: SessionDep, page: PageDep
) -> Page[DemonstrationOut]:
    """Upload batches, newest first, each with its number of trajectories and steps."""
    rows = demonstrations.list_demonstrations(session, get_task(session, task_id, lab_id=lab.id), page=page)
    return Page[DemonstrationOut].of(rows, DemonstrationOut.of)


@router.get(
    "/tasks/{task_id}/demonstrations/{batch_id}",
    summary="Read back one demonstration upload (JSON or CSV)",
    description='The batch\'s metadata and its trajectories in upload order, as `{"states", "actions"}` '
    f"(JSON), or with `?format=csv` the columns `{','.join(COLUMNS)}` that the upload route takes, the "
    "trajectories numbered 0, 1, … in upload order and the final state's row with an empty action.",
    response_model=DemonstrationBatchOut,
    responses={
        200: {"description": "JSON, or with `?format=csv` a CSV file.", "content": {"text/csv": {}}},
        404: {"description": "No such task, or no such batch of it, in your lab (problem+json)."},
    },
)
def read_batch(
    task_id: str,
    batch_id: str,
    lab: LabDep,
    session: SessionDep,
    format: Annotated[BatchFormat, Query(description="`json` (default) or `csv`.")] = "json",
) -> DemonstrationBatchOut | Response:
    """One upload batch with its trajectories."""
    task = get_task(session, task_id, lab_id=lab.id)
    batch = demonstrations.get_demonstration(session, task, batch_id)
    if format == "csv":
        return file_response(downloads.demonstrations_csv(session, task, batch))
    return DemonstrationBatchOut.of_batch(batch, batch_trajectories(session, batch))


@router.delete(
    "/tasks/{task_id}/demonstrations/{batch_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    summary="Delete one demonstration upload",
    description="Removes the batch and its stored arrays. A job refers to its tasks, not to a copy of their "
    "demonstrations, and reads them when it runs: so the jobs of this task that finished after the batch was "
    "uploaded, whose rewards came from it, are deleted with it (their events and learned rewards); jobs that "
    "finished before it stay, as do the task and its other batches. A recording that stored the batch keeps "
    "its samples, its `tasks[].demonstration_id` becomes null. 409, and nothing deleted, while a job fitting "
    "the task is queued or running, as for deleting the task.",
    responses=DELETED,
)
def delete_batch(task_id: str, batch_id: str, lab: LabDep, session: SessionDep) -> Response:
    """Removes one batch and what was derived from it; 409 while a job fitting its task is queued or running."""
    task = get_task(session, task_id, lab_id=lab.id)
    delete_demonstration(session, demonstrations.get_demonstration(session, task, batch_id))
    commit_deletion(session)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
