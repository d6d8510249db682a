"""Bodies of `/v1/tasks/{task_id}/demonstrations` (docs/api.md, "Demonstrations")."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic.json_schema import JsonDict

from metairl_engine import Trajectory
from service.domain.common import FIRST_BAD_ITEM, Body, Integer, Resource, UploadFormat
from service.store.models.demonstrators import Demonstration

Index = Annotated[Integer, Field(ge=-(2**31), le=2**31 - 1)]
"""A state or action index (range-checked against the MDP by the engine; bounded here to fit int32)."""

EXAMPLE_IN: JsonDict = {
    "trajectories": [{"states": [0, 1, 2], "actions": [1, 1]}, {"states": [1, 2], "actions": [1, 1]}]
}
EXAMPLE_OUT: dict[str, Any] = {
    "id": "trj_V0sN3kP8xR2qL5mT9wB1cD",
    "created_at": "2026-01-05T10:03:00Z",
    "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
    "format": "json",
    "n_trajectories": 2,
    "n_steps": 4,
}
BatchFormat = Literal["json", "csv"]
"""How `GET /v1/tasks/{task_id}/demonstrations/{batch_id}` answers: JSON, or the CSV an upload takes."""


class TrajectoryIn(Body):
    """One demonstration: `states[t]` is where `actions[t]` was taken; a final state may follow."""

    states: Annotated[list[Index], FIRST_BAD_ITEM]
    actions: Annotated[list[Index], FIRST_BAD_ITEM]


class DemonstrationsIn(Body):
    """A batch of trajectories, appended to the task's demonstrations (all or nothing)."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_IN]})

    trajectories: Annotated[list[TrajectoryIn], FIRST_BAD_ITEM]


class DemonstrationOut(Resource):
    """One uploaded batch of a task's demonstrations."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_OUT]})

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


class TrajectoryOut(BaseModel):
    """One stored demonstration, as uploaded: `states` one longer than `actions` where a final state was given."""

    states: list[int]
    actions: list[int]


class DemonstrationBatchOut(DemonstrationOut):
    """One upload batch with its trajectories, in upload order (the body a JSON upload of them takes)."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_OUT | EXAMPLE_IN]})

    trajectories: list[TrajectoryOut]

    @classmethod
    def of_batch(cls, row: Demonstration, trajectories: list[Trajectory]) -> DemonstrationBatchOut:
        """The API view of a batch row with its trajectories (`service.store.loaders.batch_trajectories`)."""
        return cls.model_validate(
            DemonstrationOut.of(row).model_dump()
            | {
                "trajectories": [
                    {"states": t.states.tolist(), "actions": t.actions.tolist()} for t in trajectories
                ]
            }
        )
