"""Learned rewards (docs/api.md, "Rewards"): a succeeded job's rewards, and one reward, value function or policy as a file.

Thin routes over `service.jobs.rewards`. The download route is a plain ``def``: FastAPI runs it in its thread
pool (``run_in_threadpool``), so drawing a heatmap (up to ~2 s at 80,000 states) never blocks the event loop.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Query, Response

from service.api.auth import LabDep
from service.api.deps import JobDep, SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.responses import NOT_SUCCEEDED, file_response
from service.api.schemas.rewards import Format, JobRewards, Overlay, Quantity, RewardValues
from service.jobs import rewards

router = APIRouter(tags=["rewards"], responses=PROBLEM_RESPONSES)


@router.get("/jobs/{job_id}/rewards", summary="A job's learned rewards", responses=NOT_SUCCEEDED)
def job_rewards(
    job: JobDep,
    session: SessionDep,
    exclude_top_truth: Annotated[
        bool,
        Query(
            description="Also score each task reward against its true reward without the states where the "
            "truth is highest (the goal): `truth_pearson_excluding_top`."
        ),
    ] = False,
) -> JobRewards:
    """The baseline and every task's reward in the job's task order: summary statistics, `truth_pearson`
    against the task's current true reward (when one is set) and download links."""
    rewards.require_succeeded(job)
    return rewards.job_rewards(session, job, exclude_top_truth=exclude_top_truth)


@router.get(
    "/rewards/{reward_id}",
    summary="Download a reward, value function or policy (json, npy, csv, png)",
    response_model=RewardValues,
    responses={
        200: {
            "description": "JSON (`values`), a float32 `.npy`, CSV (`state[,x,y,channel],<quantity>` or one "
            "column per action), or a PNG heatmap. `ETag` and `Content-Disposition` are set.",
            "content": {"application/octet-stream": {}, "text/csv": {}, "image/png": {}},
        },
        304: {"description": "`If-None-Match` names the current ETag: your copy is up to date."},
        409: {
            "description": "The baseline has no value or policy; a PNG of an MDP without a layout or of a "
            "policy cannot be drawn."
        },
    },
)
def download_reward(
    reward_id: str,
    session: SessionDep,
    lab: LabDep,
    format: Annotated[
        Format, Query(description="`json` (default), `npy` (float32), `csv` or `png`.")
    ] = "json",
    quantity: Annotated[
        Quantity, Query(description="`reward`, or a task's `value` function or `policy` (S×A; no png).")
    ] = "reward",
    overlay: Annotated[
        Overlay, Query(description="png only: `demos` draws the demonstrated trajectories on the map.")
    ] = "none",
    if_none_match: Annotated[str | None, Header(description="An ETag from an earlier download.")] = None,
) -> Response:
    """The values of one learned reward as a file (or a task's value function or policy)."""
    if format in rewards.STORED_FORMATS and overlay == "none":
        return file_response(
            rewards.stored_download(
                session, reward_id, lab_id=lab.id, fmt=format, quantity=quantity, if_none_match=if_none_match
            )
        )
    ctx = rewards.reward_context(session, reward_id, lab_id=lab.id)
    return file_response(
        rewards.download(
            session, ctx, fmt=format, quantity=quantity, overlay=overlay, if_none_match=if_none_match
        )
    )
