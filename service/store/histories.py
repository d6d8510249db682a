"""A succeeded job's loss curve, every step of its fit: written with its results, read by the history route.

The steps are stored columnar (`StepHistory`): one float64 matrix, a row per series, so 100,000 steps take
4.8 MB and read back as a handful of numpy slices rather than 100,000 rows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from metairl_engine.results import Progress
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, StepHistory

HISTORY_FIELDS: tuple[str, ...] = ("step", "loss", "irl_loss", "sharing_loss", "heldout_nll", "elapsed_s")
"""The series kept per step, in stored order (a `Progress` without ``max_steps``, which is one number)."""

STORED = np.dtype("<f8")
"""float64: the engine's losses exactly as it reported them (steps are exact integers in it too)."""


@dataclass(frozen=True)
class StepColumns:
    """A stored history read back: the attempt that ran it, its step budget and one array per series."""

    attempt: int
    max_steps: int
    columns: dict[str, np.ndarray]
    """Each name of `HISTORY_FIELDS` → float64 (n_steps,); ``heldout_nll`` is NaN where a step had none."""


def add_step_history(session: Session, job_id: str, attempt: int, history: Sequence[Progress]) -> StepHistory:
    """Add every step of a finished fit's ``history`` for ``job_id`` (the caller commits it with the results)."""
    matrix = np.array(
        [[np.nan if (v := getattr(p, name)) is None else v for p in history] for name in HISTORY_FIELDS],
        dtype=STORED,
    ).reshape(len(HISTORY_FIELDS), len(history))
    row = StepHistory(
        job_id=job_id,
        attempt=attempt,
        max_steps=history[-1].max_steps if history else 0,
        n_steps=len(history),
        fields=list(HISTORY_FIELDS),
        data=matrix.tobytes(),
    )
    session.add(row)
    return row


def step_history(session: Session, job: Job) -> StepColumns | None:
    """Every step of ``job``'s fit if it succeeded with its history stored (None: running, failed, cancelled,
    or a job that finished before histories were kept)."""
    if job.status != JobStatus.SUCCEEDED.value:
        return None
    row = session.execute(
        select(StepHistory).where(StepHistory.job_id == job.id, StepHistory.attempt == job.attempts)
    ).scalar_one_or_none()
    if row is None:
        return None
    matrix = np.frombuffer(row.data, dtype=STORED).reshape(len(row.fields), row.n_steps)
    return StepColumns(
        attempt=row.attempt,
        max_steps=row.max_steps,
        columns={name: matrix[i] for i, name in enumerate(row.fields)},
    )
