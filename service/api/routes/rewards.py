"""Learned rewards (docs/api.md, "Rewards"): a succeeded job's rewards, and one reward, value function or policy as a file.

Thin routes over `service.results`. The download route runs on the event loop: npy and json come from the
stored bytes, read with the key check in one statement on the async engine (service/api/async_db.py); csv and
png, and json's encoding, run in FastAPI's thread pool (``run_in_threadpool``), so building a large file or
drawing a heatmap (up to ~2 s at 80,000 states) never blocks the loop.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Query, Request, Response
from fastapi.security import HTTPAuthorizationCredentials
from starlette.concurrency import run_in_threadpool

from service.api.async_db import connection
from service.api.auth import BearerDep, authorised_row, current_lab
from service.api.deps import JobDep, SessionDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.responses import NOT_SUCCEEDED, file_response
from service.domain.rewards import Format, JobRewards, Overlay, Quantity, RewardValues
from service.results import downloads, rewards

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
            "description": "The baseline has no value or policy; a fit with one ensemble member has no "
            "uncertainty; a PNG of an MDP without a layout or of a policy cannot be drawn."
        },
    },
)
async def download_reward(
    reward_id: str,
    request: Request,
    credentials: BearerDep,
    format: Annotated[
        Format, Query(description="`json` (default), `npy` (float32), `csv` or `png`.")
    ] = "json",
    quantity: Annotated[
        Quantity,
        Query(
            description="`reward`, or a task's `value` function or `policy` (S×A; no png); `uncertainty`: "
            "the reward's spread across the ensemble's members per state; `evidence`: 1 where the "
            "demonstrations pass, 0.5 one move from there, 0 elsewhere."
        ),
    ] = "reward",
    overlay: Annotated[
        Overlay, Query(description="png only: `demos` draws the demonstrated trajectories on the map.")
    ] = "none",
    if_none_match: Annotated[str | None, Header(description="An ETag from an earlier download.")] = None,
) -> Response:
    """The values of one learned reward as a file (or a task's value function or policy)."""
    if format in downloads.STORED_FORMATS and overlay == "none":
        return file_response(
            await _stored_download(
                request, credentials, reward_id, fmt=format, quantity=quantity, if_none_match=if_none_match
            )
        )
    return file_response(
        await run_in_threadpool(
            _made_download,
            request,
            credentials,
            reward_id,
            fmt=format,
            quantity=quantity,
            overlay=overlay,
            if_none_match=if_none_match,
        )
    )


async def _stored_download(
    request: Request,
    credentials: HTTPAuthorizationCredentials | None,
    reward_id: str,
    *,
    fmt: Format,
    quantity: Quantity,
    if_none_match: str | None,
) -> downloads.Download:
    """npy or json from the stored bytes: the key check, the reward (in the key's lab), its names and the blob's
    SHA-256 and bytes are one statement. With ``If-None-Match`` the bytes are left out of it and read by a
    second only when the client's copy is out of date."""
    query = downloads.keyed_stored_file(quantity, with_data=not if_none_match)
    found = await authorised_row(request, credentials, query, reward_id=reward_id)
    stored = downloads.stored_file(found, reward_id, fmt=fmt, quantity=quantity)
    if downloads.etag_matches(if_none_match, stored.etag):
        return stored.answer(None)
    if if_none_match:
        async with connection(request) as db:
            data = (await db.execute(downloads.BLOB_DATA, {"blob_id": found.blob_id})).scalar_one()
    else:
        data = found.blob_data
    if fmt == "npy":  # a header and the stored bytes: no work worth a thread
        return stored.answer(stored.content(data))
    return stored.answer(await run_in_threadpool(stored.content, data))


def _made_download(
    request: Request,
    credentials: HTTPAuthorizationCredentials | None,
    reward_id: str,
    *,
    fmt: Format,
    quantity: Quantity,
    overlay: Overlay,
    if_none_match: str | None,
) -> downloads.Download:
    """csv, png, or a json or npy with an overlay (422): made from the loaded array in a thread of the pool, on
    the sync path (`current_lab`, a session of its own)."""
    lab = current_lab(request, credentials)
    with request.app.state.sessionmaker() as session:
        ctx = rewards.reward_context(session, reward_id, lab_id=lab.id)
        return downloads.download(
            session, ctx, fmt=fmt, quantity=quantity, overlay=overlay, if_none_match=if_none_match
        )
