"""Checking and recording a job submission (docs/api.md, "Jobs"): config, tasks, demonstrations, one state space.

Everything a person can fix is reported up front as a 422 naming the field, so a queued job only fails
for reasons no request check can foresee.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from metairl_engine.config import FitConfig, baseline_column_issues
from metairl_engine.errors import Issue, check
from metairl_engine.grids import input_columns
from metairl_engine.mdp import Layout
from service.domain.job_config import fit_config, valid_settings
from service.domain.jobs import JobIn
from service.problems import gathering, validated
from service.settings import Settings
from service.sizes import hidden_issues, mdp_size_issues
from service.store.blobs import blob_sha256
from service.store.ids import new_id
from service.store.models.base import utcnow
from service.store.models.demonstrators import Demonstration, Demonstrator, Task
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, JobEvent
from service.store.models.mdps import Mdp


def create_job(session: Session, *, lab_id: str, body: Mapping[str, Any], settings: Settings) -> Job:
    """Check a submission, the JSON object as sent, and add the queued job (flushed; the caller commits before
    sending its message); raises `InvalidInput` naming every problem at once: the body's types and ranges,
    the engine's checks of the config, the size limits (`service.sizes`), the demonstrator and its tasks."""
    issues: list[Issue] = []  # the problems of every stage, reported together in one 422
    submission = gathering(issues, lambda: validated(JobIn, body))
    config = gathering(issues, lambda: _config(body.get("config"), settings))
    chosen = None if submission is None else gathering(issues, lambda: _tasks(session, lab_id, submission))
    first = None if chosen is None else gathering(issues, lambda: _check_tasks(session, *chosen, settings))
    if config is not None and first is not None:
        layout = Layout(**first.layout) if first.layout else None
        issues += baseline_column_issues(
            config, n_columns=input_columns(first.n_features, layout, config.tabular_inputs)
        )
    check(issues)
    assert submission is not None and config is not None and chosen is not None  # else check raised
    tasks = chosen[0]
    now = utcnow()
    job = Job(
        id=new_id("job"),
        lab_id=lab_id,
        demonstrator_id=submission.demonstrator_id,
        task_ids=[t.id for t in tasks],
        config=config.to_dict(),
        status=JobStatus.QUEUED.value,
        cancel_requested=False,
        attempts=0,
        max_attempts=settings.job_max_attempts,
        created_at=now,
        updated_at=now,
    )
    session.add(job)
    session.flush()
    session.add(
        JobEvent(
            job_id=job.id, at=now, kind="status", attempt=0, status=JobStatus.QUEUED, message="submitted"
        )
    )
    session.flush()
    return job


def _config(sent: Any, settings: Settings) -> FitConfig:
    """The engine's `FitConfig` of a submission's ``config``; `InvalidInput` naming all its problems: types and
    ranges (`valid_settings`) and, on the settings that pass them, the engine's checks and the hidden-unit
    limit."""
    model, issues = valid_settings(sent)
    config = gathering(issues, lambda: fit_config(model))
    if config is not None:
        issues += hidden_issues(config.hidden, settings)
    check(issues)
    assert config is not None  # else check raised
    return config


def _tasks(session: Session, lab_id: str, body: JobIn) -> tuple[list[Task], list[str]]:
    """The job's tasks in order, and the pointer under which each one's problems are reported."""
    demonstrator = session.get(Demonstrator, body.demonstrator_id)
    if demonstrator is None or demonstrator.lab_id != lab_id:
        check([Issue("/demonstrator_id", "no demonstrator with this id exists in your lab")])
    if body.task_ids is None:
        tasks = list(
            session.execute(
                select(Task)
                .where(Task.demonstrator_id == body.demonstrator_id)
                .order_by(Task.created_at, Task.id)
            ).scalars()
        )
        if not tasks:
            check(
                [Issue("/demonstrator_id", "has no tasks yet; create tasks and upload demonstrations first")]
            )
        return tasks, ["/demonstrator_id"] * len(tasks)
    if not body.task_ids:
        check(
            [
                Issue(
                    "/task_ids",
                    "must list at least one task (or be omitted for all the demonstrator's tasks)",
                )
            ]
        )
    issues: list[Issue] = []
    found = {t.id: t for t in session.execute(select(Task).where(Task.id.in_(body.task_ids))).scalars()}
    seen: set[str] = set()
    for i, task_id in enumerate(body.task_ids):
        task = found.get(task_id)
        if task_id in seen:
            issues.append(Issue(f"/task_ids/{i}", f"{task_id} is listed twice"))
        elif task is None or task.lab_id != lab_id:
            issues.append(Issue(f"/task_ids/{i}", f"no task {task_id} exists in your lab"))
        elif task.demonstrator_id != body.demonstrator_id:
            issues.append(Issue(f"/task_ids/{i}", f"task {task_id} belongs to another demonstrator"))
        seen.add(task_id)
    check(issues)
    return [found[t] for t in body.task_ids], [f"/task_ids/{i}" for i in range(len(body.task_ids))]


def _check_tasks(session: Session, tasks: Sequence[Task], pointers: Sequence[str], settings: Settings) -> Mdp:
    """Every task has demonstrations; all share one state space (states, actions, features) with the first;
    every MDP is within the size limits (they may have been lowered since it was uploaded). Returns the first
    task's MDP."""
    counts = dict(
        session.execute(
            select(Demonstration.task_id, func.count())
            .where(Demonstration.task_id.in_([t.id for t in tasks]))
            .group_by(Demonstration.task_id)
        ).all()
    )
    mdps = {
        m.id: m for m in session.execute(select(Mdp).where(Mdp.id.in_({t.mdp_id for t in tasks}))).scalars()
    }
    first = mdps[tasks[0].mdp_id]
    first_features = _features_sha(session, first)
    issues: list[Issue] = []
    for task, pointer in zip(tasks, pointers, strict=True):
        mdp = mdps[task.mdp_id]
        issues += mdp_size_issues(
            mdp.n_states,
            mdp.n_actions,
            mdp.n_features,
            settings,
            pointer=pointer,
            what=f"MDP {mdp.id} of task {task.id}",
        )
        if not counts.get(task.id):
            issues.append(
                Issue(
                    pointer,
                    f"task {task.id} has no demonstrations; upload some to /v1/tasks/{task.id}/demonstrations",
                )
            )
        if mdp.id == first.id:
            continue
        shape = (mdp.n_states, mdp.n_actions, mdp.n_features)
        if shape != (first.n_states, first.n_actions, first.n_features):
            issues.append(
                Issue(
                    pointer,
                    f"task {task.id} is played in MDP {mdp.id} with {_describe(mdp)}, but task {tasks[0].id} in "
                    f"MDP {first.id} with {_describe(first)}; all tasks of a job must share one state space",
                )
            )
        elif _features_sha(session, mdp) != first_features:
            issues.append(
                Issue(
                    pointer,
                    f"task {task.id} is played in MDP {mdp.id} whose state features differ from those of MDP "
                    f"{first.id} (task {tasks[0].id}); all tasks of a job must share one state space",
                )
            )
    check(issues)
    return first


def _features_sha(session: Session, mdp: Mdp) -> str | None:
    """The SHA-256 of an MDP's feature matrix (None for tabular one-hot features)."""
    blob_id = mdp.array_blobs.get("features")
    return None if blob_id is None else blob_sha256(session, blob_id)


def _describe(mdp: Mdp) -> str:
    """``N states, A actions and F features`` of an MDP row."""
    features = "one-hot features" if mdp.n_features is None else f"{mdp.n_features} features"
    return f"{mdp.n_states} states, {mdp.n_actions} actions and {features}"
