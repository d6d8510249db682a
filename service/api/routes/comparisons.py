"""Comparisons (docs/api.md, "Comparisons"): two rewards, a reward and a true reward or values; a job's Pearson matrix; key states.

Thin routes over `service.results`; plain ``def`` routes, so FastAPI runs them (and the matrix PNG) in its
thread pool.
"""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Body, Query, Response

from service.api.auth import LabDep
from service.api.deps import JobDep, SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.responses import NOT_SUCCEEDED, file_response
from service.domain.comparisons import EXAMPLES, ComparisonOut, ComparisonSubmission
from service.domain.rewards import ComparisonMatrix, KeyStates
from service.results import comparisons, downloads, rewards
from service.results.key_states import reward_key_states

router = APIRouter(tags=["comparisons"], responses=PROBLEM_RESPONSES)

MAX_KEY_STATES = 1000


@router.post(
    "/comparisons",
    summary="Compare a learned reward with another, a true reward or values",
    description="Rewards of any job and demonstrator of your lab compare by id (e.g. one patient "
    "stimulated and unstimulated). A reward, task or length that does not fit is a 422 naming the field, in one "
    "answer with the body's other problems.",
    responses={409: {"description": "`b.task_id` names a task without a true reward."}},
)
def create_comparison(
    body: Annotated[ComparisonSubmission, Body(openapi_examples=EXAMPLES)], session: SessionDep, lab: LabDep
) -> ComparisonOut:
    """Pearson, Spearman (contract) and EPIC distance on all states or on the demonstrated ones."""
    return comparisons.compare(session, body, lab_id=lab.id)


@router.get(
    "/jobs/{job_id}/comparison-matrix",
    summary="Pairwise Pearson correlations of a job's rewards",
    response_model=ComparisonMatrix,
    responses={
        200: {
            "description": "JSON, or with `?format=png` an annotated matrix.",
            "content": {"image/png": {}},
        },
        **NOT_SUCCEEDED,
    },
)
def comparison_matrix(
    job: JobDep,
    session: SessionDep,
    format: Annotated[Literal["json", "png"], Query(description="`json` (default) or `png`.")] = "json",
) -> ComparisonMatrix | Response:
    """Pearson r between the baseline and every task reward, and between the task rewards."""
    rewards.require_succeeded(job)
    matrix = comparisons.comparison_matrix(session, job)
    if format == "png":
        return file_response(downloads.matrix_download(session, job, matrix))
    return matrix


@router.get(
    "/rewards/{reward_id}/key-states",
    summary="Where a task reward departs most from its baseline",
    responses={409: {"description": "The reward is the baseline itself."}},
)
def key_states(
    reward_id: str,
    session: SessionDep,
    lab: LabDep,
    top: Annotated[int, Query(ge=1, le=MAX_KEY_STATES, description="How many states.")] = 10,
) -> KeyStates:
    """The paper's key states: largest |task reward − baseline| first, with (x, y, channel) on a layout."""
    ctx = rewards.reward_context(session, reward_id, lab_id=lab.id)
    return reward_key_states(session, ctx, top=top)
