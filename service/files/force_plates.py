"""Recording files: COP samples in metres from a C3D or a CSV of plate forces and moments, or a COP CSV as it is.

A file is a C3D by its first bytes (or a name ending in ``.c3d``); a CSV whose header names the COP (x and y,
or COPx and COPy) is a CSV of COP samples (`recording_samples.csv_samples`), whatever other columns it has (a
plate's export with both gives the COP its software computed); else a plate export if its header names any of
Fx, Fy, Fz, Mx, My, Mz, else a CSV of COP samples. Conventions, units and the instructions of a C3D (its
events) are in docs/motion.md, "Force-plate files".
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from metairl_engine import InvalidInput
from metairl_engine.grids import DIRECTION_NAMES
from metairl_engine.motion.force_plate import (
    LENGTH_UNITS,
    NEVER_LOADED,
    length_unit,
    loaded_span,
    loaded_stretches,
    wrench_cop,
)
from metairl_engine.motion.recording import NO_INSTRUCTION, canonical_instruction
from service.domain.common import UploadFormat
from service.domain.recordings import PlateIn, Protocol
from service.files.c3d import C3dFile, Platform, file_problem, is_c3d, read_c3d
from service.files.csv_rows import csv_error, csv_header
from service.files.recording_samples import ALIASES, Samples, csv_samples, located, read_columns
from service.problems import Unprocessable

FORCES = ("fx", "fy", "fz")
MOMENTS = ("mx", "my", "mz")
COP = ("x", "y")
NEWTONS = ("n", "newton", "newtons")
"""Units a force column may declare: forces are in N."""
MOMENT_UNITS = {"nm": "Nm", "ncm": "Ncm", "nmm": "Nmm"}
"""A moment column's unit (letters only, any case: ``N.mm``, ``N·m``) → `PlateIn.moment_unit`."""
CSV_ONLY = ("rate_hz", "moment_unit", "origin_depth")
"""`PlateIn` fields that only a CSV of forces and moments uses."""
C3D_ONLY = ("platform", "events")
MAX_REPORTED = 20
"""Most dropped loaded stretches listed in a standing recording's settings (all are counted)."""
"""`PlateIn` fields that only a C3D uses."""


def _invalid(pointer: str, message: str) -> Unprocessable:
    """A 422 with one error."""
    return Unprocessable(
        f"The recording is invalid. {pointer}: {message}", errors=[{"pointer": pointer, "message": message}]
    )


def file_samples(
    filename: str | None,
    data: bytes,
    plate: PlateIn | None,
    protocol: Protocol = "movements",
    units: str | None = None,
) -> Samples:
    """The COP samples of an uploaded file, whichever of the three kinds it is; `plate` only for a plate file,
    `units` the request's (a plate file's must name its own length unit). A ``standing`` upload ignores C3D
    events by default and keeps the longest loaded stretch of a plate file."""
    if is_c3d(data) or (filename or "").lower().endswith(".c3d"):
        return c3d_samples(data, plate or PlateIn(), protocol, units)
    names = set(csv_header(data, ALIASES).names)
    plate_columns = names & {*FORCES, *MOMENTS}
    if plate_columns and not set(COP) <= names:
        return forces_samples(data, plate or PlateIn(), protocol, units)
    if plate is not None:
        also = ", whose COP columns are read as they are (its force and moment columns are ignored)"
        raise _invalid(
            "/plate",
            "applies to force-plate files only (a C3D, or a CSV with columns Fx, Fy, Fz, Mx, My, Mz and no "
            f"COP columns); this file is a CSV of COP samples (t, x, y){also if plate_columns else ''}",
        )
    return csv_samples(data, units)


def _own_unit(units: str | None, unit: str, where: str) -> None:
    """422 at /units if the request's `units` names neither `unit`, the length unit a plate file declares
    (`where` says how), nor metres, the unit its COP is stored in: any other would misread its numbers."""
    if units is not None and length_unit(units) not in (unit, "m"):
        raise _invalid(
            "/units",
            f"is {units!r} but the file gives its own length unit: {where}; its COP is stored in metres. "
            f"Leave units out, or send {unit} or m",
        )


def _only_for(plate: PlateIn, fields: Sequence[str], kind: str) -> None:
    """422 if `plate` sets one of `fields`, which only files of `kind` use."""
    for name in fields:
        if name in plate.model_fields_set:
            raise _invalid(f"/plate/{name}", f"applies to {kind} only")


def c3d_samples(
    data: bytes, plate: PlateIn, protocol: Protocol = "movements", units: str | None = None
) -> Samples:
    """The COP of one of the C3D's force platforms (`plate.platform`, else the one carrying the most load),
    about the plate's centre, in metres, at the analog rate; instructions from the file's events unless
    `plate.events` (by default for ``standing``) says to ignore them. 422 naming the reason and the field,
    and at /units for `units` other than the C3D's own length unit."""
    _only_for(plate, CSV_ONLY, "CSV files of forces and moments")
    c3d = read_c3d(data)
    if not c3d.platforms:
        raise file_problem("the C3D has no force platform (FORCE_PLATFORM:USED is 0 or missing)")
    if plate.platform is not None and plate.platform > len(c3d.platforms):
        raise _invalid(
            "/plate/platform", f"the C3D has {len(c3d.platforms)} force platforms; got {plate.platform}"
        )
    if c3d.analog_rate <= 0:
        raise file_problem(
            "the C3D has no force data: its analog rate is 0 in the header and in ANALOG:RATE (no analog "
            "channels were recorded)"
        )
    loads = [float(np.abs(np.nan_to_num(p.force[_normal(p)])).sum()) for p in c3d.platforms]
    number = plate.platform or int(np.argmax(loads)) + 1
    p = c3d.platforms[number - 1]
    chosen = plate.platform is not None
    normal = _normal(p)
    plane = in_plane_axes(normal)
    if p.force.shape[-1] == 0 or not np.isfinite(p.force[normal]).any():
        raise _invalid(
            "/plate/platform" if chosen else "/file",
            f"force platform {number} has no force data (no samples in its channels)",
        )
    unit = length_unit(p.position_unit)
    if unit is None:
        raise file_problem(
            f"POINT:UNITS {p.position_unit!r} names no length unit ({', '.join(LENGTH_UNITS)}, or a spelling "
            "of metres, centimetres or millimetres)"
        )
    unit, unit_reason = _plausible_unit(unit, float(np.ptp(p.corners[plane], axis=1).max()))
    declared = p.position_unit.replace("\0", "").strip()
    _own_unit(units, unit, f"POINT:UNITS {declared!r}, read as {unit}")
    centre = p.corners[plane].mean(axis=1, keepdims=True)
    cop = (p.center_of_pressure[plane] - centre).T * LENGTH_UNITS[unit]
    half = np.abs(plate.axes.to_patient(np.ptp(p.corners[plane], axis=1)[None, :] / 2 * LENGTH_UNITS[unit]))[
        0
    ]
    t = c3d.start_s + np.arange(cop.shape[0]) / c3d.analog_rate
    events = plate.events or ("ignore" if protocol == "standing" else "instructions")
    read = {
        "rate_hz": c3d.analog_rate,
        "rate_source": c3d.analog_rate_source,
        "position_unit": declared,
        "position_unit_read_as": unit,
        "position_unit_reason": unit_reason,
        "force_unit": p.force_unit.strip(),
        "platform": number,
        "platform_choice": "given" if chosen else "most load",
        "lab_axes": {"vertical": "xyz"[normal], "x": "xyz"[plane[0]], "y": "xyz"[plane[1]]},
        "platform_loads_ns": [round(load / c3d.analog_rate, 3) for load in loads],
        "plate_half_size_m": [round(float(h), 4) for h in half],
        "events": events,
        "n_events": len(c3d.events),
    }
    try:
        return _plate_samples(
            t,
            cop,
            fz=p.force[normal],
            instruction=event_instructions(c3d, t) if events == "instructions" else None,
            plate=plate,
            protocol=protocol,
            fmt="c3d",
            lines=None,
            read=plate.model_dump(exclude={*CSV_ONLY, "platform", "events"}) | read,
        )
    except Unprocessable as exc:
        if chosen and exc.errors and exc.errors[0]["message"].startswith(NEVER_LOADED):
            raise _invalid(
                "/plate/platform", f"force platform {number} was {exc.errors[0]['message']}"
            ) from exc
        raise


PLATE_SIDE_M = (0.1, 3.0)
"""Range of a real force plate's longer side, metres: a unit that makes the corners say otherwise is wrong."""


def _plausible_unit(unit: str, side: float) -> tuple[str, str]:
    """The file's length unit, or, where its plate corners (longer side `side` in that unit) would make a plate
    no real one is (`PLATE_SIDE_M`), the one unit that gives a real size (a file writing ``m`` with corners in
    millimetres); and why."""
    low, high = PLATE_SIDE_M
    if low <= side * LENGTH_UNITS[unit] <= high:
        return unit, "the file's unit"
    fits = [u for u, metres in LENGTH_UNITS.items() if low <= side * metres <= high]
    if len(fits) != 1:
        return unit, "the file's unit (its corners fit no unit)"
    return fits[0], f"the corners' size: {side:g} {unit} is no force plate, {side:g} {fits[0]} is"


def in_plane_axes(normal: int) -> list[int]:
    """The lab axes that are the plate's x and y: the two after the vertical in cyclic order (x, y under z up;
    z, x under y up; y, z under x up), so that seen from above they turn as x and y do (x × y = up) and the
    COP is not mirrored. The vertical is taken to point up, as the corners of every real C3D the tests read
    say it does (C3D numbers a plate's corners so that its own x × y points into the floor)."""
    return [(normal + 1) % 3, (normal + 2) % 3]


def _normal(platform: Platform) -> int:
    """The lab axis normal to the plate (0, 1, 2 for x, y, z): the one along which its corners vary least
    (z in a z-up lab, y in a y-up one such as Kistler's)."""
    return int(np.argmin(np.ptp(platform.corners, axis=1)))


def event_instructions(c3d: C3dFile, t: np.ndarray) -> list[str | None] | None:
    """Per sample, the label of the latest event at or before it (None before the first); None without events.

    Each event starts the instruction it names (a direction, any spelling `canonical_instruction` reads) or
    ends it (``rest``, ``none``); another label is a 422 naming the event.
    """
    if not c3d.events:
        return None
    known = set(DIRECTION_NAMES) | {NO_INSTRUCTION}
    for k, (label, _) in enumerate(c3d.events):
        if canonical_instruction(label) not in known:
            raise _invalid(
                f"/events/{k}/label",
                f"unknown instruction {label!r}; an event names one of {', '.join(DIRECTION_NAMES)} (words "
                "joined by spaces, _ or -, any case), or rest or none to end the instruction; or send "
                'plate.events = "ignore" to leave the events out',
            )
    ordered = sorted(c3d.events, key=lambda event: event[1])
    latest = np.searchsorted([time for _, time in ordered], t, side="right") - 1
    return [ordered[k][0] if k >= 0 else None for k in latest]


def forces_samples(
    data: bytes, plate: PlateIn, protocol: Protocol = "movements", units: str | None = None
) -> Samples:
    """The COP of a CSV with columns Fx, Fy, Fz (N), Mx, My, Mz (`plate.moment_unit`, else the unit their
    header gives, ``Mx[Nmm]``) and ``t`` (s) or `plate.rate_hz`, about the plate's measurement origin, in
    metres; 422 naming a missing column or bad cell, a unit the header gives that contradicts `plate` or
    `units`, or a force unit other than N."""
    _only_for(plate, C3D_ONLY, "C3D files")
    columns = read_columns(data, required=(*FORCES, *MOMENTS), optional=("t",))
    plate = plate.model_copy(update={"moment_unit": _moment_unit(columns.units, plate)})
    length = plate.moment_unit.removeprefix("N")
    _own_unit(
        units, length, f"the moments' unit {plate.moment_unit} (plate.moment_unit), so the COP's is {length}"
    )
    force = np.array([columns.values[c] for c in FORCES], dtype=np.float64).reshape(3, -1).T
    moment = np.array([columns.values[c] for c in MOMENTS], dtype=np.float64).reshape(3, -1).T
    has_t = "t" in columns.values
    if plate.rate_hz is None:
        if not has_t:
            raise _invalid(
                "/plate/rate_hz", "the CSV has no t column: give the sampling rate (samples per second)"
            )
        t = np.asarray(columns.values["t"])
    elif has_t:
        raise _invalid("/plate/rate_hz", "the CSV has a t column: give the sampling rate only without one")
    else:
        t = np.arange(len(force)) / plate.rate_hz
    cop = wrench_cop(force, moment, z_up=plate.axes.z_up, origin_depth=plate.origin_depth)
    return _plate_samples(
        t,
        cop * LENGTH_UNITS[length],
        fz=force[:, 2],
        instruction=columns.instruction,
        plate=plate,
        protocol=protocol,
        fmt="forces",
        lines=columns.lines,
        read=plate.model_dump(exclude=set(C3D_ONLY)),
    )


def _moment_unit(declared: dict[str, str], plate: PlateIn) -> str:
    """The moments' unit: `plate.moment_unit` if given, else the one the header gives Mx, My, Mz (``Mx[Nmm]``),
    else ``Nm``; 422 at /file for a force unit other than N or moment units the header gives that are not one
    of `MOMENT_UNITS`, at /plate/moment_unit for one that contradicts the header."""
    for c in FORCES:
        if c in declared and declared[c].lower() not in NEWTONS:
            raise csv_error([("/file", f"CSV line 1: {c} is in {declared[c]!r}; give forces in N")])
    found = {
        MOMENT_UNITS.get("".join(filter(str.isalpha, declared[c])).lower()) for c in MOMENTS if c in declared
    }
    if None in found or len(found) > 1:
        named = ", ".join(f"{c} in {declared[c]!r}" for c in MOMENTS if c in declared)
        raise csv_error(
            [("/file", f"CSV line 1: {named}; give the moments in one of {', '.join(MOMENT_UNITS.values())}")]
        )
    if not found:
        return plate.moment_unit
    header = str(found.pop())
    if "moment_unit" in plate.model_fields_set and plate.moment_unit != header:
        raise _invalid(
            "/plate/moment_unit", f"is {plate.moment_unit} but the CSV header gives the moments in {header}"
        )
    return header


def _plate_samples(
    t: np.ndarray,
    cop: np.ndarray,
    *,
    fz: np.ndarray,
    instruction: list[str | None] | None,
    plate: PlateIn,
    protocol: Protocol,
    fmt: UploadFormat,
    lines: list[int] | None,
    read: dict[str, Any],
) -> Samples:
    """`Samples` of the loaded span of (N, 2) COP in file axes (metres), turned into the patient's axes: for
    ``movements`` from the first to the last loaded sample (an unloaded one between is a 422), for
    ``standing`` the longest loaded stretch, the others reported in ``unloaded_stretches``."""
    try:
        span = (
            loaded_span(fz, plate.min_fz) if protocol == "movements" else _longest_stretch(fz, plate.min_fz)
        )
    except InvalidInput as exc:
        raise located(exc, lines) from exc
    xy = plate.axes.to_patient(cop[span])
    t = np.asarray(t, dtype=np.float64)
    if "plate_half_size_m" in read:  # a C3D gives the plate's size: say how much of the COP lies off it
        off = (np.abs(xy) > np.asarray(read["plate_half_size_m"]) * (1 + OFF_PLATE_TOLERANCE)).any(axis=1)
        read = read | {"off_plate_fraction": round(float(off.mean()), 4)}
    if protocol == "standing":
        others = [s for s in loaded_stretches(fz, plate.min_fz) if s != span]
        read = read | {
            "loaded_stretches_dropped": [
                {"start_s": float(t[s.start]), "stop_s": float(t[s.stop - 1]), "n_samples": s.stop - s.start}
                for s in others[:MAX_REPORTED]
            ],
            "n_loaded_stretches": len(others) + 1,
        }
    return Samples(
        t=t[span].tolist(),
        x=xy[:, 0].tolist(),
        y=xy[:, 1].tolist(),
        instruction=None if instruction is None else instruction[span],
        format=fmt,
        lines=None if lines is None else lines[span],
        plate=read | {"unloaded_samples": len(fz) - (span.stop - span.start)},
    )


OFF_PLATE_TOLERANCE = 0.01
"""A COP sample further than this fraction of a half side beyond the plate's edge counts as off the plate."""


def _longest_stretch(fz: np.ndarray, min_fz: float) -> slice:
    """The longest run of loaded samples (the first of equals); `InvalidInput` as `loaded_span`'s if none is."""
    stretches = loaded_stretches(fz, min_fz)
    if not stretches:
        loaded_span(fz, min_fz)  # raises the never-loaded issue
    return max(stretches, key=lambda s: s.stop - s.start)
