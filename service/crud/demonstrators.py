"""Demonstrators of a lab."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from service.crud.owned import get_owned
from service.ids import new_id
from service.models.demonstrators import Demonstrator
from service.pagination import Page, PageParams, paginate
from service.schemas.demonstrators import DemonstratorOut


def create_demonstrator(
    session: Session, *, lab_id: str, name: str, metadata: dict[str, Any] | None
) -> DemonstratorOut:
    """Add a demonstrator and commit."""
    row = Demonstrator(id=new_id("dem"), lab_id=lab_id, name=name, meta=metadata)
    session.add(row)
    session.commit()
    return DemonstratorOut.model_validate(row)


def get_demonstrator(session: Session, demonstrator_id: str, *, lab_id: str) -> Demonstrator:
    """The lab's demonstrator, or 404."""
    return get_owned(session, Demonstrator, demonstrator_id, lab_id=lab_id, what="demonstrator")


def list_demonstrators(session: Session, *, lab_id: str, page: PageParams) -> Page[DemonstratorOut]:
    """One page of the lab's demonstrators, newest first."""
    query = select(Demonstrator).where(Demonstrator.lab_id == lab_id)
    return paginate(session, query, Demonstrator, page, DemonstratorOut.model_validate)
