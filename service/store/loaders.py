"""What a fit reads from the database: a task's MDP, trajectories and true reward, as engine objects.

Used by the worker; numpy only (rows were validated at upload, so nothing is re-checked here).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from metairl_engine import MDP, Layout, SparseTransitions, Trajectory
from service.store.blobs import get_array
from service.store.models.blobs import Blob
from service.store.models.demonstrators import Demonstration, Task, TrueReward
from service.store.models.mdps import Mdp


@dataclass(frozen=True)
class InputSizes:
    """The sizes of a fit's inputs that its memory depends on (`metairl_engine.memory.fit_memory`'s arguments)."""

    n_tasks: int
    n_states: int
    n_actions: int
    n_features: int | None
    n_steps: int
    n_mdps: int
    successors: float


def input_sizes(session: Session, task_ids: Sequence[str]) -> InputSizes:
    """The sizes of these tasks' inputs from row metadata alone, so a worker can judge a job before loading it.

    The tasks share one state space (checked at submission); ``successors`` is the most next states per
    (state, action) of any of their MDPs (1 when all are deterministic).
    """
    mdp_ids = session.execute(select(Task.mdp_id).where(Task.id.in_(task_ids)).distinct()).scalars().all()
    mdps = session.execute(select(Mdp).where(Mdp.id.in_(mdp_ids))).scalars().all()
    first = mdps[0]
    successors = 1.0
    for mdp in mdps:
        if "p" in mdp.array_blobs:
            nonzeros = session.execute(
                select(Blob.shape).where(Blob.id == mdp.array_blobs["p"])
            ).scalar_one()[0]
            successors = max(successors, nonzeros / (mdp.n_states * mdp.n_actions))
    n_steps = session.execute(
        select(func.coalesce(func.sum(Demonstration.n_steps), 0)).where(Demonstration.task_id.in_(task_ids))
    ).scalar_one()
    return InputSizes(
        n_tasks=len(task_ids),
        n_states=first.n_states,
        n_actions=first.n_actions,
        n_features=first.n_features,
        n_steps=int(n_steps),
        n_mdps=len(mdps),
        successors=successors,
    )


def load_mdp(session: Session, mdp_id: str) -> MDP:
    """The stored MDP `mdp_id` as the engine's `MDP` (arrays read from blobs)."""
    row = session.get_one(Mdp, mdp_id)
    arrays = {name: get_array(session, blob_id) for name, blob_id in row.array_blobs.items()}
    sparse = None
    if row.transitions == "sparse":
        sparse = SparseTransitions(s=arrays["s"], a=arrays["a"], next=arrays["next"], p=arrays["p"])
    return MDP(
        n_states=row.n_states,
        n_actions=row.n_actions,
        gamma=row.gamma,
        features=arrays.get("features"),
        next_state=arrays.get("next_state"),
        sparse=sparse,
        layout=Layout(**row.layout) if row.layout else None,
    )


def load_trajectories(session: Session, task_id: str) -> list[Trajectory]:
    """Every trajectory of task `task_id`, upload batches in the order they were added."""
    batches = session.execute(
        select(Demonstration)
        .where(Demonstration.task_id == task_id)
        .order_by(Demonstration.created_at, Demonstration.id)
    ).scalars()
    return [trajectory for batch in batches for trajectory in batch_trajectories(session, batch)]


def batch_trajectories(session: Session, batch: Demonstration) -> list[Trajectory]:
    """The trajectories of one upload batch, in upload order (its blobs split by the stored lengths)."""
    states = get_array(session, batch.states_blob_id).astype(np.int64)
    actions = get_array(session, batch.actions_blob_id).astype(np.int64)
    lengths = get_array(session, batch.lengths_blob_id)
    state_ends = np.cumsum(lengths[:, 0])
    action_ends = np.cumsum(lengths[:, 1])
    return [
        Trajectory(states=s, actions=a)
        for s, a in zip(np.split(states, state_ends[:-1]), np.split(actions, action_ends[:-1]), strict=True)
    ]


def load_true_reward(session: Session, task_id: str) -> np.ndarray | None:
    """The true reward (float32, length n_states) of task `task_id`, or None if none was given."""
    row = session.get(TrueReward, task_id)
    return None if row is None else get_array(session, row.blob_id)
