"""Recording files: COP samples in metres from a C3D or a CSV of plate forces and moments, or a COP CSV as it is.

A file is a C3D by its first bytes (or a name ending in ``.c3d``), a plate export if its CSV header names any of
Fx, Fy, Fz, Mx, My, Mz, else a CSV of COP samples (`recording_samples.csv_samples`). Conventions, units and the
instructions of a C3D (its events) are in docs/motion.md, "Force-plate files".
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from typing import Any

import numpy as np

from metairl_engine import InvalidInput
from metairl_engine.grids import DIRECTION_NAMES
from metairl_engine.motion.force_plate import LENGTH_UNITS, loaded_span, wrench_cop
from metairl_engine.motion.recording import NO_INSTRUCTION, canonical_instruction
from service.domain.common import UploadFormat
from service.domain.recordings import PlateIn
from service.files.c3d import C3dFile, file_problem, is_c3d, read_c3d
from service.files.recording_samples import Samples, csv_samples, located, read_columns
from service.problems import Unprocessable

FORCES = ("fx", "fy", "fz")
MOMENTS = ("mx", "my", "mz")
CSV_ONLY = ("rate_hz", "moment_unit", "origin_depth")
"""`PlateIn` fields that only a CSV of forces and moments uses."""
C3D_ONLY = ("platform",)
"""`PlateIn` fields that only a C3D uses."""


def _invalid(pointer: str, message: str) -> Unprocessable:
    """A 422 with one error."""
    return Unprocessable(
        f"The recording is invalid. {pointer}: {message}", errors=[{"pointer": pointer, "message": message}]
    )


def file_samples(filename: str | None, data: bytes, plate: PlateIn | None) -> Samples:
    """The COP samples of an uploaded file, whichever of the three kinds it is; `plate` only for a plate file."""
    if is_c3d(data) or (filename or "").lower().endswith(".c3d"):
        return c3d_samples(data, plate or PlateIn())
    if _header(data) & {*FORCES, *MOMENTS}:
        return forces_samples(data, plate or PlateIn())
    if plate is not None:
        raise _invalid(
            "/plate",
            "applies to force-plate files only (a C3D, or a CSV with columns Fx, Fy, Fz, Mx, My, Mz); this "
            "file is a CSV of COP samples (t, x, y)",
        )
    return csv_samples(data)


def _header(data: bytes) -> set[str]:
    """The lower-cased column names of a CSV's first line (nothing if it is not text)."""
    first = data.split(b"\n", 1)[0].decode("utf-8-sig", errors="replace")
    return {cell.strip().lower() for cell in next(csv.reader([first]), [])}


def _only_for(plate: PlateIn, fields: Sequence[str], kind: str) -> None:
    """422 if `plate` sets one of `fields`, which only files of `kind` use."""
    for name in fields:
        if name in plate.model_fields_set:
            raise _invalid(f"/plate/{name}", f"applies to {kind} only")


def c3d_samples(data: bytes, plate: PlateIn) -> Samples:
    """The COP of the C3D's force platform `plate.platform`, about the plate's centre, in metres, at the
    analog rate; instructions from the file's events."""
    _only_for(plate, CSV_ONLY, "CSV files of forces and moments")
    c3d = read_c3d(data)
    if not c3d.platforms:
        raise file_problem("the C3D has no force platform (FORCE_PLATFORM:USED is 0 or missing)")
    if plate.platform > len(c3d.platforms):
        raise _invalid(
            "/plate/platform", f"the C3D has {len(c3d.platforms)} force platforms; got {plate.platform}"
        )
    if c3d.analog_rate <= 0:
        raise file_problem(f"the C3D's analog rate is {c3d.analog_rate:g}; it must be positive")
    p = c3d.platforms[plate.platform - 1]
    unit = p.position_unit.strip()
    if unit not in LENGTH_UNITS:
        raise file_problem(f"POINT:UNITS {p.position_unit!r} is not one of {', '.join(LENGTH_UNITS)}")
    centre = p.corners[:2].mean(axis=1, keepdims=True)
    cop = (p.center_of_pressure[:2] - centre).T * LENGTH_UNITS[unit]
    t = c3d.start_s + np.arange(cop.shape[0]) / c3d.analog_rate
    read = {"rate_hz": c3d.analog_rate, "position_unit": unit, "force_unit": p.force_unit.strip()}
    return _plate_samples(
        t,
        cop,
        fz=p.force[2],
        instruction=event_instructions(c3d, t),
        plate=plate,
        fmt="c3d",
        lines=None,
        read=read | plate.model_dump(exclude=set(CSV_ONLY)),
    )


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
                "joined by spaces, _ or -, any case), or rest or none to end the instruction",
            )
    ordered = sorted(c3d.events, key=lambda event: event[1])
    latest = np.searchsorted([time for _, time in ordered], t, side="right") - 1
    return [ordered[k][0] if k >= 0 else None for k in latest]


def forces_samples(data: bytes, plate: PlateIn) -> Samples:
    """The COP of a CSV with columns Fx, Fy, Fz (N), Mx, My, Mz (`plate.moment_unit`) and ``t`` (s) or
    `plate.rate_hz`, about the plate's measurement origin, in metres; 422 naming a missing column or bad cell."""
    _only_for(plate, C3D_ONLY, "C3D files")
    columns = read_columns(data, required=(*FORCES, *MOMENTS), optional=("t",))
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
    length = plate.moment_unit.removeprefix("N")
    cop = wrench_cop(force, moment, z_up=plate.axes.z_up, origin_depth=plate.origin_depth)
    return _plate_samples(
        t,
        cop * LENGTH_UNITS[length],
        fz=force[:, 2],
        instruction=columns.instruction,
        plate=plate,
        fmt="forces",
        lines=columns.lines,
        read=plate.model_dump(exclude=set(C3D_ONLY)),
    )


def _plate_samples(
    t: np.ndarray,
    cop: np.ndarray,
    *,
    fz: np.ndarray,
    instruction: list[str | None] | None,
    plate: PlateIn,
    fmt: UploadFormat,
    lines: list[int] | None,
    read: dict[str, Any],
) -> Samples:
    """`Samples` of the loaded span of (N, 2) COP in file axes (metres), turned into the patient's axes."""
    try:
        span = loaded_span(fz, plate.min_fz)
    except InvalidInput as exc:
        raise located(exc, lines) from exc
    xy = plate.axes.to_patient(cop[span])
    return Samples(
        t=np.asarray(t, dtype=np.float64)[span].tolist(),
        x=xy[:, 0].tolist(),
        y=xy[:, 1].tolist(),
        instruction=None if instruction is None else instruction[span],
        format=fmt,
        lines=None if lines is None else lines[span],
        plate=read | {"unloaded_samples": len(fz) - (span.stop - span.start)},
    )
