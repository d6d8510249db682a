"""Demonstrations uploaded as CSV with columns ``trajectory,step,state,action`` (docs/api.md, "Demonstrations"),
and stored ones written back in the same columns (`to_csv`).

Rows are grouped by `trajectory` (in order of first appearance) and sorted by `step`; the last row of a
trajectory may leave `action` empty to give the final state. Errors name the trajectory, the step and the
CSV line.
"""

from __future__ import annotations

import csv
import io
import re
from array import array
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from metairl_engine import InvalidInput, Trajectory
from service.files.csv_rows import MAX_ERRORS, check_csv_memory, csv_error, csv_rows
from service.problems import Unprocessable
from service.settings import Settings

COLUMNS = ("trajectory", "step", "state", "action")
POINTER = re.compile(r"^/trajectories/(\d+)(?:/(states|actions)(?:/(\d+))?)?")
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
NO_ACTION = INT32_MIN - 1
"""An empty action cell (the final state) in the action column."""
ROW_BYTES = 160
"""Peak memory per CSV row: five int64 columns, their sorted copies and the trajectories' arrays."""


@dataclass
class CsvDemonstrations:
    """Parsed trajectories plus where each came from: labels, and the CSV line of every row in trajectory
    order (trajectory `j` step `t` is ``lines[starts[j] + t]``)."""

    trajectories: list[Trajectory]
    labels: list[str]
    lines: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    starts: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))

    def line(self, j: int, step: int) -> int | None:
        """The CSV line of trajectory `j`'s step `step`, if there is one."""
        if j >= len(self.labels) or not 0 <= step < self.starts[j + 1] - self.starts[j]:
            return None
        return int(self.lines[self.starts[j] + step])

    def locate(self, error: InvalidInput) -> Unprocessable:
        """The engine's issues with the CSV line (and trajectory label) added to each message."""
        items = []
        for issue in error.issues:
            message = issue.message
            match = POINTER.match(issue.pointer)
            if match:
                j = int(match.group(1))
                step = int(match.group(3)) if match.group(3) else 0
                line = self.line(j, step)
                where = f"trajectory {self.labels[j]!r}" + (f", CSV line {line}" if line else "")
                message = f"{message} ({where})"
            items.append({"pointer": issue.pointer, "message": message})
        return Unprocessable(
            f"The demonstrations are invalid. {items[0]['pointer']}: {items[0]['message']}", errors=items
        )


def parse_csv(data: bytes, settings: Settings) -> CsvDemonstrations:
    """Parse an uploaded CSV into trajectories; 422 naming the line of every malformed row, and before
    reading if its rows would not fit the per-request memory budget. Rows are kept as typed columns
    (`ROW_BYTES` each at the peak), never as a Python object per row."""
    check_csv_memory(data, row_bytes=ROW_BYTES, settings=settings)
    _, rows = csv_rows(data, required=COLUMNS)
    labels: dict[str, int] = {}
    columns = {name: array("q") for name in ("trajectory", "step", "state", "action", "line")}
    errors: list[tuple[str, str]] = []
    for line, cells in rows:
        parsed = {c: _int_or_none(cells[c]) for c in ("step", "state", "action")}
        bad = [c for c in ("step", "state") if parsed[c] is None] + (
            ["action"] if cells["action"] and parsed["action"] is None else []
        )
        if bad or not cells["trajectory"]:
            what = ", ".join(f"{c} {cells[c]!r}" for c in bad) or "an empty trajectory"
            errors.append(
                ("", f"CSV line {line}: {what} (step and state must be integers, action an integer or empty)")
            )
            if len(errors) >= MAX_ERRORS:
                break
            continue
        action = parsed["action"]
        columns["trajectory"].append(labels.setdefault(cells["trajectory"], len(labels)))
        columns["step"].append(parsed["step"] or 0)
        columns["state"].append(parsed["state"] or 0)
        columns["action"].append(NO_ACTION if action is None else action)
        columns["line"].append(line)
    if errors:
        raise csv_error(errors)
    if not labels:
        raise csv_error([("/trajectories", "the CSV has no data rows")])
    arrays = {name: np.frombuffer(column, dtype=np.int64) for name, column in columns.items()}
    return _assemble(list(labels), arrays)


def to_csv(
    trajectories: Iterable[tuple[str, Sequence[int] | np.ndarray, Sequence[int] | np.ndarray]],
) -> bytes:
    """The CSV `parse_csv` reads back: the header `COLUMNS`, then a row per state of each (label, states,
    actions), the final state's action left empty (a trajectory without one has an action on every row)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    for label, states, actions in trajectories:
        acts = np.asarray(actions).tolist()
        writer.writerows(
            [label, step, state, acts[step] if step < len(acts) else ""]
            for step, state in enumerate(np.asarray(states).tolist())
        )
    return buffer.getvalue().encode()


def _assemble(labels: list[str], columns: dict[str, np.ndarray]) -> CsvDemonstrations:
    """Order each trajectory's rows by step and check steps are 0, 1, 2, … with actions on all but the last."""
    order = np.lexsort((columns["step"], columns["trajectory"]))
    trajectory, step = columns["trajectory"][order], columns["step"][order]
    state, action, lines = columns["state"][order], columns["action"][order], columns["line"][order]
    starts = np.searchsorted(trajectory, np.arange(len(labels) + 1))
    out = CsvDemonstrations(trajectories=[], labels=[], lines=lines, starts=starts)
    errors: list[tuple[str, str]] = []
    for j, label in enumerate(labels):
        lo, hi = int(starts[j]), int(starts[j + 1])
        steps = step[lo:hi]
        wrong = np.flatnonzero(steps != np.arange(hi - lo))
        if len(wrong):
            first_bad = int(wrong[0])
            errors.append(
                (
                    f"/trajectories/{j}",
                    f"trajectory {label!r}: steps must be 0, 1, 2, … without gaps or repeats; "
                    f"expected step {first_bad}, found {steps[first_bad]} (CSV line {lines[lo + first_bad]})",
                )
            )
            continue
        acts = action[lo:hi]
        for t in np.flatnonzero(acts[:-1] == NO_ACTION)[:MAX_ERRORS]:
            errors.append(
                (
                    f"/trajectories/{j}/actions/{t}",
                    f"trajectory {label!r} step {t}: action is empty "
                    f"but only the final state may omit it (CSV line {lines[lo + t]})",
                )
            )
        out.labels.append(label)
        out.trajectories.append(Trajectory.of(state[lo:hi], acts[acts != NO_ACTION]))
        if len(errors) >= MAX_ERRORS:
            break
    if errors:
        raise csv_error(errors)
    return out


def _int_or_none(cell: str) -> int | None:
    """The integer in a CSV cell, or None if it is empty, not an integer or outside the int32 range."""
    try:
        value = int(cell)
    except ValueError:
        return None
    return value if INT32_MIN <= value <= INT32_MAX else None
