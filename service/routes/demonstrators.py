"""`/v1/demonstrators`: the people, robots or sessions whose shared baseline reward is learned."""

from __future__ import annotations

from fastapi import APIRouter, Response

from service.auth import LabDep
from service.crud import demonstrators as crud
from service.deps import SessionDep
from service.openapi import PROBLEM_RESPONSES
from service.pagination import Page, PageDep
from service.schemas.demonstrators import DemonstratorIn, DemonstratorOut

router = APIRouter(tags=["demonstrators"], responses=PROBLEM_RESPONSES)


@router.post("/demonstrators", status_code=201, summary="Create a demonstrator")
def create_demonstrator(
    body: DemonstratorIn, response: Response, lab: LabDep, session: SessionDep
) -> DemonstratorOut:
    """A demonstrator groups tasks whose rewards share one baseline."""
    created = crud.create_demonstrator(session, lab_id=lab.id, name=body.name, metadata=body.metadata)
    response.headers["Location"] = f"/v1/demonstrators/{created.id}"
    return created


@router.get("/demonstrators", summary="List demonstrators")
def list_demonstrators(lab: LabDep, session: SessionDep, page: PageDep) -> Page[DemonstratorOut]:
    """Your lab's demonstrators, newest first."""
    return crud.list_demonstrators(session, lab_id=lab.id, page=page)


@router.get("/demonstrators/{demonstrator_id}", summary="Get a demonstrator")
def get_demonstrator(demonstrator_id: str, lab: LabDep, session: SessionDep) -> DemonstratorOut:
    """One demonstrator of your lab."""
    return DemonstratorOut.model_validate(crud.get_demonstrator(session, demonstrator_id, lab_id=lab.id))
