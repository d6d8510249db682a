"""Tasks of a demonstrator, their demonstration totals and their optional true rewards."""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy import delete, func, select
from sqlalchemy.orm import Session

from metairl_engine.mdp import FLOAT32_MAX
from service.domain.tasks import TaskTotals, TrueRewardOut
from service.problems import Unprocessable
from service.store.blobs import blob_sha256, get_array, put_array
from service.store.ids import new_id
from service.store.models.blobs import Blob
from service.store.models.demonstrators import Demonstration, Demonstrator, Task, TrueReward
from service.store.models.mdps import Mdp
from service.store.owned import get_owned
from service.store.paging import PageParams, RowPage, paginate


def create_task(
    session: Session, demonstrator: Demonstrator, *, name: str, mdp_id: str, metadata: dict[str, Any] | None
) -> Task:
    """Add a task of `demonstrator` in the lab's MDP `mdp_id` (422 at /mdp_id if the lab has no such MDP)."""
    mdp = session.get(Mdp, mdp_id)
    if mdp is None or mdp.lab_id != demonstrator.lab_id:
        raise Unprocessable(
            f"No MDP with id {mdp_id!r}.",
            errors=[{"pointer": "/mdp_id", "message": f"no MDP with id {mdp_id!r}"}],
        )
    row = Task(
        id=new_id("task"),
        lab_id=demonstrator.lab_id,
        demonstrator_id=demonstrator.id,
        mdp_id=mdp_id,
        name=name,
        meta=metadata,
    )
    session.add(row)
    session.flush()
    return row


def get_task(session: Session, task_id: str, *, lab_id: str) -> Task:
    """The lab's task, or 404."""
    return get_owned(session, Task, task_id, lab_id=lab_id, what="task")


def task_totals(session: Session, rows: list[Task]) -> dict[str, TaskTotals]:
    """Task id → its demonstration totals and true-reward flag, from one grouped query and one lookup."""
    ids = [r.id for r in rows]
    totals = {
        t.task_id: (int(t.n_trajectories), int(t.n_steps))
        for t in session.execute(
            select(
                Demonstration.task_id,
                func.sum(Demonstration.n_trajectories).label("n_trajectories"),
                func.sum(Demonstration.n_steps).label("n_steps"),
            )
            .where(Demonstration.task_id.in_(ids))
            .group_by(Demonstration.task_id)
        )
    }
    with_truth = set(session.execute(select(TrueReward.task_id).where(TrueReward.task_id.in_(ids))).scalars())
    return {
        row.id: TaskTotals(*totals.get(row.id, (0, 0)), has_true_reward=row.id in with_truth) for row in rows
    }


def list_tasks(session: Session, demonstrator: Demonstrator, *, page: PageParams) -> RowPage[Task]:
    """One page of a demonstrator's tasks, newest first."""
    query = select(Task).where(Task.demonstrator_id == demonstrator.id, Task.lab_id == demonstrator.lab_id)
    return paginate(session, query, page, key=(Task.created_at, Task.id))


def put_true_reward(session: Session, task: Task, values: list[float]) -> TrueReward:
    """Set (or replace) a task's true reward: one finite value per state of its MDP (422 otherwise)."""
    n_states = session.execute(select(Mdp.n_states).where(Mdp.id == task.mdp_id)).scalar_one()
    arr = np.asarray(values, dtype=np.float64)
    errors = []
    if arr.shape != (n_states,):
        errors.append(
            {"pointer": "/values", "message": f"has {arr.size} values but the MDP has {n_states} states"}
        )
    else:
        errors += [
            {"pointer": f"/values/{i}", "message": "must be a finite number (no NaN or infinity)"}
            for i in np.flatnonzero(~np.isfinite(arr))[:20]
        ]
        with np.errstate(invalid="ignore"):
            too_big = np.isfinite(arr) & (np.abs(arr) > FLOAT32_MAX)
        errors += [
            {
                "pointer": f"/values/{i}",
                "message": f"must fit a float32 (|value| ≤ {FLOAT32_MAX:.4g}); rewards are stored as float32",
            }
            for i in np.flatnonzero(too_big)[:20]
        ]
    if errors:
        raise Unprocessable(
            f"The true reward is invalid: {errors[0]['pointer']} {errors[0]['message']}.", errors=errors
        )
    blob_id = put_array(session, arr.astype(np.float32), lab_id=task.lab_id)
    row = session.get(TrueReward, task.id)
    if row is None:
        row = TrueReward(task_id=task.id, lab_id=task.lab_id, blob_id=blob_id, n_states=n_states)
        session.add(row)
    else:
        replaced, row.blob_id, row.n_states = row.blob_id, blob_id, n_states
        session.flush()
        session.execute(delete(Blob).where(Blob.id == replaced))
    session.flush()
    return row


def get_true_reward(session: Session, task: Task) -> TrueReward | None:
    """A task's true reward row, or None."""
    return session.get(TrueReward, task.id)


def true_reward_out(session: Session, row: TrueReward) -> TrueRewardOut:
    """The API view of a stored true reward, the same for PUT and GET: its values read back as stored (float32)."""
    values = get_array(session, row.blob_id).tolist()
    return TrueRewardOut.of(row, sha256=blob_sha256(session, row.blob_id), values=values)
