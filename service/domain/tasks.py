"""Bodies of tasks and their true rewards (docs/api.md, "Demonstrators and tasks")."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic.json_schema import JsonDict

from service.domain.common import FIRST_BAD_ITEM, Body, Metadata, MetadataIn, Name, Number, Resource
from service.store.models.demonstrators import Task, TrueReward

TrueRewardFormat = Literal["json", "npy", "csv"]
"""How `GET /v1/tasks/{task_id}/true-reward` answers, as a learned reward's download does (no png)."""

EXAMPLE_IN: JsonDict = {
    "name": "reach forward",
    "mdp_id": "mdp_3q0f9b2yJm6nD1Kx8cT4wA",
    "metadata": {"instruction": "forward"},
}


@dataclass(frozen=True)
class TaskTotals:
    """What a task's demonstrations add up to, and whether it has a true reward."""

    n_trajectories: int = 0
    n_steps: int = 0
    has_true_reward: bool = False


class TaskIn(Body):
    """A task of a demonstrator, played in one MDP of the same lab."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_IN]})

    name: Name
    mdp_id: str
    metadata: MetadataIn = None


class TaskOut(Resource):
    """A task, with totals over its demonstrations."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                    "created_at": "2026-01-05T10:01:00Z",
                    "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                    **EXAMPLE_IN,
                    "n_trajectories": 12,
                    "n_steps": 340,
                    "has_true_reward": False,
                }
            ]
        }
    )

    demonstrator_id: str
    mdp_id: str
    name: str
    metadata: Metadata = Field(validation_alias="meta")
    n_trajectories: int = Field(description="Trajectories over all demonstration uploads.")
    n_steps: int = Field(description="Demonstrated (state, action) pairs over all uploads.")
    has_true_reward: bool

    @classmethod
    def of(cls, row: Task, totals: TaskTotals) -> TaskOut:
        """The API view of a task row with its totals (`store.tasks.task_totals`)."""
        return cls.model_validate(
            {
                "id": row.id,
                "created_at": row.created_at,
                "demonstrator_id": row.demonstrator_id,
                "mdp_id": row.mdp_id,
                "name": row.name,
                "meta": row.meta,
                "n_trajectories": totals.n_trajectories,
                "n_steps": totals.n_steps,
                "has_true_reward": totals.has_true_reward,
            }
        )


class TrueRewardIn(Body):
    """The known reward of a simulated task: one finite number per state."""

    model_config = ConfigDict(json_schema_extra={"examples": [{"values": [0.0, 0.0, 1.0]}]})

    values: Annotated[list[Number], FIRST_BAD_ITEM]


class TrueRewardOut(BaseModel):
    """A stored true reward with its values as stored (float32): what PUT answers and GET reads back."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                    "n_states": 3,
                    "sha256": "5d41402abc4b2a76b9719d911017c592…",
                    "updated_at": "2026-01-05T10:02:00Z",
                    "values": [0.0, 0.0, 1.0],
                }
            ]
        }
    )

    task_id: str
    n_states: int
    sha256: str
    updated_at: datetime
    values: list[float] = Field(description="One value per state, as stored (float32).")

    @classmethod
    def of(cls, row: TrueReward, *, sha256: str, values: list[float]) -> TrueRewardOut:
        """The API view of a true-reward row with its stored values."""
        return cls(
            task_id=row.task_id,
            n_states=row.n_states,
            sha256=sha256,
            updated_at=row.updated_at,
            values=values,
        )
