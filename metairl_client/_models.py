"""What the client returns beyond plain JSON: a job's state, a job's reward ids, a page of a list."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Protocol

import numpy as np

TERMINAL_STATUSES = frozenset({"succeeded", "failed", "cancelled"})
"""Job statuses after which a job never changes again."""


class TrajectoryLike(Protocol):
    """A trajectory: integer arrays of visited states and the actions taken (one fewer, or as many)."""

    @property
    def states(self) -> np.ndarray: ...

    @property
    def actions(self) -> np.ndarray: ...


Trajectory = TrajectoryLike | tuple[Sequence[int] | np.ndarray, Sequence[int] | np.ndarray]
"""A trajectory object, or a (states, actions) pair of integer sequences or arrays."""


@dataclass(frozen=True)
class JobState:
    """A job's status, its progress step (None before the first) and losses, its error when it failed and,
    once it succeeded, how far its task rewards were shrunk toward the baseline; what it fits (demonstrator,
    tasks, the complete config) and the whole resource as ``body``."""

    id: str
    status: str
    step: int | None
    max_steps: int | None
    error: str | None
    started_at: datetime | None = None
    finished_at: datetime | None = None
    attempt: int = 0
    """The attempt the status and step belong to (0 before the first)."""
    updated_at: datetime | None = None
    """When the status last changed."""
    shrinkage: float | None = None
    """Once succeeded: the λ of each task reward = baseline + λ·S_q(learned task reward − baseline), chosen by
    held-out likelihood (1: deviations at full size, 0.5: half-way to the baseline); None before, and with
    the tabular methods (``maxent``, ``shared_maxent``)."""
    sparsity: float | None = None
    """Once succeeded: the q of S_q, the share of each task's deviations from the baseline set to zero (0: every
    deviation kept); None as ``shrinkage`` is."""
    created_at: datetime | None = None
    demonstrator_id: str | None = None
    task_ids: tuple[str, ...] = ()
    """The tasks the job fits."""
    config: dict[str, Any] = field(default_factory=dict, hash=False)
    """The complete config the job runs with (every default filled in)."""
    loss: float | None = None
    """The latest progress point's total loss (None before the first step); ``irl_loss`` and ``sharing_loss``
    its two parts, ``heldout_nll`` the held-out negative log-likelihood, ``elapsed_s`` the time spent."""
    irl_loss: float | None = None
    sharing_loss: float | None = None
    heldout_nll: float | None = None
    elapsed_s: float | None = None
    max_attempts: int | None = None
    """How many runs the job may take (a worker that dies mid-run starts another)."""
    cancel_requested: bool = False
    best_step: int | None = None
    """Once succeeded: the step whose parameters were kept."""
    body: dict[str, Any] = field(default_factory=dict, repr=False, compare=False, hash=False)
    """The job resource this state was read from (fields the client does not name, too)."""

    @property
    def finished(self) -> bool:
        """True once the job succeeded, failed or was cancelled."""
        return self.status in TERMINAL_STATUSES

    def already_shows(self, kind: str | None, event: dict[str, Any]) -> bool:
        """Whether this snapshot already reflects a job event (``kind`` and its JSON data): an earlier
        attempt's, a status change before `updated_at`, or a progress step of this attempt at or before
        `step`. A stream opened on a running job replays such history first."""
        attempt = int(event.get("attempt", 0))
        if attempt != self.attempt:
            return attempt < self.attempt
        if kind == "status":
            at = when(event.get("at"))
            return at is not None and self.updated_at is not None and at <= self.updated_at
        step = event.get("step")
        return kind == "progress" and step is not None and self.step is not None and step <= self.step

    @classmethod
    def from_json(cls, body: dict[str, Any]) -> JobState:
        """The state of a job resource (progress is null until the worker reports a step)."""
        progress = body.get("progress") or {}
        max_attempts = body.get("max_attempts")
        return cls(
            id=str(body["id"]),
            status=str(body["status"]),
            step=progress.get("step"),
            max_steps=progress.get("max_steps"),
            error=body.get("error"),
            started_at=when(body.get("started_at")),
            finished_at=when(body.get("finished_at")),
            attempt=int(body.get("attempts") or 0),
            updated_at=when(body.get("updated_at")),
            shrinkage=body.get("shrinkage"),
            sparsity=body.get("sparsity"),
            created_at=when(body.get("created_at")),
            demonstrator_id=body.get("demonstrator_id"),
            task_ids=tuple(str(t) for t in body.get("task_ids") or ()),
            config=dict(body.get("config") or {}),
            max_attempts=None if max_attempts is None else int(max_attempts),
            cancel_requested=bool(body.get("cancel_requested")),
            best_step=body.get("best_step"),
            body=dict(body),
            loss=progress.get("loss"),
            irl_loss=progress.get("irl_loss"),
            sharing_loss=progress.get("sharing_loss"),
            heldout_nll=progress.get("heldout_nll"),
            elapsed_s=progress.get("elapsed_s"),
        )


@dataclass(frozen=True)
class JobRewardIds:
    """`GET /v1/jobs/{id}/rewards`: the baseline's reward id and each task's, keyed by task id."""

    baseline: str
    tasks: dict[str, str]
    task_names: dict[str, str] = field(default_factory=dict)
    """Each task's name, keyed by task id."""
    body: dict[str, Any] = field(default_factory=dict, repr=False)
    """The whole answer (summaries and links of each reward, too)."""
    truth_pearson: dict[str, float] = field(default_factory=dict)
    """Pearson correlation of each task's learned reward with its true reward (`Client.put_true_reward`), keyed
    by task id: only the tasks that have one."""
    n_states: int | None = None
    """The length of every reward of the job (one value per state)."""

    @classmethod
    def from_json(cls, body: dict[str, Any]) -> JobRewardIds:
        """Read the answer of `GET /v1/jobs/{id}/rewards`."""
        n_states = body["baseline"].get("n_states")
        return cls(
            baseline=str(body["baseline"]["reward_id"]),
            tasks={str(t["task_id"]): str(t["reward_id"]) for t in body["tasks"]},
            task_names={str(t["task_id"]): str(t["task_name"]) for t in body["tasks"] if t.get("task_name")},
            body=body,
            truth_pearson={
                str(t["task_id"]): float(t["truth_pearson"])
                for t in body["tasks"]
                if t.get("truth_pearson") is not None
            },
            n_states=None if n_states is None else int(n_states),
        )


@dataclass(frozen=True)
class Page:
    """One page of a list: its items (``data``), whether more follow, and the cursor of the next page."""

    data: list[dict[str, Any]]
    has_more: bool
    next_cursor: str | None

    @classmethod
    def from_json(cls, body: dict[str, Any]) -> Page:
        """Read ``{"data", "has_more", "next_cursor"}``."""
        return cls(
            data=[dict(item) for item in body["data"]],
            has_more=bool(body.get("has_more")),
            next_cursor=body.get("next_cursor"),
        )


def progress_bar(state: JobState, *, width: int = 30) -> str:
    """One line for a log: ``job_… running [#######-------]  120/500`` (no bar before the first step)."""
    if state.step is None or not state.max_steps:
        return f"{state.id} {state.status}"
    done = min(1.0, state.step / state.max_steps)
    bar = "#" * round(done * width) + "-" * (width - round(done * width))
    return f"{state.id} {state.status} [{bar}] {state.step:>5}/{state.max_steps}"


def when(text: str | None) -> datetime | None:
    """An ISO 8601 timestamp of the API, or None."""
    return datetime.fromisoformat(text) if text else None
