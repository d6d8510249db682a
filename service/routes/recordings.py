"""`/v1/demonstrators/{demonstrator_id}/recordings`: upload a centre-of-pressure recording (JSON or CSV) that
becomes per-direction tasks and demonstrations; list a demonstrator's recordings (docs/motion.md)."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response
from pydantic import TypeAdapter
from starlette.concurrency import run_in_threadpool

from service import recordings as logic
from service.auth import LabDep
from service.crud.demonstrators import get_demonstrator
from service.deps import SessionDep
from service.openapi import PROBLEM_RESPONSES, request_body
from service.pagination import Page, PageDep
from service.routes.bodies import form_body, json_body, media_type, unsupported
from service.schemas.recordings import EXAMPLE_GRID_IN, EXAMPLE_IN, RecordingIn, RecordingOut

router = APIRouter(
    tags=["demonstrations"],
    responses=PROBLEM_RESPONSES
    | {409: {"description": "A task of a segment's label exists on another MDP (problem+json)."}},
)
RECORDING_IN = TypeAdapter(RecordingIn)
JSON_OBJECT = "A JSON object, as in the JSON body."
CSV_FORM = {
    "type": "object",
    "required": ["file", "bounds"],
    "properties": {
        "file": {
            "type": "string",
            "format": "binary",
            "description": "CSV with header t,x,y and optionally instruction; one row per sample, in time order.",
        },
        "bounds": {"type": "string", "description": f"{JSON_OBJECT} x_min, x_max, y_min, y_max."},
        "mdp_id": {"type": "string", "description": "A velocity-grid MDP of your lab (or give grid)."},
        "grid": {"type": "string", "description": f"{JSON_OBJECT} width, height, gamma."},
        "discretise": {"type": "string", "description": f"{JSON_OBJECT} smooth_s."},
        "segment": {"type": "string", "description": f"{JSON_OBJECT} the segment settings."},
        "name": {"type": "string"},
    },
}


@router.post(
    "/demonstrators/{demonstrator_id}/recordings",
    status_code=201,
    summary="Upload a centre-of-pressure recording",
    description="Samples (t, x, y, optional instruction) on a force plate of the given bounds are mapped onto a "
    "velocity-grid MDP (`mdp_id`, or `grid` to reuse or create one), cut into out-and-back movements at peaks "
    "of the distance from the origin and labelled by instruction (or nearest direction). Each label becomes "
    "or joins the demonstrator's task of that name and receives its segments as one demonstration batch. "
    "Send JSON, or the CSV as multipart/form-data with the other fields as form fields. All or nothing: an "
    "invalid recording (errors name the sample, e.g. `/samples/17/t`, and the CSV line) stores nothing.",
    openapi_extra=request_body(
        RecordingIn,
        json_examples={
            "existing MDP": {"summary": "Onto a velocity grid of your lab", "value": EXAMPLE_IN},
            "grid": {"summary": "Reuse or create a 100×100 velocity grid", "value": EXAMPLE_GRID_IN},
        },
        multipart=CSV_FORM,
    ),
)
async def upload_recording(
    demonstrator_id: str, request: Request, response: Response, lab: LabDep, session: SessionDep
) -> RecordingOut:
    """Parse the body, then validate, cut and store it in one transaction."""
    demonstrator = await run_in_threadpool(get_demonstrator, session, demonstrator_id, lab_id=lab.id)
    kind = media_type(request)
    if kind == "multipart/form-data":
        form, upload = await form_body(request)
        options = logic.form_options(form)
        samples = logic.csv_samples(await upload.read())
    elif kind == "application/json":
        body = await json_body(request, RECORDING_IN)
        options, samples = body, logic.json_samples(body)
    else:
        raise unsupported(request, accepted="application/json or multipart/form-data (CSV)")
    created = await run_in_threadpool(logic.add_recording, session, demonstrator, options, samples)
    response.headers["Location"] = f"/v1/demonstrators/{demonstrator.id}/recordings"
    return created


@router.get("/demonstrators/{demonstrator_id}/recordings", summary="List a demonstrator's recordings")
def list_recordings(
    demonstrator_id: str, lab: LabDep, session: SessionDep, page: PageDep
) -> Page[RecordingOut]:
    """Recordings, newest first, each with its segments per label and the tasks they went to."""
    return logic.list_recordings(
        session, get_demonstrator(session, demonstrator_id, lab_id=lab.id), page=page
    )
