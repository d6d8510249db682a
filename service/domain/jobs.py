"""Bodies of `/v1/jobs` (docs/api.md, "Jobs"): the submission, the job with its progress, and its event log."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, computed_field
from pydantic_core import to_json
from sqlalchemy import Row

from service.domain.common import FIRST_BAD_ITEM, AsSent, Body, Resource
from service.domain.job_config import ConfigAsSent, ignored_settings
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, JobEvent

EXAMPLE_CONFIG: dict[str, Any] = {
    "method": "meta_irl",
    "sharing": "huber",
    "sharing_weight": 1.0,
    "backup": "max",
    "confidence": 1.0,
    "hidden": [100, 50, 25],
    "learning_rate": 0.01,
    "max_steps": 500,
    "seed": 0,
}
EXAMPLE_PROGRESS: dict[str, Any] = {
    "step": 120,
    "max_steps": 500,
    "loss": 1.204,
    "irl_loss": 1.187,
    "sharing_loss": 0.017,
    "heldout_nll": 1.231,
    "elapsed_s": 14.2,
}


class JobIn(Body):
    """Learn the rewards of a demonstrator's tasks (all of them unless `task_ids` picks some)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                    "task_ids": ["task_7cXw2mB9tQk4Lr0sHn5yZa", "task_2kLm8nB3vQx9Tr1sYh6uWe"],
                    "config": EXAMPLE_CONFIG,
                }
            ]
        }
    )

    demonstrator_id: str
    task_ids: Annotated[list[str], FIRST_BAD_ITEM] | None = Field(
        default=None,
        description="Tasks to fit together (same states and features, each with demonstrations); "
        "default: every task of the demonstrator.",
    )
    config: ConfigAsSent = Field(
        default=None,
        description="Fit settings; omitted settings take their defaults (each setting's schema gives its default, "
        "range and meaning). An unknown or invalid one is a 422 naming `/config/<field>`.",
    )


JobSubmission = Annotated[dict[str, Any], AsSent(JobIn, sent=dict[str, Any])]
"""The body of `POST /v1/jobs`: any JSON object, documented as `JobIn`; `service.jobs.submit` checks it with the
checks that need the lab's tasks, so every problem of a submission comes in one 422."""


class JobProgress(BaseModel):
    """The latest optimisation step the worker reported (written at least once a second while running)."""

    step: int
    max_steps: int
    loss: float | None = Field(
        description="The step's loss; null if it was not a finite number (a fit that diverged)."
    )
    irl_loss: float | None
    sharing_loss: float | None
    heldout_nll: float | None = Field(
        description="Held-out negative log-likelihood, when a hold-out is used."
    )
    elapsed_s: float


class JobOut(Resource):
    """A job: its inputs, the complete config used, lifecycle, progress and (when failed) why."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": "job_V3n8sK2qLx0bT7mY4cW9rA",
                    "created_at": "2026-01-05T10:05:00Z",
                    "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                    "task_ids": ["task_7cXw2mB9tQk4Lr0sHn5yZa", "task_2kLm8nB3vQx9Tr1sYh6uWe"],
                    "status": "running",
                    "config": EXAMPLE_CONFIG,
                    "progress": EXAMPLE_PROGRESS,
                    "error": None,
                    "attempts": 1,
                    "max_attempts": 3,
                    "cancel_requested": False,
                    "best_step": None,
                    "shrinkage": None,
                    "sparsity": None,
                    "updated_at": "2026-01-05T10:05:15Z",
                    "started_at": "2026-01-05T10:05:01Z",
                    "finished_at": None,
                }
            ]
        }
    )

    demonstrator_id: str
    task_ids: list[str]
    status: JobStatus = Field(description="queued, running, succeeded, failed or cancelled (contract).")
    config: dict[str, Any] = Field(
        description="Every fit setting used, defaults filled in; once succeeded, as fitted (a `task_features` "
        "`auto` shows the choice the fit made, an `ensemble` 0 the members fitted)."
    )
    progress: JobProgress | None = Field(description="Null until the first step is reported.")
    error: str | None = Field(description="When failed: what went wrong and what to change.")
    attempts: int = Field(description="Runs started; more than 1 after a worker died and the job was re-run.")
    max_attempts: int
    cancel_requested: bool
    best_step: int | None = Field(description="The step whose parameters were kept (when succeeded).")
    shrinkage: float | None = Field(
        description="How far the task rewards were pulled toward the baseline: each task reward returned is "
        "baseline + λ·S_q(learned task reward − baseline), λ ∈ {0, 0.25, 0.5, 0.75, 1} and q (`sparsity`) chosen "
        "by held-out likelihood (`config.shrink_deviations`). 1: the deviations kept at full size (with "
        "`sparsity` 0, the task rewards as learned; also where no choice is made: `shrink_deviations` false, "
        "`sharing` none, no hold-out, or over 2^17 task-states); 0.5: half-way to the baseline; 0: every task "
        "gets the baseline. Null until the job succeeds, with the tabular methods (`maxent`, `shared_maxent`), and "
        "for jobs that succeeded before λ was kept.",
    )
    sparsity: float | None = Field(
        description="The share q ∈ {0, 0.5, 0.9, 0.95, 0.99, 0.995} of each task's states whose deviation "
        "from the baseline S_q set to zero (a soft threshold at that quantile of the deviation's size: what "
        "a task adds to the shared reward, a goal or an obstacle, is mostly local). 0: every deviation kept; "
        "1 with λ 0. Null as `shrinkage` is, and for jobs that succeeded before q was kept.",
    )
    updated_at: datetime
    started_at: datetime | None
    finished_at: datetime | None

    @computed_field(  # type: ignore[prop-decorator]
        description="Settings changed from their default that another setting makes the fit ignore (`bgi_k` "
        "without backup bgi, the sharing settings without sharing, the networks' settings with the tabular "
        "methods), one sentence each; empty when none."
    )
    @property
    def ignored_settings(self) -> list[str]:
        """`job_config.ignored_settings` of this job's config."""
        return ignored_settings(self.config)

    @classmethod
    def of(cls, job: Job | Row[Any]) -> JobOut:
        """The API view of a job row (an ORM object, or a Core row with the jobs table's columns)."""
        progress = None
        if job.step is not None:  # the worker writes all progress columns together
            progress = JobProgress.model_validate({k: getattr(job, k) for k in JobProgress.model_fields})
        return cls.model_validate(
            {**{k: getattr(job, k) for k in cls.model_fields if k != "progress"}, "progress": progress}
        )


class JobEventOut(BaseModel):
    """One line of a job's log: a status change (with a message) or a progress sample."""

    model_config = ConfigDict(
        from_attributes=True,
        json_schema_extra={
            "examples": [
                {"id": 7, "at": "2026-01-05T10:05:06Z", "kind": "progress", "attempt": 1, **EXAMPLE_PROGRESS},
                {
                    "id": 9,
                    "at": "2026-01-05T10:06:02Z",
                    "kind": "status",
                    "attempt": 1,
                    "status": "succeeded",
                    "message": "finished after 380 steps (kept step 280)",
                },
            ]
        },
    )

    id: int
    at: datetime
    kind: str = Field(description="`status` or `progress`.")
    attempt: int
    status: JobStatus | None = None
    message: str | None = None
    step: int | None = None
    max_steps: int | None = None
    loss: float | None = None
    irl_loss: float | None = None
    sharing_loss: float | None = None
    heldout_nll: float | None = None
    elapsed_s: float | None = None

    @classmethod
    def of(cls, event: JobEvent) -> JobEventOut:
        """The API view of an event row."""
        return cls.model_validate(event)


class HistoryPoint(BaseModel):
    """One point of a job's loss curve: a step of its fit (or, while it runs, a progress sample)."""

    model_config = ConfigDict(from_attributes=True)

    step: int
    loss: float | None = Field(description="Null where the loss was not a finite number.")
    irl_loss: float | None
    sharing_loss: float | None
    heldout_nll: float | None = None
    elapsed_s: float


HistorySource = Literal["steps", "samples"]
"""``steps``: every step of the succeeded fit, stored with its results; ``samples``: the progress samples
of the latest attempt (a running, failed or cancelled job, or one that succeeded before steps were kept)."""


class JobHistory(BaseModel):
    """A job's loss curve: every step once it has succeeded, else the progress samples of its latest attempt
    (two a second while it runs); `source` says which."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "job_id": "job_V3n8sK2qLx0bT7mY4cW9rA",
                    "attempt": 1,
                    "max_steps": 500,
                    "best_step": None,
                    "source": "samples",
                    "points": [
                        {
                            k: EXAMPLE_PROGRESS[k]
                            for k in ("step", "loss", "irl_loss", "sharing_loss", "heldout_nll")
                        }
                        | {"step": 4, "elapsed_s": 0.5},
                        {k: v for k, v in EXAMPLE_PROGRESS.items() if k != "max_steps"},
                    ],
                }
            ]
        }
    )

    job_id: str
    attempt: int = Field(description="The attempt the points are of (a re-run starts a new curve).")
    max_steps: int | None = Field(description="The step budget; null before the first sample.")
    best_step: int | None = Field(description="The step whose parameters were kept (when succeeded).")
    source: HistorySource = Field(
        default="samples",
        description="`steps`: `points` holds every step of the succeeded fit, one point each, as the engine "
        "computed it; `samples`: the progress samples of the latest attempt (a job that is queued, running, "
        "failed or cancelled, or that succeeded before every step was kept), thinned evenly to at most 2000.",
    )
    points: list[HistoryPoint] = Field(
        description="Oldest first, by step. Every step (up to `max_steps`, at most 100,000) when `source` is "
        "`steps`; samples thinned evenly to at most 2000 points, first and last kept, when it is `samples`."
    )

    @classmethod
    def of(cls, job: Job, samples: list[JobEvent]) -> JobHistory:
        """The history of ``job`` from its progress events."""
        return cls(
            job_id=job.id,
            attempt=job.attempts,
            max_steps=samples[-1].max_steps if samples else job.max_steps,
            best_step=job.best_step,
            source="samples",
            points=[HistoryPoint.model_validate(e) for e in samples],
        )

    @classmethod
    def steps_json(
        cls, job: Job, *, attempt: int, max_steps: int, columns: Mapping[str, np.ndarray]
    ) -> bytes:
        """This body, as JSON, from every stored step of ``job``: one float64 array per `HistoryPoint` field
        (NaN where a step had no held-out NLL). Encoded from plain lists, without a model per point: 100,000
        steps (17 MB) are answered in 0.4 s, where a model per point took over 4 s."""
        step, loss, irl, sharing, held, elapsed = (
            columns[name].tolist()
            for name in ("step", "loss", "irl_loss", "sharing_loss", "heldout_nll", "elapsed_s")
        )
        points = [
            {
                "step": int(s),
                "loss": lo,
                "irl_loss": i,
                "sharing_loss": sh,
                "heldout_nll": None if h != h else h,  # NaN: this step had no held-out NLL
                "elapsed_s": e,
            }
            for s, lo, i, sh, h, e in zip(step, loss, irl, sharing, held, elapsed, strict=True)
        ]
        body = {
            "job_id": job.id,
            "attempt": attempt,
            "max_steps": max_steps,
            "best_step": job.best_step,
            "source": "steps",
            "points": points,
        }
        return to_json(body)
