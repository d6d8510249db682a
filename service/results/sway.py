"""Sway measures of stored recordings, and a demonstrator's standing trials compared by a metadata label
(docs/motion.md, "Quiet standing"). numpy and scipy only; the measures are `metairl_engine.motion.sway`'s."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from sqlalchemy.orm import Session

from metairl_engine import InvalidInput
from metairl_engine.motion.sway import (
    CONFIDENCE,
    LENGTH_POWER,
    METHODS,
    N_RESAMPLES,
    NO_RATIO,
    GroupComparison,
    Interval,
    SwayMeasures,
    SwayOptions,
    analysed_samples,
    compare_groups,
    quotient,
    sway_measures,
)
from service.domain.recordings import recording_units
from service.domain.sway import Estimate, Spectra, SwayDifference, SwayGroup, SwayOut, SwaySummaryOut
from service.files.images import sway_png
from service.problems import Conflict, Unprocessable
from service.results.downloads import Download
from service.results.units import common_unit
from service.store.blobs import get_array
from service.store.models.demonstrators import Demonstrator
from service.store.models.recordings import Recording as RecordingRow
from service.store.recordings import demonstrator_recordings

SUMMARY_SKIP = ("centre_x", "centre_y")
"""Descriptors left out of group comparisons: where the plate put the feet says nothing about sway."""
ROMBERG = ("closed", "open")
"""The vision labels whose quotient of means is the Romberg quotient (eyes closed / eyes open)."""


def stated_rate(row: RecordingRow) -> float | None:
    """The sampling rate a force-plate file states (a C3D's header or ANALOG:RATE), exact where the stored
    float32 times only approximate it; None for samples that state none."""
    rate = row.settings.get("plate", {}).get("rate_hz")
    return None if rate is None else float(rate)


def recording_sway(session: Session, row: RecordingRow, options: SwayOptions = SwayOptions()) -> SwayMeasures:
    """The sway measures of a stored recording; 422 naming the query option that cannot be used."""
    samples = get_array(session, row.samples_blob_id).astype(np.float64)
    try:
        return sway_measures(samples[:, 0], samples[:, 1], samples[:, 2], options, rate_hz=stated_rate(row))
    except InvalidInput as exc:
        first = exc.issues[0]
        raise Unprocessable(
            f"The sway options cannot be used. {first.pointer}: {first.message}",
            errors=[{"pointer": i.pointer, "message": i.message} for i in exc.issues],
        ) from exc


@dataclass(frozen=True)
class SwaySummary:
    """A demonstrator's standing trials grouped by the value of one metadata label."""

    by: str
    unit: str | None
    units: list[str | None]
    recording_ids: dict[str, list[str]]
    unlabelled: list[str]
    comparison: GroupComparison
    romberg: dict[str, Interval] | None
    not_estimated: dict[str, dict[str, str]]


def sway_summary(
    session: Session, demonstrator: Demonstrator, *, by: str, options: SwayOptions = SwayOptions()
) -> SwaySummary:
    """Group the demonstrator's standing recordings by ``metadata[by]`` (groups in sorted order), compare
    each measure's means between groups and, for ``by=vision`` with ``closed`` and ``open`` groups, give the
    Romberg quotient of the measures whose ratio means something (not `NO_RATIO`); lengths in one unit
    (`common_unit`); 409 when no standing recording carries the label or the units do not convert."""
    rows = demonstrator_recordings(session, demonstrator, protocol="standing")
    labelled: dict[str, list[RecordingRow]] = {}
    unlabelled = []
    for row in rows:
        value = (row.meta or {}).get(by)
        if value is None:
            unlabelled.append(row.id)
        else:
            labelled.setdefault(str(value), []).append(row)
    if not labelled:
        raise Conflict(
            f"Demonstrator {demonstrator.id} has {len(rows)} standing recordings and none carries the metadata "
            f"label {by!r}; upload standing trials with metadata such as {{{by!r}: ...}}."
        )
    unit, factors = common_unit([r for rs in labelled.values() for r in rs])
    groups = {}
    not_estimated = {}
    for label in sorted(labelled):
        measures = []
        for row in labelled[label]:
            sway = recording_sway(session, row, options)
            scale = factors[row.id]
            measures.append({k: v * scale ** LENGTH_POWER[k] for k, v in sway.descriptors().items()})
            if sway.not_estimated:
                not_estimated[row.id] = sway.not_estimated
        groups[label] = {
            name: np.array([m[name] for m in measures]) for name in measures[0] if name not in SUMMARY_SKIP
        }
    lowered = {label.lower(): label for label in groups}
    romberg = None
    if by.lower() == "vision" and all(v in lowered for v in ROMBERG):
        closed, opened = ({k: v for k, v in groups[lowered[g]].items() if k not in NO_RATIO} for g in ROMBERG)
        romberg = quotient(closed, opened)
    return SwaySummary(
        by=by,
        unit=unit,
        units=sorted({recording_units(r) for rs in labelled.values() for r in rs}, key=str),
        recording_ids={label: [r.id for r in labelled[label]] for label in sorted(labelled)},
        unlabelled=unlabelled,
        comparison=compare_groups(groups),
        romberg=romberg,
        not_estimated=not_estimated,
    )


def off_plate_caveat(row: RecordingRow) -> dict[str, str]:
    """``{"samples": why}`` when some of a C3D recording's COP lies off its plate (upload's ``off_plate_fraction``):
    a foot off the plate, or a COP computed under little load, which every measure then includes."""
    fraction = row.settings.get("plate", {}).get("off_plate_fraction", 0.0)
    if not fraction:
        return {}
    half = row.settings["plate"]["plate_half_size_m"]
    return {
        "samples": f"{fraction:.1%} of the COP lies off the plate ({2 * half[0]:.3g} × {2 * half[1]:.3g} m): a "
        "foot off the plate, or a COP computed under little load; every measure includes those samples"
    }


def sway_out(session: Session, row: RecordingRow, options: SwayOptions, *, spectra: bool) -> SwayOut:
    """The answer of ``GET /v1/recordings/{id}/sway``: measures (non-finite as null), methods and options, and
    with ``spectra`` the Welch spectra they come from."""
    measures = recording_sway(session, row, options)
    return SwayOut(
        recording_id=row.id,
        units=recording_units(row),
        rate_hz=measures.rate_hz,
        duration_s=measures.duration_s,
        n_samples=measures.n_samples,
        options={
            "lowpass_hz": options.lowpass_hz,
            "trim_start_s": options.trim_start_s,
            "trim_end_s": options.trim_end_s,
        },
        descriptors={k: v if math.isfinite(v) else None for k, v in measures.descriptors().items()},
        not_estimated=measures.not_estimated,
        caveats=measures.caveats | off_plate_caveat(row),
        methods=METHODS,
        spectra=Spectra(
            frequencies=measures.frequencies.tolist(),
            psd_x=measures.psd_x.tolist(),
            psd_y=measures.psd_y.tolist(),
        )
        if spectra
        else None,
    )


def sway_picture(session: Session, row: RecordingRow, options: SwayOptions) -> Download:
    """The recording's analysed COP path with its 95 % prediction ellipse, as an inline PNG."""
    measures = recording_sway(session, row, options)
    units = recording_units(row)
    samples = get_array(session, row.samples_blob_id).astype(np.float64)
    _, x, y = analysed_samples(samples[:, 0], samples[:, 1], samples[:, 2], options, rate_hz=stated_rate(row))
    title = f"{row.name or row.id}: area95 {measures.area95:.3g} {units or 'units'}²"
    return Download(
        content=sway_png(x, y, measures.ellipse_outline(), units=units, title=title),
        media_type="image/png",
        filename=f"{row.id}-sway.png",
        disposition="inline",
        etag=None,
    )


def sway_summary_out(
    session: Session, demonstrator: Demonstrator, *, by: str, options: SwayOptions
) -> SwaySummaryOut:
    """The answer of ``GET /v1/demonstrators/{id}/sway-summary``: `sway_summary` with every interval as an
    `Estimate`."""
    summary = sway_summary(session, demonstrator, by=by, options=options)
    comparison = summary.comparison

    def estimates(values: dict[str, Interval]) -> dict[str, Estimate]:
        return {name: Estimate.of(interval) for name, interval in values.items()}

    return SwaySummaryOut(
        demonstrator_id=demonstrator.id,
        by=by,
        unit=summary.unit,
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
        not_estimated=summary.not_estimated,
        method=f"{CONFIDENCE:.0%} percentile bootstrap over trials, {N_RESAMPLES} resamples, seeded",
    )
