"""Deleting a demonstrator, task, demonstration batch, MDP or job with everything derived from it (docs/api.md,
"Deleting").

Each function takes a session, deletes rows, the blobs no remaining row refers to, the remembered
`Idempotency-Key` requests that created them and the webhook deliveries of their jobs, flushes, and never
commits (the route does, with `commit_deletion`, which also checkpoints SQLite's WAL). A deletion that would pull the rug from under a queued or running job, or
leave a task or recording without its MDP, raises `Conflict` before anything is deleted.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable

from sqlalchemy import Engine, delete, select
from sqlalchemy.orm import Session

from service.problems import Conflict
from service.store.models.blobs import Blob
from service.store.models.demonstrators import Demonstration, Demonstrator, Task, TrueReward
from service.store.models.idempotency import IdempotentRequest
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, JobEvent, Reward, StepHistory
from service.store.models.mdps import Mdp
from service.store.models.recordings import Recording
from service.store.models.webhooks import WebhookDelivery

ACTIVE = (JobStatus.QUEUED.value, JobStatus.RUNNING.value)
"""Statuses of a job whose inputs must not be deleted (and that cannot be deleted itself)."""

BLOB_COLUMNS = (
    Demonstration.states_blob_id,
    Demonstration.actions_blob_id,
    Demonstration.lengths_blob_id,
    TrueReward.blob_id,
    Recording.samples_blob_id,
    Recording.instructions_blob_id,
    Reward.reward_blob_id,
    Reward.value_blob_id,
    Reward.policy_blob_id,
    Reward.uncertainty_blob_id,
    Reward.evidence_blob_id,
)
"""Every column that refers to a blob (MDPs refer to theirs through the JSON `array_blobs`)."""


def commit_deletion(session: Session) -> None:
    """Commit a deletion; on SQLite also checkpoint the WAL so the deleted rows no longer linger in it."""
    session.commit()
    bind = session.get_bind()
    engine = bind if isinstance(bind, Engine) else bind.engine
    if engine.dialect.name == "sqlite":
        with engine.connect() as connection:
            connection.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)")


def forget_requests(session: Session, resource_ids: Collection[str]) -> None:
    """Delete the remembered POSTs that created `resource_ids`, so replaying one cannot answer a deleted id."""
    if resource_ids:
        session.execute(delete(IdempotentRequest).where(IdempotentRequest.resource_id.in_(resource_ids)))


def delete_job(session: Session, job: Job) -> None:
    """Delete a finished job with its events, step history, rewards and their arrays; 409 while it is queued
    or running."""
    _refuse_active([job], what=f"job {job.id}")
    _delete_jobs(session, [job.id])


def discard_unsent_job(session: Session, job_id: str) -> None:
    """Delete a job just created whose message the broker refused (no worker can have it) and its events."""
    session.execute(delete(JobEvent).where(JobEvent.job_id == job_id))
    session.execute(delete(Job).where(Job.id == job_id, Job.status == JobStatus.QUEUED))


def delete_task(session: Session, task: Task) -> None:
    """Delete a task with its demonstrations, true reward and every job that fitted it (their rewards and
    events too); 409 while such a job is queued or running."""
    jobs = _jobs_fitting(session, task)
    _refuse_active(jobs, what=f"task {task.id}")
    _delete_jobs(session, [job.id for job in jobs])
    _delete_tasks(session, [task.id])


def delete_demonstration(session: Session, batch: Demonstration) -> None:
    """Delete one demonstration batch with its arrays, and the jobs of its task that finished after it was
    uploaded (their rewards and events too): a job refers to its tasks, not to a copy of their batches, and
    reads them when it runs, so those jobs' results came from this batch. Jobs that finished before stay. A
    recording that stored the batch keeps its samples; its summary's ``demonstration_id`` becomes null.
    409 while a job fitting the task is queued or running (as for the task itself)."""
    task = session.get_one(Task, batch.task_id)
    jobs = _jobs_fitting(session, task)
    _refuse_active(jobs, what=f"demonstration batch {batch.id}")
    _delete_jobs(
        session, [job.id for job in jobs if job.finished_at is None or job.finished_at >= batch.created_at]
    )
    _unlink_recordings(session, task, batch.id)
    blobs = [batch.states_blob_id, batch.actions_blob_id, batch.lengths_blob_id]
    session.execute(delete(Demonstration).where(Demonstration.id == batch.id))
    forget_requests(session, [batch.id])
    session.flush()
    _delete_unreferenced_blobs(session, blobs, lab_id=batch.lab_id)


def delete_demonstrator(session: Session, demonstrator: Demonstrator) -> None:
    """Delete a demonstrator with its tasks, demonstrations, true rewards, recordings and jobs (their
    rewards and events too); 409 while one of its jobs is queued or running."""
    jobs = _jobs_of(session, demonstrator.id)
    _refuse_active(jobs, what=f"demonstrator {demonstrator.id}")
    _delete_jobs(session, [job.id for job in jobs])
    recordings = list(
        session.execute(
            select(Recording.id, Recording.samples_blob_id, Recording.instructions_blob_id).where(
                Recording.demonstrator_id == demonstrator.id
            )
        )
    )
    if recordings:
        session.execute(delete(Recording).where(Recording.id.in_([r.id for r in recordings])))
    task_ids = list(session.execute(select(Task.id).where(Task.demonstrator_id == demonstrator.id)).scalars())
    _delete_tasks(session, task_ids, also_blobs=[b for r in recordings for b in (r[1], r[2])])
    session.execute(delete(Demonstrator).where(Demonstrator.id == demonstrator.id))
    forget_requests(session, [demonstrator.id, *(r.id for r in recordings)])
    session.flush()


def delete_mdp(session: Session, mdp: Mdp) -> None:
    """Delete an MDP and its arrays; 409 while a task or recording still uses it."""
    users = _mdp_users(session, mdp.id, limit=6)
    if users:
        shown = "; ".join(users[:5]) + ("; …" if len(users) > 5 else "")
        raise Conflict(
            f"MDP {mdp.id} is still used by {shown}. Delete those tasks or recordings (or their "
            "demonstrator) first."
        )
    blobs = list(mdp.array_blobs.values())
    session.execute(delete(Mdp).where(Mdp.id == mdp.id))
    forget_requests(session, [mdp.id])
    session.flush()
    _delete_unreferenced_blobs(session, blobs, lab_id=mdp.lab_id)


def _mdp_users(session: Session, mdp_id: str, *, limit: int) -> list[str]:
    """Up to ``limit`` tasks, then recordings, on the MDP, each as a lab reads it: its kind, name and id, and
    its demonstrator's name (ids alone say nothing on a dashboard)."""
    users: list[str] = []
    for kind, model in (("task", Task), ("recording", Recording)):
        rows = session.execute(
            select(model.id, model.name, Demonstrator.name)
            .join(Demonstrator, Demonstrator.id == model.demonstrator_id)
            .where(model.mdp_id == mdp_id)
            .order_by(model.created_at, model.id)
            .limit(limit - len(users))
        ).all()
        users += [
            f"{kind} {repr(name) + ' ' if name else ''}({row_id}) of demonstrator {demonstrator!r}"
            for row_id, name, demonstrator in rows
        ]
    return users


def _jobs_of(session: Session, demonstrator_id: str) -> list[Job]:
    """All jobs of a demonstrator."""
    return list(session.execute(select(Job).where(Job.demonstrator_id == demonstrator_id)).scalars())


def _jobs_fitting(session: Session, task: Task) -> list[Job]:
    """The jobs whose tasks include `task` (whatever their status)."""
    return [job for job in _jobs_of(session, task.demonstrator_id) if task.id in job.task_ids]


def _unlink_recordings(session: Session, task: Task, batch_id: str) -> None:
    """Set ``demonstration_id`` to null where a recording's summary names the batch `batch_id` of `task` (a
    recording stores its segments in its demonstrator's tasks on its own MDP), so none names a deleted batch."""
    recordings = session.execute(
        select(Recording).where(
            Recording.demonstrator_id == task.demonstrator_id, Recording.mdp_id == task.mdp_id
        )
    ).scalars()
    for recording in recordings:
        entries = recording.summary.get("tasks", [])
        if any(entry.get("demonstration_id") == batch_id for entry in entries):
            unlinked = [
                entry | {"demonstration_id": None} if entry.get("demonstration_id") == batch_id else entry
                for entry in entries
            ]
            recording.summary = recording.summary | {"tasks": unlinked}


def _refuse_active(jobs: Iterable[Job], *, what: str) -> None:
    """409 naming the queued or running jobs among `jobs`."""
    active = [job for job in jobs if job.status in ACTIVE]
    if active:
        shown = ", ".join(f"{job.id} ({job.status})" for job in active[:5])
        raise Conflict(
            f"Cannot delete {what}: job {shown} is still queued or running; cancel it "
            "(POST /v1/jobs/{id}/cancel) and delete again once it has stopped."
        )


def _delete_jobs(session: Session, job_ids: Collection[str]) -> None:
    """Delete finished jobs with their events, step histories, rewards and reward arrays; 409 if one became
    active meanwhile."""
    if not job_ids:
        return
    blobs = [
        b
        for row in session.execute(
            select(
                Reward.reward_blob_id,
                Reward.value_blob_id,
                Reward.policy_blob_id,
                Reward.uncertainty_blob_id,
                Reward.evidence_blob_id,
            ).where(Reward.job_id.in_(job_ids))
        )
        for b in row
    ]
    session.execute(delete(Reward).where(Reward.job_id.in_(job_ids)))
    session.execute(delete(JobEvent).where(JobEvent.job_id.in_(job_ids)))
    session.execute(delete(StepHistory).where(StepHistory.job_id.in_(job_ids)))
    session.execute(delete(WebhookDelivery).where(WebhookDelivery.job_id.in_(job_ids)))
    forget_requests(session, job_ids)
    # Conditional: a job re-queued by the reaper since we looked is not deleted (and the whole request fails).
    deleted = session.execute(
        delete(Job)
        .where(Job.id.in_(job_ids), Job.status.not_in(ACTIVE))
        .execution_options(synchronize_session=False)
    ).rowcount  # type: ignore[attr-defined]
    if deleted != len(job_ids):
        raise Conflict("A job became queued or running while it was being deleted; try again.")
    lab_id = session.execute(select(Blob.lab_id).where(Blob.id.in_(blobs)).limit(1)).scalar()
    session.flush()
    if lab_id is not None:
        _delete_unreferenced_blobs(session, blobs, lab_id=lab_id)


def _delete_tasks(
    session: Session, task_ids: Collection[str], *, also_blobs: Iterable[str | None] = ()
) -> None:
    """Delete tasks with their demonstrations and true rewards (their jobs must be gone already)."""
    blobs: list[str | None] = list(also_blobs)
    if task_ids:
        for row in session.execute(
            select(
                Demonstration.states_blob_id, Demonstration.actions_blob_id, Demonstration.lengths_blob_id
            ).where(Demonstration.task_id.in_(task_ids))
        ):
            blobs += list(row)
        blobs += list(
            session.execute(select(TrueReward.blob_id).where(TrueReward.task_id.in_(task_ids))).scalars()
        )
        session.execute(delete(Reward).where(Reward.task_id.in_(task_ids)))
        demonstration_ids = session.execute(
            select(Demonstration.id).where(Demonstration.task_id.in_(task_ids))
        ).scalars()
        forget_requests(session, [*task_ids, *demonstration_ids])
        session.execute(delete(Demonstration).where(Demonstration.task_id.in_(task_ids)))
        session.execute(delete(TrueReward).where(TrueReward.task_id.in_(task_ids)))
        session.execute(delete(Task).where(Task.id.in_(task_ids)))
    session.flush()
    candidates = [b for b in blobs if b is not None]
    if candidates:
        lab_id = session.execute(select(Blob.lab_id).where(Blob.id.in_(candidates)).limit(1)).scalar_one()
        _delete_unreferenced_blobs(session, candidates, lab_id=lab_id)


def _delete_unreferenced_blobs(session: Session, blob_ids: Iterable[str | None], *, lab_id: str) -> None:
    """Delete those of `blob_ids` that no remaining row refers to (a blob may be shared; never pickled)."""
    candidates = {b for b in blob_ids if b is not None}
    if not candidates:
        return
    referenced: set[str] = set()
    for column in BLOB_COLUMNS:
        referenced |= {
            b for b in session.execute(select(column).where(column.in_(candidates))).scalars() if b
        }
    for array_blobs in session.execute(select(Mdp.array_blobs).where(Mdp.lab_id == lab_id)).scalars():
        referenced |= set(array_blobs.values()) & candidates
    orphans = candidates - referenced
    if orphans:
        session.execute(delete(Blob).where(Blob.id.in_(orphans)))
    session.flush()
