"""Bodies of `/v1/tasks/{task_id}/demonstrations` (docs/api.md, "Demonstrations")."""

from __future__ import annotations

from typing import Annotated

from pydantic import ConfigDict, Field
from pydantic.json_schema import JsonDict

from service.domain.common import Body, Integer, Resource, UploadFormat
from service.store.models.demonstrators import Demonstration

Index = Annotated[Integer, Field(ge=-(2**31), le=2**31 - 1)]
"""A state or action index (range-checked against the MDP by the engine; bounded here to fit int32)."""

EXAMPLE_IN: JsonDict = {
    "trajectories": [{"states": [0, 1, 2], "actions": [1, 1]}, {"states": [1, 2], "actions": [1, 1]}]
}


class TrajectoryIn(Body):
    """One demonstration: `states[t]` is where `actions[t]` was taken; a final state may follow."""

    states: list[Index]
    actions: list[Index]


class DemonstrationsIn(Body):
    """A batch of trajectories, appended to the task's demonstrations (all or nothing)."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_IN]})

    trajectories: list[TrajectoryIn]


class DemonstrationOut(Resource):
    """One uploaded batch of a task's demonstrations."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": "trj_V0sN3kP8xR2qL5mT9wB1cD",
                    "created_at": "2026-01-05T10:03:00Z",
                    "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                    "format": "json",
                    "n_trajectories": 2,
                    "n_steps": 4,
                }
            ]
        }
    )

    task_id: str
    format: UploadFormat = Field(
        description="How the batch came (a recording's batches: the recording's format)."
    )
    n_trajectories: int
    n_steps: int = Field(description="Demonstrated (state, action) pairs in this batch.")

    @classmethod
    def of(cls, row: Demonstration) -> DemonstrationOut:
        """The API view of a demonstration row."""
        return cls.model_validate(row)
