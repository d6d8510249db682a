"""Learned rewards (API.md §6): a succeeded job's rewards, and one reward, value function or policy as a file.

Thin routes over `service.results`. The download route is a plain ``def``: FastAPI runs it in its thread
pool (``run_in_threadpool``), so drawing a heatmap (up to ~2 s at 80,000 states) never blocks the event loop.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Header, Query, Response

from service import results
from service.auth import LabDep
from service.deps import SessionDep
from service.openapi import PROBLEM_RESPONSES
from service.routes.jobs import JobDep
from service.schemas.rewards import Format, JobRewards, Overlay, Quantity, RewardValues

router = APIRouter(tags=["rewards"], responses=PROBLEM_RESPONSES)

NOT_SUCCEEDED: dict[int | str, dict[str, Any]] = {409: {"description": "The job has not succeeded."}}


def file_response(download: results.Download) -> Response:
    """The file with its media type, ``Content-Disposition`` and ``ETag``; an empty 304 when not modified."""
    headers = {"Content-Disposition": f'{download.disposition}; filename="{download.filename}"'}
    if download.etag is not None:
        headers |= {"ETag": download.etag, "Cache-Control": "private, no-cache"}
    if download.content is None:
        return Response(status_code=304, headers=headers)
    return Response(download.content, media_type=download.media_type, headers=headers)


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
    results.require_succeeded(job)
    return results.job_rewards(session, job, exclude_top_truth=exclude_top_truth)


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
    ctx = results.reward_context(session, reward_id, lab_id=lab.id)
    return file_response(
        results.download(
            session, ctx, fmt=format, quantity=quantity, overlay=overlay, if_none_match=if_none_match
        )
    )
