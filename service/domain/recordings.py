"""Bodies of `/v1/demonstrators/{demonstrator_id}/recordings`: centre-of-pressure recordings (docs/motion.md).

The plate bounds and segment settings are the engine's own frozen dataclasses (`metairl_engine.motion.recording`), so a
request carries exactly the knobs the pipeline has, with the engine's defaults.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, field_validator
from pydantic.json_schema import JsonDict, JsonValue

from metairl_engine.motion.force_plate import MIN_FZ, PlateAxes, length_unit
from metairl_engine.motion.recording import Bounds, DiscretiseSettings, SegmentSettings
from service.domain.common import FIRST_BAD_ITEM, Body, Number, Resource, UploadFormat
from service.store.models.recordings import Recording as RecordingRow

PLATE_EXAMPLE: JsonDict = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
SAMPLES_EXAMPLE: list[JsonValue] = [
    {"t": 0.00, "x": 0.000, "y": 0.000, "instruction": "forward"},
    {"t": 0.01, "x": 0.001, "y": 0.004, "instruction": "forward"},
    {"t": 0.02, "x": 0.001, "y": 0.009, "instruction": "forward"},
]
EXAMPLE_IN: JsonDict = {
    "name": "session 1, unstimulated",
    "mdp_id": "mdp_3q0f9b2yJm6nD1Kx8cT4wA",
    "bounds": PLATE_EXAMPLE,
    "samples": SAMPLES_EXAMPLE,
}
EXAMPLE_GRID_IN: JsonDict = {
    "bounds": PLATE_EXAMPLE,
    "grid": {"width": 100, "height": 100, "gamma": 0.9},
    "segment": {"min_prominence": 0.3, "min_separation_s": 0.5},
    "samples": SAMPLES_EXAMPLE,
}


class SampleIn(Body):
    """One COP sample: time, position on the plate and the instruction in force (none if absent or empty)."""

    t: Number
    x: Number
    y: Number
    instruction: str | None = Field(
        default=None, description="One of the 8 direction names of docs/motion.md (any case); empty = none."
    )


class GridIn(Body):
    """A velocity grid to map the recording onto: reused if the lab already has an identical one, else created."""

    width: int = Field(ge=2, description="Cells across the plate (x).")
    height: int = Field(ge=2, description="Cells along the plate (y, forward).")
    gamma: float = Field(default=0.9, ge=0.0, lt=1.0, description="Discount factor of the MDP.")


class DiscretiseIn(Body):
    """How samples become cells (the grid size is the MDP's)."""

    smooth_s: float = Field(
        default=DiscretiseSettings().smooth_s,
        description="Moving-average window on x and y before binning, in the recording's time unit (0: off).",
    )


Protocol = Literal["movements", "standing"]
LabelValue = Annotated[str, StringConstraints(max_length=100)] | float | bool
MAX_LABELS = 20
NAME_MAX = 200
"""Longest recording name (characters)."""


class RecordingOptions(Body):
    """Everything about a recording except its samples (a CSV upload sends these as form fields)."""

    name: str | None = Field(
        default=None,
        max_length=NAME_MAX,
        description="A label for the recording; a file upload without one is named after its file.",
    )
    mdp_id: str | None = Field(
        default=None, description="A velocity-grid MDP of your lab (8 velocity channels); or give `grid`."
    )
    grid: GridIn | None = Field(default=None, description="Instead of `mdp_id`: the velocity grid to use.")
    protocol: Protocol = Field(
        default="movements",
        description="`movements`: instructed out-and-back movements cut into per-direction demonstrations "
        "(needs `mdp_id` or `grid`, and `bounds`); `standing`: a quiet-standing trial stored whole, no "
        "segmentation and no demonstrations, for its sway measures (`GET /v1/recordings/{id}/sway`).",
    )
    metadata: dict[str, LabelValue] | None = Field(
        default=None,
        max_length=MAX_LABELS,
        description='The lab\'s labels of the trial, e.g. `{"vision": "closed", "surface": "foam"}`: the '
        "groups of `GET /v1/demonstrators/{id}/sway-summary?by=vision`.",
    )
    units: str | None = Field(
        default=None,
        max_length=16,
        description="The length unit of x and y (e.g. `cm`), reported with the sway measures; a COP CSV's header "
        "may give it instead (`COPx[cm]`). A force-plate file's COP is stored in metres: a `units` sent with one "
        "must name the file's own unit (a C3D's `POINT:UNITS`) or m, else 422. A spelling of metres, "
        "centimetres or millimetres is stored as `m`, `cm` or `mm`.",
    )
    bounds: Bounds | None = Field(
        default=None,
        description="The force plate's rectangle, in the samples' units; optional for `standing` (the samples' "
        "own extent).",
    )
    discretise: DiscretiseIn = DiscretiseIn()
    segment: SegmentSettings = Field(
        default=SegmentSettings(), description="How the session splits into out-and-back movements."
    )

    @field_validator("units")
    @classmethod
    def _one_spelling(cls, units: str | None) -> str | None:
        """``metres``, ``Millimeter``, … as ``m``, ``mm``, as a header's unit is read: one spelling per unit,
        so trials compare and convert whatever their uploads called it; another unit is kept as sent."""
        return None if units is None else length_unit(units) or units


class PlateIn(Body):
    """How to read a force-plate file (a C3D, or a CSV of forces and moments) into COP samples in metres."""

    axes: PlateAxes = Field(
        default=PlateAxes(),
        description="Where the file's +x and +y axes point (`right`, `left`, `forward`, `backward`); +z completes "
        "a right-handed frame. C3D: the two lab axes after the vertical, as `settings.plate.lab_axes` records; "
        "CSV: the plate's (AMTI's, +y forward: x `left`).",
    )
    min_fz: float = Field(
        default=MIN_FZ,
        gt=0,
        description="Least |Fz| (N) of a loaded sample; unloaded samples at the start and end are cut away; "
        "between loaded ones they are a 422 for `movements`, while `standing` keeps the longest loaded stretch "
        "and reports the others in `settings.plate.unloaded_stretches`.",
    )
    platform: int | None = Field(
        default=None,
        ge=1,
        description="C3D only: which force platform, from 1; absent, the one carrying the most load (the "
        "choice is in `settings.plate.platform` and `settings.plate.platform_choice`).",
    )
    events: Literal["instructions", "ignore"] | None = Field(
        default=None,
        description="C3D only: `instructions` reads the file's events as instructions (each names a direction, "
        "or rest); `ignore` leaves them out. Default: `instructions` for `movements`, `ignore` for `standing`.",
    )
    rate_hz: float | None = Field(
        default=None, gt=0, description="CSV only, without a `t` column: samples per second."
    )
    moment_unit: Literal["Nm", "Ncm", "Nmm"] = Field(
        default="Nm", description="CSV only: unit of Mx, My, Mz (forces in N); its length is the COP's."
    )
    origin_depth: float = Field(
        default=0.0,
        ge=0,
        description="CSV only: how far the measurement origin lies below the plate surface, in the moments' "
        "length unit (AMTI's h, the z offset of the plate's manual).",
    )

    @field_validator("axes")
    @classmethod
    def _perpendicular(cls, axes: PlateAxes) -> PlateAxes:
        """x and y must point to perpendicular directions (one sideways, one forward or backward)."""
        for issue in axes.issues():
            raise ValueError(f"y {issue.message}")
        return axes


class FileOptions(RecordingOptions):
    """The form fields of a file upload: the recording's options and, for a force-plate file, how to read it."""

    plate: PlateIn | None = Field(
        default=None, description="For a C3D or a CSV of forces and moments: units, axes, threshold."
    )


class RecordingIn(RecordingOptions):
    """A COP recording as JSON: one object per sample, in time order."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_IN]})

    samples: Annotated[list[SampleIn], FIRST_BAD_ITEM]


class RecordingTask(BaseModel):
    """A task the recording's segments went to."""

    label: str = Field(
        description="The segments' label (the instructed or nearest direction): the task name."
    )
    task_id: str
    created: bool = Field(description="True if the upload created the task, false if it joined it.")
    demonstration_id: str | None = Field(
        description="The demonstration batch holding these segments; null once that batch was deleted "
        "(`DELETE /v1/tasks/{task_id}/demonstrations/{batch_id}`)."
    )
    n_trajectories: int = Field(description="Segments (out-and-back movements) added.")
    n_steps: int = Field(description="Grid moves added over those segments.")


class RecordingOut(Resource):
    """A stored recording and what it produced."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": "rec_Yx3pQ9sLm2Kd7vN0bT5wCe",
                    "created_at": "2026-01-05T10:05:00Z",
                    "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                    "protocol": "movements",
                    "metadata": {"stimulation": "off"},
                    "mdp_id": "mdp_3q0f9b2yJm6nD1Kx8cT4wA",
                    "mdp_created": False,
                    "name": "session 1, unstimulated",
                    "format": "csv",
                    "n_samples": 6012,
                    "duration": 60.11,
                    "segments": {"forward": 3, "right": 3},
                    "dropped_segments": 0,
                    "dropped_samples": 4710,
                    "tasks": [
                        {
                            "label": "forward",
                            "task_id": "task_7cXw2mB9tQk4Lr0sHn5yZa",
                            "created": True,
                            "demonstration_id": "trj_V0sN3kP8xR2qL5mT9wB1cD",
                            "n_trajectories": 3,
                            "n_steps": 212,
                        }
                    ],
                    "units": "m",
                    "settings": {
                        "bounds": PLATE_EXAMPLE,
                        "discretise": {"width": 100, "height": 100, "smooth_s": 0.05},
                        "segment": {"origin": None, "min_prominence": 0.3},
                    },
                }
            ]
        }
    )

    demonstrator_id: str
    protocol: Protocol = Field(
        description="`movements` (cut into demonstrations) or `standing` (kept whole)."
    )
    metadata: dict[str, LabelValue] | None = Field(description="The lab's labels of the trial.")
    mdp_id: str | None = Field(description="The velocity grid of the movements; null for `standing`.")
    mdp_created: bool = Field(description="True if the upload created the velocity grid (`grid` given).")
    name: str | None
    format: UploadFormat = Field(
        description="How the samples came: `json`, `csv` (COP samples), `c3d` or `forces` (a CSV of forces "
        "and moments)."
    )
    n_samples: int
    duration: float = Field(description="Last minus first sample time.")
    segments: dict[str, int] = Field(description="Segments kept per label.")
    dropped_segments: int = Field(description="Movements that never left their grid cell (nothing to learn).")
    dropped_samples: int = Field(
        description="Samples that stayed in the previous sample's cell (pauses, stationary stretches)."
    )
    tasks: list[RecordingTask]
    units: str | None = Field(
        description="The length unit of the stored COP (`m`, `cm`, `mm` or the upload's own `units`; metres "
        "for a force-plate file); null when the upload gave none: its lengths are as uploaded."
    )
    settings: dict[str, Any] = Field(
        description="Bounds and the discretise/segment settings used, defaults filled; for a force-plate file "
        "also `plate`: how it was read (the `plate` options, the file's own units, unloaded samples cut away)."
    )

    @classmethod
    def of(cls, row: RecordingRow) -> RecordingOut:
        """The API view of a recording row (its summary holds the segments and tasks)."""
        return cls.model_validate(
            {
                "id": row.id,
                "created_at": row.created_at,
                "demonstrator_id": row.demonstrator_id,
                "protocol": row.protocol,
                "metadata": row.meta,
                "mdp_id": row.mdp_id,
                "name": row.name,
                "format": row.format,
                "n_samples": row.n_samples,
                "duration": row.duration,
                "settings": row.settings,
                "units": recording_units(row),
                **row.summary,
            }
        )


def recording_units(row: RecordingRow) -> str | None:
    """The length unit of a recording's stored COP: metres for a plate file, else the upload's `units`, with
    a spelling of metres, centimetres or millimetres read as `m`, `cm` or `mm` (`length_unit`)."""
    unit: str | None = row.settings.get("units") or ("m" if "plate" in row.settings else None)
    return None if unit is None else length_unit(unit) or unit
