"""Demonstrations of a task: validated against the task's MDP by the engine, appended one batch at a time."""

from __future__ import annotations

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from metairl_engine import Trajectory, validate_trajectories
from service.store.blobs import put_array
from service.store.ids import new_id
from service.store.loaders import load_mdp
from service.store.models.demonstrators import Demonstration, Task
from service.store.owned import not_found
from service.store.paging import PageParams, RowPage, paginate


def add_demonstrations(
    session: Session, task: Task, trajectories: list[Trajectory], *, fmt: str
) -> Demonstration:
    """Validate `trajectories` against the task's MDP (raises `InvalidInput`) and add them as one batch.

    Arrays and row belong to the caller's transaction: a bad upload adds nothing, a failed one is rolled back.
    """
    validate_trajectories(load_mdp(session, task.mdp_id), trajectories)
    states = np.concatenate([t.states for t in trajectories])
    actions = np.concatenate([t.actions for t in trajectories])
    lengths = np.array([[len(t.states), len(t.actions)] for t in trajectories], dtype=np.int32)
    row = Demonstration(
        id=new_id("trj"),
        lab_id=task.lab_id,
        task_id=task.id,
        format=fmt,
        n_trajectories=len(trajectories),
        n_steps=int(actions.size),
        states_blob_id=put_array(session, states, lab_id=task.lab_id),
        actions_blob_id=put_array(session, actions, lab_id=task.lab_id),
        lengths_blob_id=put_array(session, lengths, lab_id=task.lab_id),
    )
    session.add(row)
    session.flush()
    return row


def list_demonstrations(session: Session, task: Task, *, page: PageParams) -> RowPage[Demonstration]:
    """One page of a task's demonstration batches, newest first."""
    query = select(Demonstration).where(Demonstration.task_id == task.id, Demonstration.lab_id == task.lab_id)
    return paginate(session, query, page, key=(Demonstration.created_at, Demonstration.id))


def get_demonstration(session: Session, task: Task, batch_id: str) -> Demonstration:
    """The batch `batch_id` of `task`, or 404 naming it (another task's or another lab's batch too)."""
    row = session.get(Demonstration, batch_id)
    if row is None or row.task_id != task.id or row.lab_id != task.lab_id:
        raise not_found("demonstration batch", batch_id)
    return row
