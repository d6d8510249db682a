"""Loading a lab's own rows: anything of another lab is reported as not found (never 403)."""

from __future__ import annotations

from typing import Any, TypeVar

from sqlalchemy.orm import Session

from service.problems import NotFound

Row = TypeVar("Row")


def get_owned(session: Session, model: type[Row], row_id: str, *, lab_id: str, what: str) -> Row:
    """The row `row_id` of `model` if it belongs to lab `lab_id`; else 404 naming `what` it is."""
    row: Any = session.get(model, row_id)
    if row is None or row.lab_id != lab_id:
        raise not_found(what, row_id)
    result: Row = row
    return result


def not_found(what: str, row_id: str) -> NotFound:
    """The 404 problem for a `what` (``job``, ``reward``, …) the caller's lab has no `row_id` of."""
    return NotFound(f"No {what} with id {row_id!r}.")
