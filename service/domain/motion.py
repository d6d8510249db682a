"""Bodies of the motion readout (docs/api.md, "Motion readout"): a demonstrator's kinematic
summary per direction, two demonstrators' (sessions') comparison, and the demonstrations a recording was cut
into."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.domain.common import AsSent, Body

UNITS: dict[str, Any] = {
    "peak_reach": "x, y units (as uploaded)",
    "path_length": "x, y units (as uploaded)",
    "deviation": "x, y units (as uploaded)",
    "time_to_peak_s": "t units (as uploaded)",
    "mean_speed": "x, y units per t unit",
}
"""What each descriptor is measured in where the recordings carry no length unit: their own, as uploaded."""


def descriptor_units(unit: str | None) -> dict[str, str]:
    """Each descriptor's unit for movements whose lengths are in ``unit`` (None: `UNITS`, as uploaded)."""
    if unit is None:
        return UNITS
    return {
        "peak_reach": unit,
        "path_length": unit,
        "deviation": unit,
        "time_to_peak_s": UNITS["time_to_peak_s"],
        "mean_speed": f"{unit} per t unit",
    }


UNIT_FIELD = Field(
    default=None,
    description="The length unit of every length (m, cm, mm or the recordings' own): recordings in different "
    "units among m, cm and mm are converted to the one most of them have; null where they carry none.",
)


class Interval(BaseModel):
    """A mean over repetitions with its 95 % percentile-bootstrap interval (None with one repetition)."""

    mean: float
    low: float | None
    high: float | None


def _interval(mean: float, low: float, high: float) -> dict[str, Any]:
    return {"mean": mean, "low": low, "high": high}


DIRECTION_EXAMPLE: dict[str, Any] = {
    "direction": "left",
    "n_segments": 3,
    "peak_reach": _interval(0.041, 0.037, 0.045),
    "path_length": _interval(0.094, 0.088, 0.101),
    "deviation": _interval(0.004, 0.003, 0.006),
    "time_to_peak_s": _interval(0.71, 0.66, 0.78),
    "mean_speed": _interval(0.061, 0.057, 0.066),
}


class DirectionSummary(BaseModel):
    """One instructed direction: its movements' count and descriptors (docs/api.md, "Motion readout")."""

    direction: str = Field(description="Canonical direction name (`forward`, `forward left`, …). Contract.")
    n_segments: int = Field(description="Out-and-back movements found in that direction. Contract.")
    peak_reach: Interval = Field(
        description="Farthest point along the instructed direction from the start (`mean` is contract)."
    )
    path_length: Interval = Field(description="Length of the COP path from onset to end.")
    deviation: Interval = Field(description="Mean distance from the instructed line.")
    time_to_peak_s: Interval = Field(description="Time from onset to the farthest point.")
    mean_speed: Interval = Field(description="Path length over duration.")


class LearnedDirection(BaseModel):
    """The learned rewards of one direction task of a job."""

    direction: str
    task_id: str
    reward_id: str
    n_visited_states: int = Field(description="States the task's demonstrations visit.")
    baseline_ring_centred: float | None = Field(
        description="Mean over those states of the baseline minus its mean at the same distance from the "
        "centre (docs/motion.md): higher = the baseline favours this direction's path."
    )
    task_baseline_pearson: float = Field(description="Pearson r of task reward and baseline on those states.")
    path_bend: float | None = Field(
        default=None,
        description="Model-free, no fit: the preference's level at this direction relative to the others, "
        "integrated around the centre from which way every direction's paths bend (docs/motion.md, "
        '"Path bend"); higher = preferred. Null unless all eight directions have a task.',
    )


class Agreement(BaseModel):
    """Whether the learned per-direction readout is consistent with the recordings: their peak reach and the
    way their paths bend (docs/motion.md, "Does the learned readout agree with the recordings")."""

    verdict: Literal["agrees", "disagrees", "undetermined"] = Field(
        description="Contract. Only `agrees` lets the learned readout be read beside the kinematic one as a "
        "preference; otherwise read reach and the weak side from the kinematic readout. `disagrees`: it runs "
        "significantly against the peak reach or the path bend; `agrees`: significantly with one and not "
        "against the other."
    )
    detail: str = Field(description="Contract: why, in a sentence, with the statistics behind it.")
    spearman: float | None = Field(
        default=None,
        description="Spearman ρ of the learned values with the mean peak reach across directions.",
    )
    p_value: float | None = Field(
        default=None, description="Exact one-sided permutation p-value of ρ, in the direction of its sign."
    )
    bend_spearman: float | None = Field(
        default=None,
        description="Spearman ρ of the learned values with the path-bend levels (`path_bend`, integrated from "
        "the mean bend of each direction's repetitions) across the same directions. Null where the bend was "
        "not checked: fewer than four directions, or not all eight directions moved.",
    )
    bend_p_value: float | None = Field(
        default=None,
        description="Exact one-sided permutation p-value of `bend_spearman`, in the direction of its sign.",
    )


class LearnedReadout(BaseModel):
    """The learned-reward readout of a demonstrator's latest succeeded job."""

    job_id: str
    baseline_reward_id: str | None
    caveat: str = Field(description="What a baseline learned from out-and-back movements can and cannot say.")
    recordings_after_job: list[str] = Field(
        default_factory=list,
        description="Recordings uploaded after the job was submitted: the paths, reach and verdict here include "
        "them but the fit never saw them; submit a new job to learn from them.",
    )
    agreement: Agreement = Field(
        description="Contract: the verdict on the learned readout against the recordings."
    )
    directions: list[LearnedDirection] = Field(
        description="Tasks named by a direction on a velocity grid (as recordings make them)."
    )


class MotionSummaryOut(BaseModel):
    """A demonstrator's kinematic readout from its recordings (movements pooled over recordings)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                    "units": UNITS,
                    "n_recordings": 1,
                    "directions": [DIRECTION_EXAMPLE],
                    "learned": None,
                }
            ]
        }
    )

    demonstrator_id: str
    units: dict[str, str] = Field(
        description="Each descriptor's unit: `unit` for lengths, else the uploaded t, x, y's."
    )
    unit: str | None = UNIT_FIELD
    n_recordings: int
    directions: list[DirectionSummary] = Field(description="Directions with movements, in canonical order.")
    learned: LearnedReadout | None = Field(
        description="The learned-reward readout of the demonstrator's latest succeeded job; null without one."
    )


class MotionComparisonIn(Body):
    """Two demonstrators of your lab (e.g. one patient's unstimulated and stimulated sessions)."""

    a: str = Field(description="The reference demonstrator (`dem_…`).")
    b: str = Field(description="The demonstrator compared with it: differences are b minus a.")


MotionComparisonSubmission = Annotated[dict[str, Any], AsSent(MotionComparisonIn, sent=dict[str, Any])]
"""The body of `POST /v1/motion-comparisons`: any JSON object, documented as `MotionComparisonIn`; the route
checks it with its check that `b` is not `a`, so every problem comes in one 422."""

COMPARISON_IN_EXAMPLES: dict[str, Any] = {
    "sessions": {
        "summary": "Stimulated (b) against unstimulated (a)",
        "value": {"a": "dem_Qd8s0Xz4pN2uLm7vB1cE3w", "b": "dem_Hk2s9Xq4pM1uLn7vC0dF5y"},
    }
}


class DirectionDiff(BaseModel):
    """b minus a in one direction both sides moved in; intervals resample each side's repetitions."""

    direction: str = Field(description="Canonical direction name. Contract.")
    n_a: int
    n_b: int
    peak_reach_diff: Interval = Field(description="b − a of the mean peak reach (`mean` is contract).")
    path_length_diff: Interval
    deviation_diff: Interval
    time_to_peak_s_diff: Interval
    mean_speed_diff: Interval


class ComparedSummary(BaseModel):
    """One side's own summary."""

    demonstrator_id: str
    name: str
    directions: list[DirectionSummary]


class LearnedSides(BaseModel):
    """Each side's learned-reward readout; null where the demonstrator has no succeeded job."""

    a: LearnedReadout | None
    b: LearnedReadout | None


class MotionComparisonOut(BaseModel):
    """Per direction, b minus a for each descriptor with a 95 % interval; both summaries; learned rewards."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "a": {
                        "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                        "name": "P1 unstimulated",
                        "directions": [DIRECTION_EXAMPLE],
                    },
                    "b": {
                        "demonstrator_id": "dem_Hk2s9Xq4pM1uLn7vC0dF5y",
                        "name": "P1 stimulated",
                        "directions": [DIRECTION_EXAMPLE | {"peak_reach": _interval(0.06, 0.055, 0.064)}],
                    },
                    "units": UNITS,
                    "directions": [
                        {
                            "direction": "left",
                            "n_a": 3,
                            "n_b": 3,
                            "peak_reach_diff": _interval(0.019, 0.012, 0.026),
                            "path_length_diff": _interval(0.035, 0.021, 0.049),
                            "deviation_diff": _interval(-0.001, -0.003, 0.001),
                            "time_to_peak_s_diff": _interval(-0.05, -0.14, 0.04),
                            "mean_speed_diff": _interval(0.02, 0.012, 0.027),
                        }
                    ],
                    "learned": {"a": None, "b": None},
                    "links": {"png": "/v1/motion-comparisons?format=png"},
                }
            ]
        }
    )

    a: ComparedSummary
    b: ComparedSummary
    units: dict[str, str]
    unit: str | None = UNIT_FIELD
    directions: list[DirectionDiff] = Field(description="Directions both sides moved in, canonical order.")
    learned: LearnedSides
    links: dict[str, str] = Field(description="`png`: POST the same body there for the figure (image/png).")


class CutTrajectory(BaseModel):
    """One demonstration (out-and-back movement) a recording was cut into."""

    trajectory: str = Field(description="`<label>/<k>`: the k-th segment of that label in this recording.")
    label: str = Field(description="The instructed (or nearest) direction: the task's name.")
    task_id: str
    demonstration_id: str = Field(description="The demonstration batch that holds it.")
    states: list[int] = Field(description="Velocity-grid states (one longer than actions: the final state).")
    actions: list[int]


class RecordingDemonstrationsOut(BaseModel):
    """The demonstrations a recording's upload stored, label by label in time order."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "recording_id": "rec_Yx3pQ9sLm2Kd7vN0bT5wCe",
                    "mdp_id": "mdp_3q0f9b2yJm6nD1Kx8cT4wA",
                    "trajectories": [
                        {
                            "trajectory": "forward/0",
                            "label": "forward",
                            "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                            "demonstration_id": "trj_V0sN3kP8xR2qL5mT9wB1cD",
                            "states": [210, 230, 250, 1250, 1230],
                            "actions": [0, 0, 4, 4],
                        }
                    ],
                }
            ]
        }
    )

    recording_id: str
    mdp_id: str | None = Field(
        description="The velocity grid; null for a `standing` recording (none stored)."
    )
    trajectories: list[CutTrajectory]
