"""Tasks of a demonstrator and their optional true rewards (for simulations)."""

from __future__ import annotations

from fastapi import APIRouter, Response

from service.auth import LabDep
from service.crud import tasks as crud
from service.crud.demonstrators import get_demonstrator
from service.deps import SessionDep
from service.openapi import PROBLEM_RESPONSES
from service.pagination import Page, PageDep
from service.problems import NotFound
from service.schemas.tasks import TaskIn, TaskOut, TrueRewardIn, TrueRewardOut

router = APIRouter(tags=["tasks"], responses=PROBLEM_RESPONSES)


@router.post(
    "/demonstrators/{demonstrator_id}/tasks", status_code=201, summary="Create a task of a demonstrator"
)
def create_task(
    demonstrator_id: str, body: TaskIn, response: Response, lab: LabDep, session: SessionDep
) -> TaskOut:
    """A task is played in one MDP of your lab; tasks fitted together must share one state space."""
    demonstrator = get_demonstrator(session, demonstrator_id, lab_id=lab.id)
    created = crud.create_task(
        session, demonstrator, name=body.name, mdp_id=body.mdp_id, metadata=body.metadata
    )
    response.headers["Location"] = f"/v1/tasks/{created.id}"
    return created


@router.get("/demonstrators/{demonstrator_id}/tasks", summary="List a demonstrator's tasks")
def list_tasks(demonstrator_id: str, lab: LabDep, session: SessionDep, page: PageDep) -> Page[TaskOut]:
    """The demonstrator's tasks, newest first, with demonstration totals."""
    return crud.list_tasks(session, get_demonstrator(session, demonstrator_id, lab_id=lab.id), page=page)


@router.get("/tasks/{task_id}", summary="Get a task")
def get_task(task_id: str, lab: LabDep, session: SessionDep) -> TaskOut:
    """One task with its demonstration totals and whether a true reward is set."""
    return crud.render_tasks(session, [crud.get_task(session, task_id, lab_id=lab.id)])[0]


@router.put("/tasks/{task_id}/true-reward", summary="Set a task's true reward")
def put_true_reward(task_id: str, body: TrueRewardIn, lab: LabDep, session: SessionDep) -> TrueRewardOut:
    """The known reward (one finite value per state), used to score learned rewards; replaces any earlier one."""
    return crud.put_true_reward(session, crud.get_task(session, task_id, lab_id=lab.id), body.values)


@router.get("/tasks/{task_id}/true-reward", summary="Get a task's true reward")
def get_true_reward(task_id: str, lab: LabDep, session: SessionDep) -> TrueRewardOut:
    """The stored true reward with its values; 404 if none was set."""
    found = crud.get_true_reward(session, crud.get_task(session, task_id, lab_id=lab.id))
    if found is None:
        raise NotFound(f"Task {task_id!r} has no true reward; set one with PUT.")
    return found
