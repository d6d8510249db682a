"""Demonstrations uploaded as CSV with columns ``trajectory,step,state,action`` (docs/api.md, "Demonstrations").

Rows are grouped by `trajectory` (in order of first appearance) and sorted by `step`; the last row of a
trajectory may leave `action` empty to give the final state. Errors name the trajectory, the step and the
CSV line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from metairl_engine import InvalidInput, Trajectory
from service.files.csv_rows import MAX_ERRORS, csv_error, csv_rows
from service.problems import Unprocessable

COLUMNS = ("trajectory", "step", "state", "action")
POINTER = re.compile(r"^/trajectories/(\d+)(?:/(states|actions)(?:/(\d+))?)?")
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1


@dataclass
class CsvDemonstrations:
    """Parsed trajectories plus where each came from: labels and the CSV line of every (trajectory, step)."""

    trajectories: list[Trajectory]
    labels: list[str]
    lines: dict[tuple[int, int], int] = field(default_factory=dict)

    def locate(self, error: InvalidInput) -> Unprocessable:
        """The engine's issues with the CSV line (and trajectory label) added to each message."""
        items = []
        for issue in error.issues:
            message = issue.message
            match = POINTER.match(issue.pointer)
            if match:
                j = int(match.group(1))
                step = int(match.group(3)) if match.group(3) else 0
                line = self.lines.get((j, step))
                where = f"trajectory {self.labels[j]!r}" + (f", CSV line {line}" if line else "")
                message = f"{message} ({where})"
            items.append({"pointer": issue.pointer, "message": message})
        return Unprocessable(
            f"The demonstrations are invalid. {items[0]['pointer']}: {items[0]['message']}", errors=items
        )


def parse_csv(data: bytes) -> CsvDemonstrations:
    """Parse an uploaded CSV into trajectories; 422 naming the line of every malformed row."""
    _, rows = csv_rows(data, required=COLUMNS)
    groups: dict[str, list[tuple[int, int, int | None, int]]] = {}
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
        step, state = parsed["step"], parsed["state"]
        assert step is not None and state is not None
        groups.setdefault(cells["trajectory"], []).append((step, state, parsed["action"], line))
    if errors:
        raise csv_error(errors)
    if not groups:
        raise csv_error([("/trajectories", "the CSV has no data rows")])
    return _assemble(groups)


def _assemble(groups: dict[str, list[tuple[int, int, int | None, int]]]) -> CsvDemonstrations:
    """Order each trajectory's rows by step and check steps are 0, 1, 2, … with actions on all but the last."""
    out = CsvDemonstrations(trajectories=[], labels=[])
    errors: list[tuple[str, str]] = []
    for j, (label, rows) in enumerate(groups.items()):
        rows.sort()
        steps = [r[0] for r in rows]
        if steps != list(range(len(rows))):
            first_bad = next(k for k, s in enumerate(steps) if s != k)
            errors.append(
                (
                    f"/trajectories/{j}",
                    f"trajectory {label!r}: steps must be 0, 1, 2, … without gaps or repeats; "
                    f"expected step {first_bad}, found {steps[first_bad]} (CSV line {rows[first_bad][3]})",
                )
            )
            continue
        for t, (_step, _state, action, line) in enumerate(rows[:-1]):
            if action is None:
                errors.append(
                    (
                        f"/trajectories/{j}/actions/{t}",
                        f"trajectory {label!r} step {t}: action is empty "
                        f"but only the final state may omit it (CSV line {line})",
                    )
                )
        out.labels.append(label)
        out.lines |= {(j, t): r[3] for t, r in enumerate(rows)}
        actions = [r[2] for r in rows if r[2] is not None]
        out.trajectories.append(Trajectory.of([r[1] for r in rows], actions))
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
