"""Answers of `GET /v1/recordings/{id}/sway` and `GET /v1/demonstrators/{id}/sway-summary` (docs/motion.md,
"Quiet standing")."""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field

from metairl_engine.motion.sway import Interval


class Spectra(BaseModel):
    """The Welch spectra the frequency measures come from."""

    frequencies: list[float] = Field(description="Hz.")
    psd_x: list[float] = Field(description="Power spectral density of x, units²/Hz.")
    psd_y: list[float] = Field(description="Power spectral density of y, units²/Hz.")


class SwayOut(BaseModel):
    """A recording's sway measures (lengths in `units`, times in seconds) and how each was computed."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "recording_id": "rec_Yx3pQ9sLm2Kd7vN0bT5wCe",
                    "units": "cm",
                    "rate_hz": 100.0,
                    "duration_s": 60.0,
                    "n_samples": 6000,
                    "options": {"lowpass_hz": None, "trim_start_s": 0.0, "trim_end_s": 0.0},
                    "descriptors": {"area95": 0.945, "mean_velocity": 0.620, "mean_frequency": 0.257},
                    "not_estimated": {},
                    "caveats": {},
                    "methods": {"area95": "95 % prediction ellipse of a new sample, F quantile: ..."},
                    "spectra": None,
                }
            ]
        }
    )

    recording_id: str
    units: str | None = Field(
        description="Length unit of the COP: `m` for a plate file, else the upload's `units` (null if not given)."
    )
    rate_hz: float = Field(
        description="Samples per second: (N − 1) / (last − first time); the median interval's inverse where the "
        "times have a gap (an interval over 1.5 times the median)."
    )
    duration_s: float = Field(description="Analysed samples / rate.")
    n_samples: int = Field(description="Samples analysed (after any trim).")
    options: dict[str, float | None] = Field(description="The trim and filter applied (none by default).")
    descriptors: dict[str, float | None] = Field(
        description="Null where not estimated (reason in `not_estimated`). `area95` (units²), `mean_velocity` (units/s), `mean_frequency` (Hz) and the rest of the "
        "standard set: path_length, mean_velocity_x/_y, mean_distance, rms, rms_x/_y, range_x/_y, "
        "ellipse_major/_minor (semi-axes), ellipse_angle (degrees), sway_area_per_second, mean_frequency_x/_y, "
        "f95, f95_x/_y, centre_x/_y."
    )
    not_estimated: dict[str, str] = Field(
        default_factory=dict,
        description="Why each null descriptor is null: the frequency measures of an axis that never moves.",
    )
    caveats: dict[str, str] = Field(
        default_factory=dict,
        description="Descriptors given but to be read coarsely, and why: the frequency measures of an analysed "
        "stretch under 20 s, whose Welch bins are over 0.1 Hz apart (quiet standing sways at 0.1-0.5 Hz); and "
        "`samples`, for every measure, where some of a C3D's COP lies off its plate.",
    )
    methods: dict[str, str] = Field(description="How each measure is computed, with its source.")
    spectra: Spectra | None = Field(default=None, description="With `?spectra=true`: the Welch spectra.")


class Estimate(BaseModel):
    """An estimate with its 95 % percentile-bootstrap interval (null bounds below two trials a group)."""

    value: float | None = Field(description="Null where undefined (a frequency of an axis that never moves).")
    low: float | None
    high: float | None

    @classmethod
    def of(cls, interval: Interval) -> Estimate:
        """The API view of an engine interval, non-finite numbers as null."""
        return cls(**{k: _finite(getattr(interval, k)) for k in ("value", "low", "high")})


def _finite(value: float | None) -> float | None:
    """`value`, or None when it is None or not finite (JSON has no NaN)."""
    return value if value is not None and math.isfinite(value) else None


class SwayGroup(BaseModel):
    """The standing trials carrying one value of the label."""

    label: str
    n: int
    recording_ids: list[str]
    measures: dict[str, Estimate] = Field(description="Each measure's mean over the group's trials.")


class SwayDifference(BaseModel):
    """b minus a for each measure."""

    a: str
    b: str
    measures: dict[str, Estimate]


class SwaySummaryOut(BaseModel):
    """A demonstrator's standing trials grouped by a metadata label, compared."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "demonstrator_id": "dem_Qd8s0Xz4pN2uLm7vB1cE3w",
                    "by": "vision",
                    "unit": "cm",
                    "units": ["cm"],
                    "groups": [
                        {
                            "label": "closed",
                            "n": 6,
                            "recording_ids": ["rec_Yx3pQ9sLm2Kd7vN0bT5wCe"],
                            "measures": {"area95": {"value": 1.21, "low": 0.83, "high": 1.63}},
                        }
                    ],
                    "differences": [
                        {
                            "a": "closed",
                            "b": "open",
                            "measures": {"area95": {"value": -0.3, "low": -0.7, "high": 0.1}},
                        }
                    ],
                    "romberg": {"area95": {"value": 1.33, "low": 0.9, "high": 2.0}},
                    "unlabelled": [],
                    "not_estimated": {},
                    "method": "95% percentile bootstrap over trials, 2000 resamples, seeded",
                }
            ]
        }
    )

    demonstrator_id: str
    by: str = Field(description="The metadata label grouped by.")
    unit: str | None = Field(
        description="The length unit of every measure: the trials' own, or, for trials in different units among "
        "m, cm and mm, the one most trials have (ties to the finer), the others converted (areas by the square)."
    )
    units: list[str | None] = Field(description="The length units of the trials as uploaded.")
    groups: list[SwayGroup]
    differences: list[SwayDifference] = Field(description="For every pair of groups in label order, b − a.")
    romberg: dict[str, Estimate] | None = Field(
        description="With `by=vision` and groups `closed` and `open`: each measure's mean with eyes closed over "
        "its mean with eyes open (the Romberg quotient), else null; none for `ellipse_angle` (a ratio of angles "
        "means nothing)."
    )
    unlabelled: list[str] = Field(description="Standing recordings without the label, left out.")
    not_estimated: dict[str, dict[str, str]] = Field(
        default_factory=dict,
        description="Per recording with null measures, which and why (as in its sway answer): a group's mean "
        "of such a measure is null.",
    )
    method: str = Field(description="How the intervals are computed.")
