"""Lists as the API returns them: ``{"data", "has_more", "next_cursor"}``, and the paging query parameters."""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any, Generic, TypeVar

from fastapi import Depends, Query
from pydantic import BaseModel, Field

from service.store.paging import DEFAULT_LIMIT, MAX_LIMIT, PageParams, RowPage

T = TypeVar("T")


class Page(BaseModel, Generic[T]):
    """One page of a list; pass `next_cursor` as `?cursor=` for the next page."""

    data: list[T]
    has_more: bool = Field(description="Whether more items follow this page.")
    next_cursor: str | None = Field(description="Opaque cursor of the next page, or null on the last page.")

    @classmethod
    def of(cls, page: RowPage[Any], of: Callable[[Any], T]) -> Page[T]:
        """The response page of a page of rows, each turned into a response by ``of`` (an ``XOut.of``)."""
        return cls(data=[of(r) for r in page.rows], has_more=page.has_more, next_cursor=page.next_cursor)


def page_params(
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT, description="Items per page.")] = DEFAULT_LIMIT,
    cursor: Annotated[
        str | None, Query(description="`next_cursor` of the previous page; empty or absent: the first page.")
    ] = None,
) -> PageParams:
    """Read the paging query parameters (an empty ``?cursor=`` is the first page, as if absent)."""
    return PageParams(limit=limit, cursor=cursor or None)


PageDep = Annotated[PageParams, Depends(page_params)]
