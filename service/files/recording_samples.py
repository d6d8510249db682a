"""Recording samples as uploaded: JSON rows or a CSV with columns ``t,x,y[,instruction]``, and a file upload's
other fields; every problem a 422 naming the sample (and its CSV line). Force-plate files: `force_plates`."""

from __future__ import annotations

import re
from array import array
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError
from starlette.datastructures import FormData

from metairl_engine import InvalidInput
from service.domain.common import UploadFormat
from service.domain.recordings import FileOptions, RecordingIn
from service.files.csv_rows import MAX_ERRORS, csv_error, csv_rows
from service.json_input import nul_pointer, nul_refused, parse_json
from service.problems import Unprocessable, validation_errors

REQUIRED_COLUMNS = ("t", "x", "y")
INSTRUCTION_COLUMN = "instruction"
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

    def located(self, error: InvalidInput) -> Unprocessable:
        """The engine's issues as a 422, each sample's CSV line added to its message."""
        return located(error, self.lines)


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
    )


@dataclass(frozen=True)
class CsvColumns:
    """The columns of a CSV upload: numbers by column, the instruction column (if any), each row's line."""

    values: dict[str, Sequence[float]]
    instruction: list[str | None] | None
    lines: list[int]


def read_columns(data: bytes, *, required: Sequence[str], optional: Sequence[str] = ()) -> CsvColumns:
    """The numeric columns `required` (and those of `optional` present) and the ``instruction`` column of a
    CSV, as typed arrays (never a Python float per cell); 422 naming the sample (``/samples/k/column``) and
    line of every cell that is not a number."""
    present, rows = csv_rows(data, required=required, optional=(*optional, INSTRUCTION_COLUMN))
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
    return CsvColumns(dict(values), instruction if INSTRUCTION_COLUMN in present else None, lines)


def csv_samples(data: bytes) -> Samples:
    """Parse a CSV with header ``t,x,y`` and optionally ``instruction``; 422 naming sample and line."""
    columns = read_columns(data, required=REQUIRED_COLUMNS)
    return Samples(
        t=columns.values["t"],
        x=columns.values["x"],
        y=columns.values["y"],
        instruction=columns.instruction,
        format="csv",
        lines=columns.lines,
    )


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
