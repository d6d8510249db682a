"""Demonstrators of a lab."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from service.store.ids import new_id
from service.store.models.demonstrators import Demonstrator
from service.store.owned import get_owned
from service.store.paging import PageParams, RowPage, paginate


def create_demonstrator(
    session: Session, *, lab_id: str, name: str, metadata: dict[str, Any] | None
) -> Demonstrator:
    """Add a demonstrator (flushed, not committed)."""
    row = Demonstrator(id=new_id("dem"), lab_id=lab_id, name=name, meta=metadata)
    session.add(row)
    session.flush()
    return row


def get_demonstrator(session: Session, demonstrator_id: str, *, lab_id: str) -> Demonstrator:
    """The lab's demonstrator, or 404."""
    return get_owned(session, Demonstrator, demonstrator_id, lab_id=lab_id, what="demonstrator")


def list_demonstrators(session: Session, *, lab_id: str, page: PageParams) -> RowPage[Demonstrator]:
    """One page of the lab's demonstrators, newest first."""
    query = select(Demonstrator).where(Demonstrator.lab_id == lab_id)
    return paginate(session, query, page, key=(Demonstrator.created_at, Demonstrator.id))
