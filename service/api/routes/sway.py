"""Quiet standing (docs/motion.md, "Quiet standing"): a recording's sway measures (JSON, or its COP path with
the 95 % ellipse as PNG), and a demonstrator's standing trials compared by a metadata label. Plain ``def``
routes: FastAPI runs them (spectra, bootstrap, figure) in its thread pool."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from fastapi import APIRouter, Query, Response

from metairl_engine.motion.sway import CONFIDENCE, METHODS, N_RESAMPLES, SwayOptions, analysed_samples
from service.api.auth import LabDep
from service.api.deps import SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.responses import file_response
from service.domain.sway import Estimate, Spectra, SwayDifference, SwayGroup, SwayOut, SwaySummaryOut
from service.files.images import sway_png
from service.problems import Unprocessable
from service.results.downloads import Download
from service.results.sway import recording_sway, recording_units, sway_summary
from service.store import recordings
from service.store.blobs import get_array
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
    "recording's units (metres for a plate file). `?format=png`: the COP path with its ellipse.",
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
    measures = recording_sway(session, row, options)
    units = recording_units(row)
    if format == "png":
        samples = get_array(session, row.samples_blob_id).astype("float64")
        _, x, y = analysed_samples(samples[:, 0], samples[:, 1], samples[:, 2], options)
        title = f"{row.name or row.id}: area95 {measures.area95:.3g} {units or 'units'}²"
        return file_response(
            Download(
                content=sway_png(x, y, measures.ellipse_outline(), units=units, title=title),
                media_type="image/png",
                filename=f"{row.id}-sway.png",
                disposition="inline",
                etag=None,
            )
        )
    return SwayOut(
        recording_id=row.id,
        units=units,
        rate_hz=measures.rate_hz,
        duration_s=measures.duration_s,
        n_samples=measures.n_samples,
        options={"lowpass_hz": lowpass_hz, "trim_start_s": trim_start_s, "trim_end_s": trim_end_s},
        descriptors={k: v if math.isfinite(v) else None for k, v in measures.descriptors().items()},
        methods=METHODS,
        spectra=Spectra(
            frequencies=measures.frequencies.tolist(),
            psd_x=measures.psd_x.tolist(),
            psd_y=measures.psd_y.tolist(),
        )
        if spectra
        else None,
    )


@router.get(
    "/demonstrators/{demonstrator_id}/sway-summary",
    summary="A demonstrator's standing trials compared by a metadata label",
    description="The demonstrator's `standing` recordings grouped by the value of `metadata[by]` (e.g. "
    "`by=vision`: `open`, `closed`): per group each sway measure's mean with a 95 % interval, the differences "
    "between groups (b − a for every pair in label order) with intervals, and for `by=vision` the Romberg "
    "quotient (closed / open). Intervals: percentile bootstrap over trials (scipy.stats.bootstrap, seeded); a "
    "group of one trial has none. Trials without the label are listed in `unlabelled`.",
    responses={
        404: {"description": "No such demonstrator in your lab (problem+json)."},
        409: {"description": "No standing recording of the demonstrator carries the label (problem+json)."},
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
    summary = sway_summary(session, demonstrator, by=by, options=options)
    comparison = summary.comparison

    def estimates(values: dict) -> dict[str, Estimate]:
        return {name: Estimate.of(interval) for name, interval in values.items()}

    return SwaySummaryOut(
        demonstrator_id=demonstrator.id,
        by=by,
        units=summary.units,
        groups=[
            SwayGroup(
                label=label,
                n=comparison.n[label],
                recording_ids=summary.recording_ids[label],
                measures=estimates(comparison.means[label]),
            )
            for label in comparison.means
        ],
        differences=[
            SwayDifference(a=a, b=b, measures=estimates(values))
            for (a, b), values in comparison.differences.items()
        ],
        romberg=None if summary.romberg is None else estimates(summary.romberg),
        unlabelled=summary.unlabelled,
        method=f"{CONFIDENCE:.0%} percentile bootstrap over trials, {N_RESAMPLES} resamples, seeded",
    )
