"""Where the demonstrations went (visits and occupancy per state) and the key states: where a task reward departs
most from its job's baseline, the paper's reading of what a task adds."""

from __future__ import annotations

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from service.domain.rewards import (
    KeyState,
    KeyStates,
)
from service.files import exports
from service.problems import Conflict
from service.results.engine_modules import metrics
from service.results.rewards import RewardContext, job_reward_rows
from service.store.blobs import get_array
from service.store.models.demonstrators import Demonstration


def demonstration_states(session: Session, task_ids: list[str]) -> list[np.ndarray]:
    """The state indices of the demonstrations of the given tasks, one array per upload batch (its
    trajectories' states end to end: for occupancy; `load_trajectories` splits them)."""
    blob_ids = session.execute(
        select(Demonstration.states_blob_id).where(Demonstration.task_id.in_(task_ids))
    ).scalars()
    return [get_array(session, blob_id).astype(np.int64) for blob_id in blob_ids]


def state_occupancy(session: Session, task_ids: list[str], n_states: int) -> np.ndarray:
    """How often each state occurs in the demonstrations of the given tasks."""
    counts = np.zeros(n_states)
    for states in demonstration_states(session, task_ids):
        counts += np.bincount(states, minlength=n_states)
    return counts


def visited_states(session: Session, task_ids: list[str], n_states: int) -> np.ndarray:
    """Boolean mask of the states that occur in any demonstration of the given tasks."""
    return state_occupancy(session, task_ids, n_states) > 0


def reward_key_states(session: Session, ctx: RewardContext, *, top: int) -> KeyStates:
    """The `top` states where the task reward departs most from its job's baseline, with a note when fewer
    depart at all; 409 for the baseline."""
    if ctx.task is None:
        raise Conflict(
            f"Reward {ctx.row.id} is the baseline, which key states are measured from; "
            "ask for the key states of one of the job's task rewards."
        )
    baseline_row = job_reward_rows(session, ctx.job)[0]
    task_values = get_array(session, ctx.row.reward_blob_id).astype(np.float64)
    baseline = get_array(session, baseline_row.reward_blob_id).astype(np.float64)
    states = metrics().key_states(task_values, baseline, top=top)
    note = None
    if len(states) < min(top, task_values.size):
        why = (
            " (the job's shrinkage λ is 0: it kept no deviation from the baseline)"
            if ctx.job.shrinkage == 0
            else ""
        )
        note = (
            f"The task reward differs from the baseline at {len(states)} of {task_values.size} states{why}; "
            "a state where they are equal is no key state."
            if len(states)
            else f"The task reward equals the baseline at every state{why}: no state departs from it."
        )
    layout = ctx.layout
    coords = exports.grid_coordinates(states, layout) if layout else (None, None, None)
    return KeyStates(
        reward_id=ctx.row.id,
        baseline_reward_id=baseline_row.id,
        task_id=ctx.task.id,
        top=top,
        states=[
            KeyState(
                rank=rank + 1,
                state=int(s),
                x=None if coords[0] is None else int(coords[0][rank]),
                y=None if coords[1] is None else int(coords[1][rank]),
                channel=None if coords[2] is None else int(coords[2][rank]),
                reward=float(task_values[s]),
                baseline=float(baseline[s]),
                difference=float(task_values[s] - baseline[s]),
            )
            for rank, s in enumerate(states)
        ],
        note=note,
    )
