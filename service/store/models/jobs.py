"""Jobs (the source of truth of every fit), their progress log, and the rewards a job produced.

A job row carries its lifecycle (`status`, attempts, heartbeat, cancel flag) and its latest progress;
the worker only writes it while it owns the current attempt (see `service.jobs.transitions`). Results are
`Reward` rows, unique per (job, ordinal), so a retried job can never hold two result sets, and one
`StepHistory` row per job, the loss curve of every step, written in the same transaction.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    CheckConstraint,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin, UTCDateTime, utcnow
from service.store.models.job_status import JobStatus

STATUS_VALUES = ", ".join(f"'{s.value}'" for s in JobStatus)


class ProgressColumns:
    """The engine's progress sample (`metairl_engine.fit.Progress`): on the job row (latest) and on its events."""

    step: Mapped[int | None] = mapped_column(Integer)
    max_steps: Mapped[int | None] = mapped_column(Integer)
    loss: Mapped[float | None] = mapped_column(Float)
    irl_loss: Mapped[float | None] = mapped_column(Float)
    sharing_loss: Mapped[float | None] = mapped_column(Float)
    heldout_nll: Mapped[float | None] = mapped_column(Float)
    elapsed_s: Mapped[float | None] = mapped_column(Float)


PROGRESS_FIELDS: tuple[str, ...] = tuple(ProgressColumns.__annotations__)
"""The progress column names, in order (the worker writes them together; a new attempt clears them)."""


class Job(ProgressColumns, CreatedAtMixin, Base):
    """One fit of a demonstrator's tasks: inputs, config, lifecycle and latest progress."""

    __tablename__ = "jobs"
    __table_args__ = (
        CheckConstraint(f"status IN ({STATUS_VALUES})", name="status"),
        Index("ix_jobs_lab_created", "lab_id", "created_at", "id"),
        Index("ix_jobs_status_heartbeat", "status", "heartbeat_at"),
    )

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"))
    demonstrator_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("demonstrators.id", ondelete="CASCADE"), index=True
    )
    task_ids: Mapped[list[str]] = mapped_column(JSON)
    """The tasks fitted together, in the order of the results."""
    config: Mapped[dict[str, Any]] = mapped_column(JSON)
    """The complete `FitConfig` used (defaults filled in)."""
    status: Mapped[str] = mapped_column(String(16), default=JobStatus.QUEUED.value)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    """Runs started so far; the worker that started run N may write only while this is N (fencing)."""
    max_attempts: Mapped[int] = mapped_column(Integer)
    error: Mapped[str | None] = mapped_column(Text)

    best_step: Mapped[int | None] = mapped_column(Integer)
    shrinkage: Mapped[float | None] = mapped_column(Float)
    """The λ that pulled the task rewards toward the baseline (`FitResult.shrinkage`); null until succeeded,
    for maxent, and for jobs that succeeded before it was kept."""
    sparsity: Mapped[float | None] = mapped_column(Float)
    """The share q of each task's deviations from the baseline set to zero (`FitResult.sparsity`); null as
    ``shrinkage`` is, and for jobs that succeeded before it was kept."""

    updated_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    heartbeat_at: Mapped[datetime | None] = mapped_column(UTCDateTime())


class JobEvent(ProgressColumns, Base):
    """One line of a job's log: a status change or a (throttled) progress sample."""

    __tablename__ = "job_events"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    job_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("jobs.id", ondelete="CASCADE"), index=True
    )
    at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow)
    kind: Mapped[str] = mapped_column(String(16))
    """``status`` or ``progress``."""
    attempt: Mapped[int] = mapped_column(Integer)
    status: Mapped[str | None] = mapped_column(String(16))
    message: Mapped[str | None] = mapped_column(Text)


class Reward(CreatedAtMixin, Base):
    """One learned reward of a job: the baseline (ordinal 0) or task ``ordinal - 1``, with value and policy."""

    __tablename__ = "rewards"
    __table_args__ = (UniqueConstraint("job_id", "ordinal", name="uq_rewards_job_ordinal"),)

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    job_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("jobs.id", ondelete="CASCADE"))
    ordinal: Mapped[int] = mapped_column(Integer)
    kind: Mapped[str] = mapped_column(String(8))
    """``baseline`` or ``task``."""
    task_id: Mapped[str | None] = mapped_column(
        String(ID_LENGTH), ForeignKey("tasks.id", ondelete="CASCADE"), index=True
    )
    n_states: Mapped[int] = mapped_column(Integer)
    n_actions: Mapped[int] = mapped_column(Integer)
    reward_blob_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    value_blob_id: Mapped[str | None] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    policy_blob_id: Mapped[str | None] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    uncertainty_blob_id: Mapped[str | None] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    """The reward's spread across the ensemble's members per state (`FitResult.reward_spread`); None with
    one member, or for rows stored before it was kept."""
    evidence_blob_id: Mapped[str | None] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    """Per state, the demonstrations' evidence (`metairl_engine.evidence`); None for rows stored before it was kept."""
    summary: Mapped[dict[str, Any]] = mapped_column(JSON)
    """min, max, mean, std, argmax_state, argmin_state of the reward (`service.files.exports.summary`)."""


class StepHistory(Base):
    """Every step's progress of a succeeded fit (`FitResult.history`), stored with its rewards.

    Columnar and compact: ``data`` is one little-endian float64 matrix with a row per name of ``fields`` (in
    that order) and a column per step, so each series is one contiguous slice; a step without a held-out NLL
    holds NaN. 48 bytes a step: 48 kB for 1,000 steps, 4.8 MB at the 100,000-step limit of ``max_steps``.
    """

    __tablename__ = "job_step_histories"

    job_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True
    )
    attempt: Mapped[int] = mapped_column(Integer)
    """The attempt that ran these steps (the one that succeeded)."""
    max_steps: Mapped[int] = mapped_column(Integer)
    n_steps: Mapped[int] = mapped_column(Integer)
    fields: Mapped[list[str]] = mapped_column(JSON)
    """The series of ``data``, in row order (`service.store.histories.HISTORY_FIELDS` when written)."""
    data: Mapped[bytes] = mapped_column(LargeBinary)
