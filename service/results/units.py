"""The length unit of stored recordings, and one unit for several: what the sway and motion summaries report
their lengths in when a demonstrator's recordings came in different units."""

from __future__ import annotations

from collections import Counter

from service.domain.recordings import recording_units
from service.problems import Conflict
from service.store.models.recordings import Recording as RecordingRow

LENGTH_UNITS = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
"""Length units trials in different units are converted between (metres per unit), finest first."""


def common_unit(rows: list[RecordingRow]) -> tuple[str | None, dict[str, float]]:
    """The one length unit a summary of ``rows`` reports and, per recording, the factor its lengths are
    multiplied by to be in it: the recordings' own unit when they share one, else (all in m, cm or mm) the unit
    most of them have, ties to the finer; 409 naming the recordings when their lengths cannot be put in one
    unit (some without a unit, or one outside m, cm, mm)."""
    units = {row.id: recording_units(row) for row in rows}
    if len(set(units.values())) == 1:
        return next(iter(units.values())), dict.fromkeys(units, 1.0)
    known = {rid: (u or "").strip().lower() for rid, u in units.items()}
    if all(u in LENGTH_UNITS for u in known.values()):
        counts = Counter(known.values())
        unit = max(LENGTH_UNITS, key=lambda u: (counts[u], -LENGTH_UNITS[u]))
        return unit, {rid: LENGTH_UNITS[u] / LENGTH_UNITS[unit] for rid, u in known.items()}
    by_unit: dict[str | None, list[str]] = {}
    for rid, u in units.items():
        by_unit.setdefault(u, []).append(rid)
    listing = "; ".join(
        f"{'no unit' if u is None else repr(u)}: {', '.join(ids)}"
        for u, ids in sorted(by_unit.items(), key=str)
    )
    raise Conflict(
        f"The recordings' lengths cannot be put in one unit ({listing}): only m, cm and mm convert, and a "
        "recording without a unit has none to convert from. Upload them again with `units` m, cm or mm (a "
        "stored recording's unit cannot be changed; DELETE /v1/demonstrators/{id} removes a demonstrator with "
        "its recordings), or leave out those in other units (for sway, by a label only some recordings carry).",
        errors=[
            {
                "pointer": "",
                "recording_id": rid,
                "message": "has no length unit (`units`)"
                if u is None
                else f"is in {u!r}, which does not convert to the others' units",
            }
            for rid, u in units.items()
            if u is None or known[rid] not in LENGTH_UNITS
        ],
    )
