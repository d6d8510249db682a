"""Recording samples as uploaded: JSON rows or a CSV with columns ``t,x,y[,instruction]``, and a file upload's
other fields; every problem a 422 naming the sample (and its CSV line). Force-plate files: `force_plates`.

A CSV may be comma-, tab- or semicolon-separated and write ``time`` for ``t``, ``COPx``/``COPy`` for ``x``/``y``
and a unit after a name (``COPx[cm]``, ``t (s)``): the COP columns' unit is the recording's `units`.
"""

from __future__ import annotations

import re
from array import array
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import ValidationError
from starlette.datastructures import FormData

from metairl_engine import InvalidInput, Issue
from metairl_engine.mdp import FLOAT32_MAX, MAX_ISSUES
from metairl_engine.motion.force_plate import length_unit
from service.domain.common import UploadFormat
from service.domain.recordings import FileOptions, RecordingIn
from service.files.csv_rows import MAX_ERRORS, csv_error, csv_table
from service.json_input import nul_pointer, nul_refused, parse_json
from service.problems import Unprocessable, validation_errors

REQUIRED_COLUMNS = ("t", "x", "y")
INSTRUCTION_COLUMN = "instruction"
ALIASES = {"time": "t", "copx": "x", "copy": "y"}
"""Other header names of a recording CSV's columns (any case, a unit suffix cut off first)."""
SECONDS = ("s", "sec", "second", "seconds")
"""Units the time column may declare: times are seconds."""
OBJECT_FIELDS = ("bounds", "grid", "discretise", "segment", "plate", "metadata")
"""Form fields of a file upload that hold a JSON object (the others are plain strings)."""
SAMPLE_BYTES = 320
"""Peak memory per sample (CSV row) of an uploaded recording: its columns, then the engine's arrays while it
is smoothed, binned and cut."""
SAMPLE_POINTER = re.compile(r"^/samples/(\d+)(/|$)")


def located(error: InvalidInput, lines: Sequence[int] | None) -> Unprocessable:
    """The engine's issues as a 422, the CSV line of each sample (``lines[k]`` for ``/samples/k``) added."""
    items = []
    for issue in error.issues:
        match = SAMPLE_POINTER.match(issue.pointer)
        line = lines[int(match.group(1))] if match and lines else None
        suffix = f" (CSV line {line})" if line else ""
        items.append({"pointer": issue.pointer, "message": issue.message + suffix})
    first = items[0]
    return Unprocessable(
        f"The recording is invalid. {first['pointer'] or '/'}: {first['message']}", errors=items
    )


@dataclass(frozen=True)
class Samples:
    """Uploaded sample columns; ``lines`` gives the CSV line of every sample (None for JSON and C3D), ``plate``
    how a force-plate file was read (None for COP samples)."""

    t: Sequence[float]
    x: Sequence[float]
    y: Sequence[float]
    instruction: list[str | None] | None
    format: UploadFormat
    lines: Sequence[int] | None = None
    plate: dict[str, Any] | None = None
    units: str | None = None
    """The length unit of x and y: a COP upload's `units`, else its CSV header's (None for plate files)."""

    def located(self, error: InvalidInput) -> Unprocessable:
        """The engine's issues as a 422, each sample's CSV line added to its message."""
        return located(error, self.lines)


def float32_issues(samples: Samples) -> list[Issue]:
    """An issue per sample whose t, x or y lies past float32's range, in sample order (at most `MAX_ISSUES`):
    recordings are stored as float32, where such a value would become infinite."""
    found: list[tuple[int, Issue]] = []
    for name in ("t", "x", "y"):
        column = np.asarray(getattr(samples, name), dtype=np.float64)
        with np.errstate(invalid="ignore"):
            too_big = np.flatnonzero(np.isfinite(column) & (np.abs(column) > FLOAT32_MAX))
        message = f"must fit a float32 (|{name}| ≤ {FLOAT32_MAX:.4g}); recordings are stored as float32"
        found += [(int(k), Issue(f"/samples/{k}/{name}", message)) for k in too_big[:MAX_ISSUES]]
    found.sort(key=lambda item: item[0])  # stable: per sample, columns in t, x, y order
    return [issue for _, issue in found[:MAX_ISSUES]]


def json_samples(body: RecordingIn) -> Samples:
    """The sample columns of a JSON body (the instruction column only if some sample has one)."""
    rows = body.samples
    given = any(r.instruction is not None for r in rows)
    return Samples(
        t=[r.t for r in rows],
        x=[r.x for r in rows],
        y=[r.y for r in rows],
        instruction=[r.instruction for r in rows] if given else None,
        format="json",
        units=body.units,
    )


@dataclass(frozen=True)
class CsvColumns:
    """The columns of a CSV upload: numbers by column, the instruction column (if any), each row's line."""

    values: dict[str, Sequence[float]]
    instruction: list[str | None] | None
    lines: list[int]
    units: dict[str, str]
    """The unit the header gives each column that has one (``COPx[cm]``: ``{"x": "cm"}``)."""


def read_columns(data: bytes, *, required: Sequence[str], optional: Sequence[str] = ()) -> CsvColumns:
    """The numeric columns `required` (and those of `optional` present) and the ``instruction`` column of a
    CSV, as typed arrays (never a Python float per cell), header names read with `ALIASES`; 422 naming the
    sample (``/samples/k/column``) and line of every cell that is not a number, and for a time column in a
    unit other than seconds."""
    table = csv_table(data, required=required, optional=(*optional, INSTRUCTION_COLUMN), aliases=ALIASES)
    present, rows = set(table.columns), table.rows
    time_unit = table.units.get("t")
    if time_unit is not None and time_unit.lower() not in SECONDS:
        read = table.header.described()
        raise csv_error(
            [("/file", f"CSV line 1: the time column is in {time_unit!r}; give t in seconds ({read})")]
        )
    values: dict[str, array[float]] = {c: array("d") for c in (*required, *optional) if c in present}
    instruction: list[str | None] = []
    labels: dict[str, str] = {}  # one string object per distinct instruction, however many rows name it
    lines: list[int] = []  # a list: `force_plates` takes it as one
    errors: list[tuple[str, str]] = []
    for line, cells in rows:
        k = len(lines)
        for c, column in values.items():
            try:
                column.append(float(cells[c]))
            except ValueError:
                column.append(float("nan"))
                errors.append((f"/samples/{k}/{c}", f"{c} {cells[c]!r} is not a number (CSV line {line})"))
        label = cells.get(INSTRUCTION_COLUMN) or None
        instruction.append(None if label is None else labels.setdefault(label, label))
        lines.append(line)
        if len(errors) >= MAX_ERRORS:
            break
    if errors:
        raise csv_error(errors)
    return CsvColumns(
        dict(values), instruction if INSTRUCTION_COLUMN in present else None, lines, table.units
    )


def csv_samples(data: bytes, units: str | None = None) -> Samples:
    """Parse a CSV with header ``t,x,y`` (or their `ALIASES`) and optionally ``instruction``; 422 naming
    sample and line. The length unit is `units`, else the one the header gives x and y (`cop_units`)."""
    columns = read_columns(data, required=REQUIRED_COLUMNS)
    return Samples(
        t=columns.values["t"],
        x=columns.values["x"],
        y=columns.values["y"],
        instruction=columns.instruction,
        format="csv",
        lines=columns.lines,
        units=cop_units(columns.units, units),
    )


def _same_unit(a: str, b: str) -> bool:
    """Whether two unit strings mean one unit (`length_unit` spellings: ``cm``, ``centimetres``; else any case)."""
    return (length_unit(a) or a.strip().lower()) == (length_unit(b) or b.strip().lower())


def cop_units(declared: dict[str, str], given: str | None) -> str | None:
    """The length unit of a COP CSV: `given` (the request's `units`), else the one its header gives x and y
    (``COPx[cm]``); 422 at /file if x and y declare different ones, at /units if `given` contradicts them."""
    found = {declared[c] for c in ("x", "y") if c in declared}
    if len(found) > 1 and not _same_unit(*found):
        message = f"CSV line 1: x is in {declared['x']!r} but y in {declared['y']!r}; give both in one unit"
        raise csv_error([("/file", message)])
    if not found:
        return given
    header = found.pop()
    if given is None:
        return length_unit(header) or header
    if not _same_unit(given, header):
        message = (
            f"is {given!r} but the CSV header gives x and y in {header!r}; send that unit or leave units out"
        )
        raise Unprocessable(
            f"The recording is invalid. /units: {message}", errors=[{"pointer": "/units", "message": message}]
        )
    return given


def form_options(form: FormData) -> FileOptions:
    """The options of a file upload from its form fields (``bounds``, ``grid``, ``discretise``, ``segment``,
    ``plate``, ``metadata`` as JSON objects; ``mdp_id``, ``name``, ``protocol``, ``units`` as text); 422 with pointers as for a JSON body."""
    raw: dict[str, Any] = {}
    for key, value in form.items():
        if not isinstance(value, str):
            continue
        if key not in OBJECT_FIELDS:
            raw[key] = value
            continue
        raw[key] = parse_json(value, pointer=f"/{key}", what=f"The form field {key}")
        nul = nul_pointer(raw[key], f"/{key}")
        if nul is not None:
            raise nul_refused(nul)
    try:
        return FileOptions.model_validate(raw)
    except ValidationError as exc:
        raise validation_errors(exc.errors(include_url=False), raw) from exc
