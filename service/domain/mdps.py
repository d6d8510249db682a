"""Bodies of `/v1/mdps`: explicit and grid MDPs in, metadata and summary out (docs/api.md, "MDPs")."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic.json_schema import JsonDict

from service.domain.common import FIRST_BAD_ITEM, Body, Integer, Name, Number, Resource
from service.store.models.mdps import Mdp


class DeterministicTransitions(Body):
    """Deterministic transitions: `next_state[s][a]` is the state action a leads to from state s."""

    kind: Literal["deterministic"]
    next_state: Annotated[list[Annotated[list[Integer], FIRST_BAD_ITEM]], FIRST_BAD_ITEM] = Field(
        description="S×A table of next states (0-based)."
    )


class SparseTransitions(Body):
    """Stochastic transitions as K triples: P(next[k] | s[k], a[k]) = p[k]; each (s, a) must sum to 1."""

    kind: Literal["sparse"]
    s: Annotated[list[Integer], FIRST_BAD_ITEM]
    a: Annotated[list[Integer], FIRST_BAD_ITEM]
    next: Annotated[list[Integer], FIRST_BAD_ITEM]
    p: Annotated[list[Number], FIRST_BAD_ITEM]


class LayoutIn(Body):
    """How states tile a picture, so rewards can be drawn: state = (channel·height + y)·width + x."""

    width: Integer
    height: Integer
    channels: Integer = 1


EXPLICIT_EXAMPLE: JsonDict = {
    "kind": "explicit",
    "name": "corridor",
    "n_states": 3,
    "n_actions": 2,
    "gamma": 0.9,
    "transitions": {"kind": "deterministic", "next_state": [[0, 1], [0, 2], [1, 2]]},
    "layout": {"width": 3, "height": 1},
}
SPARSE_EXAMPLE: JsonDict = {
    "kind": "explicit",
    "name": "slippery pair",
    "n_states": 2,
    "n_actions": 1,
    "gamma": 0.95,
    "features": [[0.0, 1.0], [1.0, 0.0]],
    "transitions": {
        "kind": "sparse",
        "s": [0, 0, 1],
        "a": [0, 0, 0],
        "next": [0, 1, 1],
        "p": [0.2, 0.8, 1.0],
    },
}
GRID_EXAMPLE: JsonDict = {
    "kind": "grid",
    "name": "plate",
    "width": 100,
    "height": 100,
    "moves": 8,
    "velocity": True,
    "gamma": 0.9,
}


class ExplicitMdpIn(Body):
    """An MDP given as arrays; features default to one-hot (tabular)."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXPLICIT_EXAMPLE, SPARSE_EXAMPLE]})

    kind: Literal["explicit"]
    name: Name
    n_states: Integer | None = Field(default=None, description="Number of states (default: from the arrays).")
    n_actions: Integer | None = Field(
        default=None, description="Number of actions (default: from the arrays)."
    )
    gamma: Number = Field(description="Discount factor in [0, 1).")
    features: Annotated[list[Annotated[list[Number], FIRST_BAD_ITEM]], FIRST_BAD_ITEM] | None = Field(
        default=None, description="S×F state features."
    )
    transitions: Annotated[DeterministicTransitions | SparseTransitions, Field(discriminator="kind")]
    layout: LayoutIn | None = None


class GridMdpIn(Body):
    """A grid world built server side with its layout; `velocity: true` is the paper's motion model."""

    model_config = ConfigDict(json_schema_extra={"examples": [GRID_EXAMPLE]})

    kind: Literal["grid"]
    name: Name
    width: Integer = Field(ge=1)
    height: Integer = Field(ge=1)
    moves: Literal[4, 8] | None = Field(default=None, description="4 or 8 neighbours (velocity grids: 8).")
    stay: bool = False
    slip: Number = Field(default=0.0, ge=0.0, le=1.0, description="Probability of a random other action.")
    velocity: bool = Field(default=False, description="States are (cell, one of 8 directions).")
    gamma: Number = Field(description="Discount factor in [0, 1).")


MdpIn = Annotated[ExplicitMdpIn | GridMdpIn, Field(discriminator="kind")]


class ArrayInfo(BaseModel):
    """A stored array's shape, dtype and checksum (the data is at `/v1/mdps/{id}/arrays`)."""

    shape: list[int]
    dtype: str
    sha256: str


class MdpOut(Resource):
    """An MDP's metadata and summary; never its arrays."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": "mdp_3q0f9b2yJm6nD1Kx8cT4wA",
                    "created_at": "2026-01-05T10:00:00Z",
                    "name": "plate",
                    "source": "grid",
                    "n_states": 80000,
                    "n_actions": 8,
                    "n_features": 10,
                    "tabular": False,
                    "gamma": 0.9,
                    "transitions": "deterministic",
                    "layout": {"width": 100, "height": 100, "channels": 8},
                    "grid": {
                        "width": 100,
                        "height": 100,
                        "moves": 8,
                        "stay": False,
                        "slip": 0.0,
                        "velocity": True,
                    },
                    "summary": {"n_transitions": 640000, "absorbing_states": 0, "unreachable_states": 0},
                    "arrays": {
                        "features": {"shape": [80000, 10], "dtype": "<f4", "sha256": "9f86d0…"},
                        "next_state": {"shape": [80000, 8], "dtype": "<i4", "sha256": "2c26b4…"},
                    },
                }
            ]
        }
    )

    name: str
    source: Literal["explicit", "grid", "npz"]
    n_states: int
    n_actions: int
    n_features: int = Field(description="Feature width (n_states when tabular).")
    tabular: bool = Field(description="True when features are one-hot (none were given).")
    gamma: float
    transitions: Literal["deterministic", "sparse"]
    layout: dict[str, int] | None
    grid: dict[str, Any] | None
    summary: dict[str, Any]
    arrays: dict[str, ArrayInfo]

    @classmethod
    def of(cls, row: Mdp, blobs: Mapping[str, Any]) -> MdpOut:
        """The API view of an MDP row; ``blobs`` maps its blob ids to their metadata (`store.mdps.array_blobs`)."""
        arrays = {}
        for name, blob_id in row.array_blobs.items():
            blob = blobs[blob_id]
            arrays[name] = ArrayInfo(shape=blob.shape, dtype=blob.dtype, sha256=blob.sha256)
        return cls(
            id=row.id,
            created_at=row.created_at,
            name=row.name,
            source=row.source,  # type: ignore[arg-type]
            n_states=row.n_states,
            n_actions=row.n_actions,
            n_features=row.n_states if row.n_features is None else row.n_features,
            tabular=row.n_features is None,
            gamma=row.gamma,
            transitions=row.transitions,  # type: ignore[arg-type]
            layout=row.layout,
            grid=row.grid,
            summary=row.summary,
            arrays=arrays,
        )
