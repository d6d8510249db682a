"""The motion readout (docs/api.md, "Motion readout"): a demonstrator's kinematics per direction
from its recordings, and two demonstrators' (sessions') differences with the learned-reward readout beside
them. Plain ``def`` routes: FastAPI runs them (bootstrap and figure) in its thread pool."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Body, Query, Response

from metairl_engine.errors import Issue, check
from service.api.auth import LabDep
from service.api.deps import SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.responses import file_response
from service.domain.motion import (
    COMPARISON_IN_EXAMPLES,
    MotionComparisonIn,
    MotionComparisonOut,
    MotionComparisonSubmission,
    MotionSummaryOut,
)
from service.problems import gathering, validated
from service.results import readout
from service.results.downloads import Download
from service.store.demonstrators import get_demonstrator

router = APIRouter(tags=["motion"], responses=PROBLEM_RESPONSES)

NO_RECORDINGS = "The demonstrator (a side) has no recordings; `detail` says which (problem+json)."


@router.get(
    "/demonstrators/{demonstrator_id}/motion-summary",
    summary="Kinematic readout of a demonstrator's recordings, per direction",
    description="Every recording of the demonstrator is cut into out-and-back movements again (with the "
    "segment settings of its upload) and, per instructed direction, peak reach, path length, deviation from "
    "the instructed line, time to peak and mean speed are summarised by their mean over repetitions with a 95 % "
    "percentile-bootstrap interval (seeded: the same recordings give the same numbers). Lengths are in the "
    "units of the uploaded x, y, times in those of t. `learned` is the learned-reward readout of the "
    "demonstrator's latest succeeded job (null without one), as in the comparison.",
    responses={
        404: {"description": "No such demonstrator in your lab (problem+json)."},
        409: {"description": "The demonstrator has no recordings (problem+json with the reason)."},
    },
)
def motion_summary(demonstrator_id: str, session: SessionDep, lab: LabDep) -> MotionSummaryOut:
    """Per direction: n_segments and each descriptor's mean, low, high; the latest learned readout."""
    demonstrator = get_demonstrator(session, demonstrator_id, lab_id=lab.id)
    return MotionSummaryOut.model_validate(readout.motion_summary(session, demonstrator))


@router.post(
    "/motion-comparisons",
    summary="Compare two demonstrators' (sessions') motion, per direction",
    description="b minus a per direction (those both sides moved in) for every descriptor, with a 95 % "
    "bootstrap interval that resamples each side's repetitions; both sides' summaries; and the learned-reward "
    "readout of each side's latest succeeded job (null without one). With `?format=png` the answer is one "
    "figure: peak reach per direction of both sides, then b − a per descriptor, red where the interval "
    "excludes 0. Nothing is stored.",
    response_model=MotionComparisonOut,
    responses={
        200: {"description": "JSON, or with `?format=png` the figure.", "content": {"image/png": {}}},
        404: {"description": "`a` or `b` is not a demonstrator of your lab (problem+json)."},
        422: {"description": "`b` is the same demonstrator as `a` (problem+json)."},
        409: {"description": NO_RECORDINGS},
    },
)
def motion_comparison(
    body: Annotated[MotionComparisonSubmission, Body(openapi_examples=COMPARISON_IN_EXAMPLES)],
    session: SessionDep,
    lab: LabDep,
    format: Annotated[Literal["json", "png"], Query(description="`json` (default) or `png`.")] = "json",
) -> MotionComparisonOut | Response:
    """Differences with intervals, summaries and learned readouts; or their figure."""
    issues: list[Issue] = []  # the body's problems and a repeated demonstrator, in one 422
    sides = gathering(issues, lambda: validated(MotionComparisonIn, body))
    if isinstance(body.get("a"), str) and body.get("a") == body.get("b"):
        issues.append(
            Issue("/b", "is the same demonstrator as a: every difference would be 0; give another session")
        )
    check(issues)
    assert sides is not None  # else check raised
    a = get_demonstrator(session, sides.a, lab_id=lab.id)
    b = get_demonstrator(session, sides.b, lab_id=lab.id)
    comparison = readout.motion_comparison(session, a, b)
    if format == "png":
        png = readout.comparison_figure(comparison)
        return file_response(
            Download(
                content=png,
                media_type="image/png",
                filename=f"motion-{a.id}-{b.id}.png",
                disposition="inline",
                etag=None,
            )
        )
    return MotionComparisonOut.model_validate(comparison)
