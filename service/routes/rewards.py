"""Learned rewards (API.md §6, minimal): a succeeded job's reward ids, and one reward as JSON or ``.npy``.

``?quantity=value|policy`` gives a task's value function (S,) or policy (S, A) the same way.
"""

from __future__ import annotations

import io
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Query, Response
from pydantic import BaseModel, ConfigDict, Field
from sqlalchemy import select

from service.auth import LabDep
from service.blobs import get_array
from service.deps import SessionDep
from service.jobstatus import JobStatus
from service.models.jobs import Reward
from service.problems import Conflict, NotFound
from service.routes.jobs import JobDep

router = APIRouter(tags=["rewards"])

Quantity = Literal["reward", "value", "policy"]
Format = Literal["json", "npy"]


class RewardRef(BaseModel):
    """One learned reward of a job: its id (contract) and how it scores against a true reward, if given."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe",
                    "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                    "n_states": 100,
                    "truth_pearson": 0.93,
                }
            ]
        }
    )

    reward_id: str
    task_id: str | None = None
    n_states: int
    truth_pearson: float | None = Field(
        default=None, description="Pearson correlation with the task's true reward, when one was given."
    )


class JobRewards(BaseModel):
    """The baseline reward and each task's reward of a succeeded job (contract shape)."""

    job_id: str
    baseline: RewardRef
    tasks: list[RewardRef]


class RewardValues(BaseModel):
    """A reward (or a task's value function or policy) as JSON; `values` is (S,) or, for a policy, (S, A)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe",
                    "n_states": 3,
                    "quantity": "reward",
                    "values": [0.1, -0.2, 1.3],
                }
            ]
        }
    )

    reward_id: str
    n_states: int
    quantity: Quantity
    values: list[float] | list[list[float]]


@router.get(
    "/jobs/{job_id}/rewards",
    summary="A job's learned rewards",
    responses={
        404: {"description": "No such job in your lab."},
        409: {"description": "The job has not succeeded."},
    },
)
def job_rewards(job: JobDep, session: SessionDep) -> JobRewards:
    """Reward ids of the baseline and of every task, in the job's task order."""
    if job.status != JobStatus.SUCCEEDED:
        raise Conflict(f"Job {job.id} is {job.status}; rewards exist once it has succeeded.")
    rows = (
        session.execute(select(Reward).where(Reward.job_id == job.id).order_by(Reward.ordinal))
        .scalars()
        .all()
    )
    refs = [
        RewardRef(reward_id=r.id, task_id=r.task_id, n_states=r.n_states, truth_pearson=r.truth_pearson)
        for r in rows
    ]
    return JobRewards(job_id=job.id, baseline=refs[0], tasks=refs[1:])


@router.get(
    "/rewards/{reward_id}",
    summary="Download a reward, value function or policy",
    response_model=RewardValues,
    responses={
        200: {"content": {"application/octet-stream": {}}, "description": "JSON, or a float32 `.npy` file."},
        404: {"description": "No such reward in your lab."},
        409: {"description": "The baseline has no value function or policy."},
    },
)
def download_reward(
    reward_id: str,
    session: SessionDep,
    lab: LabDep,
    format: Annotated[Format, Query(description="`json` or `npy` (float32).")] = "json",
    quantity: Annotated[Quantity, Query(description="`reward`, or a task's `value` or `policy`.")] = "reward",
) -> Response | RewardValues:
    """The values of one learned reward; ``?quantity=value|policy`` for a task's value function or policy."""
    row = session.get(Reward, reward_id)
    if row is None or row.lab_id != lab.id:
        raise NotFound(f"No reward {reward_id} in your lab.")
    blob_id = {"reward": row.reward_blob_id, "value": row.value_blob_id, "policy": row.policy_blob_id}[
        quantity
    ]
    if blob_id is None:
        raise Conflict(
            f"Reward {reward_id} is the baseline, which has no {quantity}; ask a task's reward for its value or policy."
        )
    array = get_array(session, blob_id).astype(np.float32)
    if format == "npy":
        buffer = io.BytesIO()
        np.save(buffer, array)
        return Response(
            buffer.getvalue(),
            media_type="application/octet-stream",
            headers={"Content-Disposition": f'attachment; filename="{reward_id}_{quantity}.npy"'},
        )
    return RewardValues(reward_id=row.id, n_states=row.n_states, quantity=quantity, values=array.tolist())
