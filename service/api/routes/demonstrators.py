"""`/v1/demonstrators`: the people, robots or sessions whose shared baseline reward is learned."""

from __future__ import annotations

from fastapi import APIRouter, Response, status

from service.api.auth import LabDep
from service.api.deps import SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.pagination import Page, PageDep
from service.api.responses import DELETED
from service.domain.demonstrators import DemonstratorIn, DemonstratorOut
from service.store import demonstrators
from service.store.deletion import commit_deletion
from service.store.deletion import delete_demonstrator as delete_demonstrator_rows

router = APIRouter(tags=["demonstrators"], responses=PROBLEM_RESPONSES)


@router.post("/demonstrators", status_code=201, summary="Create a demonstrator")
def create_demonstrator(
    body: DemonstratorIn, response: Response, lab: LabDep, session: SessionDep
) -> DemonstratorOut:
    """A demonstrator groups tasks whose rewards share one baseline."""
    row = demonstrators.create_demonstrator(session, lab_id=lab.id, name=body.name, metadata=body.metadata)
    session.commit()
    response.headers["Location"] = f"/v1/demonstrators/{row.id}"
    return DemonstratorOut.of(row)


@router.get("/demonstrators", summary="List demonstrators")
def list_demonstrators(lab: LabDep, session: SessionDep, page: PageDep) -> Page[DemonstratorOut]:
    """Your lab's demonstrators, newest first."""
    rows = demonstrators.list_demonstrators(session, lab_id=lab.id, page=page)
    return Page[DemonstratorOut].of(rows, DemonstratorOut.of)


@router.get("/demonstrators/{demonstrator_id}", summary="Get a demonstrator")
def get_demonstrator(demonstrator_id: str, lab: LabDep, session: SessionDep) -> DemonstratorOut:
    """One demonstrator of your lab."""
    return DemonstratorOut.of(demonstrators.get_demonstrator(session, demonstrator_id, lab_id=lab.id))


@router.delete(
    "/demonstrators/{demonstrator_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    summary="Delete a demonstrator and everything derived from it",
    responses=DELETED,
)
def delete_demonstrator(demonstrator_id: str, lab: LabDep, session: SessionDep) -> Response:
    """Removes the demonstrator, its tasks, demonstrations, true rewards, recordings, jobs, job events and
    learned rewards, with their stored arrays (e.g. when a patient withdraws consent); 409 while one of
    its jobs is queued or running (cancel it first)."""
    delete_demonstrator_rows(session, demonstrators.get_demonstrator(session, demonstrator_id, lab_id=lab.id))
    commit_deletion(session)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
