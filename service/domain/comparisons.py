"""Bodies of `POST /v1/comparisons` (docs/api.md, "Comparisons and key states"): a learned reward against another, a true reward, or values."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from service.domain.common import FIRST_BAD_ITEM, AsSent, Body

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]


class RewardSide(Body):
    """A learned reward of your lab (of any job and demonstrator)."""

    reward_id: str


class OtherSide(Body):
    """Exactly one of: a learned reward, a task (its true reward), or one finite value per state."""

    reward_id: str | None = None
    task_id: str | None = Field(default=None, description="Compare with this task's true reward.")
    values: Annotated[list[FiniteFloat], FIRST_BAD_ITEM] | None = Field(
        default=None, description="One finite value per state."
    )

    @model_validator(mode="after")
    def _exactly_one(self) -> OtherSide:
        """Refuse zero or several of reward_id, task_id and values."""
        given = [name for name in ("reward_id", "task_id", "values") if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of reward_id, task_id or values (got {given or 'none'})")
        return self


EXAMPLES: dict[str, Any] = {
    "two rewards": {
        "summary": "A task reward against its baseline, or sessions of two demonstrators",
        "value": {
            "a": {"reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe"},
            "b": {"reward_id": "rwd_B4s9kL2xN6mQ1vT8wP3yZe"},
        },
    },
    "true reward": {
        "summary": "A learned reward against its task's true reward, on demonstrated states",
        "value": {
            "a": {"reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe"},
            "b": {"task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa"},
            "states": "visited",
        },
    },
    "values": {
        "summary": "A learned reward against values of your own (one per state)",
        "value": {"a": {"reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe"}, "b": {"values": [0.0, 0.5, 1.0]}},
    },
}


class ComparisonIn(Body):
    """Compare learned reward `a` with `b` on all states, or on the states visited in the demonstrations."""

    model_config = ConfigDict(
        extra="forbid", json_schema_extra={"examples": [EXAMPLES["two rewards"]["value"]]}
    )

    a: RewardSide
    b: OtherSide
    states: Literal["all", "visited"] = Field(
        default="all",
        description="`visited`: only states in the demonstrations behind a (its task; for a baseline every task "
        "of its job) and behind b when b is a learned reward or a task.",
    )
    weights: Literal["uniform", "occupancy"] = Field(
        default="uniform",
        description="State weighting of the dynamics-aware distances (`dynamics`): `uniform`, or `occupancy` — "
        "how often each state occurs in the demonstrations behind a and b.",
    )
    bootstrap: int = Field(
        default=0,
        ge=0,
        le=1000,
        description="Resamplings of the weighted states for 95 % intervals of `dynamics.epic` and "
        "`dynamics.starc` (0: no intervals).",
    )


ComparisonSubmission = Annotated[dict[str, Any], AsSent(ComparisonIn, sent=dict[str, Any])]
"""The body of `POST /v1/comparisons`: any JSON object, documented as `ComparisonIn`; `service.results.comparisons`
checks it with the rewards, task and lengths it names, so every problem comes in one 422."""


class Interval(BaseModel):
    """A 95 % bootstrap percentile interval."""

    low: float
    high: float


class DynamicsDistances(BaseModel):
    """Distances that know the dynamics: each reward canonicalised by potential shaping under the MDP's
    transitions and discount (docs/method.md, "Reward distances")."""

    epic: float = Field(
        description="EPIC: Pearson distance sqrt((1 − ρ) / 2) of the canonicalised rewards, in [0, 1]; 0 for "
        "rewards equal up to potential shaping, shift and positive scale."
    )
    epic_interval: Interval | None = Field(description="With `bootstrap` > 0: its 95 % interval.")
    starc: float = Field(
        description="STARC: half the distance between the canonicalised rewards normalised to unit norm, in [0, 1]."
    )
    starc_interval: Interval | None
    weights: Literal["uniform", "occupancy"]
    n_bootstrap: int
    mdp_id: str = Field(description="The MDP whose transitions and discount were used (reward a's).")
    gamma: float


class ComparedSide(BaseModel):
    """What one side of a comparison was: a learned reward, a task's true reward, or posted values."""

    kind: Literal["reward", "true_reward", "values"]
    label: str = Field(description="`task — demonstrator` (`baseline — demonstrator`), or `posted values`.")
    reward_id: str | None = None
    job_id: str | None = None
    task_id: str | None = None
    demonstrator_id: str | None = None


class ComparisonOut(BaseModel):
    """Pearson and Spearman correlations (contract) and an EPIC-style distance over the compared states."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "pearson": 0.91,
                    "spearman": 0.88,
                    "epic_distance": 0.21,
                    "states": "all",
                    "n_states": 25,
                    "n_compared": 25,
                    "dynamics": {
                        "epic": 0.18,
                        "epic_interval": {"low": 0.12, "high": 0.25},
                        "starc": 0.17,
                        "starc_interval": {"low": 0.11, "high": 0.24},
                        "weights": "uniform",
                        "n_bootstrap": 200,
                        "mdp_id": "mdp_H5t2nQ8xK3mB0vS7wL1yPc",
                        "gamma": 0.9,
                    },
                    "a": {
                        "kind": "reward",
                        "label": "walk right — patient 07",
                        "reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe",
                        "job_id": "job_V3n8sK2qLx0bT7mY4cW9rA",
                        "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                        "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                    },
                    "b": {
                        "kind": "reward",
                        "label": "walk right — patient 07, stimulated",
                        "reward_id": "rwd_Z2k7mN4xQ8sB1vT6wL3yRa",
                        "job_id": "job_K8d2nW5xR1sB7vT4qL9yMe",
                        "task_id": "task_9fRt3mB8tQk1Lr6sHn2yWc",
                        "demonstrator_id": "dem_Wq3s7Xz1pN9uLm4vB6cE2r",
                    },
                }
            ]
        }
    )

    pearson: float = Field(description="Pearson r in [−1, 1]; 0 when either side is constant on the states.")
    spearman: float = Field(
        description="Spearman rank correlation in [−1, 1] (ties share their average rank)."
    )
    epic_distance: float = Field(
        description="sqrt((1 − pearson) / 2) in [0, 1]: 0 for rewards ordering states alike up to shift and "
        "scale, 1 for opposite ones (coverage only; `dynamics.epic` also removes potential shaping)."
    )
    states: Literal["all", "visited"]
    n_states: int
    n_compared: int = Field(description="How many states the numbers are computed on.")
    dynamics: DynamicsDistances = Field(
        description="EPIC and STARC under reward a's MDP (transitions and γ), weighted as asked, on the "
        "compared states."
    )
    a: ComparedSide
    b: ComparedSide
