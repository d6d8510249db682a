"""Sway measures of stored recordings, and a demonstrator's standing trials compared by a metadata label
(docs/motion.md, "Quiet standing"). numpy and scipy only; the measures are `metairl_engine.motion.sway`'s."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sqlalchemy.orm import Session

from metairl_engine import InvalidInput
from metairl_engine.motion.sway import (
    GroupComparison,
    Interval,
    SwayMeasures,
    SwayOptions,
    compare_groups,
    quotient,
    sway_measures,
)
from service.problems import Conflict, Unprocessable
from service.store.blobs import get_array
from service.store.models.demonstrators import Demonstrator
from service.store.models.recordings import Recording as RecordingRow
from service.store.recordings import demonstrator_recordings

SUMMARY_SKIP = ("centre_x", "centre_y")
"""Descriptors left out of group comparisons: where the plate put the feet says nothing about sway."""
ROMBERG = ("closed", "open")
"""The vision labels whose quotient of means is the Romberg quotient (eyes closed / eyes open)."""


def recording_units(row: RecordingRow) -> str | None:
    """The length unit of a recording's stored COP: metres for a plate file, else the upload's `units`."""
    return row.settings.get("units") or ("m" if "plate" in row.settings else None)


def recording_sway(session: Session, row: RecordingRow, options: SwayOptions = SwayOptions()) -> SwayMeasures:
    """The sway measures of a stored recording; 422 naming the query option that cannot be used."""
    samples = get_array(session, row.samples_blob_id).astype(np.float64)
    try:
        return sway_measures(samples[:, 0], samples[:, 1], samples[:, 2], options)
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
    units: list[str | None]
    recording_ids: dict[str, list[str]]
    unlabelled: list[str]
    comparison: GroupComparison
    romberg: dict[str, Interval] | None


def sway_summary(
    session: Session, demonstrator: Demonstrator, *, by: str, options: SwayOptions = SwayOptions()
) -> SwaySummary:
    """Group the demonstrator's standing recordings by ``metadata[by]`` (groups in sorted order), compare
    each measure's means between groups and, for ``by=vision`` with ``closed`` and ``open`` groups, give the
    Romberg quotient; 409 when no standing recording carries the label."""
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
    groups = {}
    for label in sorted(labelled):
        measures = [recording_sway(session, row, options).descriptors() for row in labelled[label]]
        groups[label] = {
            name: np.array([m[name] for m in measures]) for name in measures[0] if name not in SUMMARY_SKIP
        }
    lowered = {label.lower(): label for label in groups}
    romberg = None
    if by.lower() == "vision" and all(v in lowered for v in ROMBERG):
        romberg = quotient(groups[lowered["closed"]], groups[lowered["open"]])
    return SwaySummary(
        by=by,
        units=sorted({recording_units(r) for rs in labelled.values() for r in rs}, key=str),
        recording_ids={label: [r.id for r in labelled[label]] for label in sorted(labelled)},
        unlabelled=unlabelled,
        comparison=compare_groups(groups),
        romberg=romberg,
    )
