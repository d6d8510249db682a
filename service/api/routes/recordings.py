"""`/v1/demonstrators/{demonstrator_id}/recordings`: upload a centre-of-pressure recording (JSON, a CSV, a C3D or
a CSV of plate forces and moments) that becomes per-direction tasks and demonstrations; list a demonstrator's
recordings (docs/motion.md)."""

from __future__ import annotations

from functools import partial
from pathlib import PureWindowsPath
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request, Response
from pydantic import TypeAdapter
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from metairl_engine.errors import Issue
from service.api.auth import LabDep
from service.api.bodies import Upload, json_or_upload
from service.api.deps import SessionDep, SettingsDep
from service.api.openapi import PROBLEM_RESPONSES, request_body
from service.api.pagination import Page, PageDep
from service.api.responses import file_response
from service.domain.motion import CutTrajectory, RecordingDemonstrationsOut
from service.domain.recordings import (
    EXAMPLE_GRID_IN,
    EXAMPLE_IN,
    NAME_MAX,
    RecordingIn,
    RecordingOptions,
    RecordingOut,
)
from service.files.csv_demonstrations import to_csv
from service.files.csv_rows import check_csv_memory
from service.files.force_plates import file_samples
from service.files.recording_samples import SAMPLE_BYTES, form_options, json_samples
from service.problems import valid_fields
from service.results.downloads import Download
from service.settings import Settings
from service.store import recordings
from service.store.demonstrators import get_demonstrator

router = APIRouter(tags=["demonstrations"], responses=PROBLEM_RESPONSES)
OTHER_MDP: dict[int | str, dict[str, object]] = {
    409: {"description": "A task of a segment's label exists on another MDP (problem+json)."}
}
RECORDING_IN = TypeAdapter(RecordingIn)
JSON_OBJECT = "A JSON object, as in the JSON body."
FILE_FORM = {
    "type": "object",
    "required": ["file"],
    "properties": {
        "file": {
            "type": "string",
            "format": "binary",
            "description": "One of: a CSV with header t,x,y (or time, COPx, COPy; a unit may follow a name, "
            "`COPx[cm]`) and optionally instruction; a C3D file (recognised by its bytes or a .c3d name) with a "
            "force platform; a CSV with header Fx,Fy,Fz,Mx,My,Mz, optionally t (s) and instruction, and no COP "
            "columns. Comma-, tab- or semicolon-separated. One row or frame per sample, in time order.",
        },
        "bounds": {
            "type": "string",
            "description": f"{JSON_OBJECT} x_min, x_max, y_min, y_max (optional for `standing`).",
        },
        "protocol": {"type": "string", "description": "`movements` (default) or `standing`."},
        "metadata": {
            "type": "string",
            "description": f'{JSON_OBJECT} the lab\'s labels, e.g. {{"vision": "closed"}}.',
        },
        "units": {
            "type": "string",
            "description": "The length unit of x and y, e.g. `cm`; a COP CSV's header may give it instead "
            "(`COPx[cm]`). A plate file's must be the file's own or `m` (its COP is stored in metres).",
        },
        "mdp_id": {"type": "string", "description": "A velocity-grid MDP of your lab (or give grid)."},
        "grid": {"type": "string", "description": f"{JSON_OBJECT} width, height, gamma."},
        "discretise": {"type": "string", "description": f"{JSON_OBJECT} smooth_s."},
        "segment": {"type": "string", "description": f"{JSON_OBJECT} the segment settings."},
        "plate": {
            "type": "string",
            "description": f"{JSON_OBJECT} force-plate files only: axes, min_fz, platform and events (C3D), "
            "rate_hz, moment_unit, origin_depth (CSV of forces and moments).",
        },
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
    "Send JSON, or a file as multipart/form-data with the other fields as form fields: a CSV of samples, a C3D "
    "file (its force platform's centre of pressure, read with ezc3d; instructions from its events) or a CSV of "
    "plate forces and moments Fx…Mz (COP = (−My/Fz, Mx/Fz)). A force-plate file's COP is stored in metres about "
    "the plate's centre, in the axes its `plate.axes` declare; unloaded samples (|Fz| < `plate.min_fz`) at the "
    'start and end are cut away (docs/motion.md, "Force-plate files"). All or nothing: an invalid recording '
    "(errors name the sample, e.g. `/samples/17/t`, and the CSV line; `/file` a file without a usable force "
    'platform) stores nothing. With `protocol: "standing"` (a quiet-standing trial) the samples are stored '
    "whole, not cut and not mapped onto an MDP (`bounds` optional, C3D events ignored by default, the longest "
    "loaded stretch of a plate file kept); `GET /v1/recordings/{id}/sway` gives its sway measures.",
    responses=OTHER_MDP,
    openapi_extra=request_body(
        RecordingIn,
        json_examples={
            "existing MDP": {"summary": "Onto a velocity grid of your lab", "value": EXAMPLE_IN},
            "grid": {"summary": "Reuse or create a 100×100 velocity grid", "value": EXAMPLE_GRID_IN},
        },
        multipart=FILE_FORM,
    ),
)
async def upload_recording(
    demonstrator_id: str,
    request: Request,
    response: Response,
    lab: LabDep,
    session: SessionDep,
    settings: SettingsDep,
) -> RecordingOut:
    """Parse the body, then validate, cut and store it in one transaction."""
    demonstrator = await run_in_threadpool(get_demonstrator, session, demonstrator_id, lab_id=lab.id)
    body = await json_or_upload(
        request,
        RECORDING_IN,
        accepted="application/json or multipart/form-data (a CSV or C3D file)",
        later=partial(_refused_issues, session, demonstrator.lab_id, settings),
    )
    options: RecordingOptions
    if isinstance(body, Upload):
        options = form_options(body.form)
        data = await body.file.read()
        check_csv_memory(data, row_bytes=SAMPLE_BYTES, settings=settings)
        samples = await run_in_threadpool(
            file_samples, body.file.filename, data, options.plate, options.protocol, options.units
        )
        if samples.plate is None and samples.units != options.units:  # a COP CSV's header gave the unit
            options = options.model_copy(update={"units": samples.units})
        if options.name is None and body.file.filename:  # a lab names its trials by their files
            options = options.model_copy(update={"name": PureWindowsPath(body.file.filename).name[:NAME_MAX]})
    else:
        options, samples = body, json_samples(body)
    created = await run_in_threadpool(
        recordings.add_recording, session, demonstrator, options, samples, settings
    )
    await run_in_threadpool(session.commit)
    response.headers["Location"] = f"/v1/demonstrators/{demonstrator.id}/recordings"
    return RecordingOut.of(created)


def _refused_issues(session: Session, lab_id: str, settings: Settings, sent: Any) -> list[Issue]:
    """What the upload's checks (`recordings.check_upload`) find in the parts of a JSON recording the schema
    refused that pass it."""
    if not isinstance(sent, dict):
        return []
    options = valid_fields(RecordingIn, sent)
    samples = json_samples(RecordingIn.model_construct(**options)) if "samples" in options else None
    given = {name for name in options if name in sent}
    return recordings.check_upload(session, options, given, samples, lab_id=lab_id, settings=settings)[1]


@router.get("/demonstrators/{demonstrator_id}/recordings", summary="List a demonstrator's recordings")
def list_recordings(
    demonstrator_id: str, lab: LabDep, session: SessionDep, page: PageDep
) -> Page[RecordingOut]:
    """Recordings, newest first, each with its segments per label and the tasks they went to."""
    rows = recordings.list_recordings(
        session, get_demonstrator(session, demonstrator_id, lab_id=lab.id), page=page
    )
    return Page[RecordingOut].of(rows, RecordingOut.of)


@router.get(
    "/recordings/{recording_id}/demonstrations",
    summary="Download the demonstrations a recording was cut into",
    description="Every out-and-back movement the upload stored, as velocity-grid states and actions, label "
    "(task) by label in time order: JSON, or with `?format=csv` the columns `trajectory,step,state,action` "
    "that `POST /v1/tasks/{task_id}/demonstrations` accepts (the final state's row has an empty action). "
    "`?label=` keeps one direction. Segments whose task was deleted since are gone with it.",
    response_model=RecordingDemonstrationsOut,
    responses={
        200: {"description": "JSON, or with `?format=csv` a CSV file.", "content": {"text/csv": {}}},
        404: {"description": "No such recording in your lab (problem+json)."},
    },
)
def recording_demonstrations(
    recording_id: str,
    lab: LabDep,
    session: SessionDep,
    format: Annotated[Literal["json", "csv"], Query(description="`json` (default) or `csv`.")] = "json",
    label: Annotated[
        str | None, Query(description="Only this label (direction), e.g. `forward left`.")
    ] = None,
) -> RecordingDemonstrationsOut | Response:
    """The recording's segments as trajectories (JSON) or CSV rows."""
    row = recordings.get_recording(session, recording_id, lab_id=lab.id)
    segments = [
        s for s in recordings.recording_demonstrations(session, row) if label is None or s.label == label
    ]
    out = RecordingDemonstrationsOut(
        recording_id=row.id,
        mdp_id=row.mdp_id,
        trajectories=[
            CutTrajectory(
                trajectory=f"{s.label}/{s.index}",
                label=s.label,
                task_id=s.task_id,
                demonstration_id=s.demonstration_id,
                states=s.trajectory.states.tolist(),
                actions=s.trajectory.actions.tolist(),
            )
            for s in segments
        ],
    )
    if format == "json":
        return out
    return file_response(
        Download(
            content=to_csv((t.trajectory, t.states, t.actions) for t in out.trajectories),
            media_type="text/csv",
            filename=f"{row.id}-demonstrations.csv",
            disposition="attachment",
            etag=None,
        )
    )
