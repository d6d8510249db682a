"""Bodies of `/v1/demonstrators` (docs/api.md, "Demonstrators and tasks")."""

from __future__ import annotations

from pydantic import ConfigDict, Field
from pydantic.json_schema import JsonDict

from service.domain.common import Body, Metadata, MetadataIn, Name, Resource
from service.store.models.demonstrators import Demonstrator

EXAMPLE_IN: JsonDict = {
    "name": "patient 07",
    "metadata": {"condition": "spinal cord injury", "session": "2026-01-05"},
}


class DemonstratorIn(Body):
    """A person, robot or session whose inherent (baseline) reward is to be learned."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_IN]})

    name: Name
    metadata: MetadataIn = None


class DemonstratorOut(Resource):
    """A demonstrator."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {"id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w", "created_at": "2026-01-05T10:00:00Z", **EXAMPLE_IN}
            ]
        }
    )

    name: str
    metadata: Metadata = Field(validation_alias="meta")

    @classmethod
    def of(cls, row: Demonstrator) -> DemonstratorOut:
        """The API view of a demonstrator row."""
        return cls.model_validate(row)
