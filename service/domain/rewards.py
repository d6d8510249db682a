"""Bodies of the results routes (docs/api.md, "Rewards" and "Comparisons and key states"): a job's rewards, one reward as JSON, key states, the Pearson matrix."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

Quantity = Literal["reward", "value", "policy", "uncertainty", "evidence"]
Format = Literal["json", "npy", "csv", "png"]
Overlay = Literal["none", "demos"]

EXAMPLE_SUMMARY: dict[str, Any] = {
    "min": -0.41,
    "max": 1.12,
    "mean": 0.08,
    "std": 0.27,
    "argmax_state": 24,
    "argmin_state": 0,
}


def reward_links(
    reward_id: str, *, drawable: bool, task: bool, stored: tuple[str, ...] = ("uncertainty", "evidence")
) -> dict[str, str]:
    """Relative download links of one reward: each format (png only with a layout), for a task its key
    states, and each of the ``stored`` per-state quantities beside it (`uncertainty`, `evidence`) as json
    and, with a layout, as ``<quantity>_png``."""
    links = {fmt: f"/v1/rewards/{reward_id}?format={fmt}" for fmt in ("json", "npy", "csv", "png")}
    if not drawable:
        del links["png"]
    if task:
        links["key_states"] = f"/v1/rewards/{reward_id}/key-states?top=10"
    for quantity in stored:
        links[quantity] = f"/v1/rewards/{reward_id}?quantity={quantity}&format=json"
        if drawable:
            links[f"{quantity}_png"] = f"/v1/rewards/{reward_id}?quantity={quantity}&format=png"
    return links


class RewardSummary(BaseModel):
    """Summary statistics of a reward vector (population std; states of the max and the min)."""

    min: float
    max: float
    mean: float
    std: float
    argmax_state: int
    argmin_state: int


class RewardRef(BaseModel):
    """One learned reward of a job: its id (contract), what it is, statistics, truth scores and download links."""

    reward_id: str
    kind: Literal["baseline", "task"]
    task_id: str | None = Field(description="The task (contract); null for the baseline.")
    task_name: str | None
    n_states: int
    n_actions: int
    summary: RewardSummary
    truth_pearson: float | None = Field(
        description="Pearson correlation with the task's current true reward on all states; null without one."
    )
    truth_pearson_excluding_top: float | None = Field(
        description="The same, leaving out the states where the true reward is highest (e.g. the goal), "
        "when `?exclude_top_truth=true` was asked; else null."
    )
    links: dict[str, str] = Field(
        description="Relative URLs: `json`, `npy`, `csv`, `png` (MDPs with a layout) and `key_states` (tasks)."
    )
    note: str | None = Field(
        default=None,
        description="How to read this reward, where it needs saying: for the baseline of a job with sharing "
        "`none` (no baseline was learned: it is the mean of the task rewards), and for a baseline learned on "
        "a velocity grid (what out-and-back movements can and cannot identify; docs/motion.md).",
    )


EXAMPLE_JOB_REWARDS: dict[str, Any] = {
    "job_id": "job_V3n8sK2qLx0bT7mY4cW9rA",
    "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
    "baseline": {
        "reward_id": "rwd_B4s9kL2xN6mQ1vT8wP3yZe",
        "kind": "baseline",
        "task_id": None,
        "task_name": None,
        "n_states": 25,
        "n_actions": 4,
        "summary": EXAMPLE_SUMMARY,
        "truth_pearson": None,
        "truth_pearson_excluding_top": None,
        "links": reward_links("rwd_B4s9kL2xN6mQ1vT8wP3yZe", drawable=True, task=False),
    },
    "tasks": [
        {
            "reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe",
            "kind": "task",
            "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
            "task_name": "walk right",
            "n_states": 25,
            "n_actions": 4,
            "summary": EXAMPLE_SUMMARY,
            "truth_pearson": 0.93,
            "truth_pearson_excluding_top": 0.88,
            "links": reward_links("rwd_P0q9sL3xN6mB2vT8kW1yZe", drawable=True, task=True),
        }
    ],
}


class JobRewards(BaseModel):
    """The baseline reward and each task's reward of a succeeded job, in the job's task order (contract shape)."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_JOB_REWARDS]})

    job_id: str
    demonstrator_id: str
    baseline: RewardRef
    tasks: list[RewardRef]


class RewardValues(BaseModel):
    """A reward (or a task's value function or policy) as JSON; `values` is (S,) or, for a policy, (S, A)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe",
                    "quantity": "reward",
                    "n_states": 3,
                    "values": [0.1, -0.2, 1.3],
                }
            ]
        }
    )

    reward_id: str
    quantity: Quantity
    n_states: int
    n_actions: int | None = Field(default=None, description="For a policy only.")
    values: list[float] | list[list[float]]


class KeyState(BaseModel):
    """A state where the task reward departs from the baseline, with its grid position when there is a layout."""

    rank: int = Field(description="1 for the largest departure.")
    state: int
    x: int | None
    y: int | None
    channel: int | None = Field(description="The layout channel (on a velocity grid: the direction moved).")
    reward: float = Field(description="The task reward here.")
    baseline: float = Field(description="The baseline reward here.")
    difference: float = Field(description="reward − baseline; key states are ranked by its absolute value.")


class KeyStates(BaseModel):
    """The `top` states where a task reward departs most from its job's baseline (the paper's key states)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "reward_id": "rwd_P0q9sL3xN6mB2vT8kW1yZe",
                    "baseline_reward_id": "rwd_B4s9kL2xN6mQ1vT8wP3yZe",
                    "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                    "top": 2,
                    "states": [
                        {
                            "rank": 1,
                            "state": 24,
                            "x": 4,
                            "y": 4,
                            "channel": 0,
                            "reward": 1.12,
                            "baseline": 0.15,
                            "difference": 0.97,
                        },
                        {
                            "rank": 2,
                            "state": 0,
                            "x": 0,
                            "y": 0,
                            "channel": 0,
                            "reward": -0.41,
                            "baseline": 0.2,
                            "difference": -0.61,
                        },
                    ],
                }
            ]
        }
    )

    reward_id: str
    baseline_reward_id: str
    task_id: str
    top: int
    states: list[KeyState] = Field(
        description="At most `top`, largest departure first; only states where the task reward differs from "
        "the baseline (none where it is the baseline)."
    )
    note: str | None = Field(
        default=None, description="Why fewer than `top` states are listed, when they are; else null."
    )


class ComparisonMatrix(BaseModel):
    """Pairwise Pearson correlations of a job's baseline (first) and task rewards (in the job's task order)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "job_id": "job_V3n8sK2qLx0bT7mY4cW9rA",
                    "labels": ["baseline", "walk right", "walk up"],
                    "reward_ids": [
                        "rwd_B4s9kL2xN6mQ1vT8wP3yZe",
                        "rwd_P0q9sL3xN6mB2vT8kW1yZe",
                        "rwd_Z2k7mN4xQ8sB1vT6wL3yRa",
                    ],
                    "task_ids": [None, "task_7cXw2mB9tQk4Lr0sHn5yZa", "task_2kLm8nB3vQx9Tr1sYh6uWe"],
                    "matrix": [[1.0, 0.62, 0.57], [0.62, 1.0, 0.11], [0.57, 0.11, 1.0]],
                    "epic": [[0.0, 0.31, 0.35], [0.31, 0.0, 0.52], [0.35, 0.52, 0.0]],
                }
            ]
        }
    )

    job_id: str
    labels: list[str] = Field(description="`baseline`, then each task's name.")
    reward_ids: list[str]
    task_ids: list[str | None]
    matrix: list[list[float]] = Field(
        description="matrix[i][j]: Pearson r of rewards i and j (0 when undefined)."
    )
    epic: list[list[float]] = Field(
        description="epic[i][j]: EPIC distance with dynamics (canonicalised by potential shaping under the MDP of "
        "the job's first task, uniform state weights) of rewards i and j, in [0, 1]."
    )
