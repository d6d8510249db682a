"""Demonstrations of a task: validated against the task's MDP by the engine, appended one batch at a time."""

from __future__ import annotations

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from metairl_engine import Trajectory, validate_trajectories
from service.blobs import put_array
from service.ids import new_id
from service.inputs import load_mdp
from service.models.demonstrators import Demonstration, Task
from service.pagination import Page, PageParams, paginate
from service.schemas.demonstrations import DemonstrationOut


def add_demonstrations(
    session: Session, task: Task, trajectories: list[Trajectory], *, fmt: str
) -> DemonstrationOut:
    """Validate `trajectories` against the task's MDP (raises `InvalidInput`) and store them as one batch.

    Arrays and row go in one transaction: a bad or failed upload leaves the task's demonstrations unchanged.
    """
    validate_trajectories(load_mdp(session, task.mdp_id), trajectories)
    states = np.concatenate([t.states for t in trajectories])
    actions = np.concatenate([t.actions for t in trajectories])
    lengths = np.array([[len(t.states), len(t.actions)] for t in trajectories], dtype=np.int32)
    row = Demonstration(
        id=new_id("demo"),
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
    session.commit()
    return DemonstrationOut.model_validate(row)


def list_demonstrations(session: Session, task: Task, *, page: PageParams) -> Page[DemonstrationOut]:
    """One page of a task's demonstration batches, newest first."""
    query = select(Demonstration).where(Demonstration.task_id == task.id, Demonstration.lab_id == task.lab_id)
    return paginate(session, query, Demonstration, page, DemonstrationOut.model_validate)
