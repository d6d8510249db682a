"""Comparisons (docs/api.md, "Comparisons"): two rewards, or a reward and a true reward or posted values, by
Pearson, Spearman and EPIC, and EPIC and STARC under the MDP's dynamics; the job's pairwise matrix."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

if TYPE_CHECKING:
    from metairl_engine.distances import Interval as Bootstrapped

from service.domain.comparisons import (
    ComparedSide,
    ComparisonIn,
    ComparisonOut,
    DynamicsDistances,
    Interval,
    OtherSide,
)
from service.domain.rewards import (
    ComparisonMatrix,
)
from service.problems import Conflict, Unprocessable
from service.results.engine_modules import dynamics, metrics, planning
from service.results.key_states import state_occupancy, visited_states
from service.results.rewards import (
    RewardContext,
    context,
    job_reward_rows,
)
from service.store.blobs import get_array
from service.store.loaders import load_mdp, load_true_reward
from service.store.models.demonstrators import Demonstrator, Task
from service.store.models.jobs import Job, Reward


def compare(session: Session, body: ComparisonIn, *, lab_id: str) -> ComparisonOut:
    """Pearson, Spearman and EPIC distance of reward `a` and side `b` on all or the demonstrated states, and
    EPIC and STARC with the dynamics of a's MDP."""
    a = _body_reward(session, body.a.reward_id, lab_id=lab_id, pointer="/a/reward_id")
    x_all = get_array(session, a.row.reward_blob_id)
    y_all, side, b_tasks = _other_side(session, body.b, n_states=a.row.n_states, lab_id=lab_id)
    tasks = [*a.task_ids, *b_tasks]
    mask = visited_states(session, tasks, a.row.n_states) if body.states == "visited" else None
    x, y = (x_all[mask], y_all[mask]) if mask is not None else (x_all, y_all)
    return ComparisonOut(
        pearson=metrics().pearson(x, y),
        spearman=metrics().spearman(x, y),
        epic_distance=metrics().epic_distance(x, y),
        states=body.states,
        n_states=a.row.n_states,
        n_compared=int(x.size),
        dynamics=dynamics_distances(session, a, x_all, y_all, body=body, tasks=tasks, mask=mask),
        a=a.describe(),
        b=side,
    )


def dynamics_distances(
    session: Session,
    a: RewardContext,
    x: np.ndarray,
    y: np.ndarray,
    *,
    body: ComparisonIn,
    tasks: list[str],
    mask: np.ndarray | None,
) -> DynamicsDistances:
    """EPIC and STARC of the two rewards under a's MDP, states weighted uniformly or by the demonstrations'
    occupancy (and only the compared states)."""
    mdp = load_mdp(session, a.mdp.id)
    weights = np.ones(mdp.n_states)
    if body.weights == "occupancy":
        weights = state_occupancy(session, tasks, mdp.n_states)
    if mask is not None:
        weights = weights * mask
    found = dynamics().distances(
        x,
        y,
        transitions=planning().transition_matrix(mdp),
        gamma=mdp.gamma,
        n_actions=mdp.n_actions,
        state_weights=weights,
        bootstrap=body.bootstrap,
    )

    def interval(i: Bootstrapped | None) -> Interval | None:
        return None if i is None else Interval(low=i.low, high=i.high)

    return DynamicsDistances(
        epic=found.epic,
        epic_interval=interval(found.epic_interval),
        starc=found.starc,
        starc_interval=interval(found.starc_interval),
        weights=body.weights,
        n_bootstrap=found.n_bootstrap,
        mdp_id=a.mdp.id,
        gamma=mdp.gamma,
    )


def comparison_matrix(session: Session, job: Job) -> ComparisonMatrix:
    """Pearson r of every pair among the job's baseline and task rewards (metrics.pearson: 0 when undefined)."""
    rows = job_reward_rows(session, job)
    values = [get_array(session, row.reward_blob_id) for row in rows]
    tasks = {t.id: t for t in session.execute(select(Task).where(Task.id.in_(job.task_ids))).scalars()}
    names = {t.id: t.name for t in tasks.values()}
    mdp = load_mdp(session, tasks[job.task_ids[0]].mdp_id)
    return ComparisonMatrix(
        job_id=job.id,
        labels=[names[row.task_id] if row.task_id else "baseline" for row in rows],
        reward_ids=[row.id for row in rows],
        task_ids=[row.task_id for row in rows],
        matrix=[[metrics().pearson(u, v) for v in values] for u in values],
        epic=dynamics()
        .pairwise_epic(
            values, transitions=planning().transition_matrix(mdp), gamma=mdp.gamma, n_actions=mdp.n_actions
        )
        .tolist(),
    )


def _body_reward(session: Session, reward_id: str, *, lab_id: str, pointer: str) -> RewardContext:
    """A reward named in a request body: 422 at `pointer` when the lab has none with this id."""
    row = session.get(Reward, reward_id)
    if row is None or row.lab_id != lab_id:
        raise Unprocessable(
            f"No reward with id {reward_id!r}.",
            errors=[{"pointer": pointer, "message": "no reward with this id exists in your lab"}],
        )
    return context(session, row)


def _other_side(
    session: Session, side: OtherSide, *, n_states: int, lab_id: str
) -> tuple[np.ndarray, ComparedSide, list[str]]:
    """Side b's values (checked to have `n_states`), its description, and the tasks whose visits count."""
    if side.reward_id is not None:
        ctx = _body_reward(session, side.reward_id, lab_id=lab_id, pointer="/b/reward_id")
        _check_length(ctx.row.n_states, n_states, pointer="/b/reward_id", what=f"reward {ctx.row.id}")
        return get_array(session, ctx.row.reward_blob_id), ctx.describe(), ctx.task_ids
    if side.task_id is not None:
        task = session.get(Task, side.task_id)
        if task is None or task.lab_id != lab_id:
            raise Unprocessable(
                f"No task with id {side.task_id!r}.",
                errors=[{"pointer": "/b/task_id", "message": "no task with this id exists in your lab"}],
            )
        truth = load_true_reward(session, task.id)
        if truth is None:
            raise Conflict(
                f"Task {task.id} has no true reward; PUT /v1/tasks/{task.id}/true-reward first, "
                "or post the values as b.values."
            )
        _check_length(truth.size, n_states, pointer="/b/task_id", what=f"the true reward of task {task.id}")
        demonstrator = session.get_one(Demonstrator, task.demonstrator_id)
        described = ComparedSide(
            kind="true_reward",
            label=f"{task.name} — {demonstrator.name} (true reward)",
            task_id=task.id,
            demonstrator_id=demonstrator.id,
        )
        return truth, described, [task.id]
    assert side.values is not None  # OtherSide holds exactly one of the three
    _check_length(len(side.values), n_states, pointer="/b/values", what="values")
    return np.asarray(side.values, dtype=np.float64), ComparedSide(kind="values", label="posted values"), []


def _check_length(length: int, n_states: int, *, pointer: str, what: str) -> None:
    """422 at `pointer` when side b does not have one value per state of reward a."""
    if length != n_states:
        message = f"{what} has {length} values; reward a has {n_states} states"
        raise Unprocessable(f"Cannot compare: {message}.", errors=[{"pointer": pointer, "message": message}])
