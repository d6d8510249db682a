"""`/v1/mdps`: create an MDP (explicit JSON, grid, or `.npz` upload), read its metadata, download its arrays."""

from __future__ import annotations

from functools import partial
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request, Response, status
from pydantic import TypeAdapter
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import FormData, UploadFile

from metairl_engine import MDP, Layout
from metairl_engine.errors import Issue, check
from service.api.auth import LabDep
from service.api.bodies import Upload, json_or_upload
from service.api.deps import SessionDep, SettingsDep
from service.api.openapi import PROBLEM_RESPONSES, request_body
from service.api.pagination import Page, PageDep
from service.api.responses import DELETED
from service.domain.mdps import (
    EXPLICIT_EXAMPLE,
    GRID_EXAMPLE,
    SPARSE_EXAMPLE,
    ExplicitMdpIn,
    GridMdpIn,
    MdpIn,
    MdpOut,
)
from service.files.npz import npz_headers, read_npz, write_npz
from service.problems import Unprocessable, gathering, valid_fields
from service.settings import Settings
from service.sizes import first_too_large, grid_issues, mdp_size_issues
from service.store import mdps
from service.store.deletion import commit_deletion
from service.store.deletion import delete_mdp as delete_mdp_rows
from service.store.loaders import load_mdp

router = APIRouter(tags=["mdps"], responses=PROBLEM_RESPONSES)
MDP_IN: TypeAdapter[ExplicitMdpIn | GridMdpIn] = TypeAdapter(MdpIn)
CHECKED: dict[str, tuple[type[ExplicitMdpIn] | type[GridMdpIn], tuple[str, ...]]] = {
    "explicit": (ExplicitMdpIn, ("n_states", "n_actions", "transitions")),
    "grid": (GridMdpIn, ("width", "height", "moves", "stay", "slip", "velocity")),
}
"""Each JSON kind's model and the fields its checks after the schema (`_json_mdp`) read besides `gamma`."""
STAND_IN_GAMMA = 0.0
"""The discount those checks are given in place of a `gamma` the schema refused: none of the others reads it."""
NPZ_ARRAYS = ("features", "next_state", "s", "a", "next", "p")
NPZ_FORM = {
    "type": "object",
    "required": ["file", "name", "gamma"],
    "properties": {
        "file": {
            "type": "string",
            "format": "binary",
            "description": f"mdp.npz with arrays {', '.join(NPZ_ARRAYS)}",
        },
        "name": {"type": "string"},
        "gamma": {"type": "number"},
        "n_states": {"type": "integer"},
        "n_actions": {"type": "integer"},
        "width": {"type": "integer", "description": "Layout width (with height)."},
        "height": {"type": "integer"},
        "channels": {"type": "integer", "default": 1},
    },
}


@router.post(
    "/mdps",
    status_code=201,
    summary="Create an MDP",
    description="Send an explicit MDP or a grid as JSON, or upload `mdp.npz` as multipart/form-data. "
    "Every array is validated (shapes, index ranges, probabilities summing to 1 per (s, a)).",
    openapi_extra=request_body(
        MdpIn,
        json_examples={
            "deterministic": {"summary": "Deterministic, tabular features", "value": EXPLICIT_EXAMPLE},
            "sparse": {"summary": "Stochastic, with features", "value": SPARSE_EXAMPLE},
            "grid": {"summary": "The paper's 100×100 velocity grid", "value": GRID_EXAMPLE},
        },
        multipart=NPZ_FORM,
    ),
)
async def create_mdp(
    request: Request, response: Response, lab: LabDep, session: SessionDep, settings: SettingsDep
) -> MdpOut:
    """Validate with the engine and store; the arrays are then downloadable from `/v1/mdps/{id}/arrays`.

    Size limits (`METAIRL_MAX_STATE_ACTIONS`, `METAIRL_MAX_FEATURES`, `METAIRL_MAX_ARRAY_ELEMENTS`) are a 422
    naming the setting; an `.npz` is checked from its members' headers before any array is read."""
    body = await json_or_upload(
        request,
        MDP_IN,
        accepted="application/json or multipart/form-data",
        later=partial(_refused_issues, settings),
    )
    if isinstance(body, Upload):
        mdp = await run_in_threadpool(_mdp_from_upload, body.form, body.file, settings)
        created = await run_in_threadpool(
            mdps.create_mdp, session, lab_id=lab.id, name=_form_name(body.form), source="npz", mdp=mdp
        )
    else:
        mdp, grid = await run_in_threadpool(_json_mdp, body, settings)
        created = await run_in_threadpool(
            mdps.create_mdp, session, lab_id=lab.id, name=body.name, source=body.kind, mdp=mdp, grid=grid
        )
    await run_in_threadpool(session.commit)
    response.headers["Location"] = f"/v1/mdps/{created.id}"
    return MdpOut.of(created, mdps.array_blobs(session, [created]))


def _json_mdp(body: ExplicitMdpIn | GridMdpIn, settings: Settings) -> tuple[MDP, dict[str, Any] | None]:
    """The engine's MDP of a JSON body, and a grid's parameters; `InvalidInput` naming every problem the checks
    after the schema find: a grid over the size or memory limits (before it is built), the engine's checks, the
    built MDP over the size limits."""
    if isinstance(body, ExplicitMdpIn):
        mdp, grid = mdps.build_explicit(body), None
    else:
        check(
            grid_issues(
                width=body.width,
                height=body.height,
                moves=body.moves or (8 if body.velocity else 4),
                stay=body.stay,
                slip=body.slip,
                velocity=body.velocity,
                settings=settings,
            )
        )
        mdp, grid = mdps.build_grid(body)
    features = None if mdp.features is None else mdp.n_features
    check(mdp_size_issues(mdp.n_states, mdp.n_actions, features, settings, pointer=""))
    return mdp, grid


def _refused_issues(settings: Settings, sent: Any) -> list[Issue]:
    """What `_json_mdp` finds in a JSON MDP the schema refused, when its kind and the fields those checks read
    (`CHECKED`) pass the schema; a refused `gamma` is only the schema's issue. Nothing otherwise: the checks
    would judge the arrays against counts or a grid the body does not validly give."""
    kind = sent.get("kind") if isinstance(sent, dict) else None
    if not isinstance(kind, str) or kind not in CHECKED:
        return []
    model, read = CHECKED[kind]
    fields = valid_fields(model, sent)
    if not set(read) <= fields.keys():
        return []
    body = model.model_construct(**({"gamma": STAND_IN_GAMMA} | fields))
    issues: list[Issue] = []
    gathering(issues, lambda: _json_mdp(body, settings))
    return issues


def _form_name(form: FormData) -> str:
    """The `name` form field, checked like the JSON `name`."""
    name = form.get("name")
    if not isinstance(name, str) or not 1 <= len(name.strip()) <= 200:
        raise Unprocessable(
            "The form field name is required.",
            errors=[{"pointer": "/name", "message": "is required (1 to 200 characters)"}],
        )
    return name.strip()


def _form_number(form: FormData, field: str, kind: type[int] | type[float]) -> Any:
    """An optional numeric form field, or None; 422 at /field if it is not a number of that kind."""
    raw = form.get(field)
    if raw is None or raw == "":
        return None
    try:
        return kind(str(raw))
    except ValueError as exc:
        raise Unprocessable(
            f"The form field {field} must be {'an integer' if kind is int else 'a number'}.",
            errors=[
                {
                    "pointer": f"/{field}",
                    "message": f"must be {'an integer' if kind is int else 'a number'}, got {raw!r}",
                }
            ],
        ) from exc


def _mdp_from_upload(form: FormData, upload: UploadFile, settings: Settings) -> MDP:
    """The engine's MDP from an `.npz` upload and its form fields (raises 422 / `InvalidInput`); sizes are
    checked from the members' headers before any array is read, and again on the built MDP."""
    _form_name(form)
    headers = npz_headers(upload.file, pointer="/file", settings=settings)
    next_state = headers.get("next_state", ((), None))[0]
    features = headers.get("features", ((), None))[0]
    if len(next_state) == 2:
        first_too_large(mdp_size_issues(*next_state, None, settings, pointer="/file", what="next_state"))
    if len(features) == 2:
        first_too_large(
            mdp_size_issues(features[0], 1, features[1], settings, pointer="/file", what="features")
        )
    arrays = read_npz(upload.file, pointer="/file")
    unknown = sorted(set(arrays) - set(NPZ_ARRAYS))
    if unknown:
        raise Unprocessable(
            f"mdp.npz holds unexpected arrays {unknown}.",
            errors=[
                {
                    "pointer": "/file",
                    "message": f"unexpected arrays {unknown}; expected some of {list(NPZ_ARRAYS)}",
                }
            ],
        )
    gamma = _form_number(form, "gamma", float)
    if gamma is None:
        raise Unprocessable(
            "The form field gamma is required.", errors=[{"pointer": "/gamma", "message": "is required"}]
        )
    width, height = _form_number(form, "width", int), _form_number(form, "height", int)
    if (width is None) != (height is None):
        raise Unprocessable(
            "Give both width and height, or neither.",
            errors=[{"pointer": "/width", "message": "width and height go together"}],
        )
    channels = _form_number(form, "channels", int)
    layout = None
    if width is not None:
        layout = Layout(width=width, height=height, channels=1 if channels is None else channels)
    mdp = MDP.build(
        gamma=gamma,
        n_states=_form_number(form, "n_states", int),
        n_actions=_form_number(form, "n_actions", int),
        layout=layout,
        **arrays,
    )
    features_width = None if mdp.features is None else mdp.n_features
    first_too_large(mdp_size_issues(mdp.n_states, mdp.n_actions, features_width, settings, pointer="/file"))
    return mdp


@router.get("/mdps", summary="List MDPs")
def list_mdps(lab: LabDep, session: SessionDep, page: PageDep) -> Page[MdpOut]:
    """Your lab's MDPs, newest first (metadata only)."""
    rows = mdps.list_mdps(session, lab_id=lab.id, page=page)
    blobs = mdps.array_blobs(session, rows.rows)
    return Page[MdpOut].of(rows, lambda row: MdpOut.of(row, blobs))


@router.get("/mdps/{mdp_id}", summary="Get an MDP's metadata and summary")
def get_mdp(mdp_id: str, lab: LabDep, session: SessionDep) -> MdpOut:
    """Sizes, layout, a summary and array checksums; never the arrays themselves."""
    row = mdps.get_mdp(session, mdp_id, lab_id=lab.id)
    return MdpOut.of(row, mdps.array_blobs(session, [row]))


@router.delete(
    "/mdps/{mdp_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    summary="Delete an MDP",
    responses=DELETED,
)
def delete_mdp(mdp_id: str, lab: LabDep, session: SessionDep) -> Response:
    """Removes the MDP and its stored arrays; 409 while a task or recording still uses it (delete those
    first)."""
    delete_mdp_rows(session, mdps.get_mdp(session, mdp_id, lab_id=lab.id))
    commit_deletion(session)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get(
    "/mdps/{mdp_id}/arrays",
    summary="Download an MDP's arrays as .npz",
    response_class=Response,
    responses={
        200: {"content": {"application/octet-stream": {}}, "description": "An .npz archive (no pickles)."}
    },
)
def get_mdp_arrays(
    mdp_id: str,
    lab: LabDep,
    session: SessionDep,
    format: Annotated[Literal["npz"], Query(description="Archive format (only npz).")] = "npz",
) -> Response:
    """`features` (unless tabular), and `next_state` or `s`, `a`, `next`, `p`: the names `POST /v1/mdps` takes."""
    row = mdps.get_mdp(session, mdp_id, lab_id=lab.id)
    content = write_npz(load_mdp(session, row.id).arrays())
    return Response(
        content,
        media_type="application/octet-stream",
        headers={"Content-Disposition": f'attachment; filename="{row.id}.{format}"'},
    )
