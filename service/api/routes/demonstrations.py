"""`/v1/tasks/{task_id}/demonstrations`: append trajectories (JSON or CSV upload), list upload batches."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response
from pydantic import TypeAdapter
from starlette.concurrency import run_in_threadpool

from metairl_engine import InvalidInput, Trajectory
from service.api.auth import LabDep
from service.api.bodies import Upload, json_or_upload
from service.api.deps import SessionDep
from service.api.openapi import PROBLEM_RESPONSES, request_body
from service.api.pagination import Page, PageDep
from service.domain.demonstrations import EXAMPLE_IN, DemonstrationOut, DemonstrationsIn
from service.files.csv_demonstrations import COLUMNS, parse_csv
from service.problems import from_invalid_input
from service.store import demonstrations
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
