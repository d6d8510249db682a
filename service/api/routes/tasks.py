"""Tasks of a demonstrator and their optional true rewards (for simulations)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Query, Response, status

from service.api.auth import LabDep
from service.api.deps import SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.pagination import Page, PageDep
from service.api.responses import DELETED, file_response
from service.domain.tasks import TaskIn, TaskOut, TrueRewardFormat, TrueRewardIn, TrueRewardOut
from service.problems import NotFound
from service.results import downloads
from service.store import tasks
from service.store.deletion import commit_deletion
from service.store.deletion import delete_task as delete_task_rows
from service.store.demonstrators import get_demonstrator

router = APIRouter(tags=["tasks"], responses=PROBLEM_RESPONSES)


@router.post(
    "/demonstrators/{demonstrator_id}/tasks", status_code=201, summary="Create a task of a demonstrator"
)
def create_task(
    demonstrator_id: str, body: TaskIn, response: Response, lab: LabDep, session: SessionDep
) -> TaskOut:
    """A task is played in one MDP of your lab; tasks fitted together must share one state space."""
    demonstrator = get_demonstrator(session, demonstrator_id, lab_id=lab.id)
    row = tasks.create_task(session, demonstrator, name=body.name, mdp_id=body.mdp_id, metadata=body.metadata)
    session.commit()
    response.headers["Location"] = f"/v1/tasks/{row.id}"
    return TaskOut.of(row, tasks.task_totals(session, [row])[row.id])


@router.get("/demonstrators/{demonstrator_id}/tasks", summary="List a demonstrator's tasks")
def list_tasks(demonstrator_id: str, lab: LabDep, session: SessionDep, page: PageDep) -> Page[TaskOut]:
    """The demonstrator's tasks, newest first, with demonstration totals."""
    rows = tasks.list_tasks(session, get_demonstrator(session, demonstrator_id, lab_id=lab.id), page=page)
    totals = tasks.task_totals(session, rows.rows)
    return Page[TaskOut].of(rows, lambda row: TaskOut.of(row, totals[row.id]))


@router.get("/tasks/{task_id}", summary="Get a task")
def get_task(task_id: str, lab: LabDep, session: SessionDep) -> TaskOut:
    """One task with its demonstration totals and whether a true reward is set."""
    row = tasks.get_task(session, task_id, lab_id=lab.id)
    return TaskOut.of(row, tasks.task_totals(session, [row])[row.id])


@router.delete(
    "/tasks/{task_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    summary="Delete a task and everything derived from it",
    responses=DELETED,
)
def delete_task(task_id: str, lab: LabDep, session: SessionDep) -> Response:
    """Removes the task, its demonstrations and true reward, and every job that fitted it (with their
    events and learned rewards), with their stored arrays; 409 while such a job is queued or running."""
    delete_task_rows(session, tasks.get_task(session, task_id, lab_id=lab.id))
    commit_deletion(session)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.put("/tasks/{task_id}/true-reward", summary="Set a task's true reward")
def put_true_reward(task_id: str, body: TrueRewardIn, lab: LabDep, session: SessionDep) -> TrueRewardOut:
    """The known reward (one finite value per state), used to score learned rewards; replaces any earlier one.
    Answers what GET then reads: the values as stored (float32)."""
    row = tasks.put_true_reward(session, tasks.get_task(session, task_id, lab_id=lab.id), body.values)
    session.commit()
    return tasks.true_reward_out(session, row)


@router.get(
    "/tasks/{task_id}/true-reward",
    summary="Get a task's true reward (json, npy, csv)",
    response_model=TrueRewardOut,
    responses={
        200: {
            "description": "JSON (the reward with its `values`, as PUT answers), a float32 `.npy`, or CSV "
            "(`state[,x,y,channel],true_reward`); the files with `ETag` and `Content-Disposition`.",
            "content": {"application/octet-stream": {}, "text/csv": {}},
        },
        304: {"description": "`If-None-Match` names the file's current ETag: your copy is up to date."},
        404: {"description": "No such task in your lab, or it has no true reward (problem+json)."},
    },
)
def get_true_reward(
    task_id: str,
    lab: LabDep,
    session: SessionDep,
    format: Annotated[
        TrueRewardFormat,
        Query(description="`json` (default), `npy` (float32) or `csv`, as a learned reward downloads."),
    ] = "json",
    if_none_match: Annotated[
        str | None, Header(description="An ETag from an earlier npy or csv download.")
    ] = None,
) -> TrueRewardOut | Response:
    """The stored true reward; 404 if none was set."""
    task = tasks.get_task(session, task_id, lab_id=lab.id)
    row = tasks.get_true_reward(session, task)
    if row is None:
        raise NotFound(f"Task {task_id!r} has no true reward; set one with PUT.")
    if format == "json":
        return tasks.true_reward_out(session, row)
    return file_response(
        downloads.true_reward_download(session, task, row, fmt=format, if_none_match=if_none_match)
    )
