"""Keyset pagination, the one paginator of every list: rows after a cursor, ordered by a unique key.

Lists of resources go newest first by ``(created_at, id)``; a job's event log oldest first by ``id``. The
cursor is opaque to clients: the key of the last row sent, as base64 JSON.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Generic, TypeVar

from sqlalchemy import ColumnElement, Select, and_, or_
from sqlalchemy.orm import InstrumentedAttribute, Session

from service.problems import Unprocessable

Row = TypeVar("Row")
DEFAULT_LIMIT = 20
MAX_LIMIT = 100


@dataclass(frozen=True)
class PageParams:
    """The `?limit=` and `?cursor=` query parameters of every list."""

    limit: int = DEFAULT_LIMIT
    cursor: str | None = None


@dataclass(frozen=True)
class RowPage(Generic[Row]):
    """One page of rows and the cursor of the next page (None on the last page)."""

    rows: list[Row]
    has_more: bool
    next_cursor: str | None


def encode_cursor(values: Sequence[Any]) -> str:
    """An opaque cursor pointing just after the row whose key is ``values``."""
    raw = json.dumps([{"at": v.isoformat()} if isinstance(v, datetime) else v for v in values]).encode()
    return base64.urlsafe_b64encode(raw).decode().rstrip("=")


def decode_cursor(cursor: str, key: Sequence[InstrumentedAttribute[Any]]) -> list[Any]:
    """The key values inside a cursor, each of its column's type; 422 if it was not made by `encode_cursor`
    for this list (a cursor is opaque, but a client can still send any base64 JSON)."""
    try:
        raw = json.loads(base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4)))
        if not isinstance(raw, list) or len(raw) != len(key):
            raise ValueError("wrong number of keys")
        return [_key_value(v, column.type.python_type) for v, column in zip(raw, key, strict=True)]
    except (ValueError, TypeError, KeyError) as exc:
        raise Unprocessable(
            "The cursor is not valid; pass next_cursor from a previous page unchanged.",
            errors=[{"pointer": "", "parameter": "cursor", "message": "is not a cursor of this list"}],
        ) from exc


def _key_value(value: Any, kind: type) -> Any:
    """A cursor's value for a key column of Python type `kind`: a timestamp as ``{"at": iso}``, an integer
    within 64 bits, a string; TypeError or ValueError for anything else."""
    if kind is datetime:
        return datetime.fromisoformat(value["at"])  # TypeError unless a {"at": str}
    if kind is int and (type(value) is not int or not -(2**63) <= value < 2**63):
        raise ValueError("not a 64-bit integer")
    if not isinstance(value, kind):
        raise TypeError(f"not a {kind.__name__}")
    return value


def paginate(
    session: Session,
    query: Select[Any],
    params: PageParams,
    *,
    key: Sequence[InstrumentedAttribute[Any]],
    newest_first: bool = True,
) -> RowPage[Any]:
    """Run `query` (already filtered to the lab) one page at a time, ordered by the unique `key` columns:
    descending when `newest_first`, else ascending."""
    if params.cursor is not None:
        query = query.where(_after(key, decode_cursor(params.cursor, key), newest_first))
    order = [c.desc() if newest_first else c.asc() for c in key]
    rows: Sequence[Any] = session.execute(query.order_by(*order).limit(params.limit + 1)).scalars().all()
    has_more = len(rows) > params.limit
    rows = rows[: params.limit]
    cursor = encode_cursor([getattr(rows[-1], c.key) for c in key]) if has_more else None
    return RowPage(rows=list(rows), has_more=has_more, next_cursor=cursor)


def _after(
    key: Sequence[InstrumentedAttribute[Any]], values: Sequence[Any], newest_first: bool
) -> ColumnElement[bool]:
    """Rows strictly after ``values`` in the order: lexicographic on the key columns."""
    first, rest = key[0], key[1:]
    beyond = first < values[0] if newest_first else first > values[0]
    if not rest:
        return beyond
    return or_(beyond, and_(first == values[0], _after(rest, values[1:], newest_first)))
