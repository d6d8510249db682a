"""Comparisons (docs/api.md, "Comparisons"): two rewards, or a reward and a true reward or posted values, by
Pearson, Spearman and EPIC, and EPIC and STARC under the MDP's dynamics; the job's pairwise matrix."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

if TYPE_CHECKING:
    from metairl_engine.distances import Interval as Bootstrapped

from metairl_engine.errors import Issue, check
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
from service.problems import Conflict, gathering, valid_fields, validated
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


def compare(session: Session, body: Mapping[str, Any], *, lab_id: str) -> ComparisonOut:
    """Pearson, Spearman and EPIC distance of reward `a` and side `b` on all or the demonstrated states, and
    EPIC and STARC with the dynamics of a's MDP. ``body`` is the JSON object as sent; `InvalidInput` names
    every problem at once: the schema's, and on the sides that pass it an unknown reward or task and a `b` whose
    length is not a's (a task without a true reward is a 409, once nothing else is wrong)."""
    issues: list[Issue] = []  # the body's problems and those of the rewards and task it names, in one 422
    request = gathering(issues, lambda: validated(ComparisonIn, body))
    sides = valid_fields(ComparisonIn, body)  # a and b, each where it passes the schema
    a: RewardContext | None = None
    b: _Side | None = None
    if "a" in sides:
        reward_id = sides["a"].reward_id
        a = gathering(issues, lambda: _body_reward(session, reward_id, lab_id=lab_id, pointer="/a/reward_id"))
    if "b" in sides:
        b = gathering(issues, lambda: _other_side(session, sides["b"], lab_id=lab_id))
    if a is not None and b is not None and b.values is not None and b.values.size != a.row.n_states:
        message = f"{b.what} has {b.values.size} values; reward a has {a.row.n_states} states"
        issues.append(Issue(b.pointer, message))
    check(issues)
    assert request is not None and a is not None and b is not None  # else check raised
    if b.values is None:
        task_id = b.described.task_id
        raise Conflict(
            f"Task {task_id} has no true reward; PUT /v1/tasks/{task_id}/true-reward first, "
            "or post the values as b.values."
        )
    x_all, y_all = get_array(session, a.row.reward_blob_id), b.values
    tasks = [*a.task_ids, *b.tasks]
    mask = visited_states(session, tasks, a.row.n_states) if request.states == "visited" else None
    x, y = (x_all[mask], y_all[mask]) if mask is not None else (x_all, y_all)
    return ComparisonOut(
        pearson=metrics().pearson(x, y),
        spearman=metrics().spearman(x, y),
        epic_distance=metrics().epic_distance(x, y),
        states=request.states,
        n_states=a.row.n_states,
        n_compared=int(x.size),
        dynamics=dynamics_distances(session, a, x_all, y_all, body=request, tasks=tasks, mask=mask),
        a=a.describe(),
        b=b.described,
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
    """A reward named in a request body; `InvalidInput` at `pointer` when the lab has none with this id."""
    row = session.get(Reward, reward_id)
    if row is None or row.lab_id != lab_id:
        check([Issue(pointer, "no reward with this id exists in your lab")])
    assert row is not None  # else check raised
    return context(session, row)


@dataclass(frozen=True)
class _Side:
    """Side b as its body names it: its values (None: a task without a true reward), its description, the
    tasks whose visits count, and where and as what a length other than a's is reported."""

    values: np.ndarray | None
    described: ComparedSide
    tasks: list[str]
    pointer: str
    what: str


def _other_side(session: Session, side: OtherSide, *, lab_id: str) -> _Side:
    """Side b: a learned reward or a task of the lab (else `InvalidInput` naming the field), or posted values."""
    if side.reward_id is not None:
        ctx = _body_reward(session, side.reward_id, lab_id=lab_id, pointer="/b/reward_id")
        values = get_array(session, ctx.row.reward_blob_id)
        return _Side(values, ctx.describe(), ctx.task_ids, "/b/reward_id", f"reward {ctx.row.id}")
    if side.task_id is not None:
        task = session.get(Task, side.task_id)
        if task is None or task.lab_id != lab_id:
            check([Issue("/b/task_id", "no task with this id exists in your lab")])
        assert task is not None  # else check raised
        demonstrator = session.get_one(Demonstrator, task.demonstrator_id)
        described = ComparedSide(
            kind="true_reward",
            label=f"{task.name} — {demonstrator.name} (true reward)",
            task_id=task.id,
            demonstrator_id=demonstrator.id,
        )
        truth = load_true_reward(session, task.id)
        return _Side(truth, described, [task.id], "/b/task_id", f"the true reward of task {task.id}")
    assert side.values is not None  # OtherSide holds exactly one of the three
    values = np.asarray(side.values, dtype=np.float64)
    return _Side(values, ComparedSide(kind="values", label="posted values"), [], "/b/values", "values")
