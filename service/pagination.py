"""Keyset pagination over (created_at, id), newest first: ``{"data", "has_more", "next_cursor"}``."""

from __future__ import annotations

import base64
import json
from collections.abc import Callable, Sequence
from datetime import datetime
from typing import Annotated, Any, Generic, TypeVar

from fastapi import Depends, Query
from pydantic import BaseModel, Field
from sqlalchemy import Select, and_, or_
from sqlalchemy.orm import Session

from service.problems import Unprocessable

T = TypeVar("T")
DEFAULT_LIMIT = 20
MAX_LIMIT = 100


class Page(BaseModel, Generic[T]):
    """One page of a list, newest first; pass `next_cursor` as `?cursor=` for the next page."""

    data: list[T]
    has_more: bool = Field(description="Whether more items follow this page.")
    next_cursor: str | None = Field(description="Opaque cursor of the next page, or null on the last page.")


class PageParams(BaseModel):
    """The `?limit=` and `?cursor=` query parameters of every list."""

    limit: int
    cursor: str | None


def page_params(
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT, description="Items per page.")] = DEFAULT_LIMIT,
    cursor: Annotated[str | None, Query(description="`next_cursor` of the previous page.")] = None,
) -> PageParams:
    """Read the paging query parameters."""
    return PageParams(limit=limit, cursor=cursor)


PageDep = Annotated[PageParams, Depends(page_params)]


def encode_cursor(created_at: datetime, row_id: str) -> str:
    """An opaque cursor pointing just after (created_at, id)."""
    raw = json.dumps([created_at.isoformat(), row_id]).encode()
    return base64.urlsafe_b64encode(raw).decode().rstrip("=")


def decode_cursor(cursor: str) -> tuple[datetime, str]:
    """The (created_at, id) inside a cursor; 422 if it was not made by `encode_cursor`."""
    try:
        raw = base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4))
        created, row_id = json.loads(raw)
        return datetime.fromisoformat(created), str(row_id)
    except (ValueError, TypeError) as exc:
        raise Unprocessable(
            "The cursor is not valid; pass next_cursor from a previous page unchanged.",
            errors=[{"pointer": "", "parameter": "cursor", "message": "is not a cursor of this list"}],
        ) from exc


def paginate(
    session: Session, query: Select[Any], model: Any, params: PageParams, render: Callable[[Any], T]
) -> Page[T]:
    """Run `query` (already filtered to the lab) one page at a time, newest first, by (created_at, id)."""
    if params.cursor is not None:
        created, row_id = decode_cursor(params.cursor)
        query = query.where(
            or_(model.created_at < created, and_(model.created_at == created, model.id < row_id))
        )
    rows: Sequence[Any] = (
        session.execute(query.order_by(model.created_at.desc(), model.id.desc()).limit(params.limit + 1))
        .scalars()
        .all()
    )
    has_more = len(rows) > params.limit
    rows = rows[: params.limit]
    cursor = encode_cursor(rows[-1].created_at, rows[-1].id) if has_more else None
    return Page[T](data=[render(r) for r in rows], has_more=has_more, next_cursor=cursor)
