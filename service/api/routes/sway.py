"""Quiet standing (docs/motion.md, "Quiet standing"): a recording's sway measures (JSON, or its COP path with
the 95 % ellipse as PNG), and a demonstrator's standing trials compared by a metadata label. Plain ``def``
routes: FastAPI runs them (spectra, bootstrap, figure) in its thread pool."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Query, Response

from metairl_engine.motion.sway import SwayOptions
from service.api.auth import LabDep
from service.api.deps import SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.responses import file_response
from service.domain.sway import SwayOut, SwaySummaryOut
from service.problems import Unprocessable
from service.results.sway import sway_out, sway_picture, sway_summary_out
from service.store import recordings
from service.store.demonstrators import get_demonstrator

router = APIRouter(tags=["motion"], responses=PROBLEM_RESPONSES)

LowpassQuery = Annotated[
    float | None,
    Query(
        description="Cut-off (Hz) of a zero-lag 4th-order Butterworth low-pass applied first; default none."
    ),
]
TrimStartQuery = Annotated[float, Query(description="Seconds left out at the start; default 0.")]
TrimEndQuery = Annotated[float, Query(description="Seconds left out at the end; default 0.")]


@router.get(
    "/recordings/{recording_id}/sway",
    summary="A recording's sway measures (quiet-standing posturography)",
    description="The standard centre-of-pressure measures of the whole stored recording (any protocol), "
    "unfiltered unless asked: path length, mean velocity (total and per axis), mean distance, RMS and range per "
    "axis, the 95 % prediction ellipse (area `area95`, semi-axes, angle; F quantile), sway area per second, "
    "mean and 95 % power frequency of the Welch spectra; each method named in `methods`. Lengths are in the "
    "recording's units (metres for a plate file). Frequency measures of under 20 s analysed come with a "
    "caveat in `caveats` (their Welch bins are over 0.1 Hz apart). `?format=png`: the COP path with its ellipse.",
    response_model=SwayOut,
    responses={
        200: {"description": "JSON, or with `?format=png` the picture.", "content": {"image/png": {}}},
        404: {"description": "No such recording in your lab (problem+json)."},
        422: {"description": "An option cannot be used, e.g. a cut-off above the Nyquist frequency."},
    },
)
def recording_sway_route(
    recording_id: str,
    lab: LabDep,
    session: SessionDep,
    lowpass_hz: LowpassQuery = None,
    trim_start_s: TrimStartQuery = 0.0,
    trim_end_s: TrimEndQuery = 0.0,
    spectra: Annotated[bool, Query(description="Include the Welch spectra.")] = False,
    format: Annotated[Literal["json", "png"], Query(description="`json` (default) or `png`.")] = "json",
) -> SwayOut | Response:
    """Measures and methods, or the picture."""
    row = recordings.get_recording(session, recording_id, lab_id=lab.id)
    options = SwayOptions(lowpass_hz=lowpass_hz, trim_start_s=trim_start_s, trim_end_s=trim_end_s)
    if format == "png":
        return file_response(sway_picture(session, row, options))
    return sway_out(session, row, options, spectra=spectra)


@router.get(
    "/demonstrators/{demonstrator_id}/sway-summary",
    summary="A demonstrator's standing trials compared by a metadata label",
    description="The demonstrator's `standing` recordings grouped by the value of `metadata[by]` (e.g. "
    "`by=vision`: `open`, `closed`): per group each sway measure's mean with a 95 % interval, the differences "
    "between groups (b − a for every pair in label order) with intervals, and for `by=vision` the Romberg "
    "quotient (closed / open; none for the ellipse angle). Lengths are in one `unit`: trials in m, cm and mm "
    "are converted. Intervals: percentile bootstrap over trials (scipy.stats.bootstrap, seeded); a "
    "group of one trial has none. Trials without the label are listed in `unlabelled`.",
    responses={
        404: {"description": "No such demonstrator in your lab (problem+json)."},
        409: {
            "description": "No standing recording of the demonstrator carries the label, or the trials' lengths "
            "cannot be put in one unit: some without `units` beside some with, or a unit other than m, cm, mm "
            "(problem+json naming the recordings)."
        },
    },
)
def demonstrator_sway_summary(
    demonstrator_id: str,
    lab: LabDep,
    session: SessionDep,
    by: Annotated[
        str | None,
        Query(min_length=1, max_length=100, description="The metadata label to group by (required)."),
    ] = None,
    lowpass_hz: LowpassQuery = None,
    trim_start_s: TrimStartQuery = 0.0,
    trim_end_s: TrimEndQuery = 0.0,
) -> SwaySummaryOut:
    """Groups, differences and (for vision) the Romberg quotient."""
    demonstrator = get_demonstrator(session, demonstrator_id, lab_id=lab.id)  # another lab's: 404 first
    if by is None:
        raise Unprocessable(
            "Say which metadata label to group by, e.g. ?by=vision.",
            errors=[{"pointer": "", "parameter": "by", "message": "query parameter by is required"}],
        )
    options = SwayOptions(lowpass_hz=lowpass_hz, trim_start_s=trim_start_s, trim_end_s=trim_end_s)
    return sway_summary_out(session, demonstrator, by=by, options=options)
